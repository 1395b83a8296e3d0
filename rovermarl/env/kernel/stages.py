"""The world in stages (numba): sense, act and move (SPEC sections 2-4; the reward stage is
:mod:`~rovermarl.env.kernel.reward`). E episodes, N rovers, P POIs, D = 3P + 2N observation size, H hidden units, G
genome length.

:func:`act` takes batch-first arrays and runs the same compiled loops (``*_flat``) as the fused
:func:`~rovermarl.env.kernel.fused.rollout`, so ``fused.observe -> act -> fused.step`` then ``reward`` gives the
rollout's numbers bit for bit. The flat layout (docs/WORLDS.md) keeps the pairs ``q = i*E + e`` rover-major in (N*E,)
arrays and the observations feature-major in (D*N*E,), so that the loops over episodes are contiguous and LLVM
vectorises them; indices there are unsigned (``U``): numba's negative-index wraparound blocks vectorisation. The small
flat functions are inlined (no per-call array reference counting in the step loop) and take their caller's compile
options, so every caller of ``act_flat``/``move_flat`` is ``FAST``. A function that stays a call of its own (``_mlp``,
``_sense_rows``) has one way out (no break, no early return) and calls no other with its arrays: else numba keeps two
atomic reference counts per array argument per call (on this Intel CPU, 13% of the rollout's time before).
"""

from __future__ import annotations

import math

import numpy as np

from rovermarl.env.kernel.checks import in_range
from rovermarl.env.kernel.math import FAST, U, like, sincos_all, tanh, wrap
from rovermarl.env.kernel.rules import bearing, reading, speed, turn
from rovermarl.env.kernel.simd import UNITS, hidden_tile, lanes, output_tile, output_tile2
from rovermarl.jit import njit

# ---- batch-first stages ------------------------------------------------------------------------------------------

@njit(**FAST)
def act(genomes, obs, hidden, out):
    """Actions of a team over a batch of episodes: genomes (N, G) one row per rover, obs (E, N, D) -> out (E, N, 2),
    the two tanh outputs ``(a0, a1)`` of each rover's MLP (D -> H -> 2, tanh on both layers; SPEC section 4).

    >>> import numpy as np
    >>> g = np.zeros((1, 3 * 2 + 2 + 2 * 2 + 2)); g[0, -2:] = [0.5, -1.0]   # N = 1, D = 3, H = 2: biases only
    >>> out = np.empty((1, 1, 2))
    >>> act(g, np.ones((1, 1, 3)), 2, out)
    >>> out.round(4).tolist()
    [[[0.4621, -0.7616]]]
    """
    n_ep, n, d = obs.shape
    ne = n * n_ep
    if genomes.shape != (n, (d + 3) * hidden + 2) or out.shape != (n_ep, n, 2):
        raise ValueError("act: expected genomes (N, (D + 3) H + 2), obs (E, N, D) and out (E, N, 2)")
    flat = np.empty(d * ne, dtype=obs.dtype)
    for k in range(d):
        to_flat(obs[:, :, k], flat[k * ne:(k + 1) * ne])
    g = np.empty(genomes.shape, dtype=obs.dtype)            # the MLP runs in the observations' precision
    g[:] = genomes
    a = np.empty((2, ne), dtype=obs.dtype)
    every = np.empty((n, d), dtype=np.int64)                # any input row may be nonzero here
    every[:] = np.arange(d)
    act_flat(g, flat, every, n_ep, hidden, np.empty((hidden + 2) * n_ep, dtype=obs.dtype),
             np.empty(d, dtype=np.int64), a[0], a[1])
    from_flat(a[0], out[:, :, 0])
    from_flat(a[1], out[:, :, 1])


@njit(cache=True)
def sense_libm(xy, heading, poi_xy, poi_type, sensor_range, out):
    """``fused.observe`` of the paper's world with libm ``atan2``, ``wrap(atan2(dy, dx) - heading)`` and true
    division: the same readings within a few ulp. ``World.observe`` reports these. xy (E, N, 2), heading (E, N) -> out
    (E, N, D)."""
    n = xy.shape[1]
    p = poi_xy.shape[0]
    for b in range(xy.shape[0]):
        for i in range(n):
            x = xy[b, i, 0]
            y = xy[b, i, 1]
            h = heading[b, i]
            for j in range(p):
                dx = poi_xy[j, 0] - x
                dy = poi_xy[j, 1] - y
                d = math.sqrt(dx * dx + dy * dy)
                o = 3 * j
                out[b, i, o], out[b, i, o + 1], out[b, i, o + 2] = reading(
                    d, sensor_range, d / sensor_range, wrap(math.atan2(dy, dx) - h) / math.pi, poi_type[j])
            for m in range(n):
                o = 3 * p + 2 * m
                dx = xy[b, m, 0] - x
                dy = xy[b, m, 1] - y
                d = math.sqrt(dx * dx + dy * dy)
                r0, r1, _ = reading(d, sensor_range, d / sensor_range, wrap(math.atan2(dy, dx) - h) / math.pi, 0.0)
                out[b, i, o] = 0.0 if m == i else r0
                out[b, i, o + 1] = 0.0 if m == i else r1


# ---- flat layout: the loops of the fused rollout -----------------------------------------------------------------

@njit(inline="always", cache=True)
def to_flat(a, out):
    """a (E, N) -> out (N*E,) rover-major: ``out[i*E + e] = a[e, i]``."""
    n_ep, n = a.shape
    for i in range(n):
        for e in range(n_ep):
            out[i * n_ep + e] = a[e, i]


@njit(inline="always", cache=True)
def from_flat(v, out):
    """v (N*E,) rover-major -> out (E, N): ``out[e, i] = v[i*E + e]``."""
    n_ep, n = out.shape
    for i in range(n):
        for e in range(n_ep):
            out[e, i] = v[i * n_ep + e]


@njit(**FAST)
def flat_pose(xy, heading, rows):
    """The pose in the flat layout: xy (E, N, 2), heading (E, N) -> state (rows >= 5, N*E) with rows x, y, heading,
    sin_h, cos_h (rover-major, as :func:`to_flat`); the rows after them are the caller's."""
    n_ep, n = heading.shape
    state = np.empty((rows, n * n_ep), dtype=xy.dtype)
    to_flat(xy[:, :, 0], state[0])
    to_flat(xy[:, :, 1], state[1])
    to_flat(heading, state[2])
    sincos_all(state[2], state[3], state[4])
    return state


@njit(inline="always", **FAST)
def sense_flat(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs):
    """Observations in the flat layout: x, y, sin_h, cos_h (N*E,) of n rovers -> obs (D*N*E,) feature-major. POI j
    fills ``[d / range, bearing / pi, type]`` at 3j; rover m fills ``[d / range, bearing / pi]`` at 3P + 2m (own slot
    ``[0, 0]``); beyond ``sensor_range`` a target reads ``[1, 0, 0]`` / ``[1, 0]`` (:func:`reading`). Where
    :func:`in_range` holds (every step of a world of finite numbers at sane scales) the bearings take the ranged
    ``atan2`` (the same bits with fewer operations), else the general one; returns whether it held. Inlined: as a
    call of its own it counted references to its 7 arrays around its call of :func:`_sense_rows`, 16 atomic
    instructions a step (gdb on NRT_incref/NRT_decref)."""
    if in_range(x, y, sin_h, cos_h, poi_xy):
        _sense_rows(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs, True)
        return True
    _sense_rows(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs, False)
    return False


@njit(**FAST)
def _sense_rows(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs, ranged):
    """The loops of :func:`sense_flat`; ``ranged`` goes to :func:`bearing`. Not inlined by numba (LLVM still may):
    numba's inlining of it, twice, took 9-10 s of a cold start's 55-60 s of compiling; numba still specialises it
    on the literal ``ranged``, and the kernel's absolute rate is the same (docs/PERFORMANCE.md)."""
    ne = x.shape[0]
    p = poi_xy.shape[0]
    inv_pi = like(sensor_range, 1.0 / math.pi)
    inv_range = like(sensor_range, 1.0) / sensor_range
    for j in range(p):
        px = poi_xy[j, 0]
        py = poi_xy[j, 1]
        typ = poi_type[j]
        o = U(3 * j * ne)
        for q in range(ne):
            dx = px - x[q]
            dy = py - y[q]
            d = math.sqrt(dx * dx + dy * dy)
            b = bearing(dx, dy, cos_h[q], sin_h[q], ranged)
            obs[o + U(q)], obs[o + U(ne + q)], obs[o + U(2 * ne + q)] = reading(
                d, sensor_range, d * inv_range, b * inv_pi, typ)
    sense_rovers(x, y, sin_h, cos_h, n, 3 * p, sensor_range, obs, ranged)


@njit(inline="always", **FAST)
def sense_rovers(x, y, sin_h, cos_h, n, row, sensor_range, obs, ranged=False):
    """The rover block of the observation in the flat layout: rover m's ``[d / range, bearing / pi]`` at rows
    ``row + 2m`` (own slot ``[0, 0]``), for a world plug-in's ``sense`` hook too. ``ranged``: as :func:`bearing`."""
    ne = x.shape[0]
    ep = ne // n
    inv_pi = like(sensor_range, 1.0 / math.pi)
    inv_range = like(sensor_range, 1.0) / sensor_range
    for m in range(n):
        o = U((row + 2 * m) * ne)
        for i in range(n):
            qi = U(i * ep)
            qm = U(m * ep)
            if i == m:
                for e in range(ep):
                    obs[o + qi + U(e)] = 0.0
                    obs[o + U(ne) + qi + U(e)] = 0.0
                continue
            for e in range(ep):
                q = qi + U(e)
                dx = x[qm + U(e)] - x[q]
                dy = y[qm + U(e)] - y[q]
                d = math.sqrt(dx * dx + dy * dy)
                b = bearing(dx, dy, cos_h[q], sin_h[q], ranged)
                obs[o + q], obs[o + U(ne) + q], _ = reading(d, sensor_range, d * inv_range, b * inv_pi, 0.0)


@njit(inline="always", **FAST)
def act_flat(genomes, obs, cand, n_ep, hidden, hid, rows, a0, a1, finite=False):
    """:func:`act` in the flat layout: genomes (N, G), obs (D*N*E,) feature-major -> a0, a1 (N*E,) rover-major.
    cand (N, D) int64: the input rows of each rover that may be nonzero (``checks.input_rows``; ``arange(D)`` when
    unknown); hid ((H+2)*E / B,) and rows (D,) int64 are scratch. ``finite``: every sum is finite (``checks.mlp_finite``
    and ``checks.in_range``), so the tanh may leave out its NaN case.
    genomes (B*N, G) are B teams side by side: team b's rover i (row ``b*N + i``) acts in the E / B episodes from
    ``i*E + b*E/B`` (the batched rollout's lanes; B = 1 is one team)."""
    per = n_ep * cand.shape[0] // genomes.shape[0]  # episodes per team
    p0 = hidden * per
    for r in range(genomes.shape[0]):
        _mlp(genomes, r, obs, cand, per, hidden, hid, rows, finite)
        q0 = _lane0(r, cand.shape[0], genomes.shape[0], per)
        for e in range(per):                        # the outputs' sums, from the end of the scratch
            a0[U(q0 + e)] = hid[U(p0 + e)]
            a1[U(q0 + e)] = hid[U(p0 + per + e)]
    # The output tanh over all rovers at once: the same values, and the long loops hide its latency (the act
    # stage took 57.4 instead of 65.6 ns per agent-step with E = 16 per rover).
    if finite:
        _squash(a0, a0.shape[0], True)
        _squash(a1, a1.shape[0], True)
    else:
        _squash(a0, a0.shape[0], False)
        _squash(a1, a1.shape[0], False)


@njit(inline="always", cache=True)
def _lane0(r, n, rows, per):
    """The first lane of genome row r (team ``r // n``'s rover ``r % n``) of ``rows`` rows, ``per`` episodes a team."""
    return ((r % n) * (rows // n) + r // n) * per


@njit(inline="always", **FAST)
def _squash(a, n, finite):
    """a[:n] <- tanh(a[:n]) in place (no view, so no reference counting); ``finite`` a constant at the call."""
    for v in range(n):
        a[U(v)] = tanh(a[U(v)], finite)


@njit(inline="always", **FAST)
def move_flat(x, y, heading, sin_h, cos_h, a0, a1, v_max, w_max, speed_mode):
    """One step of motion in the flat layout, in place: each rover turns by :func:`turn` first, then moves
    :func:`speed` along its new heading (``speed_mode``: the index of ``env.speed`` in
    :data:`~rovermarl.env.kernel.rules.SPEEDS`); all arrays (N*E,); sin_h, cos_h follow the new heading."""
    ne = x.shape[0]
    for q in range(ne):
        heading[q] = turn(heading[q], a1[q], w_max)
    sincos_all(heading, sin_h, cos_h)
    for q in range(ne):
        v = speed(a0[q], v_max, speed_mode)
        x[q] += v * cos_h[q]
        y[q] += v * sin_h[q]


@njit(**FAST)
def _mlp(genomes, i, obs, cand, ep, hidden, hid, rows, finite):
    """MLP of genome row i (team ``i // N``'s rover ``i % N``) over its ``ep`` episodes from the lane :func:`_lane0`
    gives, inputs summed in index order: genomes, cand and ``finite`` as in :func:`act_flat`, obs (D*N*E,)
    feature-major; hid ((H+2)*ep,): the hidden units, then the two outputs' sums before their tanh in its last 2 ep
    entries (:func:`act_flat` applies it); rows (D,) int scratch. Every array is read in place, never through a view
    (a rover's row, a slice), and the call takes few arrays: each view, and each array argument of a call, costs two
    atomic reference counts (without the views the rollout ran 1.02x, without a0 and a1 here 1.01-1.04x)."""
    g = genomes.shape[1]
    ne = ep * genomes.shape[0]
    q0 = _lane0(i, cand.shape[0], genomes.shape[0], ep)
    rover = i % cand.shape[0]
    d = obs.shape[0] // ne
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    p0 = hidden * ep                                  # the output layer's sums: hid[p0 + j*ep + e]
    # Rows of obs that are zero in all E episodes add nothing: skip them. Exact for finite weights (h + 0 * w == h,
    # up to the sign of a zero h). cand leaves out those that always are (own rover slot, POI types of 0).
    # (No break or early return in this function: see the module docstring.)
    nr, zero = 0, like(genomes[0, 0], 0.0)
    for c in range(d):
        k = cand[U(rover), U(c)]
        if k >= 0:
            ok = U(k * ne + q0)
            nz = obs[ok] != zero                     # most rows that are not zero are so in the first episode
            if not nz:
                for e in range(1, ep):
                    nz |= obs[ok + U(e)] != zero
            if nz:
                rows[nr] = k
                nr += 1
    # the tiles read the genomes as contiguous memory, rover i's from g0 = i*G
    tiles = genomes.strides[1] == genomes.itemsize and genomes.strides[0] == g * genomes.itemsize
    g0 = i * g
    width = lanes(hid)                                # episodes per tile: 8 float64 or 16 float32
    eb = ep - ep % width
    hb = hidden - hidden % UNITS if tiles else 0
    ob = eb if tiles else 0
    # -- the hidden layer's sums: register tiles from the biases (simd.hidden_tile), then what the tiles leave --
    for u0 in range(0, hb, UNITS):
        for e0 in range(0, eb, width):
            hidden_tile(hid, obs, genomes, rows, nr, q0, ne, hidden, u0, ep, e0, g0, g0 + o_b1)
    if hb < hidden or eb < ep:
        for u in range(hidden):
            b = genomes[U(i), U(o_b1 + u)]
            for e in range(eb if u < hb else 0, ep):
                hid[U(u * ep + e)] = b
        for r in range(nr):
            k = rows[r]
            ok = U(k * ne + q0)
            for u in range(hidden):
                w = genomes[U(i), U(k * hidden + u)]
                ou = U(u * ep)
                for e in range(eb if u < hb else 0, ep):
                    hid[ou + U(e)] += obs[ok + U(e)] * w
    # -- the hidden layer's tanh, the output layer --
    if finite:
        _squash(hid, p0, True)
    else:
        _squash(hid, p0, False)
    o2 = ob - ob % (2 * width)
    for e0 in range(0, o2, 2 * width):                # register tiles from the biases (simd.output_tile2, ...
        output_tile2(hid, genomes, hidden, g0 + o_w2, ep, e0, g0 + o_b2)
    for e0 in range(o2, ob, width):                   # ... simd.output_tile) ...
        output_tile(hid, genomes, hidden, g0 + o_w2, ep, e0, g0 + o_b2)
    if ob < ep:                                       # ... then the rest
        b0 = genomes[U(i), U(o_b2)]
        b1 = genomes[U(i), U(o_b2 + 1)]
        for e in range(ob, ep):
            hid[U(p0 + e)] = b0
            hid[U(p0 + ep + e)] = b1
        for u in range(hidden):
            w0 = genomes[U(i), U(o_w2 + 2 * u)]
            w1 = genomes[U(i), U(o_w2 + 2 * u + 1)]
            ou = U(u * ep)
            for e in range(ob, ep):
                hid[U(p0 + e)] += hid[ou + U(e)] * w0
                hid[U(p0 + ep + e)] += hid[ou + U(e)] * w1
