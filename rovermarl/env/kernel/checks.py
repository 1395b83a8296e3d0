"""What the rollout checks to take its cheaper paths (numba), each giving the same bits as the general one:
:func:`in_range` (each step: the sensing's ranged atan2), :func:`mlp_finite` (each rollout: the MLP's tanh without
its NaN case) and :func:`input_rows` (each rollout: the MLP skips the rows the sensing always fills with zeros).
``tests/test_kernel_math.py`` checks each cheaper path against the general one, bit for bit.
"""

from __future__ import annotations

import numpy as np

from rovermarl.env.kernel.math import FAST, like, pick
from rovermarl.jit import njit


@njit(inline="always", **FAST)
def in_range(x, y, sin_h, cos_h, poi_xy):
    """True when the bearings of these rovers and POIs meet the promise of ``atan2(ranged=True)``: every
    coordinate is 0 or of magnitude in [2^-700, 2^700) (float32: [2^-30, 2^30)), and every (cos, sin) has both
    magnitudes <= 1 and one >= 1/2. Then a nonzero offset is at least 2^-752 (2^-53) long, the rover frame keeps
    at least half of it and ``max(|xr|, |yr|)`` lies in ``[RANGED_MIN, RANGED_MAX]``; a zero offset reads
    (cos, -sin). x, y, sin_h, cos_h (M,), poi_xy (P, 2)."""
    if x.shape[0] == 0:                              # no rover, no bearing (and no x[0] to read the dtype from)
        return True
    lo, hi = pick(x[0], 2.0 ** -700, 2.0 ** -30), pick(x[0], 2.0 ** 700, 2.0 ** 30)
    bad = False
    for q in range(x.shape[0]):
        bad |= _off(x[q], lo, hi) | _off(y[q], lo, hi) | _off_unit(cos_h[q], sin_h[q])
    for j in range(poi_xy.shape[0]):
        bad |= _off(poi_xy[j, 0], lo, hi) | _off(poi_xy[j, 1], lo, hi)
    return not bad


@njit(cache=True)
def input_rows(n, poi_type):
    """The rows of each rover's observation that may be nonzero, for ``stages.act_flat``: (N, D) int64, rover i's in
    increasing order, then -1. Leaves out what ``stages.sense_flat`` always fills with zeros: the type rows of POIs
    whose type is 0 and the rover's own slot.

    >>> import numpy as np
    >>> input_rows(2, np.array([0.0, 1.0])).tolist()       # P = 2 POIs, the first of type 0; D = 3P + 2N = 10
    [[0, 1, 3, 4, 5, 8, 9, -1, -1, -1], [0, 1, 3, 4, 5, 6, 7, -1, -1, -1]]
    """
    p = poi_type.shape[0]
    d = 3 * p + 2 * n
    out = np.full((n, d), -1, dtype=np.int64)
    for i in range(n):
        c = 0
        for k in range(d):
            if (k < 3 * p and k % 3 == 2 and poi_type[k // 3] == 0) or (k >= 3 * p and (k - 3 * p) // 2 == i):
                continue
            out[i, c] = k
            c += 1
    return out


@njit(inline="always", **FAST)
def mlp_finite(genomes, poi_type, sensor_range):
    """True when every sum of the MLP is finite on the steps whose sensing is :func:`in_range`, so that its tanh may
    take ``finite=True``: every weight below 2^900 (float32: 2^60) and every POI type below 2^100 (2^30) in
    magnitude, ``1 / sensor_range`` finite, and G < 2^20. The readings are then within [-1, 1] but the types, and
    a sum of fewer than 2^20 products stays below 2^1020 (2^110). genomes (N, G), poi_type (P,)."""
    big, typ = pick(sensor_range, 2.0 ** 900, 2.0 ** 60), pick(sensor_range, 2.0 ** 100, 2.0 ** 30)
    bad = not abs(like(sensor_range, 1.0) / sensor_range) < np.inf       # as sense_flat's inv_range
    bad |= genomes.shape[1] >= 2 ** 20                                   # a sum has fewer than G terms
    for i in range(genomes.shape[0]):
        for v in range(genomes.shape[1]):
            bad |= not abs(genomes[i, v]) < big
    for j in range(poi_type.shape[0]):
        bad |= not abs(poi_type[j]) < typ
    return not bad


@njit(inline="always")
def _off(v, lo, hi):
    a = abs(v)
    return ((a > like(v, 0.0)) & (a < lo)) | (not a < hi)          # NaN too


@njit(inline="always")
def _off_unit(c, s):
    ac, as_ = abs(c), abs(s)
    return (not ac <= like(c, 1.0)) | (not as_ <= like(c, 1.0)) | (not max(ac, as_) >= like(c, 0.5))
