"""Arithmetic of the simulator pinned to the same bits on every x86-64 CPU (issue 22).

The simulator's outputs are shipped and compared bit for bit (``sample_data/``).  Three things in a
numpy/numba program give different last bits on different CPUs of the same architecture:

* numpy's SIMD transcendental loops (tan, arctan, arctan2, exp, log, power, ...), chosen at run time
  by the CPU's features (AVX2, AVX-512);
* the C library's ``sin``/``cos``/``tan``/``exp``..., which glibc also picks by CPU feature (an FMA
  version on CPUs with FMA); numba's kernels call the same functions;
* BLAS (``@``, ``np.dot``): OpenBLAS picks its kernels by CPU, with or without FMA and with other
  summation orders.

Elementwise ``+ - * /`` and ``sqrt`` are exactly rounded (IEEE 754) whatever the SIMD width, numba does
not contract ``a * b + c`` into an FMA (no ``fastmath``), and numpy's sums and ``einsum`` loops are
not chosen by CPU; so the functions here are written in those operations only: the fdlibm algorithms
(Sun Microsystems, 1993; the reference implementations of most C libraries) for sin, cos, arctan,
arctan2, exp and log, each within 1 ulp of the exact value, tan, within 1 ulp of
the exact value, and a matrix product with one fixed order of summation.  ``tests/test_sim_pinned.py``
checks them against the C library and runs the simulator with the other code paths forced
(``NPY_DISABLE_CPU_FEATURES``, ``OPENBLAS_CORETYPE``, ``GLIBC_TUNABLES``) for the same bits.

Each function takes arrays or scalars (a scalar in, a float out); a :class:`sinscli.sim.jets.Jet`
is handed to numpy's function, which the Jet dispatches to its own rules (which call these).
"""
from __future__ import annotations

import math
from fractions import Fraction
from functools import lru_cache

import numpy as np

# --- fdlibm constants (k_sin.c, k_cos.c, e_rem_pio2.c, s_atan.c, e_atan2.c, e_exp.c, e_log.c) ----------
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1, _PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11
_PIO2_2, _PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
_PIO2_3, _PIO2_3T = 2.02226624871116645580e-21, 8.47842766036889956997e-32
_MEDIUM = 2.0 ** 19 * (math.pi / 2)        # beyond: the exact reduction (big integers), element by element

_ATANHI = np.array([4.63647609000806093515e-01, 7.85398163397448278999e-01, 9.82793723247329054082e-01,
                    1.57079632679489655800e+00])
_ATANLO = np.array([2.26987774529616870924e-17, 3.06161699786838301793e-17, 1.39033110312309984516e-17,
                    6.12323399573676603587e-17])
_AT = (3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01,
       -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02,
       6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02,
       -3.65315727442169155270e-02, 1.62858201153657823623e-02)
_T = (3.33333333333334091986e-01, 1.33333333333201242699e-01, 5.39682539762260521377e-02, 2.18694882948595424599e-02,
      8.86323982359930005737e-03, 3.59207910759131235356e-03, 1.45620945432529025516e-03, 5.88041240820264096874e-04,
      2.46463134818469906812e-04, 7.81794442939557092300e-05, 7.14072491382608190305e-05,
      -1.85586374855275456654e-05, 2.59073051863633712884e-05)
_PI, _PI_O_2, _PI_LO = 3.1415926535897931160e+00, 1.5707963267948965580e+00, 1.2246467991473531772e-16

_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10
_INVLN2 = 1.44269504088896338700e+00
_P = (1.66666666666666019037e-01, -2.77777777770155933842e-03, 6.61375632143793436117e-05,
      -1.65339022054652515390e-06, 4.13813679705723846039e-08)
_O_THRESHOLD, _U_THRESHOLD = 7.09782712893383973096e+02, -7.45133219101941108420e+02
_LG = (6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01, 2.222219843214978396e-01,
       1.818357216161805012e-01, 1.531383769920937332e-01, 1.479819860511658591e-01)


def _jet(x) -> bool:
    return hasattr(x, "__array_ufunc__") and not isinstance(x, (np.ndarray, np.generic, float, int))


def _out(x_in, y):
    """A float for a scalar argument, the array otherwise."""
    return float(y) if np.ndim(x_in) == 0 else y


# --- argument reduction and kernels ------------------------------------------------------------------

@lru_cache(maxsize=1)
def _pio2_scaled(bits: int = 1280) -> int:
    """floor(pi/2 * 2^bits) by Machin's formula in integers (for the exact reduction of huge angles)."""
    guard = bits + 64
    one = 1 << guard

    def arctan_inv(k):
        total, term, n, sign = 0, one // k, 1, 1
        while term:
            total += sign * (term // n)
            term //= k * k
            n += 2
            sign = -sign
        return total
    pi = 4 * (4 * arctan_inv(5) - arctan_inv(239))
    return (pi >> 1) >> 64


def _reduce_exact(x: float):
    """``(n mod 4, y0, y1)`` with ``x = n pi/2 + y0 + y1`` exactly to double-double, for any finite x."""
    bits = 1280
    P = _pio2_scaled(bits)
    num = Fraction(x) * (1 << bits)                    # x 2^bits, exact
    k = round(num / P)
    r = Fraction(int(num.numerator) - k * P * num.denominator, num.denominator * (1 << bits))
    y0 = float(r)
    return k % 4, y0, float(r - Fraction(y0))


def _rem_pio2(x):
    """``(n mod 4, y0, y1)``: ``x - n pi/2 = y0 + y1`` (fdlibm e_rem_pio2.c, medium case: the second and
    third Cody-Waite steps where the first cancels more than 16, the second more than 49 bits; the exact
    reduction beyond 2^19 pi/2)."""
    x = np.asarray(x, dtype=np.float64)
    fn = np.rint(x * _INVPIO2)
    ex = np.frexp(x)[1]
    r1 = x - fn * _PIO2_1                              # exact: pio2_1 has 33 bits, |fn| < 2^20
    w1 = fn * _PIO2_1T                                 # 1st round good to 85 bits
    w = fn * _PIO2_2
    r2 = r1 - w
    w2 = fn * _PIO2_2T - ((r1 - r2) - w)               # 2nd round good to 118 bits
    w = fn * _PIO2_3
    r3 = r2 - w
    w3 = fn * _PIO2_3T - ((r2 - r3) - w)               # 3rd round good to 151 bits
    second = ex - np.frexp(r1 - w1)[1] > 16
    third = second & (ex - np.frexp(r2 - w2)[1] > 49)
    r = np.where(third, r3, np.where(second, r2, r1))
    w = np.where(third, w3, np.where(second, w2, w1))
    y0 = r - w
    y1 = (r - y0) - w
    n = np.mod(fn, 4.0).astype(np.int64)
    big = ~(np.abs(x) < _MEDIUM)
    if np.any(big):
        n, y0, y1 = np.array(n), np.array(y0), np.array(y1)
        for idx in zip(*np.nonzero(big)) if x.ndim else [()]:
            v = float(x[idx])
            if math.isfinite(v):
                n[idx], y0[idx], y1[idx] = _reduce_exact(v)
            else:
                n[idx], y0[idx], y1[idx] = 0, math.nan, math.nan
    return n, y0, y1


def _ksin(x, y):
    """sin(x + y), |x| <= pi/4 (fdlibm __kernel_sin with the tail y)."""
    z = x * x
    v = z * x
    r = _S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * _S[5])))
    return x - ((z * (0.5 * y - v * r) - y) - v * _S[0])


def _kcos(x, y):
    """cos(x + y), |x| <= pi/4 (fdlibm __kernel_cos)."""
    z = x * x
    r = z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (_C[3] + z * (_C[4] + z * _C[5])))))
    small = 1.0 - (0.5 * z - (z * r - x * y))
    ax = np.abs(x)
    hi_word = (ax.view(np.uint64) >> np.uint64(32)).astype(np.int64)
    qx = ((hi_word - 0x00200000).astype(np.uint64) << np.uint64(32)).view(np.float64)   # |x|/4, low word 0
    qx = np.where(ax > 0.78125, 0.28125, qx)
    hz = 0.5 * z - qx
    a = 1.0 - qx
    large = a - (hz - (z * r - x * y))
    return np.where(ax < 0.3, small, large)


def sin(x):
    """sin(x), within 1 ulp (fdlibm s_sin.c)."""
    if _jet(x):
        return np.sin(x)
    n, y0, y1 = _rem_pio2(x)
    s, c = _ksin(y0, y1), _kcos(np.asarray(y0), y1)
    return _out(x, np.select([n == 0, n == 1, n == 2], [s, c, -s], -c))


def cos(x):
    """cos(x), within 1 ulp (fdlibm s_cos.c)."""
    if _jet(x):
        return np.cos(x)
    n, y0, y1 = _rem_pio2(x)
    s, c = _ksin(y0, y1), _kcos(np.asarray(y0), y1)
    return _out(x, np.select([n == 0, n == 1, n == 2], [c, -s, -c], s))


def _low_word_zero(v):
    v = np.array(v, dtype=np.float64)                  # a copy, C order, its shape kept (also 0-d)
    return (v.view(np.uint64) & np.uint64(0xFFFFFFFF00000000)).view(np.float64)


def _ktan(x, y, iy):
    """tan(x + y) (``iy`` 1) or -1/tan(x + y) (``iy`` -1), |x| <= pi/4 (fdlibm __kernel_tan)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    big = np.abs(x) >= 0.6743316650390625              # 0x3FE59428
    sgn = np.where(np.signbit(x), -1.0, 1.0)
    xb = np.where(big, (7.85398163397448278999e-01 - sgn * x) + (3.06161699786838301793e-17 - sgn * y), x)
    yb = np.where(big, 0.0, y)
    z = xb * xb
    w = z * z
    r = _T[1] + w * (_T[3] + w * (_T[5] + w * (_T[7] + w * (_T[9] + w * _T[11]))))
    v = z * (_T[2] + w * (_T[4] + w * (_T[6] + w * (_T[8] + w * (_T[10] + w * _T[12])))))
    s = z * xb
    r = yb + z * (s * (r + v) + yb)
    r = r + _T[0] * s
    w = xb + r
    with np.errstate(divide="ignore", invalid="ignore"):
        vb = iy.astype(np.float64)
        out_big = sgn * (vb - 2.0 * (xb - (w * w / (w + vb) - r)))
        zl = _low_word_zero(w)                          # -1/(x + r) to full precision
        vl = r - (zl - xb)
        a = -1.0 / w
        t = _low_word_zero(a)
        sl = 1.0 + t * zl
        inv = t + a * (sl + t * vl)
        out = np.where(big, out_big, np.where(iy == 1, w, inv))
        tiny = np.abs(x) < 2.0 ** -28
        out = np.where(tiny, np.where(iy == 1, x, -1.0 / x), out)
    return out


def tan(x):
    """tan(x), within 1 ulp (fdlibm s_tan.c)."""
    if _jet(x):
        return np.tan(x)
    n, y0, y1 = _rem_pio2(x)
    iy = 1 - 2 * (np.asarray(n) & 1)
    return _out(x, _ktan(y0, y1, iy))


def arctan(x):
    """arctan(x), within 1 ulp (fdlibm s_atan.c)."""
    if _jet(x):
        return np.arctan(x)
    x0 = np.asarray(x, dtype=np.float64)
    a = np.abs(x0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ident = np.select([a < 0.4375, a < 0.6875, a < 1.1875, a < 2.4375], [-1, 0, 1, 2], 3)
        t = np.select([ident == 0, ident == 1, ident == 2, ident == 3],
                      [(2.0 * a - 1.0) / (2.0 + a), (a - 1.0) / (a + 1.0), (a - 1.5) / (1.0 + 1.5 * a), -1.0 / a], a)
        z = t * t
        w = z * z
        s1 = z * (_AT[0] + w * (_AT[2] + w * (_AT[4] + w * (_AT[6] + w * (_AT[8] + w * _AT[10])))))
        s2 = w * (_AT[1] + w * (_AT[3] + w * (_AT[5] + w * (_AT[7] + w * _AT[9]))))
        k = np.maximum(ident, 0)
        reduced = _ATANHI[k] - ((t * (s1 + s2) - _ATANLO[k]) - t)
        out = np.where(ident < 0, t - t * (s1 + s2), reduced)
    out = np.where(a >= 2.0 ** 66, _ATANHI[3] + _ATANLO[3], out)
    out = np.where(a < 2.0 ** -27, a, out)
    out = np.where(np.isnan(x0), np.nan, np.copysign(out, x0))
    return _out(x, out)


def arctan2(y, x):
    """arctan2(y, x), within 1 ulp (fdlibm e_atan2.c; finite arguments, signed zeros as in C)."""
    if _jet(y) or _jet(x):
        return np.arctan2(y, x)
    y0, x0 = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    m = np.signbit(y0).astype(np.int64) | (np.signbit(x0).astype(np.int64) << 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.frexp(y0)[1] - np.frexp(x0)[1]
        z = arctan(np.abs(np.where(k > 60, 1.0, y0) / np.where(k > 60, 1.0, x0)))
        z = np.where(k > 60, _PI_O_2 + 0.5 * _PI_LO, np.where((x0 < 0) & (k < -60), 0.0, z))
        out = np.select([m == 0, m == 1, m == 2], [z, -z, _PI - (z - _PI_LO)], (z - _PI_LO) - _PI)
        out = np.where(x0 == 1.0, arctan(y0), out)
        yzero = np.select([m == 2, m == 3], [_PI, -_PI], y0)
        out = np.where(y0 == 0.0, yzero, out)
        out = np.where((x0 == 0.0) & (y0 != 0.0), np.where(y0 < 0, -_PI_O_2, _PI_O_2), out)
        bad = ~(np.isfinite(y0) & np.isfinite(x0))
        if np.any(bad):
            out = np.where(bad, np.arctan2(y0, x0), out)
    return float(out) if np.ndim(out) == 0 else out


def exp(x):
    """exp(x), within 1 ulp (fdlibm e_exp.c)."""
    if _jet(x):
        return np.exp(x)
    x0 = np.asarray(x, dtype=np.float64)
    a = np.abs(x0)
    sign = np.where(x0 < 0, -1.0, 1.0)
    k = np.where(a > 0.5 * 0.6931471805599453,
                 np.where(a < 1.5 * 0.6931471805599453, sign, np.trunc(_INVLN2 * x0 + 0.5 * sign)), 0.0)
    hi = x0 - k * _LN2_HI
    lo = k * _LN2_LO
    t0 = hi - lo
    t = t0 * t0
    c = t0 - t * (_P[0] + t * (_P[1] + t * (_P[2] + t * (_P[3] + t * _P[4]))))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        y_k0 = 1.0 - ((t0 * c) / (c - 2.0) - t0)
        y = 1.0 - ((lo - (t0 * c) / (2.0 - c)) - hi)
        out = np.where(k == 0, y_k0, np.ldexp(y, np.clip(k, -2000, 2000).astype(np.int64)))
        out = np.where(a < 2.0 ** -28, 1.0 + x0, out)
        out = np.where(x0 > _O_THRESHOLD, np.inf, np.where(x0 < _U_THRESHOLD, 0.0, out))
        out = np.where(np.isnan(x0), np.nan, out)
    return _out(x, out)


def log(x):
    """log(x), within 1 ulp (fdlibm e_log.c)."""
    if _jet(x):
        return np.log(x)
    x0 = np.asarray(x, dtype=np.float64)
    sub = (x0 > 0) & (x0 < 2.2250738585072014e-308)
    xs = np.where(sub, np.where(sub, x0, 0.0) * 1.80143985094819840000e+16, x0)
    bits = np.array(np.abs(xs), dtype=np.float64).view(np.uint64)
    hx = (bits >> np.uint64(32)).astype(np.int64)
    low = bits & np.uint64(0xFFFFFFFF)
    k = (hx >> 20) - 1023 - np.where(sub, 54, 0)
    hx = hx & 0x000fffff
    i = (hx + 0x95f64) & 0x100000
    xn = ((((hx | (i ^ 0x3ff00000)).astype(np.uint64)) << np.uint64(32)) | low).view(np.float64)
    k = k + (i >> 20)
    f = xn - 1.0
    dk = k.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        r0 = f * f * (0.5 - 0.33333333333333333 * f)
        tiny = np.where(k == 0, f - r0, dk * _LN2_HI - ((r0 - dk * _LN2_LO) - f))
        tiny = np.where(f == 0.0, dk * _LN2_HI + dk * _LN2_LO, tiny)
        s = f / (2.0 + f)
        z = s * s
        w = z * z
        t1 = w * (_LG[1] + w * (_LG[3] + w * _LG[5]))
        t2 = z * (_LG[0] + w * (_LG[2] + w * (_LG[4] + w * _LG[6])))
        R = t2 + t1
        ii = (hx - 0x6147a) | (0x6b851 - hx)
        hfsq = 0.5 * f * f
        big = np.where(k == 0, f - (hfsq - s * (hfsq + R)), dk * _LN2_HI - ((hfsq - (s * (hfsq + R) + dk * _LN2_LO)) - f))
        small = np.where(k == 0, f - s * (f - R), dk * _LN2_HI - ((s * (f - R) - dk * _LN2_LO) - f))
        out = np.where(((0x000fffff & (2 + hx)) < 3), tiny, np.where(ii > 0, big, small))
        out = np.where(x0 == 0.0, -np.inf, np.where(x0 < 0, np.nan, out))
        out = np.where(np.isfinite(x0) | (x0 < 0), out, x0)          # +inf -> +inf, nan -> nan
    return _out(x, out)


def power(a, b):
    """``a ** b``: a whole exponent ``b`` (|b| <= 16) by products in one order, ``b = 0.5`` by ``sqrt``,
    else ``exp(b log a)`` (a > 0)."""
    if _jet(a) or _jet(b):
        return a ** b
    if np.ndim(b) == 0 and float(b) == round(float(b)) and abs(float(b)) <= 16:
        k = int(round(float(b)))
        x = np.asarray(a, dtype=np.float64)
        out = np.ones_like(x)
        for _ in range(abs(k)):
            out = out * x
        return _out(a, out if k >= 0 else 1.0 / out)
    if np.ndim(b) == 0 and float(b) == 0.5:
        return _out(a, np.sqrt(np.asarray(a, dtype=np.float64)))
    return _out(a, exp(np.asarray(b, dtype=np.float64) * log(a)))


def matmul(a, b):
    """``a @ b`` with one order of summation (the contracted index from first to last) and no BLAS; the
    shapes and broadcasting of ``np.matmul`` (a 1-D operand is a row or a column vector)."""
    if _jet(a) or _jet(b):
        return a @ b
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    row, col = a.ndim == 1, b.ndim == 1
    if row:
        a = a[None, :]
    if col:
        b = b[:, None]
    if a.shape[-1] != b.shape[-2]:
        raise ValueError(f"matmul: shapes {a.shape} and {b.shape} do not match")
    out = a[..., :, 0, None] * b[..., None, 0, :]
    for j in range(1, a.shape[-1]):
        out = out + a[..., :, j, None] * b[..., None, j, :]
    if col:
        out = out[..., 0]
    if row:
        out = out[..., 0, :] if not col else out[..., 0]
    return out


def hypot(x, y):
    """sqrt(x^2 + y^2) scaled by a power of two (exact) against overflow, within 1 ulp."""
    if _jet(x) or _jet(y):
        return np.hypot(x, y)
    x0, y0 = np.abs(np.asarray(x, dtype=np.float64)), np.abs(np.asarray(y, dtype=np.float64))
    e = np.frexp(np.maximum(x0, y0))[1]
    xs, ys = np.ldexp(x0, -e), np.ldexp(y0, -e)
    out = np.ldexp(np.sqrt(xs * xs + ys * ys), e)
    return float(out) if np.ndim(out) == 0 else out


# numpy names of exactly rounded operations, for the functions of nav/earth.py that take a math namespace
sqrt, stack, where, abs, maximum, zeros_like = np.sqrt, np.stack, np.where, np.abs, np.maximum, np.zeros_like
