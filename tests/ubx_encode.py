"""Test helper: UBX bytes (RXM-RAWX, RXM-SFRBX GPS LNAV) from an observation table and ephemeris rows."""
from __future__ import annotations

import math
import struct

import numpy as np

from sinscli.gnss import ephemeris as E
from sinscli.io.ubx import crc24q
from sinscli.gnss.timesys import SECONDS_PER_WEEK

PI = math.pi


def frame(cls, mid, payload: bytes) -> bytes:
    body = bytes([cls, mid]) + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for x in body:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes([a, b])


def rawx(t, sats, pr, cp, dop, cno, lock=None, trk_extra=None, cpstd=None) -> bytes:
    """RXM-RAWX: per measurement ``lock`` time (ms, default 1000), ``trk_extra`` trkStat bits 2-3 (default 4: the
    half cycle resolved, none subtracted), ``cpstd`` the cpStdev field (default 3)."""
    week = int(t // SECONDS_PER_WEEK)
    tow = t - week * SECONDS_PER_WEEK
    out = struct.pack("<dHbBBB2x", tow, week, 18, len(sats), 1, 1)
    n_m = len(sats)
    lock = [1000] * n_m if lock is None else lock
    trk_extra = [4] * n_m if trk_extra is None else trk_extra
    cpstd = [3] * n_m if cpstd is None else cpstd
    for (gid, sv, sig), p, c, d, n, lk, tx, cs in zip(sats, pr, cp, dop, cno, lock, trk_extra, cpstd):
        trk = (0 if np.isnan(p) else 1) | (0 if np.isnan(c) else 2) | tx
        out += struct.pack("<ddfBBBBHBBBBBx", 0.0 if np.isnan(p) else p, 0.0 if np.isnan(c) else c,
                           0.0 if np.isnan(d) else d, gid, sv, sig, 0, lk, int(round(n)), 3, cs, 3, trk)
    return frame(0x02, 0x15, out)


def _put(fields):
    v = 0
    for val, n in fields:
        v = (v << n) | (int(val) & ((1 << n) - 1))
    return v


def lnav_subframes(row, tow_next=0):
    """Three 240-bit subframes (as ints) of an ephemeris row, IS-GPS-200 20.3.3.3 / 20.3.3.4 layout."""
    week = int(math.floor(row[E.TOE] / SECONDS_PER_WEEK))
    toe = row[E.TOE] - week * SECONDS_PER_WEEK
    toc = row[E.TOC] - math.floor(row[E.TOC] / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
    iodc = int(row[E.IODC])
    r = lambda x, s: int(round(x / s))
    tlm = [(0x8B, 8), (0, 16)]
    how = lambda sid: [(tow_next, 17), (0, 2), (sid, 3), (0, 2)]
    s1 = tlm + how(1) + [(week % 1024, 10), (1, 2), (0, 4), (int(row[E.HEALTH]), 6), (iodc >> 8, 2),
                          (0, 24), (0, 24), (0, 24), (0, 16), (r(row[E.TGD1], 2.0 ** -31), 8),
                          (iodc & 0xFF, 8), (r(toc, 16), 16), (r(row[E.AF2], 2.0 ** -55), 8),
                          (r(row[E.AF1], 2.0 ** -43), 16), (r(row[E.AF0], 2.0 ** -31), 22), (0, 2)]
    m0 = r(row[E.M0] / PI, 2.0 ** -31)
    e = r(row[E.ECC], 2.0 ** -33)
    sa = r(row[E.SQRTA], 2.0 ** -19)
    s2 = tlm + how(2) + [(int(row[E.IODE]), 8), (r(row[E.CRS], 2.0 ** -5), 16), (r(row[E.DELTAN] / PI, 2.0 ** -43), 16),
                          (m0 >> 24, 8), (m0, 24), (r(row[E.CUC], 2.0 ** -29), 16), (e >> 24, 8), (e, 24),
                          (r(row[E.CUS], 2.0 ** -29), 16), (sa >> 24, 8), (sa, 24), (r(toe, 16), 16), (0, 1),
                          (0, 5), (0, 2)]
    om0 = r(row[E.OMEGA0] / PI, 2.0 ** -31)
    i0 = r(row[E.I0] / PI, 2.0 ** -31)
    w = r(row[E.OMEGA] / PI, 2.0 ** -31)
    s3 = tlm + how(3) + [(r(row[E.CIC], 2.0 ** -29), 16), (om0 >> 24, 8), (om0, 24), (r(row[E.CIS], 2.0 ** -29), 16),
                          (i0 >> 24, 8), (i0, 24), (r(row[E.CRC], 2.0 ** -5), 16), (w >> 24, 8), (w, 24),
                          (r(row[E.OMEGADOT] / PI, 2.0 ** -43), 24), (int(row[E.IODE]), 8),
                          (r(row[E.IDOT] / PI, 2.0 ** -43), 14), (0, 2)]
    return [_put(s) for s in (s1, s2, s3)]


def sfrbx_lnav(prn, sub: int) -> bytes:
    words = [((sub >> (240 - 24 * (i + 1))) & 0xFFFFFF) << 6 for i in range(10)]
    payload = struct.pack("<BBBBBBBx", 0, prn, 0, 0, 10, 0, 2) + b"".join(struct.pack("<I", w) for w in words)
    return frame(0x02, 0x13, payload)


def inav_words(row):
    """The 128-bit I/NAV word types 1-5 of a Galileo ephemeris row (OS-SIS-ICD 4.3.5)."""
    r = lambda x, s: int(round(x / s))
    week = int(math.floor(row[E.TOE] / SECONDS_PER_WEEK))
    toe = row[E.TOE] - week * SECONDS_PER_WEEK
    toc = row[E.TOC] - math.floor(row[E.TOC] / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
    iod = int(row[E.IODE])
    w1 = [(1, 6), (iod, 10), (r(toe, 60), 14), (r(row[E.M0] / PI, 2.0 ** -31), 32), (r(row[E.ECC], 2.0 ** -33), 32),
          (r(row[E.SQRTA], 2.0 ** -19), 32), (0, 2)]
    w2 = [(2, 6), (iod, 10), (r(row[E.OMEGA0] / PI, 2.0 ** -31), 32), (r(row[E.I0] / PI, 2.0 ** -31), 32),
          (r(row[E.OMEGA] / PI, 2.0 ** -31), 32), (r(row[E.IDOT] / PI, 2.0 ** -43), 14), (0, 2)]
    w3 = [(3, 6), (iod, 10), (r(row[E.OMEGADOT] / PI, 2.0 ** -43), 24), (r(row[E.DELTAN] / PI, 2.0 ** -43), 16),
          (r(row[E.CUC], 2.0 ** -29), 16), (r(row[E.CUS], 2.0 ** -29), 16), (r(row[E.CRC], 2.0 ** -5), 16),
          (r(row[E.CRS], 2.0 ** -5), 16), (107, 8)]
    w4 = [(4, 6), (iod, 10), (int(row[E.PRN]), 6), (r(row[E.CIC], 2.0 ** -29), 16), (r(row[E.CIS], 2.0 ** -29), 16),
          (r(toc, 60), 14), (r(row[E.AF0], 2.0 ** -34), 31), (r(row[E.AF1], 2.0 ** -46), 21),
          (r(row[E.AF2], 2.0 ** -59), 6), (0, 2)]
    w5 = [(5, 6), (0, 11), (0, 11), (0, 14), (0, 5), (r(row[E.TGD1], 2.0 ** -32), 10), (r(row[E.TGD2], 2.0 ** -32), 10),
          (0, 2), (0, 2), (0, 1), (0, 1), (week - 1024, 12), (0, 20), (0, 23)]
    return [_put(w) for w in (w1, w2, w3, w4, w5)]


def sfrbx_inav(prn, word: int) -> bytes:
    """An E1-B page pair carrying one 128-bit word, as RXM-SFRBX (8 words: even page bits 0-127, odd 128-255)."""
    even = (0 << 127) | (0 << 126) | ((word >> 16) << 14)                 # even/odd 0, page 0, 112 data bits
    odd_head = (1 << 81) | (0 << 80) | ((word & 0xFFFF) << 64)            # 82 bits: odd 1, page 0, 16 data bits
    crc_in = ((even >> 14) << 82) | odd_head                              # 114 + 82 bits
    crc = crc24q(crc_in.to_bytes(25, "big"))
    odd = (odd_head << 46) | (crc << 22)
    bits = (even << 128) | odd
    words = [(bits >> (256 - 32 * (i + 1))) & 0xFFFFFFFF for i in range(8)]
    payload = struct.pack("<BBBBBBBx", 2, prn, 1, 0, 8, 0, 2) + b"".join(struct.pack("<I", w) for w in words)
    return frame(0x02, 0x13, payload)


class _Sub:
    """A 300-bit BeiDou subframe/page built field by field (positions of BDS-SIS-ICD 5.2.4 / 5.3.3)."""

    def __init__(self):
        self.v = 0

    def put(self, value, *parts):
        n = sum(parts[1::2])
        value = int(value) & ((1 << n) - 1)
        rest = n
        for pos, k in zip(parts[::2], parts[1::2]):
            rest -= k
            self.v |= ((value >> rest) & ((1 << k) - 1)) << (300 - pos - k)
        return self

    def words(self):
        return [(self.v >> (300 - 30 * (i + 1))) & 0x3FFFFFFF for i in range(10)]


def bds_frames(row, sow0):
    """D1 subframes 1-3 (MEO/IGSO) or D2 pages 1-10 of subframe 1 (GEO) of a BeiDou ephemeris row."""
    r = lambda x, s: int(round(x / s))
    toe_bdt = row[E.TOE] - 14.0
    week = int(math.floor(toe_bdt / SECONDS_PER_WEEK))
    toe = toe_bdt - week * SECONDS_PER_WEEK
    bweek = week - 1356
    prn = int(row[E.PRN])
    if 6 <= prn <= 58:
        s1, s2, s3 = _Sub(), _Sub(), _Sub()
        for k, s in enumerate((s1, s2, s3)):
            s.put(k + 1, 15, 3).put(sow0 + 6 * k, 18, 8, 30, 12)
        s1.put(0, 42, 1).put(int(row[E.IODC]), 43, 5).put(0, 48, 4).put(bweek, 60, 13).put(r(toe, 8), 73, 9, 90, 8)
        s1.put(r(row[E.TGD1], 0.1e-9), 98, 10).put(r(row[E.TGD2], 0.1e-9), 108, 4, 120, 6)
        s1.put(r(row[E.AF2], 2.0 ** -66), 214, 11).put(r(row[E.AF0], 2.0 ** -33), 225, 7, 240, 17)
        s1.put(r(row[E.AF1], 2.0 ** -50), 257, 5, 270, 17).put(int(row[E.IODE]), 287, 5)
        s2.put(r(row[E.DELTAN] / PI, 2.0 ** -43), 42, 10, 60, 6).put(r(row[E.CUC], 2.0 ** -31), 66, 16, 90, 2)
        s2.put(r(row[E.M0] / PI, 2.0 ** -31), 92, 20, 120, 12).put(r(row[E.ECC], 2.0 ** -33), 132, 10, 150, 22)
        s2.put(r(row[E.CUS], 2.0 ** -31), 180, 18).put(r(row[E.CRC], 2.0 ** -6), 198, 4, 210, 14)
        s2.put(r(row[E.CRS], 2.0 ** -6), 224, 8, 240, 10).put(r(row[E.SQRTA], 2.0 ** -19), 250, 12, 270, 20)
        t8 = r(toe, 8)
        s2.put(t8 >> 15, 290, 2)
        s3.put(t8 & 0x7FFF, 42, 10, 60, 5).put(r(row[E.I0] / PI, 2.0 ** -31), 65, 17, 90, 15)
        s3.put(r(row[E.CIC], 2.0 ** -31), 105, 7, 120, 11).put(r(row[E.OMEGADOT] / PI, 2.0 ** -43), 131, 11, 150, 13)
        s3.put(r(row[E.CIS], 2.0 ** -31), 163, 9, 180, 9).put(r(row[E.IDOT] / PI, 2.0 ** -43), 189, 13, 210, 1)
        s3.put(r(row[E.OMEGA0] / PI, 2.0 ** -31), 211, 21, 240, 11).put(r(row[E.OMEGA] / PI, 2.0 ** -31), 251, 11, 270, 21)
        return [s.words() for s in (s1, s2, s3)]
    p = {k: _Sub().put(1, 15, 3).put(k, 42, 4) for k in range(1, 11)}
    p[1].put(sow0, 18, 8, 30, 12)
    for k in range(2, 11):
        p[k].put(sow0 + 6 + 3 * (k - 3) if k >= 3 else sow0 + 3, 18, 8, 30, 12)
    p[1].put(0, 46, 1).put(int(row[E.IODC]), 47, 5).put(0, 60, 4).put(bweek, 64, 13).put(r(toe, 8), 77, 5, 90, 12)
    p[1].put(r(row[E.TGD1], 0.1e-9), 102, 10).put(r(row[E.TGD2], 0.1e-9), 120, 10)
    af1 = r(row[E.AF1], 2.0 ** -50)
    p[3].put(r(row[E.AF0], 2.0 ** -33), 100, 12, 120, 12).put(af1 >> 18, 132, 4)
    p[4].put(af1 & 0x3FFFF, 46, 6, 60, 12).put(r(row[E.AF2], 2.0 ** -66), 72, 10, 90, 1).put(int(row[E.IODE]), 91, 5)
    cuc = r(row[E.CUC], 2.0 ** -31)
    p[4].put(r(row[E.DELTAN] / PI, 2.0 ** -43), 96, 16).put(cuc >> 4, 120, 14)
    e = r(row[E.ECC], 2.0 ** -33)
    p[5].put(cuc & 0xF, 46, 4).put(r(row[E.M0] / PI, 2.0 ** -31), 50, 2, 60, 22, 90, 8)
    p[5].put(r(row[E.CUS], 2.0 ** -31), 98, 14, 120, 4).put(e >> 22, 124, 10)
    cic = r(row[E.CIC], 2.0 ** -31)
    p[6].put(e & 0x3FFFFF, 46, 6, 60, 16).put(r(row[E.SQRTA], 2.0 ** -19), 76, 6, 90, 22, 120, 4).put(cic >> 8, 124, 10)
    i0 = r(row[E.I0] / PI, 2.0 ** -31)
    p[7].put(cic & 0xFF, 46, 6, 60, 2).put(r(row[E.CIS], 2.0 ** -31), 62, 18).put(r(toe, 8), 80, 2, 90, 15)
    p[7].put(i0 >> 11, 105, 7, 120, 14)
    od = r(row[E.OMEGADOT] / PI, 2.0 ** -43)
    p[8].put(i0 & 0x7FF, 46, 6, 60, 5).put(r(row[E.CRC], 2.0 ** -6), 65, 17, 90, 1).put(r(row[E.CRS], 2.0 ** -6), 91, 18)
    p[8].put(od >> 5, 109, 3, 120, 16)
    w = r(row[E.OMEGA] / PI, 2.0 ** -31)
    p[9].put(od & 0x1F, 46, 5).put(r(row[E.OMEGA0] / PI, 2.0 ** -31), 51, 1, 60, 22, 90, 9).put(w >> 5, 99, 13, 120, 14)
    p[10].put(w & 0x1F, 46, 5).put(r(row[E.IDOT] / PI, 2.0 ** -43), 51, 1, 60, 13)
    return [p[k].words() for k in range(1, 11)]


def sfrbx_bds(prn, words) -> bytes:
    payload = struct.pack("<BBBBBBBx", 3, prn, 0, 0, 10, 0, 2) + b"".join(struct.pack("<I", w) for w in words)
    return frame(0x02, 0x13, payload)


def lnav_ion_page(ion):
    """GPS subframe 4 page 18 (SV ID 56) with the Klobuchar coefficients (IS-GPS-200 20.3.3.5.1.7)."""
    scale = (2.0 ** -30, 2.0 ** -27, 2.0 ** -24, 2.0 ** -24, 2.0 ** 11, 2.0 ** 14, 2.0 ** 16, 2.0 ** 16)
    fields = [(0x8B, 8), (0, 16), (0, 17), (0, 2), (4, 3), (0, 2), (1, 2), (56, 6)]
    fields += [(int(round(a / s)), 8) for a, s in zip(ion, scale)]
    fields += [(0, 240 - 120)]
    return _put(fields)
