"""Byte-level parsers of RINEX observation bodies (numba kernels over the file's bytes; no file access).

One pass over the bytes fills preallocated arrays; a problem stops the pass with an error code, the line and
the column (1-based) for :mod:`sinscli.io.rinex` to turn into a message.  RINEX 3.02-3.05 (one satellite per
line, ``>`` epoch lines) and RINEX 2.11 (satellite lists in the epoch line, 5 observations per line).
"""
from __future__ import annotations

import numpy as np
from numba import njit


from ..gnss.timesys import GPS_EPOCH_DAYS, days_from_civil

POW10 = 10.0 ** np.arange(23)     # 10^0 .. 10^22: every one exact in float64

NL = 10
CR = 13
SP = 32

# error codes
OK = 0
E_EPOCH = 1          # not an epoch line where one is expected
E_NUMBER = 2         # a field that is not a number
E_COUNT = 3          # impossible satellite count
E_SAT = 4            # bad satellite id / system not in the header
E_TRUNC = 5          # the file ends inside an epoch
E_FLAG = 6           # epoch flag outside 0..6
E_DATE = 7           # impossible date or time


@njit(cache=True)
def parse_number(buf, a, b):
    """Decimal number in ``buf[a:b]`` (blanks around it; sign; digits; '.'; exponent E/D).
    Returns ``(value, status)``: status 1 a number, 0 blank, -1 not a number."""
    i = a
    while i < b and buf[i] == SP:
        i += 1
    if i >= b:
        return 0.0, 0
    neg = False
    if buf[i] == 45 or buf[i] == 43:          # - +
        neg = buf[i] == 45
        i += 1
    mant = 0
    ndig = 0
    dec = 0
    seen_dot = False
    while i < b:
        c = buf[i]
        if 48 <= c <= 57:
            if ndig < 18:
                mant = mant * 10 + (c - 48)
                ndig += 1
                if seen_dot:
                    dec += 1
            elif not seen_dot:
                dec -= 1
        elif c == 46 and not seen_dot:
            seen_dot = True
        else:
            break
        i += 1
    if ndig == 0:
        return 0.0, -1
    exp = 0
    if i < b and (buf[i] == 69 or buf[i] == 68 or buf[i] == 101 or buf[i] == 100):   # E D e d
        i += 1
        eneg = False
        if i < b and (buf[i] == 45 or buf[i] == 43):
            eneg = buf[i] == 45
            i += 1
        nd = 0
        while i < b and 48 <= buf[i] <= 57:
            exp = exp * 10 + (buf[i] - 48)
            nd += 1
            i += 1
        if nd == 0:
            return 0.0, -1
        if eneg:
            exp = -exp
    while i < b and buf[i] == SP:
        i += 1
    if i < b:
        return 0.0, -1
    p = dec - exp
    if 0 <= p <= 22:
        v = mant / POW10[p]                   # exact powers of ten from a table: pow() is slow per field
    elif p >= 0:
        v = mant / 10.0 ** p
    else:
        v = mant * 10.0 ** (-p)
    return (-v if neg else v), 1


@njit(cache=True)
def _int(buf, a, b, blank):
    v, st = parse_number(buf, a, b)
    if st == 0:
        return blank, True
    if st < 0 or v != np.floor(v):
        return 0, False
    return int(v), True


@njit(cache=True)
def _line_end(buf, p, n):
    """(end of content, start of the next line) of the line starting at ``p``."""
    q = p
    while q < n and buf[q] != NL:
        q += 1
    nxt = q + 1
    e = q
    if e > p and buf[e - 1] == CR:
        e -= 1
    return e, nxt


@njit(cache=True)
def _epoch_time(year, month, day, hour, minute, sec):
    days = days_from_civil(year, month, day) - GPS_EPOCH_DAYS
    return days * 86400.0 + hour * 3600.0 + minute * 60.0 + sec


@njit(cache=True)
def _valid_date(year, month, day, hour, minute, sec):
    return (1980 <= year <= 2200 and 1 <= month <= 12 and 1 <= day <= 31 and 0 <= hour <= 24
            and 0 <= minute <= 59 and 0.0 <= sec < 61.0)


@njit(cache=True)
def _skip_lines(buf, p, n, k):
    """``(position, lines skipped)`` after skipping up to ``k`` lines from byte ``p``."""
    done = 0
    while done < k and p < n:
        _, p = _line_end(buf, p, n)
        done += 1
    return p, done


@njit(cache=True)
def _alloc(max_rows, nmax):
    """The output arrays of the body parsers (rows: an upper bound, the line count)."""
    return (np.empty(max_rows), np.empty(max_rows, np.int8), np.full(max_rows, np.nan), np.empty(max_rows, np.int64),
            np.zeros(max_rows + 1, np.int64), np.empty(max_rows, np.uint8), np.empty(max_rows, np.int16),
            np.empty(max_rows, np.int64), np.full((max_rows, nmax), np.nan), np.zeros((max_rows, nmax), np.int8))


@njit(cache=True)
def _obs_field(buf, a, e, vals, lli, r, j):
    """One observation field (F14.3, then the loss-of-lock digit, then the signal-strength digit) at byte ``a`` of a
    line ending at ``e`` into ``vals[r, j]`` and ``lli[r, j]``, which holds ``LLI + 8 SSI`` (LLI 0-7, SSI 0-9:
    :func:`sinscli.io.rinex.read_obs` splits them); returns the status of :func:`parse_number`."""
    v, st = parse_number(buf, a, min(a + 14, e))
    if st > 0:
        vals[r, j] = v
        if a + 14 < e:
            ch = buf[a + 14]
            if 48 <= ch <= 55:
                lli[r, j] = ch - 48
        if a + 15 < e:
            ch = buf[a + 15]
            if 48 <= ch <= 57:
                lli[r, j] += 8 * (ch - 48)
    return st


@njit(cache=True)
def parse_obs3(buf, pos, line0, ntypes, nmax, max_rows):
    """RINEX 3 observation body from byte ``pos`` (line number ``line0``).  ``ntypes[c]`` is the number of
    observation types of the system with ASCII letter c (-1: not in the header).

    Returns ``(err, err_line, err_col, err_val, n_ep, n_rec, ep_time, ep_flag, ep_clk, ep_line, ep_start,
    rec_sys, rec_prn, rec_line, vals, lli)``."""
    n = buf.shape[0]
    ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn, rec_line, vals, lli = _alloc(max_rows, nmax)
    ne = 0
    nr = 0
    line = line0
    p = pos
    while p < n:
        e, nxt = _line_end(buf, p, n)
        if e == p:                                # an empty line (at the end)
            p = nxt
            line += 1
            continue
        if buf[p] != 62:                          # '>'
            return (E_EPOCH, line, 1, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        year, ok1 = _int(buf, p + 1, min(p + 6, e), -1)
        month, ok2 = _int(buf, min(p + 6, e), min(p + 9, e), -1)
        day, ok3 = _int(buf, min(p + 9, e), min(p + 12, e), -1)
        hour, ok4 = _int(buf, min(p + 12, e), min(p + 15, e), -1)
        minute, ok5 = _int(buf, min(p + 15, e), min(p + 18, e), -1)
        sec, st = parse_number(buf, min(p + 18, e), min(p + 29, e))
        flag, ok6 = _int(buf, min(p + 29, e), min(p + 32, e), 0)
        nsat, ok7 = _int(buf, min(p + 32, e), min(p + 35, e), -1)
        if not (ok1 and ok2 and ok3 and ok4 and ok5 and ok6 and st == 1):
            return (E_NUMBER, line, 2, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        if not ok7 or nsat < 0:
            return (E_COUNT, line, 33, -1.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        if flag < 0 or flag > 6:
            return (E_FLAG, line, 32, flag, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        if flag <= 1 or flag == 6:
            if not _valid_date(year, month, day, hour, minute, sec):
                return (E_DATE, line, 3, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                        rec_prn, rec_line, vals, lli)
        p = nxt
        line += 1
        if flag >= 2:                             # event records / cycle-slip records: skipped
            p, skipped = _skip_lines(buf, p, n, nsat)
            line += skipped
            if skipped < nsat:
                return (E_TRUNC, line, 1, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                        rec_prn, rec_line, vals, lli)
            continue
        ep_time[ne] = _epoch_time(year, month, day, hour, minute, sec)
        ep_flag[ne] = flag
        ep_line[ne] = line - 1
        ep_start[ne] = nr
        for k in range(nsat):
            if p >= n:
                return (E_TRUNC, line, 1, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                        rec_prn, rec_line, vals, lli)
            e2, nxt2 = _line_end(buf, p, n)
            if e2 > p and buf[p] == 62:           # the next epoch before nsat records
                return (E_COUNT, line, 33, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                        rec_prn, rec_line, vals, lli)
            c = buf[p] if e2 > p else SP
            if c == SP:
                c = 71                            # 'G' (a blank system letter means GPS)
            prn, okp = _int(buf, min(p + 1, e2), min(p + 3, e2), -1)
            if c > 127 or ntypes[c] < 0 or not okp or prn <= 0:
                return (E_SAT, line, 1, c, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                        rec_line, vals, lli)
            rec_sys[nr] = c
            rec_prn[nr] = prn
            rec_line[nr] = line
            for j in range(ntypes[c]):
                a = p + 3 + 16 * j
                if a >= e2:
                    break
                if _obs_field(buf, a, e2, vals, lli, nr, j) < 0:
                    return (E_NUMBER, line, 4 + 16 * j, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start,
                            rec_sys, rec_prn, rec_line, vals, lli)
            nr += 1
            p = nxt2
            line += 1
        ne += 1
        ep_start[ne] = nr
    return (OK, line, 0, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn, rec_line,
            vals, lli)


@njit(cache=True)
def parse_obs2(buf, pos, line0, ntypes, default_sys, known, max_rows):
    """RINEX 2.11 observation body: ``ntypes`` types for every system (``known[c]`` True for the system
    letters accepted), ``default_sys`` the letter of a blank system field.  Returns what :func:`parse_obs3`
    returns."""
    n = buf.shape[0]
    nmax = max(ntypes, 1)
    nl = (ntypes + 4) // 5
    ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn, rec_line, vals, lli = _alloc(max_rows, nmax)
    sats_c = np.empty(512, np.uint8)
    sats_p = np.empty(512, np.int64)
    ne = 0
    nr = 0
    line = line0
    p = pos
    while p < n:
        e, nxt = _line_end(buf, p, n)
        if e == p:
            p = nxt
            line += 1
            continue
        yy, ok1 = _int(buf, p, min(p + 3, e), -1)
        month, ok2 = _int(buf, min(p + 3, e), min(p + 6, e), -1)
        day, ok3 = _int(buf, min(p + 6, e), min(p + 9, e), -1)
        hour, ok4 = _int(buf, min(p + 9, e), min(p + 12, e), -1)
        minute, ok5 = _int(buf, min(p + 12, e), min(p + 15, e), -1)
        sec, st = parse_number(buf, min(p + 15, e), min(p + 26, e))
        flag, ok6 = _int(buf, min(p + 26, e), min(p + 29, e), 0)
        nsat, ok7 = _int(buf, min(p + 29, e), min(p + 32, e), -1)
        if not (ok6 and ok7):
            return (E_EPOCH, line, 27, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        if flag < 0 or flag > 6:
            return (E_FLAG, line, 29, flag, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        if nsat < 0 or nsat > 512:
            return (E_COUNT, line, 30, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        eline = line
        eb = p
        p = nxt
        line += 1
        if flag >= 2 and flag <= 5:
            p, skipped = _skip_lines(buf, p, n, nsat)
            line += skipped
            if skipped < nsat:
                return (E_TRUNC, line, 1, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                        rec_prn, rec_line, vals, lli)
            continue
        if not (ok1 and ok2 and ok3 and ok4 and ok5 and st == 1):
            return (E_NUMBER, eline, 1, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        year = yy + 2000 if yy < 80 else yy + 1900
        if not _valid_date(year, month, day, hour, minute, sec):
            return (E_DATE, eline, 1, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn,
                    rec_line, vals, lli)
        # satellite list: 12 per line from column 33, then continuation lines
        ce = e
        cb = eb
        for i in range(nsat):
            if i > 0 and i % 12 == 0:            # a continuation line
                if p >= n:
                    return (E_TRUNC, line, 1, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                            rec_prn, rec_line, vals, lli)
                ce, nxt3 = _line_end(buf, p, n)
                cb = p
                p = nxt3
                line += 1
            a = cb + 32 + 3 * (i % 12)
            if a + 3 > ce:
                return (E_COUNT, line - 1, 33 + 3 * (i % 12), nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line,
                        ep_start, rec_sys, rec_prn, rec_line, vals, lli)
            c = buf[a]
            if c == SP:
                c = default_sys
            prn, okp = _int(buf, a + 1, a + 3, -1)
            if c > 127 or not known[c] or not okp or prn <= 0:
                return (E_SAT, line - 1, 33 + 3 * (i % 12), c, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start,
                        rec_sys, rec_prn, rec_line, vals, lli)
            sats_c[i] = c
            sats_p[i] = prn
        if flag == 6:                             # cycle-slip records: skipped
            p, skipped = _skip_lines(buf, p, n, nsat * nl)
            line += skipped
            continue
        ep_time[ne] = _epoch_time(year, month, day, hour, minute, sec)
        ep_flag[ne] = flag
        ep_line[ne] = eline
        ep_start[ne] = nr
        for i in range(nsat):
            rec_sys[nr] = sats_c[i]
            rec_prn[nr] = sats_p[i]
            rec_line[nr] = line
            for li in range(nl):
                if p >= n:
                    return (E_TRUNC, line, 1, nsat, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys,
                            rec_prn, rec_line, vals, lli)
                e2, nxt2 = _line_end(buf, p, n)
                for jj in range(5):
                    j = li * 5 + jj
                    if j >= ntypes:
                        break
                    a = p + 16 * jj
                    if a >= e2:
                        break
                    if _obs_field(buf, a, e2, vals, lli, nr, j) < 0:
                        return (E_NUMBER, line, 1 + 16 * jj, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line,
                                ep_start, rec_sys, rec_prn, rec_line, vals, lli)
                p = nxt2
                line += 1
            nr += 1
        ne += 1
        ep_start[ne] = nr
    return (OK, line, 0, 0.0, ne, nr, ep_time, ep_flag, ep_clk, ep_line, ep_start, rec_sys, rec_prn, rec_line,
            vals, lli)
