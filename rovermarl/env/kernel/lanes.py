"""Several teams in one rollout's lanes (numba). The fused rollout keeps (rover, episode) pairs rover-major,
``q = i*L + l`` over L lanes; B teams on the same E initial conditions take L = B*E lanes, team b's episodes at
``l = b*E + e`` (genome row ``b*N + i``), so one pass of every stage serves B teams (B = 1: the single rollout, lane
for lane). Every stage works lane by lane, so each team's returns are the bits its own rollout gives.
"""

from __future__ import annotations

import numpy as np
from numba.extending import overload

from rovermarl.jit import njit

SANE = 1e150   # a weight at or beyond this (or nan) makes the MLP's sums overflow: the rovers stop and score 0


@njit(inline="always", cache=True)
def tile_flat(a, teams, out):
    """a (E, N) -> out (N*B*E,) in the flat layout of B = ``teams`` teams: ``out[i*B*E + b*E + e] = a[e, i]``."""
    n_ep, n = a.shape
    for i in range(n):
        for b in range(teams):
            q0 = (i * teams + b) * n_ep
            for e in range(n_ep):
                out[q0 + e] = a[e, i]


@njit(cache=True)
def tile_rows(a, teams):
    """a (E, K) -> (B*E, K): a plug-in's per-episode layout for the lanes of B teams (lane ``b*E + e`` reads row e)."""
    out = np.empty((teams * a.shape[0], a.shape[1]), dtype=a.dtype)
    for b in range(teams):
        for e in range(a.shape[0]):
            for k in range(a.shape[1]):
                out[b * a.shape[0] + e, k] = a[e, k]
    return out


def in_precision(genomes, like):
    """genomes (M, G) float64 in ``like``'s dtype (the kernel's precision): themselves, or a float32 copy."""
    return genomes.astype(like.dtype)


@overload(in_precision, inline="always")
def _in_precision(genomes, like):
    if genomes.dtype == like.dtype:
        return lambda genomes, like: genomes

    def cast(genomes, like):
        out = np.empty(genomes.shape, dtype=like.dtype)
        for r in range(genomes.shape[0]):
            for v in range(genomes.shape[1]):
                out[r, v] = genomes[r, v]
        return out
    return cast


@njit(inline="always", cache=True)
def sane_teams(genomes, n, out):
    """out[b] (B,) bool: every weight of team b's rows ``b*n .. b*n + n - 1`` of genomes (B*n, G) float64 has
    magnitude below :data:`SANE` (so not nan or inf either)."""
    for b in range(out.shape[0]):
        ok = True
        for r in range(b * n, (b + 1) * n):
            for v in range(genomes.shape[1]):
                ok &= abs(genomes[r, v]) < SANE
        out[b] = ok
