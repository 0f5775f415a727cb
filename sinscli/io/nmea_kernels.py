"""NMEA 0183 sentences from raw bytes: numba kernels over a uint8 buffer (no I/O, no Python objects per sentence).

:func:`scan` finds every sentence ``$ttsss,...*hh`` (talker ``tt``, formatter ``sss``) with a valid checksum (the
XOR of the bytes between ``$`` and ``*``, NMEA 0183 v4.11 section 5.2.1), also between binary data as u-blox and
other loggers interleave them; :func:`parse` reads the fields of one formatter into a float table.  The field
layouts are NMEA 0183 v4.11's (GGA 6.3.63, RMC 6.3.143, VTG 6.3.188, GST 6.3.72, GSA 6.3.68).  Numbers are read
digit by digit into an integer and divided by a power of ten: the quotient of two exact doubles is correctly
rounded, so every value equals Python's ``float()`` of the same text (the parser of the RINEX kernels).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .rinex_kernels import parse_number

# formatter codes (column 'kind' of the scan)
K_OTHER, K_GGA, K_RMC, K_VTG, K_GST, K_GSA = 0, 1, 2, 3, 4, 5
KIND_NAMES = ("other", "GGA", "RMC", "VTG", "GST", "GSA")
MAX_SENTENCE = 160        # bytes from '$' to '*': NMEA 0183 allows 82 in all; high-precision and multi-GNSS
                          # variants run longer, so a sentence is cut only well beyond them
MAX_FIELDS = 48
# fields of each formatter in NMEA 0183 v2.0 (later versions add fields at the end: RMC's mode and navigational
# status, VTG's mode, GSA's system id); a sentence with fewer is garbled (a field lost would shift the rest)
MIN_FIELDS = (0, 14, 11, 8, 8, 17)
NCOL = 8                  # columns of a parsed table (module docstring of sinscli.io.nmea says what each holds)
# scan counters
C_VALID, C_OTHER, C_CHECKSUM, C_GARBLED, C_FIRST_CHECKSUM, C_FIRST_GARBLED = 0, 1, 2, 3, 4, 5


@njit(cache=True)
def _head_char(c):
    """A character of a sentence's address field: printable, not a delimiter ('$', ',', '*', '!', '\\')."""
    return 33 <= c <= 126 and c != 36 and c != 44 and c != 42 and c != 33 and c != 92


@njit(cache=True)
def _hex(c):
    if 48 <= c <= 57:
        return c - 48
    if 65 <= c <= 70:
        return c - 55
    if 97 <= c <= 102:
        return c - 87
    return -1


@njit(cache=True)
def _kind(buf, i):
    """Formatter code of the sentence whose '$' is at ``i`` (talker at i+1, i+2; formatter at i+3..i+5)."""
    a, b, c = buf[i + 3], buf[i + 4], buf[i + 5]
    if a == 71 and b == 71 and c == 65:           # GGA
        return K_GGA
    if a == 82 and b == 77 and c == 67:           # RMC
        return K_RMC
    if a == 86 and b == 84 and c == 71:           # VTG
        return K_VTG
    if a == 71 and b == 83 and c == 84:           # GST
        return K_GST
    if a == 71 and b == 83 and c == 65:           # GSA
        return K_GSA
    return K_OTHER


def scan(buf):
    """:func:`scan_kernel` with its arrays sized by the '$' bytes of ``buf`` (counted by numpy)."""
    return scan_kernel(buf, int(np.count_nonzero(buf == 36)))


@njit(cache=True)
def scan_kernel(buf, nd):
    """Every checksummed sentence of a known formatter: ``(start, end, kind, counts)`` with ``start`` the index of
    its '$', ``end`` that of its '*', and ``counts`` (:data:`C_VALID` ...): valid sentences of a known formatter,
    of other formatters, sentences with a bad checksum, and truncated or garbled ones (a sentence head
    ``$ttsss,`` not followed by ``*hh`` within :data:`MAX_SENTENCE` printable bytes), then the byte offsets of the
    first bad-checksum and the first garbled sentence (-1: none).  A '$' not followed by a sentence head (five
    printable characters and a comma) is binary data and not counted.  ``nd``: the number of '$' bytes."""
    n = buf.shape[0]
    start = np.empty(nd, np.int64)
    end = np.empty(nd, np.int64)
    kind = np.empty(nd, np.int8)
    counts = np.zeros(6, np.int64)
    counts[C_FIRST_CHECKSUM] = -1
    counts[C_FIRST_GARBLED] = -1
    m = 0
    i = 0
    while i < n:
        if buf[i] != 36:
            i += 1
            continue
        if i + 7 > n:
            # a head cut by the end of the file: garbled when what is there looks like one
            head = True
            for j in range(i + 1, n):
                if not _head_char(buf[j]):
                    head = False
            if head and n - i > 1:
                counts[C_GARBLED] += 1
                if counts[C_FIRST_GARBLED] < 0:
                    counts[C_FIRST_GARBLED] = i
            break
        head = buf[i + 6] == 44
        for j in range(i + 1, i + 6):
            if not _head_char(buf[j]):
                head = False
        if not head:
            i += 1
            continue
        cs = 0
        star = -1
        j = i + 1
        while j < n and j - i <= MAX_SENTENCE:
            c = buf[j]
            if c == 42:
                star = j
                break
            if c < 32 or c > 126 or c == 36:
                break
            cs ^= c
            j += 1
        if star < 0 or star + 2 >= n:
            counts[C_GARBLED] += 1
            if counts[C_FIRST_GARBLED] < 0:
                counts[C_FIRST_GARBLED] = i
            i = max(j, i + 1)
            continue
        h1, h2 = _hex(buf[star + 1]), _hex(buf[star + 2])
        if h1 < 0 or h2 < 0:
            counts[C_GARBLED] += 1
            if counts[C_FIRST_GARBLED] < 0:
                counts[C_FIRST_GARBLED] = i
            i = star + 1
            continue
        if h1 * 16 + h2 != cs:
            counts[C_CHECKSUM] += 1
            if counts[C_FIRST_CHECKSUM] < 0:
                counts[C_FIRST_CHECKSUM] = i
            i = star + 3
            continue
        k = _kind(buf, i)
        talker = 65 <= buf[i + 1] <= 90 and 65 <= buf[i + 2] <= 90 and buf[i + 1] != 80
        if k == K_OTHER or not talker:            # other formatters; proprietary ($P...) sentences
            counts[C_OTHER] += 1
        else:
            start[m] = i
            end[m] = star
            kind[m] = k
            m += 1
            counts[C_VALID] += 1
        i = star + 3
    return start[:m], end[:m], kind[:m], counts


@njit(cache=True)
def _fields(buf, s, e, pos):
    """Split the sentence at ``s`` ('$') .. ``e`` ('*') at its commas after the head: field k is
    ``buf[pos[k]:pos[k + 1] - 1]``.  Returns the number of fields (at most :data:`MAX_FIELDS`; -1 beyond)."""
    nf = 0
    pos[0] = s + 7
    for j in range(s + 7, e):
        if buf[j] == 44:
            nf += 1
            if nf >= MAX_FIELDS:
                return -1
            pos[nf] = j + 1
    pos[nf + 1] = e + 1
    return nf + 1


@njit(cache=True)
def _number(buf, a, b):
    """The decimal number in ``buf[a:b]`` (:func:`sinscli.io.rinex_kernels.parse_number`): ``(value, 1)``;
    ``(nan, 0)`` when empty; ``(nan, -1)`` when not a number."""
    v, st = parse_number(buf, a, b)
    return (v if st == 1 else np.nan), st


@njit(cache=True)
def _numbers(buf, pos, row, col, field, n):
    """Fields ``field .. field + n - 1`` as numbers into ``row[col:col + n]``; False when one is not a number."""
    good = True
    for i in range(n):
        row[col + i], f = _number(buf, pos[field + i], pos[field + i + 1] - 1)
        good = good and f >= 0
    return good


@njit(cache=True)
def _digits(buf, a, n):
    """The integer of the ``n`` digits at ``a``; -1 when one is not a digit."""
    v = 0
    for j in range(a, a + n):
        c = buf[j]
        if not 48 <= c <= 57:
            return -1
        v = v * 10 + (c - 48)
    return v


@njit(cache=True)
def _time_of_day(buf, a, b):
    """``hhmmss[.sss]`` -> seconds of the day: ``(value, 1)``, ``(nan, 0)`` empty, ``(nan, -1)`` malformed."""
    if a >= b:
        return np.nan, 0
    if b - a < 6:
        return np.nan, -1
    hh, mm = _digits(buf, a, 2), _digits(buf, a + 2, 2)
    ss, ok = _number(buf, a + 4, b)
    if hh < 0 or mm < 0 or ok != 1 or hh > 23 or mm > 59 or not (0.0 <= ss < 61.0) or _digits(buf, a + 4, 2) < 0:
        return np.nan, -1
    return float(hh * 3600 + mm * 60) + ss, 1


@njit(cache=True)
def _date(buf, a, b):
    """``ddmmyy`` -> ``yyyymmdd`` (two-digit years 80-99: 19yy, else 20yy), a date of the Gregorian calendar."""
    if a >= b:
        return np.nan, 0
    if b - a != 6:
        return np.nan, -1
    dd, mo, yy = _digits(buf, a, 2), _digits(buf, a + 2, 2), _digits(buf, a + 4, 2)
    if dd < 1 or mo < 1 or mo > 12 or yy < 0:
        return np.nan, -1
    year = 1900 + yy if yy >= 80 else 2000 + yy
    mdays = (31, 29 if (year % 4 == 0 and (year % 100 != 0 or year % 400 == 0)) else 28, 31, 30, 31, 30, 31, 31,
             30, 31, 30, 31)
    if dd > mdays[mo - 1]:
        return np.nan, -1
    return float(year * 10000 + mo * 100 + dd), 1


@njit(cache=True)
def _angle(buf, a, b, ha, hb, deg_max):
    """``(d)ddmm.mmmm`` with the hemisphere letter ``buf[ha:hb]`` (N, S for a latitude, ``deg_max`` 90; E, W for a
    longitude; S and W negative) -> signed degrees:
    ``deg + minutes / 60`` (the degrees all digits but the two before the '.')."""
    if a >= b:
        return np.nan, 0
    p = a
    while p < b and buf[p] != 46:
        p += 1
    if p - a < 3:
        return np.nan, -1
    deg = 0
    for j in range(a, p - 2):
        c = buf[j]
        if not 48 <= c <= 57:
            return np.nan, -1
        deg = deg * 10 + (c - 48)
    minutes, ok = _number(buf, p - 2, b)
    if ok != 1 or minutes >= 60.0 or deg > deg_max:
        return np.nan, -1
    h = _char(buf, ha, hb)
    if h == (78 if deg_max == 90 else 69):            # N | E
        sign = 1.0
    elif h == (83 if deg_max == 90 else 87):          # S | W
        sign = -1.0
    else:
        return np.nan, -1
    return sign * (deg + minutes / 60.0), 1


@njit(cache=True)
def _char(buf, a, b):
    """The one letter of a field: its code, 0 when empty, -1 when longer."""
    if a >= b:
        return 0
    if b - a != 1:
        return -1
    return int(buf[a])


@njit(cache=True)
def parse(buf, start, end, want):
    """The fields of the sentences ``start[k]..end[k]`` (all of formatter ``want``) as an ``(m, NCOL)`` table
    and ``ok`` (False: garbled: a field that is not what the formatter puts there; NaN marks an empty field).

    GGA: time of day (s), lat, lon (deg), quality, satellites, HDOP, altitude (m above mean sea level),
    geoid separation (m).  RMC: time of day, status (1 A valid, 0 V), lat, lon, speed (knots), course (deg),
    date (yyyymmdd), mode letter (0: none).  VTG: course (deg true), speed (knots), speed (km/h),
    mode letter.  GST: time of day, sigma lat, lon, alt (m).  GSA: fix type, PDOP, HDOP, VDOP."""
    m = start.shape[0]
    out = np.full((m, NCOL), np.nan)
    ok = np.ones(m, np.bool_)
    pos = np.empty(MAX_FIELDS + 2, np.int64)
    for k in range(m):
        s, e = start[k], end[k]
        nf = _fields(buf, s, e, pos)
        good = nf > 0
        row = out[k]
        if want == K_GGA:
            good = good and nf >= MIN_FIELDS[K_GGA]
            if good:
                row[0], f0 = _time_of_day(buf, pos[0], pos[1] - 1)
                q, fq = _number(buf, pos[5], pos[6] - 1)
                good = f0 >= 0 and fq == 1 and q == np.floor(q) and 0.0 <= q <= 8.0
                row[3] = q
            if good:
                row[1], f1 = _angle(buf, pos[1], pos[2] - 1, pos[2], pos[3] - 1, 90)
                row[2], f2 = _angle(buf, pos[3], pos[4] - 1, pos[4], pos[5] - 1, 180)
                row[4], f4 = _number(buf, pos[6], pos[7] - 1)
                row[5], f5 = _number(buf, pos[7], pos[8] - 1)
                row[6], f6 = _number(buf, pos[8], pos[9] - 1)
                f7 = 0
                if nf >= 11:
                    row[7], f7 = _number(buf, pos[10], pos[11] - 1)
                good = f1 >= 0 and f2 >= 0 and f4 >= 0 and f5 >= 0 and f6 >= 0 and f7 >= 0
                if good and q > 0.0:            # a fix has its position and altitude
                    good = f1 == 1 and f2 == 1 and f6 == 1
        elif want == K_RMC:
            good = good and nf >= MIN_FIELDS[K_RMC]
            if good:
                row[0], f0 = _time_of_day(buf, pos[0], pos[1] - 1)
                st = _char(buf, pos[1], pos[2] - 1)
                row[1] = 1.0 if st == 65 else 0.0
                row[2], f2 = _angle(buf, pos[2], pos[3] - 1, pos[3], pos[4] - 1, 90)
                row[3], f3 = _angle(buf, pos[4], pos[5] - 1, pos[5], pos[6] - 1, 180)
                row[4], f4 = _number(buf, pos[6], pos[7] - 1)
                row[5], f5 = _number(buf, pos[7], pos[8] - 1)
                row[6], f6 = _date(buf, pos[8], pos[9] - 1)
                mode = 0
                if nf >= 12:
                    mode = _char(buf, pos[11], pos[12] - 1)
                row[7] = mode
                good = (f0 >= 0 and (st == 65 or st == 86) and f2 >= 0 and f3 >= 0 and f4 >= 0 and f5 >= 0
                        and f6 >= 0 and mode >= 0)
        elif want == K_VTG:
            good = good and nf >= MIN_FIELDS[K_VTG]
            if good:
                row[0], f0 = _number(buf, pos[0], pos[1] - 1)
                row[1], f1 = _number(buf, pos[4], pos[5] - 1)
                row[2], f2 = _number(buf, pos[6], pos[7] - 1)
                mode = 0
                if nf >= 9:
                    mode = _char(buf, pos[8], pos[9] - 1)
                row[3] = mode
                u1, u5, u7 = _char(buf, pos[1], pos[2] - 1), _char(buf, pos[5], pos[6] - 1), _char(buf, pos[7], pos[8] - 1)
                good = (f0 >= 0 and f1 >= 0 and f2 >= 0 and mode >= 0 and (u1 == 84 or u1 == 0)      # T, N, K
                        and (u5 == 78 or u5 == 0) and (u7 == 75 or u7 == 0))
        elif want == K_GST:
            good = good and nf >= MIN_FIELDS[K_GST]
            if good:
                row[0], f0 = _time_of_day(buf, pos[0], pos[1] - 1)
                good = f0 >= 0 and _numbers(buf, pos, row, 1, 5, 3)          # sigma lat, lon, alt
        elif want == K_GSA:
            good = good and nf >= MIN_FIELDS[K_GSA]
            if good:
                good = _numbers(buf, pos, row, 0, 1, 1) and _numbers(buf, pos, row, 1, 14, 3)    # fix; P/H/VDOP
        ok[k] = good
    return out, ok
