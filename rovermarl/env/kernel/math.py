"""Elementary functions of the kernel (numba): branchless ``atan2``, ``tanh``, ``sincos``, and ``wrap``.

Branchless (selects only) so that LLVM vectorises the loops that inline them: numba 0.68 without SVML leaves calls to
libm ``atan2``/``tanh``/``sin``/``cos`` scalar. Each is within 2 ulp of libm (tests/test_kernel_math.py) and works in
its argument's precision: numba types a float literal as float64, so constants go through :func:`like` (or :func:`pick`,
for a float32 value of its own), the literal itself for float64 and a float32 constant for float32. :func:`tanh` and
:func:`atan2`'s core are overloads with a float32 formula of their own (:func:`_tanh32`, :func:`_atan32`: fewer
operations, float32 accuracy), compiled as functions that LLVM inlines (inlining them in numba's IR trips its SSA
check). ``FAST``, the options of every vectorised kernel function, allows FMA contraction only (no reassociation, no
finite-math assumptions), so results differ from plain IEEE arithmetic by rounding only.

The one LLVM intrinsic, :func:`_pow2` (2^n from its bits), is worth 3.9x a call: ``python benchmarks/intrinsics.py
--pairs 3`` (``plain_pow2``: ``math.ldexp(1.0, n)`` instead, a libm call that leaves the tanh loops scalar), float64
duo ``World.evaluate`` 181-185 against 46.8-48.5 us, alternated processes on one pinned core of a loaded machine
(load average 8.7, 2026-12-06; ``docs/PERFORMANCE.md``).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

from rovermarl.jit import njit

TWO_PI = 2.0 * math.pi
FAST = {"cache": True, "fastmath": {"contract"}, "error_model": "numpy"}
U = np.uint64      # loop indices: unsigned, so numba emits no negative-index wraparound (which blocks vectorisation)
_SCALAR = {"fastmath": {"contract"}, "error_model": "numpy"}   # FAST for scalar functions that LLVM inlines


def like(x, c):
    """The constant ``c`` in the precision of the float ``x``: ``c`` itself for float64, ``float32(c)`` for float32."""
    return np.float32(c) if isinstance(x, np.float32) else c


def pick(x, c64, c32):
    """``c64`` for a float64 ``x``, ``float32(c32)`` for a float32 one (constants that float32 needs of its own)."""
    return np.float32(c32) if isinstance(x, np.float32) else c64


def _is32(x) -> bool:
    return isinstance(x, types.Float) and x.bitwidth == 32


@overload(like, inline="always")
def _like(x, c):
    return (lambda x, c: np.float32(c)) if _is32(x) else (lambda x, c: c)


@overload(pick, inline="always")
def _pick(x, c64, c32):
    return (lambda x, c64, c32: np.float32(c32)) if _is32(x) else (lambda x, c64, c32: c64)


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
_BIG, _TINY = 2.0 ** 800, 2.0 ** -800
_BIG32, _TINY32 = 2.0 ** 60, 2.0 ** -60  # float32's: its range ends at 2^128
RANGED_MIN, RANGED_MAX = _TINY, _BIG     # atan2(ranged=True)'s promise on max(|x|, |y|) (float32: _TINY32, _BIG32)
_PIO4_HI32 = 0.7853981852531433          # fl32(pi/4) and pi/4 - fl32(pi/4)
_PIO4_LO32 = -2.1855695031547384e-08
_TAN_PI8 = 0.41421356237309503            # float32's reduction bound
_AF0, _AF1, _AF2, _AF3 = 8.05374449538e-2, -1.38776856032e-1, 1.99777106478e-1, -3.33329491539e-1   # Cephes atanf


@njit(inline="always", **FAST)
def _atan64(t):
    z = t * t
    p = (((_AP0 * z + _AP1) * z + _AP2) * z + _AP3) * z + _AP4
    q = ((((z + _AQ0) * z + _AQ1) * z + _AQ2) * z + _AQ3) * z + _AQ4
    return t + t * (z * p / q)


@njit(inline="always", **FAST)
def _atan32(t):
    z = t * t
    f = np.float32
    return t + (((f(_AF0) * z + f(_AF1)) * z + f(_AF2)) * z + f(_AF3)) * z * t


def _atan(t):
    """atan(t) on the reduced range of :func:`atan2` (no division in float32)."""
    return math.atan(t)


@overload(_atan, jit_options=_SCALAR)
def _atan_impl(t):
    return _atan32.py_func if _is32(t) else _atan64.py_func


@njit(inline="always", **FAST)
def atan2(y, x, ranged=False):
    """Branchless ``math.atan2(y, x)`` for floats (within 2 ulp; signed zeros, infinities, NaN as libm).

    Octant reduction to ``t = min/max`` or ``(min - max)/(min + max)`` (one division), the Cephes
    rational on ``|t| <= 0.66`` (float32: Cephes ``atanf``'s polynomial on ``|t| <= tan(pi/8)``), then
    ``k*pi/4 +- atan(t)`` with ``pi/4`` split in two parts. ``ranged=True`` (a constant at the call) promises
    finite x, y with ``max(|x|, |y|)`` in ``[RANGED_MIN, RANGED_MAX]``: there the scaling, the equal-magnitude and
    the NaN cases change nothing, so it leaves them out and gives the same bits with fewer operations.
    """
    one, zero, two = like(x, 1.0), like(x, 0.0), like(x, 2.0)
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    if ranged:                                     # den > 0: num == den already takes the big branch to t = +0
        big = num > pick(x, 0.66, _TAN_PI8) * den
        t = (num - den if big else num) / (num + den if big else den)
    else:
        big_, tiny_ = pick(x, _BIG, _BIG32), pick(x, _TINY, _TINY32)
        down = den > big_
        up = den < tiny_
        scale = tiny_ if down else one
        scale = big_ if up else scale              # keeps num + den finite and normal
        num = num * scale
        den = den * scale
        eq = (num == den) & (den > zero)           # also inf / inf
        big = (num > pick(x, 0.66, _TAN_PI8) * den) | eq
        diff = num - den                           # exact (Sterbenz) where used
        total = num + den
        n2 = diff if big else num
        n2 = zero if eq else n2
        d2 = total if big else den
        d2 = one if eq | (den == zero) else d2
        t = n2 / d2
    a = _atan(t)
    # quadrant bookkeeping: k in 0 .. 4 and sgn = +-1, exact small integers, by selects on single conditions
    neg = math.copysign(one, x) < zero            # x < 0 or x = -0
    sgn = -one if swap ^ neg else one              # -1 where exactly one of swap, x < 0 holds
    base = like(x, 4.0) if neg else zero
    base = two if swap else base
    k = base + (sgn if big else zero)
    r = math.copysign(k * pick(x, _PIO4_HI, _PIO4_HI32) + (k * pick(x, _PIO4_LO, _PIO4_LO32) + sgn * a), y)
    if ranged:
        return r
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
    n = np.int64(w * _LOG2E + 0.5)                       # truncation: floor, as the argument is >= 0.5
    nf = float(n)
    r = (w - nf * _LN2_HI) - nf * _LN2_LO
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
    return p * _pow2(n)                                  # 2^n exactly, 0 <= n <= 58


@intrinsic
def _pow2(typingctx, n):
    """2.0 ** n for an int64 n with -1023 < n < 1024, built from its bits (no conversion)."""
    if n != types.int64:
        return None

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        bits = builder.shl(builder.add(args[0], ir.Constant(i64, 1023)), ir.Constant(i64, 52))
        return builder.bitcast(bits, ir.DoubleType())

    return types.float64(types.int64), codegen


def tanh(x, finite=False):
    """Branchless ``math.tanh(x)`` in the kernel (:func:`_tanh64`; float32: :func:`_tanh32`); ``math.tanh`` from
    Python. ``finite=True`` (a constant at the call) promises a finite x: float64 then leaves out the NaN case,
    the same bits with fewer operations."""
    return math.tanh(x)


@overload(tanh, jit_options=_SCALAR)
def _tanh(x, finite=False):
    return _tanh32.py_func if _is32(x) else _tanh64.py_func


_TANH32_CLAMP = 7.90531110763549805      # Eigen's float tanh: an odd rational of degree 13/6 on [-c, c]
_TANH32_A = (4.89352455891786e-03, 6.37261928875436e-04, 1.48572235717979e-05, 5.12229709037114e-08,
             -8.60467152213735e-11, 2.00018790482477e-13, -2.76076847742355e-16)
_TANH32_B = (4.89352518554385e-03, 2.26843463243900e-03, 1.18534705686654e-04, 1.19825839466702e-06)


@njit(inline="always", **FAST)
def _tanh32(x, finite=False):
    """float32 tanh: Eigen's rational (one division; within a few float32 ulp), ``x`` itself for ``|x| < 4e-4``."""
    f = np.float32
    a0, a1, a2, a3, a4, a5, a6 = _TANH32_A
    b0, b1, b2, b3 = _TANH32_B
    c = min(max(x, f(-_TANH32_CLAMP)), f(_TANH32_CLAMP))
    s = c * c
    p = ((((((f(a6) * s + f(a5)) * s + f(a4)) * s + f(a3)) * s + f(a2)) * s + f(a1)) * s + f(a0)) * c
    q = ((f(b3) * s + f(b2)) * s + f(b1)) * s + f(b0)
    r = p / q
    return x if abs(x) < f(0.0004) else r


@njit(inline="always", **FAST)
def _tanh64(x, finite=False):
    """Branchless ``math.tanh(x)`` for float64 (within 2 ulp; signed zeros, +-inf -> +-1, NaN -> NaN).

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
    if finite:
        return r
    return x if x != x else r


# fdlibm: pi/2 in three 33-bit pieces (k * piece exact for |k| < 2^20) and a tail; sin/cos kernels on [-pi/4, pi/4]
_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_PIO2_3T = 8.47842766036889956997e-32    # pi/2 - (_PIO2_1 + _PIO2_2 + _PIO2_3)
_PIO2_1F, _PIO2_2F, _PIO2_3F = 1.5703125, 4.837512969970703125e-4, 7.54978995489188216e-8   # float32's (Cephes sinf)
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
    one = like(a, 1.0)
    k = math.floor(a * like(a, _TWO_OVER_PI) + like(a, 0.5))
    kf = like(a, k)
    r = (((a - kf * pick(a, _PIO2_1, _PIO2_1F)) - kf * pick(a, _PIO2_2, _PIO2_2F))
         - kf * pick(a, _PIO2_3, _PIO2_3F)) - kf * pick(a, _PIO2_3T, 0.0)
    z = r * r
    w = z * z
    sr = like(a, _S2) + z * (like(a, _S3) + z * (like(a, _S4) + z * (like(a, _S5) + z * like(a, _S6))))
    sn = r + r * z * (like(a, _S1) + z * sr)
    cr = (z * (like(a, _C1) + z * (like(a, _C2) + z * like(a, _C3)))
          + w * w * (like(a, _C4) + z * (like(a, _C5) + z * like(a, _C6))))
    hz = like(a, 0.5) * z
    cw = one - hz
    cs = cw + (((one - cw) - hz) + z * cr)
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


@njit(inline="always", **FAST)
def sincos_all(heading, sin_h, cos_h):
    """sin_h, cos_h (M,) <- sin, cos of heading (M,): :func:`sincos`, libm beyond ``SINCOS_MAX``. Inlined: a call
    of it in the move stage kept numba from pruning the reference counts of the pose's five arrays around it."""
    m = heading.shape[0]
    far = False
    for q in range(m):
        sin_h[q], cos_h[q] = sincos(heading[q])
        far |= abs(heading[q]) > SINCOS_MAX
    if far:                                          # rare: the scalar pass only then
        for q in range(m):
            if abs(heading[q]) > SINCOS_MAX:
                sin_h[q] = math.sin(heading[q])
                cos_h[q] = math.cos(heading[q])
