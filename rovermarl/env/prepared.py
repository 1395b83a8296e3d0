"""Evaluation at the kernel's speed: initial conditions prepared once (:class:`Prepared`), teams scored in the
kernel's lanes and on every core (:func:`score_teams`).

``World.prepare(ic)`` checks the initial conditions and puts them in the kernel's precision once; ``World.evaluate``,
``returns``, ``evaluate_many``, ``rollout`` and ``kernel_args`` take the :class:`Prepared` wherever they take ``ic``,
and then check and convert only the genomes per call. Plain initial conditions still work: they are prepared on
every call (a few microseconds). ``World.evaluate_many`` lays several teams' episodes side by side in one rollout's
lanes (:mod:`rovermarl.env.kernel.lanes`) and, for a population of at least two teams per core, shares its passes
with helper threads that wait in compiled code (:mod:`rovermarl.env.relay`); each score is the bits
``World.evaluate`` gives.
"""

from __future__ import annotations

import os
import warnings
from typing import NamedTuple

import numpy as np

from rovermarl import jit
from rovermarl.env.relay import relay

PASS_LANES = 256        # episodes of all teams in one pass of the batched rollout (16 teams of 16 episodes)
SHARED_LANES = 64       # the same when threads share the passes: smaller passes end together (4 teams of 16)
_NO_FINAL = np.empty((0, 1, 2))
_COUNTERS = np.zeros(1, dtype=np.int64)   # a stand-in of the pass counter's type, for jit.say_if_cold
_F64 = np.dtype(np.float64)


class Prepared(NamedTuple):
    """Initial conditions as the kernel reads them (``World.prepare``): ``ic`` the checked initial conditions
    (float64), ``xy`` (E, N, 2) and ``heading`` (E, N) in ``env.dtype``, C-ordered, writeable copies (later changes
    to the arrays passed in are not seen), ``kernel`` the world's :class:`~rovermarl.env.kernel.KernelWorld` with
    their layout, ``fields`` the same as a plain tuple (numba takes it faster), ``world`` the world that prepared them
    (another world prepares ``ic`` again)."""

    ic: tuple
    xy: np.ndarray
    heading: np.ndarray
    kernel: tuple
    fields: tuple
    world: object

    @property
    def episodes(self) -> int:
        return self.heading.shape[0]


def genomes_in(genomes, shape: tuple[int, ...], what: str) -> np.ndarray:
    """genomes as the kernel takes them: float64, C-ordered and writeable (numba compiles again for a read-only
    array, as Ray delivers it), of ``shape`` (a copy only where needed)."""
    if type(genomes) is np.ndarray and genomes.dtype is _F64 and genomes.shape == shape:
        flags = genomes.flags
        if flags.c_contiguous and flags.writeable:
            return genomes                                  # the common case: 4 checks
    genomes = np.ascontiguousarray(genomes, dtype=np.float64)
    if genomes.shape != shape:
        raise ValueError(f"{what} must have shape ({', '.join(map(str, shape))}), got {genomes.shape}")
    return genomes if genomes.flags.writeable else genomes.copy()


def score_teams(world, teams: np.ndarray, p: Prepared, final_xy=None, workers: int | None = None):
    """Scores (B,), returns (B*E,) of teams (B*N, P) float64 (:func:`genomes_in`) on ``p``; final_xy (B*E, N, 2) if
    given. ``workers``: threads (None: the CPUs this process may run on); used only for at least 2 teams each."""
    b, e = teams.shape[0] // world.n_rovers, p.episodes
    scores, returns, sane = np.empty(b), np.empty(b * e), np.empty(b, dtype=np.bool_)
    final = _NO_FINAL if final_xy is None else final_xy
    threads = min(_cores() if workers is None else workers, b // 2) if b >= 4 else 1
    per_pass = max(1, (PASS_LANES if threads <= 1 else min(SHARED_LANES, PASS_LANES)) // e)
    compiled = world.compiled
    jit.say_if_cold(compiled.evaluate_many, (teams, p.xy, p.heading, p.fields, returns, scores, sane, final, per_pass,
                                             _COUNTERS), "the world's rollout")
    job = (teams, returns, scores, sane, final, per_pass)
    shared = threads > 1 and relay(threads - 1).run(compiled, p, job, threads)
    if not shared:                                       # one thread, or another thread is using the relay
        compiled.evaluate_many(teams, p.xy, p.heading, p.fields, returns, scores, sane, final, per_pass,
                               np.zeros(1, dtype=np.int64))
    if not sane.all():
        warn_insane(sane, returns.reshape(b, e))
    return scores, returns


def warn_insane(sane: np.ndarray, returns: np.ndarray) -> None:
    """One warning naming the first team (B,) whose genomes are not finite numbers of sane size (|w| < 1e150:
    beyond that the MLP's sums overflow) and whose returns (B, E) are all 0: the rollout plays such genomes as rovers
    that stop. A team that scored anyway is not warned about."""
    bad = np.flatnonzero(~sane & ~returns.any(axis=1))
    if bad.size:
        warnings.warn(f"team {int(bad[0])}'s genomes hold nan, inf or magnitudes >= 1e150: the rollout plays them as "
                      "non-finite actions, which score 0", RuntimeWarning, stacklevel=4)


def _cores() -> int:
    """The CPUs this process may run on (its affinity, e.g. under taskset)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                               # not on Linux
        return os.cpu_count() or 1
