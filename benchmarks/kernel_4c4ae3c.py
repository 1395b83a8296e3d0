"""Compiled rollout kernel (numba).

Shapes: N rovers, P POIs, D = 3P + 2N observation size, H hidden units, E episodes, T steps.

Two families live here:

* scalar helpers :func:`sense`, :func:`team_return`, :func:`act` (and their batch forms), a direct
  transcription of SPEC sections 2-4 with libm ``atan2``/``tanh``; ``World.observe`` and
  ``World.team_return`` use them;
* the fast :func:`rollout`, which evaluates a whole team at once. It keeps the state of all ``N*E``
  (rover, episode) pairs in flat rover-major arrays (index ``q = i*E + e``) and runs every stage as
  a loop over those contiguous arrays, so that LLVM vectorises it. For that it uses its own
  branchless :func:`atan2`, :func:`tanh` and :func:`sincos` (pure arithmetic and selects, within a
  few ulp of libm), and measures bearings in the rover's rotated frame. Results agree with the
  scalar transcription up to float rounding.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi

# Only FMA contraction: no reassociation, no finite-math assumptions. Results change by rounding only.
FASTMATH = {"contract"}
_FAST = {"cache": True, "fastmath": FASTMATH, "error_model": "numpy"}


@njit(cache=True, inline="always")
def _wrap(a):
    """Angle wrapped to [-pi, pi)."""
    r = a - TWO_PI * math.floor((a + math.pi) / TWO_PI)
    if r >= math.pi:  # rounding in the floor can land one ulp outside
        r -= TWO_PI
    elif r < -math.pi:
        r += TWO_PI
    return r


@njit(cache=True)
def sense(xy, heading, poi_xy, poi_type, sensor_range, out):
    """Observations of one episode's rovers.

    xy (N, 2), heading (N,), poi_xy (P, 2), poi_type (P,) = coupling - 1 -> out (N, 3P + 2N).
    POI j fills ``[d / range, bearing / pi, type]`` at 3j; rover m fills ``[d / range, bearing / pi]``
    at 3P + 2m (own slot ``[0, 0]``). Targets beyond range read ``[1, 0, 0]`` / ``[1, 0]``.
    """
    n = xy.shape[0]
    p = poi_xy.shape[0]
    for i in range(n):
        x = xy[i, 0]
        y = xy[i, 1]
        h = heading[i]
        for j in range(p):
            dx = poi_xy[j, 0] - x
            dy = poi_xy[j, 1] - y
            d = math.sqrt(dx * dx + dy * dy)
            o = 3 * j
            if d > sensor_range:
                out[i, o] = 1.0
                out[i, o + 1] = 0.0
                out[i, o + 2] = 0.0
            else:
                out[i, o] = d / sensor_range
                out[i, o + 1] = _wrap(math.atan2(dy, dx) - h) / math.pi
                out[i, o + 2] = poi_type[j]
        for m in range(n):
            o = 3 * p + 2 * m
            dx = xy[m, 0] - x
            dy = xy[m, 1] - y
            d = math.sqrt(dx * dx + dy * dy)
            if m == i:
                out[i, o] = 0.0
                out[i, o + 1] = 0.0
            elif d > sensor_range:
                out[i, o] = 1.0
                out[i, o + 1] = 0.0
            else:
                out[i, o] = d / sensor_range
                out[i, o + 1] = _wrap(math.atan2(dy, dx) - h) / math.pi


@njit(cache=True)
def team_return(xy, poi_xy, coupling, value, obs_radius):
    """Return of one episode from final positions xy (N, 2): sum of values of satisfied POIs."""
    total = 0.0
    for j in range(poi_xy.shape[0]):
        count = 0
        for i in range(xy.shape[0]):
            dx = poi_xy[j, 0] - xy[i, 0]
            dy = poi_xy[j, 1] - xy[i, 1]
            if math.sqrt(dx * dx + dy * dy) <= obs_radius:
                count += 1
        if count >= coupling[j]:
            total += value[j]
    return total


@njit(cache=True)
def act(genome, obs, hidden, h_buf):
    """MLP forward for one rover: genome (P,), obs (D,) -> (a0, a1) in [-1, 1]; h_buf (H,) scratch."""
    d = obs.shape[0]
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    for u in range(hidden):
        h_buf[u] = genome[o_b1 + u]
    for i in range(d):
        v = obs[i]
        row = i * hidden
        for u in range(hidden):
            h_buf[u] += v * genome[row + u]
    z0 = genome[o_b2]
    z1 = genome[o_b2 + 1]
    for u in range(hidden):
        t = math.tanh(h_buf[u])
        z0 += t * genome[o_w2 + 2 * u]
        z1 += t * genome[o_w2 + 2 * u + 1]
    return math.tanh(z0), math.tanh(z1)


@njit(cache=True)
def sense_batch(xy, heading, poi_xy, poi_type, sensor_range, out):
    """xy (B, N, 2), heading (B, N) -> out (B, N, D)."""
    for b in range(xy.shape[0]):
        sense(xy[b], heading[b], poi_xy, poi_type, sensor_range, out[b])


@njit(cache=True)
def team_return_batch(xy, poi_xy, coupling, value, obs_radius, out):
    """xy (B, N, 2) -> out (B,)."""
    for b in range(xy.shape[0]):
        out[b] = team_return(xy[b], poi_xy, coupling, value, obs_radius)


# ---- vectorisable elementary functions ------------------------------------------------------------
# Branchless (selects only) so that LLVM vectorises the loops that inline them; numba 0.68 without
# SVML leaves calls to libm atan2/tanh/sin/cos scalar. Accuracy is checked in tests/test_kernel_math.py.

_PIO4_HI = 0.7853981633974483            # fl(pi/4) has 50 significant bits: k * _PIO4_HI is exact for k <= 4
_PIO4_LO = 3.061616997868383e-17         # pi/4 - _PIO4_HI
# Cephes atan rational approximation on |t| <= 0.66: atan(t) = t + t z P(z) / Q(z), z = t^2
_AP0, _AP1, _AP2, _AP3, _AP4 = (-8.750608600031904122785e-01, -1.615753718733365076637e+01,
                                -7.500855792314704667340e+01, -1.228866684490136173410e+02,
                                -6.485021904942025371773e+01)
_AQ0, _AQ1, _AQ2, _AQ3, _AQ4 = (2.485846490142306297962e+01, 1.650270098316988542046e+02,
                                4.328810604912902668951e+02, 4.853903996359136964868e+02,
                                1.945506571482613964425e+02)
_BIG = 2.0 ** 800
_TINY = 2.0 ** -800


@njit(inline="always", **_FAST)
def atan2(y, x):
    """Branchless ``math.atan2(y, x)`` for floats (within 2 ulp; signed zeros, infinities, NaN as libm).

    Octant reduction to ``t = min/max`` or ``(min - max)/(min + max)`` (one division), the Cephes
    rational on ``|t| <= 0.66``, then ``k*pi/4 +- atan(t)`` with ``pi/4`` split in two parts.
    """
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    down = den > _BIG
    up = den < _TINY
    scale = _TINY if down else 1.0
    scale = _BIG if up else scale                  # keeps num + den finite and normal
    num = num * scale
    den = den * scale
    eq = (num == den) & (den > 0.0)                # also inf / inf
    big = (num > 0.66 * den) | eq
    diff = num - den                               # exact (Sterbenz) where used
    total = num + den
    n2 = diff if big else num
    n2 = 0.0 if eq else n2
    d2 = total if big else den
    d2 = 1.0 if eq | (den == 0.0) else d2
    t = n2 / d2
    z = t * t
    p = (((_AP0 * z + _AP1) * z + _AP2) * z + _AP3) * z + _AP4
    q = ((((z + _AQ0) * z + _AQ1) * z + _AQ2) * z + _AQ3) * z + _AQ4
    a = t + t * (z * p / q)
    # quadrant bookkeeping in arithmetic (selects on combined conditions would become branches)
    sw = 1.0 if swap else 0.0
    bg = 1.0 if big else 0.0
    xn = 0.5 - 0.5 * math.copysign(1.0, x)        # 1 for x < 0 or x = -0
    sgn = 1.0 - 2.0 * abs(sw - xn)                 # -1 where exactly one of swap, x < 0 holds
    k = 2.0 * sw + 4.0 * xn * (1.0 - sw) + bg * sgn
    r = math.copysign(k * _PIO4_HI + (k * _PIO4_LO + sgn * a), y)
    nan = (x != x) | (y != y)
    return x + y if nan else r


_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01     # fdlibm split: n * _LN2_HI is exact for |n| < 2^11
_LN2_LO = 1.90821492927058770002e-10
# Cephes tanh rational approximation on |x| < 0.625: tanh(x) = x + x s P(s) / Q(s), s = x^2
_TP0, _TP1, _TP2 = -9.64399179425052238628e-1, -9.92877231001918586564e1, -1.61468768441708447952e3
_TQ0, _TQ1, _TQ2 = 1.12811678491632931402e2, 2.23548839060100448583e3, 4.84406305325125486048e3


@njit(inline="always", **_FAST)
def _exp_pos(w):
    """exp(w) for 0 <= w <= 40: ``2^n * exp(r)``, ``|r| <= ln2/2``, Taylor degree 13 (error < 1e-17)."""
    n = math.floor(w * _LOG2E + 0.5)
    r = (w - n * _LN2_HI) - n * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    p = p * r + 1.0
    return p * float(np.int64(1) << np.int64(n))       # 2^n exactly, n <= 58


@njit(inline="always", **_FAST)
def tanh(x):
    """Branchless ``math.tanh(x)`` (within 2 ulp; signed zeros, +-inf -> +-1, NaN -> NaN).

    ``|x| < 0.625``: Cephes rational; else ``1 - 2 / (exp(2|x|) + 1)`` with ``2|x|`` capped at 40
    (``tanh(20) == 1.0`` in double). Both branches share one division.
    """
    z = abs(x)
    s = x * x
    small = z < 0.625
    e = _exp_pos(min(z + z, 40.0))
    num_small = x * s * ((_TP0 * s + _TP1) * s + _TP2)
    den_small = ((s + _TQ0) * s + _TQ1) * s + _TQ2
    den_big = e + 1.0
    num = num_small if small else 2.0
    den = den_small if small else den_big
    q = num / den
    r_small = x + q
    r_big = 1.0 - q
    r = math.copysign(r_small if small else r_big, x)
    return x if x != x else r


# fdlibm: pi/2 in three 33-bit pieces (k * piece exact for |k| < 2^20) and a tail; sin/cos kernels on [-pi/4, pi/4]
_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32    # pi/2 - (_PIO2_1 + _PIO2_2 + _PIO2_3)
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
SINCOS_MAX = 1.0e5                       # beyond this |angle| the kernel falls back to libm


@njit(inline="always", **_FAST)
def sincos(a):
    """Branchless ``(math.sin(a), math.cos(a))`` for ``|a| <= SINCOS_MAX`` (within 2 ulp; 1 ulp for ``|a| < 40``).

    Cody-Waite reduction by ``k*pi/2`` (``k = round(2a/pi)``, pi/2 in four pieces) and the fdlibm polynomials.
    """
    k = math.floor(a * _TWO_OVER_PI + 0.5)
    r = (((a - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3) - k * _PIO2_3T
    z = r * r
    w = z * z
    sr = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
    sn = r + r * z * (_S1 + z * sr)
    cr = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    cw = 1.0 - hz
    cs = cw + (((1.0 - cw) - hz) + z * cr)
    quad = np.int64(k)
    odd = (quad & 1) != 0
    neg_sin = (quad & 2) != 0
    neg_cos = ((quad + 1) & 2) != 0
    s_abs = cs if odd else sn
    c_abs = sn if odd else cs
    s_neg = -s_abs
    c_neg = -c_abs
    sin_a = s_neg if neg_sin else s_abs
    cos_a = c_neg if neg_cos else c_abs
    return sin_a, cos_a


@njit(**_FAST)
def atan2_array(y, x, out):
    """out (M,) <- :func:`atan2` of y, x (M,) (vectorised; for tests and benchmarks)."""
    for q in range(out.shape[0]):
        out[q] = atan2(y[q], x[q])


@njit(**_FAST)
def tanh_array(x, out):
    """out (M,) <- :func:`tanh` of x (M,) (vectorised; for tests and benchmarks)."""
    for q in range(out.shape[0]):
        out[q] = tanh(x[q])


# ---- fast team rollout ---------------------------------------------------------------------------------

U = np.uint64      # unsigned array index: numba adds no negative-index wraparound (which blocks vectorisation)


@njit(**_FAST)
def _sincos_all(heading, sin_h, cos_h):
    """sin_h, cos_h (M,) <- sin, cos of heading (M,); libm beyond ``SINCOS_MAX``."""
    m = heading.shape[0]
    for q in range(m):
        sin_h[q], cos_h[q] = sincos(heading[q])
    for q in range(m):
        if abs(heading[q]) > SINCOS_MAX:
            sin_h[q] = math.sin(heading[q])
            cos_h[q] = math.cos(heading[q])


@njit(inline="always", **_FAST)
def _bearing(dx, dy, c, s):
    """Bearing in [-pi, pi) of world offset (dx, dy) seen by a rover with heading h, c = cos h, s = sin h.

    ``atan2`` of the offset rotated into the rover frame equals ``wrap(atan2(dy, dx) - h)`` up to
    rounding. A zero offset reads as the world x axis (``atan2(0, 0) = 0``), as in the SPEC formula.
    """
    zero = (dx == 0.0) & (dy == 0.0)
    xr = dx * c + dy * s
    yr = dy * c - dx * s
    ms = -s
    xr = c if zero else xr
    yr = ms if zero else yr
    b = atan2(yr, xr)
    return -math.pi if b >= math.pi else b


@njit(**_FAST)
def _sense_all(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs):
    """Observations of all rovers of all episodes.

    x, y, sin_h, cos_h (N*E,) rover-major -> obs (D*N*E,) feature-major: feature k of pair q at
    ``k*N*E + q`` (same values as :func:`sense`, up to rounding of the bearings).
    Indices are unsigned so that numba emits no negative-index wraparound, which blocks vectorisation.
    """
    ne = x.shape[0]
    ep = ne // n
    p = poi_xy.shape[0]
    inv_pi = 1.0 / math.pi
    inv_range = 1.0 / sensor_range
    for j in range(p):
        px = poi_xy[j, 0]
        py = poi_xy[j, 1]
        typ = poi_type[j]
        o = U(3 * j * ne)
        for q in range(ne):
            dx = px - x[q]
            dy = py - y[q]
            d = math.sqrt(dx * dx + dy * dy)
            b = _bearing(dx, dy, cos_h[q], sin_h[q])
            seen = d <= sensor_range
            dn = d * inv_range
            bn = b * inv_pi
            obs[o + U(q)] = dn if seen else 1.0
            obs[o + U(ne + q)] = bn if seen else 0.0
            obs[o + U(2 * ne + q)] = typ if seen else 0.0
    for m in range(n):
        o = U((3 * p + 2 * m) * ne)
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
                b = _bearing(dx, dy, cos_h[q], sin_h[q])
                seen = d <= sensor_range
                dn = d * inv_range
                bn = b * inv_pi
                obs[o + q] = dn if seen else 1.0
                obs[o + U(ne) + q] = bn if seen else 0.0


@njit(**_FAST)
def _policy(genome, obs, q0, ne, hidden, hid, rows, out0, out1):
    """MLP of one rover over its E episodes.

    genome (P,), obs (D*N*E,) feature-major, episodes at ``q0 .. q0+E-1``; hid (H*E,) scratch ->
    out0, out1 (E,) = the two tanh outputs; rows (D,) int scratch. Sums run in the same order as :func:`act`.
    """
    d = obs.shape[0] // ne
    ep = out0.shape[0]
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    for u in range(hidden):
        b = genome[U(o_b1 + u)]
        for e in range(ep):
            hid[U(u * ep + e)] = b
    # Rows of obs that are zero in all E episodes (own rover slot, solo POI types, ...) add nothing:
    # skip them. Exact for finite weights (h + 0 * w == h, up to the sign of a zero h).
    nr = 0
    for k in range(d):
        ok = U(k * ne + q0)
        nz = False
        for e in range(ep):
            nz |= obs[ok + U(e)] != 0.0
        if nz:
            rows[nr] = k
            nr += 1
    n4 = nr - nr % 4
    for r in range(0, n4, 4):                     # four inputs per pass: a quarter of the loads/stores of hid
        k0 = rows[r]
        k1 = rows[r + 1]
        k2 = rows[r + 2]
        k3 = rows[r + 3]
        o0 = U(k0 * ne + q0)
        o1 = U(k1 * ne + q0)
        o2 = U(k2 * ne + q0)
        o3 = U(k3 * ne + q0)
        for u in range(hidden):
            w0 = genome[U(k0 * hidden + u)]
            w1 = genome[U(k1 * hidden + u)]
            w2 = genome[U(k2 * hidden + u)]
            w3 = genome[U(k3 * hidden + u)]
            ou = U(u * ep)
            for e in range(ep):
                i = U(e)
                hid[ou + i] = (((hid[ou + i] + obs[o0 + i] * w0) + obs[o1 + i] * w1)
                               + obs[o2 + i] * w2) + obs[o3 + i] * w3
    for r in range(n4, nr):
        k = rows[r]
        ok = U(k * ne + q0)
        for u in range(hidden):
            w = genome[U(k * hidden + u)]
            ou = U(u * ep)
            for e in range(ep):
                hid[ou + U(e)] += obs[ok + U(e)] * w
    for v in range(hidden * ep):
        hid[v] = tanh(hid[v])
    b0 = genome[U(o_b2)]
    b1 = genome[U(o_b2 + 1)]
    for e in range(ep):
        out0[e] = b0
        out1[e] = b1
    for u in range(hidden):
        w0 = genome[U(o_w2 + 2 * u)]
        w1 = genome[U(o_w2 + 2 * u + 1)]
        ou = U(u * ep)
        for e in range(ep):
            out0[e] += hid[ou + U(e)] * w0
            out1[e] += hid[ou + U(e)] * w1
    for e in range(ep):
        out0[e] = tanh(out0[e])
        out1[e] = tanh(out1[e])


@njit(**_FAST)
def rollout(genomes, xy0, heading0, poi_xy, poi_type, coupling, value, steps, hidden,
            sensor_range, obs_radius, v_max, w_max, returns, traj_xy, traj_heading, final_xy):
    """Run E episodes of T steps for one team.

    genomes (N, P) one row per rover; xy0 (E, N, 2), heading0 (E, N) -> returns (E,) written in place.
    If ``traj_xy`` has shape (E, T+1, N, 2) (and ``traj_heading`` (E, T+1, N)) the states are
    recorded there; pass arrays with a zero-sized first axis to skip recording. Likewise the final
    positions go to ``final_xy`` (E, N, 2) unless its first axis is zero-sized.
    Each step: all rovers sense, all act, then each turns by ``a1 * w_max`` and moves
    ``(a0 + 1) / 2 * v_max`` along its new heading.
    """
    n_ep, n = heading0.shape
    ne = n * n_ep
    record = traj_xy.shape[0] == n_ep
    keep_final = final_xy.shape[0] == n_ep
    d = 3 * poi_xy.shape[0] + 2 * n
    state = np.empty((7, ne))
    x, y, heading, sin_h, cos_h, a0, a1 = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    obs = np.empty(d * ne)
    hid = np.empty(hidden * n_ep)
    rows = np.empty(d, dtype=np.int64)
    for i in range(n):
        for e in range(n_ep):
            x[i * n_ep + e] = xy0[e, i, 0]
            y[i * n_ep + e] = xy0[e, i, 1]
            heading[i * n_ep + e] = heading0[e, i]
    if record:
        traj_xy[:, 0] = xy0
        traj_heading[:, 0] = heading0
    _sincos_all(heading, sin_h, cos_h)
    for t in range(steps):
        _sense_all(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs)
        for i in range(n):
            q0 = i * n_ep
            _policy(genomes[i], obs, q0, ne, hidden, hid, rows, a0[q0:q0 + n_ep], a1[q0:q0 + n_ep])
        for q in range(ne):
            heading[q] += a1[q] * w_max
        _sincos_all(heading, sin_h, cos_h)
        for q in range(ne):
            speed = (a0[q] + 1.0) * 0.5 * v_max
            x[q] += speed * cos_h[q]
            y[q] += speed * sin_h[q]
        if record:
            for i in range(n):
                for e in range(n_ep):
                    traj_xy[e, t + 1, i, 0] = x[i * n_ep + e]
                    traj_xy[e, t + 1, i, 1] = y[i * n_ep + e]
                    traj_heading[e, t + 1, i] = heading[i * n_ep + e]
    xy = np.empty((n, 2))
    for e in range(n_ep):
        for i in range(n):
            xy[i, 0] = x[i * n_ep + e]
            xy[i, 1] = y[i * n_ep + e]
        if keep_final:
            final_xy[e] = xy
        returns[e] = team_return(xy, poi_xy, coupling, value, obs_radius)
