"""Shortest round-trip text of float64 values, compiled (issue 21): Ryu, written into a byte buffer.

``d2d`` is Ulf Adams' Ryu (PLDI 2018, "Ryu: fast float-to-string conversion", the reference ``d2s.c``):
the shortest decimal ``m * 10**e`` inside the interval of reals that round to the double (bounds included
when its significand is even, as IEEE round-half-even reads them), the closest to the double when several
are as short, ties to even digits.  That is the digit string of Python's ``repr`` and of double-conversion's
``ToShortest`` (which pyarrow's CSV writer used before), so the text reads back to the identical float64.

The layout is the one the trajectory files have always had (pyarrow's, double-conversion with
``EMIT_POSITIVE_EXPONENT_SIGN``, decimal notation for decimal exponents -6 .. 9): ``0.000001``,
``123``, ``12.5``, ``1e+10``, ``1.5e-7``, ``-0``; no trailing ``.0``.  docs/io_formats.md names it.
Finite values only: the writers pass every chunk through ``io/atomic.check_finite`` first.

``format_rows`` writes whole CSV rows (values, ``,``, the constant suffix of text columns, ``\\n``); it
releases the GIL, so several slices are formatted on threads at once (``csvcore.CsvTableWriter``).
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

POW5_INV_BITCOUNT = 125
POW5_BITCOUNT = 125
MAX_CHARS = 24                       # "-1.2345678901234567e-308": the longest text of one float64


def _tables():
    """Ryu's 128-bit tables: ``5**i`` in its top 125 bits (i < 326) and ``2**(bits(5**q) - 1 + 125) // 5**q + 1``
    (q < 342), each as (low 64 bits, high 64 bits)."""
    mask = (1 << 64) - 1
    pos = np.zeros((326, 2), np.uint64)
    for i in range(326):
        p = 5 ** i
        shift = p.bit_length() - POW5_BITCOUNT
        v = p >> shift if shift >= 0 else p << -shift
        pos[i] = (v & mask, v >> 64)
    inv = np.zeros((342, 2), np.uint64)
    for q in range(342):
        p = 5 ** q
        v = (1 << (p.bit_length() - 1 + POW5_INV_BITCOUNT)) // p + 1
        inv[q] = (v & mask, v >> 64)
    return pos, inv


POW5_SPLIT, POW5_INV_SPLIT = _tables()


@intrinsic
def _mul_shift64(typingctx, m, lo, hi, shift):
    """``((m * (hi * 2**64 + lo)) >> shift) mod 2**64`` (``mulShift64`` of d2s.c: two 64x64 -> 128-bit
    products; ``m`` below 2**55, 64 <= ``shift`` < 192)."""
    sig = types.uint64(types.uint64, types.uint64, types.uint64, types.int64)

    def codegen(context, builder, signature, args):
        i128 = ir.IntType(128)
        mm, ll, hh = (builder.zext(a, i128) for a in args[:3])
        b0 = builder.mul(mm, ll)
        b2 = builder.mul(mm, hh)
        total = builder.add(builder.lshr(b0, ir.Constant(i128, 64)), b2)
        sh = builder.zext(builder.sub(args[3], ir.Constant(ir.IntType(64), 64)), i128)
        return builder.trunc(builder.lshr(total, sh), ir.IntType(64))

    return sig, codegen


@njit(cache=True, inline="always")
def _pow5bits(e):
    return ((e * 1217359) >> 19) + 1


@njit(cache=True)
def _pow5_factor(v):
    n = 0
    while v > np.uint64(0):
        q = v // np.uint64(5)
        if v - q * np.uint64(5) != np.uint64(0):
            break
        v = q
        n += 1
    return n


@njit(cache=True)
def d2d(bits):
    """Ryu's shortest decimal of the finite, non-zero double with IEEE bits ``bits`` (uint64, sign ignored):
    ``(digits, exponent)``, value = digits * 10**exponent, digits with no trailing zero removed by
    necessity (d2s.c ``d2d``)."""
    ieee_m = bits & np.uint64((1 << 52) - 1)
    ieee_e = np.int64((bits >> np.uint64(52)) & np.uint64(0x7FF))
    if ieee_e == 0:
        e2 = 1 - 1023 - 52 - 2
        m2 = ieee_m
    else:
        e2 = ieee_e - 1023 - 52 - 2
        m2 = ieee_m | np.uint64(1 << 52)
    even = (m2 & np.uint64(1)) == np.uint64(0)
    mv = np.uint64(4) * m2
    mm_shift = np.uint64(1) if (ieee_m != np.uint64(0) or ieee_e <= 1) else np.uint64(0)
    mp_ = mv + np.uint64(2)
    mm_ = mv - np.uint64(1) - mm_shift
    vm_trailing = False
    vr_trailing = False
    if e2 >= 0:
        q = ((e2 * 78913) >> 18) - (1 if e2 > 3 else 0)
        e10 = q
        k = POW5_INV_BITCOUNT + _pow5bits(q) - 1
        i = -e2 + q + k
        lo, hi = POW5_INV_SPLIT[q, 0], POW5_INV_SPLIT[q, 1]
        vr = _mul_shift64(mv, lo, hi, i)
        vp = _mul_shift64(mp_, lo, hi, i)
        vm = _mul_shift64(mm_, lo, hi, i)
        if q <= 21:
            if mv % np.uint64(5) == np.uint64(0):
                vr_trailing = _pow5_factor(mv) >= q
            elif even:
                vm_trailing = _pow5_factor(mm_) >= q
            elif _pow5_factor(mp_) >= q:
                vp -= np.uint64(1)
    else:
        q = ((-e2 * 732923) >> 20) - (1 if -e2 > 1 else 0)
        e10 = q + e2
        i = -e2 - q
        k = _pow5bits(i) - POW5_BITCOUNT
        j = q - k
        lo, hi = POW5_SPLIT[i, 0], POW5_SPLIT[i, 1]
        vr = _mul_shift64(mv, lo, hi, j)
        vp = _mul_shift64(mp_, lo, hi, j)
        vm = _mul_shift64(mm_, lo, hi, j)
        if q <= 1:
            vr_trailing = True
            if even:
                vm_trailing = mm_shift == np.uint64(1)
            else:
                vp -= np.uint64(1)
        elif q < 63:
            vr_trailing = (mv & ((np.uint64(1) << np.uint64(q)) - np.uint64(1))) == np.uint64(0)
    removed = 0
    last = np.uint64(0)
    ten = np.uint64(10)
    if vm_trailing or vr_trailing:
        while True:
            vp10 = vp // ten
            vm10 = vm // ten
            if vp10 <= vm10:
                break
            vm_trailing = vm_trailing and (vm - vm10 * ten) == np.uint64(0)
            vr_trailing = vr_trailing and last == np.uint64(0)
            vr10 = vr // ten
            last = vr - vr10 * ten
            vr, vp, vm = vr10, vp10, vm10
            removed += 1
        if vm_trailing:
            while True:
                vm10 = vm // ten
                if vm - vm10 * ten != np.uint64(0):
                    break
                vr_trailing = vr_trailing and last == np.uint64(0)
                vr10 = vr // ten
                last = vr - vr10 * ten
                vr, vp, vm = vr10, vp // ten, vm10
                removed += 1
        if vr_trailing and last == np.uint64(5) and (vr & np.uint64(1)) == np.uint64(0):
            last = np.uint64(4)                       # exactly ...50..0: round to even
        up = (vr == vm and (not even or not vm_trailing)) or last >= np.uint64(5)
    else:
        up = False
        vp100 = vp // np.uint64(100)
        vm100 = vm // np.uint64(100)
        if vp100 > vm100:
            vr100 = vr // np.uint64(100)
            up = vr - vr100 * np.uint64(100) >= np.uint64(50)
            vr, vp, vm = vr100, vp100, vm100
            removed += 2
        while True:
            vp10 = vp // ten
            vm10 = vm // ten
            if vp10 <= vm10:
                break
            vr10 = vr // ten
            up = vr - vr10 * ten >= np.uint64(5)
            vr, vp, vm = vr10, vp10, vm10
            removed += 1
        up = up or vr == vm
    return vr + (np.uint64(1) if up else np.uint64(0)), e10 + removed


_PAIRS = np.frombuffer("".join(f"{i:02d}" for i in range(100)).encode(), np.uint8).copy()   # "00".."99"


_U10, _U100, _U10K, _U48 = np.uint64(10), np.uint64(100), np.uint64(10_000), np.uint64(48)


@njit(cache=True, inline="always")
def _ndigits(v):
    """Decimal digits of ``v`` (uint64, > 0)."""
    n = 1
    while v >= _U10K:
        v //= _U10K
        n += 4
    if v >= _U100:
        v //= _U100
        n += 2
    if v >= _U10:
        n += 1
    return n


@njit(cache=True, inline="always")
def _put_digits(v, out, end, count):
    """The last ``count`` decimal digits of ``v`` (uint64: unsigned division is the cheaper) into
    ``out[end - count:end]``, two at a time; returns what is left of ``v``."""
    while count >= 2:
        q = v // _U100
        r = v - q * _U100
        v = q
        out[end - 1] = _PAIRS[2 * r + 1]
        out[end - 2] = _PAIRS[2 * r]
        end -= 2
        count -= 2
    if count:
        q = v // _U10
        out[end - 1] = v - q * _U10 + _U48
        v = q
    return v


@njit(cache=True)
def write_float(x, out, pos):
    """Write the shortest round-trip text of the finite float64 ``x`` into ``out`` (uint8) at ``pos``;
    returns the position after it.  Layout of the module docstring."""
    bits = np.float64(x).view(np.uint64)
    if bits >> np.uint64(63):
        out[pos] = 45                                  # "-"
        pos += 1
        bits &= np.uint64(0x7FFFFFFFFFFFFFFF)
    if bits == np.uint64(0):
        out[pos] = 48
        return pos + 1
    digits, exp = d2d(bits)                            # at most 17 digits
    n = _ndigits(digits)
    point = n + exp                                    # value = 0.d1d2...dn * 10**point
    sci = point - 1
    fixed = -6 <= sci < 10
    if fixed and point <= 0:                           # 0.000ddd
        out[pos] = 48
        out[pos + 1] = 46
        pos += 2
        for _ in range(-point):
            out[pos] = 48
            pos += 1
    start = pos if fixed else pos + 1
    _put_digits(digits, out, start + n, n)             # the digits, once; then the point or the exponent
    if fixed:
        if point <= 0:
            return start + n
        if point >= n:                                 # ddd000
            end = start + n
            for _ in range(point - n):
                out[end] = 48
                end += 1
            return end
        for k in range(start + n, start + point, -1):  # dd.ddd: the fraction one to the right
            out[k] = out[k - 1]
        out[start + point] = 46
        return start + n + 1
    out[pos] = out[pos + 1]                            # d.ddde+XX
    if n > 1:
        out[pos + 1] = 46
    pos += n + (1 if n > 1 else 0)
    out[pos] = 101                                     # "e"
    out[pos + 1] = 43 if sci >= 0 else 45
    pos += 2
    a = sci if sci >= 0 else -sci
    if a >= 100:
        out[pos] = 48 + a // 100
        out[pos + 1] = 48 + (a // 10) % 10
        out[pos + 2] = 48 + a % 10
        return pos + 3
    if a >= 10:
        out[pos] = 48 + a // 10
        out[pos + 1] = 48 + a % 10
        return pos + 2
    out[pos] = 48 + a
    return pos + 1


@njit(cache=True, nogil=True)
def format_rows(rows, suffix, out):
    """CSV rows of ``rows`` (float64, C-contiguous, shape (rows, columns)) into ``out`` (uint8, at least
    ``rows * (columns * (MAX_CHARS + 1) + len(suffix) + 1)`` bytes): the values of a row separated by
    ``,``, then ``suffix`` (e.g. ``,flu``), then ``\\n``.  Returns the number of bytes written."""
    nrow, ncol = rows.shape
    pos = 0
    for r in range(nrow):
        for c in range(ncol):
            if c:
                out[pos] = 44
                pos += 1
            pos = write_float(rows[r, c], out, pos)
        for b in suffix:
            out[pos] = b
            pos += 1
        out[pos] = 10
        pos += 1
    return pos


def row_bytes(ncol: int, suffix_len: int = 0) -> int:
    """The most bytes :func:`format_rows` writes per row."""
    return ncol * (MAX_CHARS + 1) + suffix_len + 1


def format_floats(values) -> bytes:
    """``values`` (1-D) as one text per line (tests and small uses)."""
    v = np.ascontiguousarray(values, dtype=np.float64).reshape(-1, 1)
    out = np.empty(v.shape[0] * row_bytes(1), np.uint8)
    n = format_rows(v, np.empty(0, np.uint8), out)
    return out[:n].tobytes()
