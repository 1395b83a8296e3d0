"""Elementary functions of the kernel (numba): branchless ``atan2``, ``tanh``, ``sincos``, and ``wrap``.

Branchless (selects only) so that LLVM vectorises the loops that inline them: numba 0.68 without SVML leaves calls
to libm ``atan2``/``tanh``/``sin``/``cos`` scalar. Each is within 2 ulp of libm (tests/test_kernel_math.py).
``FAST`` are the compile options of every vectorised kernel function: FMA contraction only (no reassociation, no
finite-math assumptions), so results differ from plain IEEE arithmetic by rounding only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi
FAST = {"cache": True, "fastmath": {"contract"}, "error_model": "numpy"}


@njit(cache=True, inline="always")
def wrap(a):
    """Angle wrapped to [-pi, pi)."""
    r = a - TWO_PI * math.floor((a + math.pi) / TWO_PI)
    if r >= math.pi:  # rounding in the floor can land one ulp outside
        r -= TWO_PI
    elif r < -math.pi:
        r += TWO_PI
    return r


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


@njit(inline="always", **FAST)
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


@njit(inline="always", **FAST)
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


@njit(inline="always", **FAST)
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


@njit(inline="always", **FAST)
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


@njit(**FAST)
def sincos_all(heading, sin_h, cos_h):
    """sin_h, cos_h (M,) <- sin, cos of heading (M,): :func:`sincos`, libm beyond ``SINCOS_MAX``."""
    m = heading.shape[0]
    for q in range(m):
        sin_h[q], cos_h[q] = sincos(heading[q])
    for q in range(m):
        if abs(heading[q]) > SINCOS_MAX:
            sin_h[q] = math.sin(heading[q])
            cos_h[q] = math.cos(heading[q])
