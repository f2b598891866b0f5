"""Scalar building blocks of the compiled engine: vectorisable sin/cos and atan2, a counter-based
random generator and NumPy's pairwise summation order.

Uniform numbers are made without integer-to-float conversion (which AVX2 lacks for 64-bit
integers): random bits are written as the mantissa of a double in ``[1, 2)`` into a ``uint64``
buffer that the kernels read back through a ``float64`` view, minus 1.

Everything here is compiled by Numba without ``fastmath`` (IEEE semantics: comparisons with
``inf`` and signed zeros behave as in NumPy). The polynomial ``sincos`` and ``atan2`` are the
Cephes ones (relative error below ~2 ulp); unlike calls into ``libm`` they contain no function
call, so LLVM vectorises the particle loops that use them. Where a result feeds a threshold
decision, the kernels re-check values lying within :data:`DECISION_TOL` of the threshold with
``libm`` (``math.atan2``, ``math.hypot``: the functions NumPy calls), so decisions are exactly
NumPy's.
"""

from __future__ import annotations

import math

import numpy as np

from staghunt.engine.jit import subroutine

DECISION_TOL = 1e-9
"""Values within this (absolute, in the value's unit) of a decision threshold are recomputed exactly."""

RAD2DEG = 180.0 / math.pi  # np.degrees multiplies by this constant

_PIO2 = 1.5707963267948966
_PIO4 = 0.7853981633974483
_PI = 3.141592653589793
_TWO_OVER_PI = 0.6366197723675814
# Cody-Waite split of pi/2 (Cephes DP1..DP3 doubled): q * _PIO2_1 is exact for |q| < 2**20.
_PIO2_1 = 1.5707962512969971
_PIO2_2 = 7.549789415861596e-08
_PIO2_3 = 5.390302858158119e-15
_MOREBITS = 6.123233995736766e-17

_U64_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_U64_M1 = np.uint64(0xBF58476D1CE4E5B9)
_U64_M2 = np.uint64(0x94D049BB133111EB)
_U64_30 = np.uint64(30)
_U64_27 = np.uint64(27)
_U64_31 = np.uint64(31)
_U64_32 = np.uint64(32)
_U64_12 = np.uint64(12)
_U64_20 = np.uint64(20)
_U64_ONE_BITS = np.uint64(0x3FF0000000000000)  # the bits of 1.0
_U64_LOW32 = np.uint64(0xFFFFFFFF)


@subroutine
def sincos_small(r: float) -> tuple[float, float]:
    """``(sin r, cos r)`` to ~1 ulp for ``|r| <= pi/4`` (no range reduction; the Cephes kernels)."""
    z = r * r
    ps = ((((1.58962301576546568060e-10 * z - 2.50507477628578072866e-8) * z
            + 2.75573136213857245213e-6) * z - 1.98412698295895385996e-4) * z
          + 8.33333333332211858878e-3) * z - 1.66666666666666307295e-1
    pc = ((((-1.13585365213876817300e-11 * z + 2.08757008419747316778e-9) * z
             - 2.75573141792967388112e-7) * z + 2.48015872888517045348e-5) * z
          - 1.38888888888730564116e-3) * z + 4.16666666666665929218e-2
    return r + r * z * ps, 1.0 - 0.5 * z + z * z * pc


@subroutine
def sincos(x: float) -> tuple[float, float]:
    """``(sin x, cos x)`` to ~1 ulp for ``|x| < 1e5``: reduction by ``pi/2`` (Cody-Waite), Cephes
    polynomials, branch-free so that loops over particles vectorise. The encoding's angles stay
    within a few radians."""
    q = math.floor(x * _TWO_OVER_PI + 0.5)
    s, c = sincos_small(((x - q * _PIO2_1) - q * _PIO2_2) - q * _PIO2_3)
    m = q - 4.0 * math.floor(q * 0.25)  # quadrant 0..3, exact
    odd = m == 1.0 or m == 3.0
    sin_x = c if odd else s
    cos_x = s if odd else c
    if m >= 2.0:
        sin_x = -sin_x
    if m == 1.0 or m == 2.0:
        cos_x = -cos_x
    return sin_x, cos_x


@subroutine
def atan2(y: float, x: float) -> float:
    """``atan2(y, x)`` to ~2 ulp with NumPy's (C99) signed-zero and quadrant rules.

    ``atan2(+-0, +0) = +-0``, ``atan2(+-0, -0) = +-pi``, ``atan2(+-0, x<0) = +-pi``,
    ``atan2(y, +-0) = +-pi/2`` for ``y != 0``; exactly ``pi/4`` for ``|y| = |x|``. Finite inputs only.
    """
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax  # num / den in [0, 1]
    big = num > 0.66 * den
    # One division: t = num / den, or for num / den > 0.66 Cephes' (a - 1) / (a + 1) formed
    # directly as (num - den) / (num + den).
    t = ((num - den) if big else num) / ((num + den) if big else den) if den > 0.0 else 0.0
    z = t * t
    p = (((-8.750608600031904122785e-1 * z - 1.615753718733365076637e1) * z
          - 7.500855792314704667340e1) * z - 1.228866684490136173410e2) * z - 6.485021904942025371773e1
    qq = ((((z + 2.485846490142306297962e1) * z + 1.650270098316988542046e2) * z
           + 4.328810604912902668951e2) * z + 4.853903996359136964868e2) * z + 1.945506571482613964425e2
    r = t * (z * p / qq) + t
    if big:
        r = _PIO4 + (r + 0.5 * _MOREBITS)
    if swap:
        r = _PIO2 - r
    if x < 0.0 or (x == 0.0 and math.copysign(1.0, x) < 0.0):
        r = _PI - r
    return math.copysign(r, y)


@subroutine
def mix64(z: np.uint64) -> np.uint64:
    """SplitMix64 finaliser: a bijective 64-bit hash with full avalanche."""
    z = (z ^ (z >> _U64_30)) * _U64_M1
    z = (z ^ (z >> _U64_27)) * _U64_M2
    return z ^ (z >> _U64_31)


@subroutine
def counter_hash(key: np.uint64, counter: np.uint64) -> np.uint64:
    """Output number ``counter`` of the SplitMix64 stream seeded with ``key`` (counter-based:
    any draw is computed directly from its index, so results do not depend on threads or blocks)."""
    return mix64(key + counter * _U64_GOLDEN)


@subroutine
def unit_bits(h: np.uint64) -> np.uint64:
    """The bits of a double in ``[1, 2)`` with the hash's top 52 bits as mantissa (view the
    stored value as float64 and subtract 1: a uniform in ``[0, 1)`` with 52 random bits)."""
    return (h >> _U64_12) | _U64_ONE_BITS


@subroutine
def unit_bits_pair(h: np.uint64) -> tuple[np.uint64, np.uint64]:
    """Two such bit patterns from one hash, with its high and low 32 bits (PSO's ``r1``, ``r2``)."""
    return ((h >> _U64_32) << _U64_20) | _U64_ONE_BITS, ((h & _U64_LOW32) << _U64_20) | _U64_ONE_BITS


@subroutine
def pairwise_lanes(vals: np.ndarray, n: int, nb: int, out: np.ndarray) -> None:
    """``out[b] = sum(vals[:n, b])`` in NumPy's pairwise order for ``n <= 128`` (sequential
    beyond); destroys ``vals``. ``vals``: ``(>= n, >= nb)``; ``out``: ``(>= nb,)``.

    NumPy's ``add.reduce`` over a contiguous axis adds ``n < 8`` values in order and otherwise
    keeps 8 running sums, combined as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, then
    adds the remaining ``n % 8`` values in order.
    """
    if n < 8 or n > 128:
        for b in range(nb):
            out[b] = 0.0
        for i in range(n):
            for b in range(nb):
                out[b] += vals[i, b]
        return
    m = n - n % 8
    for i in range(8, m, 8):
        for j in range(8):
            for b in range(nb):
                vals[j, b] += vals[i + j, b]
    for b in range(nb):
        out[b] = ((vals[0, b] + vals[1, b]) + (vals[2, b] + vals[3, b])) + (
            (vals[4, b] + vals[5, b]) + (vals[6, b] + vals[7, b])
        )
    for i in range(m, n):
        for b in range(nb):
            out[b] += vals[i, b]
