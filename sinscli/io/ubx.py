"""u-blox UBX logs: RXM-RAWX observations and RXM-SFRBX broadcast navigation words (GPS/QZSS LNAV subframes
1-3, Galileo I/NAV word types 1-5, BeiDou D1 subframes 1-3 and D2 pages 1-10) into the same tables as the RINEX
readers.

Messages are framed by pyubx2 (``UBXReader``, raw mode); each frame's Fletcher checksum is checked here, and the
payloads are decoded with numpy (u-blox F9/M8 interface description: RXM-RAWX 16-byte header and 32 bytes per
measurement; RXM-SFRBX words).  A truncated or corrupt message is skipped and counted (one warning line naming
the file and the epoch after which it came).  Field positions: IS-GPS-200 20.3.3, OS-SIS-ICD 4.3.5, BDS-SIS-ICD
5.2.4 and 5.3.3 (the same positions as RTKLIB's ``decode_bds_d1``/``decode_bds_d2``).
"""
from __future__ import annotations

import io
import logging
import math
from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..gnss import ephemeris as E
from ..gnss.ephemeris import NavData, finish_table
from ..gnss.observations import ObsData
from ..gnss.signals import SYS_BDS, SYS_GAL, SYS_GLO, SYS_GPS, SYS_QZS, SYS_SBS, sat_name
from ..gnss.timesys import SECONDS_PER_WEEK, epoch_text
from ..inputs import input_file
from .rinex import report_skipped
from .ubx_frames import fletcher, is_ubx  # noqa: F401 (is_ubx: the name the raw readers import)

log = logging.getLogger("sins")

# u-blox gnssId -> our system
GNSS_ID = {0: SYS_GPS, 1: SYS_SBS, 2: SYS_GAL, 3: SYS_BDS, 5: SYS_QZS, 6: SYS_GLO}
# (gnssId, sigId) -> RINEX band + attribute (u-blox F9 interface description, signal identifiers)
SIG_CODE = {(0, 0): "1C", (0, 3): "2L", (0, 4): "2S", (0, 6): "5I", (0, 7): "5Q",
            (1, 0): "1C",
            (2, 0): "1C", (2, 1): "1B", (2, 3): "5I", (2, 4): "5Q", (2, 5): "7I", (2, 6): "7Q",
            (3, 0): "2I", (3, 1): "2I", (3, 2): "7I", (3, 3): "7I", (3, 5): "1P", (3, 7): "5P",
            (5, 0): "1C", (5, 4): "2S", (5, 5): "2L",
            (6, 0): "1C", (6, 2): "2C"}
PI = math.pi


def frames(data: bytes, source: str, skipped: dict, last_epoch):
    """``(class, id, payload)`` of each UBX message with a valid checksum, framed by pyubx2; corrupt and
    truncated messages are recorded in ``skipped``."""
    from pyubx2 import ERR_LOG, UBX_PROTOCOL, UBXReader  # pyubx2 only for a UBX log
    from pyubx2.ubxtypes_core import PARSE_NONE  # pyubx2 only for a UBX log

    errors = []
    reader = UBXReader(io.BytesIO(data), protfilter=UBX_PROTOCOL, quitonerror=ERR_LOG, parsing=PARSE_NONE,
                       errorhandler=errors.append)
    while True:
        try:
            raw, _ = reader.read()
        except Exception as exc:        # pyubx2's stream errors on a message cut at the end of the file
            errors.append(exc)
            raw = None
        if errors:
            for _ in errors:
                skipped.setdefault("truncated", []).append(f"{source}: after {last_epoch()}")
            errors.clear()
        if raw is None:
            break
        buf = np.frombuffer(raw, dtype=np.uint8)
        if buf.size < 8:
            skipped.setdefault("truncated", []).append(f"{source}: after {last_epoch()}")
            continue
        length = int(buf[4]) | (int(buf[5]) << 8)
        if buf.size != length + 8:
            skipped.setdefault("truncated", []).append(f"{source}: after {last_epoch()}")
            continue
        a, b = fletcher(buf[2:-2])
        if a != buf[-2] or b != buf[-1]:
            skipped.setdefault("checksum", []).append(f"{source}: after {last_epoch()}")
            continue
        yield int(buf[2]), int(buf[3]), buf[6:-2]


def _bits(words: np.ndarray, nbits_word: int, take_from: int):
    """Concatenate ``nbits_word`` bits of each word starting at bit ``take_from`` (from the MSB side) into a
    Python int and its length."""
    v = 0
    for w in words:
        v = (v << nbits_word) | ((int(w) >> take_from) & ((1 << nbits_word) - 1))
    return v, nbits_word * len(words)


def _field(v: int, total: int, start: int, n: int, signed: bool = False) -> int:
    x = (v >> (total - start - n)) & ((1 << n) - 1)
    if signed and x >> (n - 1):
        x -= 1 << n
    return x


class _LnavCollector:
    """GPS/QZSS LNAV subframes 1-3 (IS-GPS-200 20.3.3.3, 20.3.3.4) into ephemeris rows."""

    def __init__(self, skipped, source):
        self.sub: dict[tuple, dict] = {}
        self.rows = []
        self.skipped = skipped
        self.source = source
        self.seen = set()
        self.ion = None                                   # Klobuchar alpha0-3, beta0-3 of subframe 4 page 18

    def add(self, sys, prn, words, week_full, t_now):
        if len(words) < 10:
            return
        v, tot = _bits(words[:10], 24, 6)            # 24 data bits of each 30-bit word (bits 29..6)
        if _field(v, tot, 0, 8) != 0x8B:
            return
        sid = _field(v, tot, 43, 3)
        if sid == 4 and _field(v, tot, 50, 6) == 56 and sys == SYS_GPS:   # page 18: ionosphere (20.3.3.5.1.7)
            scale = (2.0 ** -30, 2.0 ** -27, 2.0 ** -24, 2.0 ** -24, 2.0 ** 11, 2.0 ** 14, 2.0 ** 16, 2.0 ** 16)
            self.ion = np.array([_field(v, tot, 56 + 8 * i, 8, True) * scale[i] for i in range(8)])
            return
        if sid not in (1, 2, 3):
            return
        d = self.sub.setdefault((sys, prn), {})
        d[sid] = v
        if not all(k in d for k in (1, 2, 3)):
            return
        s1, s2, s3 = d[1], d[2], d[3]
        iodc = (_field(s1, tot, 70, 2) << 8) | _field(s1, tot, 168, 8)
        iode2 = _field(s2, tot, 48, 8)
        iode3 = _field(s3, tot, 216, 8)
        if not (iode2 == iode3 == (iodc & 0xFF)):
            if iode2 == iode3:                   # subframe 1 of another issue: wait for its match
                key = ("iode", sys, prn, iodc, iode2)
                if key not in self.seen:
                    self.seen.add(key)
                    self.skipped.setdefault("iode", []).append(
                        f"{self.source}: {sat_name(sys, prn)} subframes of {epoch_text(t_now)}: IODE {iode2} "
                        f"does not match IODC {iodc}")
            return
        key = (sys, prn, iodc, _field(s2, tot, 216, 16))
        if key in self.seen:
            return
        self.seen.add(key)
        health = _field(s1, tot, 64, 6)
        week10 = _field(s1, tot, 48, 10)
        week = week_full - ((week_full - week10) % 1024) if week_full is not None else week10 + 2048
        if (week_full - week) > 512:
            week += 1024
        toe_sow = _field(s2, tot, 216, 16) * 16.0
        toc_sow = _field(s1, tot, 176, 16) * 16.0
        row = np.zeros(E.NCOL)
        row[E.SYS], row[E.PRN] = sys, prn
        toe = week * SECONDS_PER_WEEK + toe_sow
        toc = week * SECONDS_PER_WEEK + toc_sow
        for name in ("toe", "toc"):            # the week of a toe/toc across a week boundary from t_now
            val = toe if name == "toe" else toc
            while val - t_now > SECONDS_PER_WEEK / 2:
                val -= SECONDS_PER_WEEK
            while t_now - val > SECONDS_PER_WEEK / 2:
                val += SECONDS_PER_WEEK
            if name == "toe":
                toe = val
            else:
                toc = val
        row[E.TOE], row[E.TOC], row[E.WEEK] = toe, toc, math.floor(toe / SECONDS_PER_WEEK)
        row[E.TGD1] = _field(s1, tot, 160, 8, True) * 2.0 ** -31
        row[E.AF2] = _field(s1, tot, 192, 8, True) * 2.0 ** -55
        row[E.AF1] = _field(s1, tot, 200, 16, True) * 2.0 ** -43
        row[E.AF0] = _field(s1, tot, 216, 22, True) * 2.0 ** -31
        ura = _field(s1, tot, 60, 4)
        row[E.URA] = [2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0,
                      6144.0, 6144.0][ura]
        row[E.HEALTH], row[E.IODC], row[E.IODE] = health, iodc, iode2
        row[E.CRS] = _field(s2, tot, 56, 16, True) * 2.0 ** -5
        row[E.DELTAN] = _field(s2, tot, 72, 16, True) * 2.0 ** -43 * PI
        row[E.M0] = ((_field(s2, tot, 88, 8) << 24 | _field(s2, tot, 96, 24)) - (1 << 32 if _field(s2, tot, 88, 1)
                                                                                 else 0)) * 2.0 ** -31 * PI
        row[E.CUC] = _field(s2, tot, 120, 16, True) * 2.0 ** -29
        row[E.ECC] = (_field(s2, tot, 136, 8) << 24 | _field(s2, tot, 144, 24)) * 2.0 ** -33
        row[E.CUS] = _field(s2, tot, 168, 16, True) * 2.0 ** -29
        row[E.SQRTA] = (_field(s2, tot, 184, 8) << 24 | _field(s2, tot, 192, 24)) * 2.0 ** -19
        row[E.CIC] = _field(s3, tot, 48, 16, True) * 2.0 ** -29
        row[E.OMEGA0] = _signed32(_field(s3, tot, 64, 8) << 24 | _field(s3, tot, 72, 24)) * 2.0 ** -31 * PI
        row[E.CIS] = _field(s3, tot, 96, 16, True) * 2.0 ** -29
        row[E.I0] = _signed32(_field(s3, tot, 112, 8) << 24 | _field(s3, tot, 120, 24)) * 2.0 ** -31 * PI
        row[E.CRC] = _field(s3, tot, 144, 16, True) * 2.0 ** -5
        row[E.OMEGA] = _signed32(_field(s3, tot, 160, 8) << 24 | _field(s3, tot, 168, 24)) * 2.0 ** -31 * PI
        row[E.OMEGADOT] = _field(s3, tot, 192, 24, True) * 2.0 ** -43 * PI
        row[E.IDOT] = _field(s3, tot, 224, 14, True) * 2.0 ** -43 * PI
        row[E.TTR] = t_now - math.floor(t_now / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
        if health != 0:
            self.skipped.setdefault("health", []).append(
                f"{self.source}: {sat_name(sys, prn)} ephemeris of {epoch_text(toc)}: health flag {health}")
            return
        self.rows.append(row)


def crc24q(data: bytes) -> int:
    """CRC-24Q (polynomial 0x1864CFB), the checksum of Galileo I/NAV pages (OS-SIS-ICD 4.3.2.3)."""
    crc = 0
    for byte in data:
        crc ^= byte << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB
    return crc & 0xFFFFFF


class _InavCollector:
    """Galileo I/NAV word types 1-5 (OS-SIS-ICD 4.3.5) from E1-B/E5b-I page pairs into ephemeris rows."""

    def __init__(self, skipped, source):
        self.words: dict[int, dict] = {}
        self.rows = []
        self.skipped = skipped
        self.source = source
        self.seen = set()

    def add(self, prn, words, t_now):
        if len(words) < 8:
            return
        v, tot = _bits(words[:8], 32, 0)                  # even page bits 0-127, odd page 128-255
        if _field(v, tot, 1, 1) or _field(v, tot, 129, 1):
            return                                        # alert pages
        if _field(v, tot, 0, 1) != 0 or _field(v, tot, 128, 1) != 1:
            return
        crc_bits = (_field(v, tot, 0, 114) << 82) | _field(v, tot, 128, 82)      # 196 bits, 4 zero bits ahead
        if crc24q(crc_bits.to_bytes(25, "big")) != _field(v, tot, 128 + 82, 24):
            self.skipped.setdefault("checksum", []).append(f"{self.source}: E{prn:02d} I/NAV page of "
                                                           f"{epoch_text(t_now)}")
            return
        word = (_field(v, tot, 2, 112) << 16) | _field(v, tot, 130, 16)       # the 128-bit data word
        wtype = word >> 122
        if not 1 <= wtype <= 5:
            return
        d = self.words.setdefault(prn, {})
        d[wtype] = word
        if not all(k in d for k in range(1, 6)):
            return
        f = lambda w, a, n, sgn=False: _field(d[w], 128, a, n, sgn)      # noqa: E731
        iod = [f(k, 6, 10) for k in (1, 2, 3, 4)]
        if len(set(iod)) != 1:
            return                                        # words of two issues: wait for the rest
        key = (prn, iod[0], f(1, 16, 14))
        if key in self.seen:
            return
        self.seen.add(key)
        row = np.zeros(E.NCOL)
        row[E.SYS], row[E.PRN] = SYS_GAL, prn
        week = f(5, 73, 12) + 1024                          # GST week -> GPS week
        toe = _near(week * SECONDS_PER_WEEK + f(1, 16, 14) * 60.0, t_now)
        toc = _near(week * SECONDS_PER_WEEK + f(4, 54, 14) * 60.0, t_now)
        row[E.TOE], row[E.TOC], row[E.WEEK] = toe, toc, math.floor(toe / SECONDS_PER_WEEK)
        row[E.M0] = f(1, 30, 32, True) * 2.0 ** -31 * PI
        row[E.ECC] = f(1, 62, 32) * 2.0 ** -33
        row[E.SQRTA] = f(1, 94, 32) * 2.0 ** -19
        row[E.OMEGA0] = f(2, 16, 32, True) * 2.0 ** -31 * PI
        row[E.I0] = f(2, 48, 32, True) * 2.0 ** -31 * PI
        row[E.OMEGA] = f(2, 80, 32, True) * 2.0 ** -31 * PI
        row[E.IDOT] = f(2, 112, 14, True) * 2.0 ** -43 * PI
        row[E.OMEGADOT] = f(3, 16, 24, True) * 2.0 ** -43 * PI
        row[E.DELTAN] = f(3, 40, 16, True) * 2.0 ** -43 * PI
        row[E.CUC] = f(3, 56, 16, True) * 2.0 ** -29
        row[E.CUS] = f(3, 72, 16, True) * 2.0 ** -29
        row[E.CRC] = f(3, 88, 16, True) * 2.0 ** -5
        row[E.CRS] = f(3, 104, 16, True) * 2.0 ** -5
        sisa = f(3, 120, 8)
        row[E.URA] = sisa / 100.0 if sisa < 50 else (0.5 + (sisa - 50) * 0.02 if sisa < 75 else
                                                     (1.0 + (sisa - 75) * 0.04 if sisa < 100 else 6.0))
        row[E.CIC] = f(4, 22, 16, True) * 2.0 ** -29
        row[E.CIS] = f(4, 38, 16, True) * 2.0 ** -29
        row[E.AF0] = f(4, 68, 31, True) * 2.0 ** -34
        row[E.AF1] = f(4, 99, 21, True) * 2.0 ** -46
        row[E.AF2] = f(4, 120, 6, True) * 2.0 ** -59
        row[E.TGD1] = f(5, 47, 10, True) * 2.0 ** -32
        row[E.TGD2] = f(5, 57, 10, True) * 2.0 ** -32
        health = (f(5, 67, 2) << 7) | (f(5, 71, 1) << 6) | (f(5, 69, 2) << 1) | f(5, 72, 1)
        row[E.HEALTH], row[E.IODE], row[E.IODC] = health, iod[0], iod[0]
        row[E.SOURCE] = 513                                  # I/NAV E1-B, af0-af2 and toc for E5b,E1
        row[E.TTR] = t_now - math.floor(t_now / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
        if health != 0:
            self.skipped.setdefault("health", []).append(
                f"{self.source}: E{prn:02d} ephemeris of {epoch_text(toc)}: health flag {health}")
            return
        self.rows.append(row)


class _Bits:
    """Fields of a 300-bit BeiDou subframe/page (10 words of 30 bits, parity bits in place; BDS-SIS-ICD 5.2.4)."""

    def __init__(self, words):
        self.v, self.tot = _bits(words[:10], 30, 0)

    def u(self, *parts):
        """Unsigned value of the concatenated (position, length) parts."""
        x = 0
        for pos, n in zip(parts[::2], parts[1::2]):
            x = (x << n) | _field(self.v, self.tot, pos, n)
        return x

    def s(self, *parts):
        n = sum(parts[1::2])
        x = self.u(*parts)
        return x - (1 << n) if x >> (n - 1) else x


def _signed(x: int, n: int) -> int:
    return x - (1 << n) if x >> (n - 1) else x


URA_M = [2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0, 1536.0, 3072.0, 6144.0, 6144.0]


class _BdsCollector:
    """BeiDou D1 subframes 1-3 (MEO/IGSO, BDS-SIS-ICD 5.2.4) and D2 subframe 1 pages 1-10 (GEO, 5.3.3) into
    ephemeris rows (BDT -> GPST + 14 s)."""

    def __init__(self, skipped, source):
        self.d1: dict[int, dict] = {}
        self.d2: dict[int, dict] = {}
        self.rows = []
        self.skipped = skipped
        self.source = source
        self.seen = set()

    def add(self, prn, words, t_now):
        if len(words) < 10:
            return
        b = _Bits(np.asarray(words[:10], dtype=np.int64) & 0x3FFFFFFF)
        frame_id = b.u(15, 3)
        geo = prn <= 5 or prn >= 59
        if not geo:
            if frame_id not in (1, 2, 3):
                return
            d = self.d1.setdefault(prn, {})
            d[frame_id] = b
            if frame_id == 3 and all(k in d for k in (1, 2, 3)):
                self._d1(prn, d[1], d[2], d[3], t_now)
            return
        if frame_id != 1:
            return
        page = b.u(42, 4)
        if not 1 <= page <= 10:
            return
        d = self.d2.setdefault(prn, {})
        d[page] = b
        if page == 10 and all(k in d for k in (1, 3, 4, 5, 6, 7, 8, 9, 10)):
            self._d2(prn, d, t_now)

    def _finish(self, prn, row, week, toe_sow, toc_sow, health, t_now):
        toe = _near((week + 1356) * SECONDS_PER_WEEK + toe_sow + 14.0, t_now)
        toc = _near((week + 1356) * SECONDS_PER_WEEK + toc_sow + 14.0, t_now)
        key = (prn, toe, row[E.IODE])
        if key in self.seen:
            return
        self.seen.add(key)
        row[E.SYS], row[E.PRN] = SYS_BDS, prn
        row[E.TOE], row[E.TOC], row[E.WEEK] = toe, toc, math.floor(toe / SECONDS_PER_WEEK)
        row[E.HEALTH] = health
        row[E.TTR] = t_now - math.floor(t_now / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
        if health != 0:
            self.skipped.setdefault("health", []).append(
                f"{self.source}: C{prn:02d} ephemeris of {epoch_text(toc)}: health flag {health}")
            return
        self.rows.append(row)

    def _d1(self, prn, s1, s2, s3, t_now):
        sow = [x.u(18, 8, 30, 12) for x in (s1, s2, s3)]
        if sow[1] != sow[0] + 6 or sow[2] != sow[1] + 6:
            return
        toe_sow = ((s2.u(290, 2) << 15) | s3.u(42, 10, 60, 5)) * 8.0
        toc_sow = s1.u(73, 9, 90, 8) * 8.0
        if toe_sow != toc_sow:
            return
        row = np.zeros(E.NCOL)
        row[E.URA] = URA_M[s1.u(48, 4)]
        row[E.IODC], row[E.IODE] = s1.u(43, 5), s1.u(287, 5)
        row[E.TGD1] = s1.s(98, 10) * 0.1e-9
        row[E.TGD2] = s1.s(108, 4, 120, 6) * 0.1e-9
        row[E.AF2] = s1.s(214, 11) * 2.0 ** -66
        row[E.AF0] = s1.s(225, 7, 240, 17) * 2.0 ** -33
        row[E.AF1] = s1.s(257, 5, 270, 17) * 2.0 ** -50
        row[E.DELTAN] = s2.s(42, 10, 60, 6) * 2.0 ** -43 * PI
        row[E.CUC] = s2.s(66, 16, 90, 2) * 2.0 ** -31
        row[E.M0] = s2.s(92, 20, 120, 12) * 2.0 ** -31 * PI
        row[E.ECC] = s2.u(132, 10, 150, 22) * 2.0 ** -33
        row[E.CUS] = s2.s(180, 18) * 2.0 ** -31
        row[E.CRC] = s2.s(198, 4, 210, 14) * 2.0 ** -6
        row[E.CRS] = s2.s(224, 8, 240, 10) * 2.0 ** -6
        row[E.SQRTA] = s2.u(250, 12, 270, 20) * 2.0 ** -19
        row[E.I0] = s3.s(65, 17, 90, 15) * 2.0 ** -31 * PI
        row[E.CIC] = s3.s(105, 7, 120, 11) * 2.0 ** -31
        row[E.OMEGADOT] = s3.s(131, 11, 150, 13) * 2.0 ** -43 * PI
        row[E.CIS] = s3.s(163, 9, 180, 9) * 2.0 ** -31
        row[E.IDOT] = s3.s(189, 13, 210, 1) * 2.0 ** -43 * PI
        row[E.OMEGA0] = s3.s(211, 21, 240, 11) * 2.0 ** -31 * PI
        row[E.OMEGA] = s3.s(251, 11, 270, 21) * 2.0 ** -31 * PI
        self._finish(prn, row, s1.u(60, 13), toe_sow, toc_sow, s1.u(42, 1), t_now)

    def _d2(self, prn, p, t_now):
        sow = [p[k].u(18, 8, 30, 12) for k in (1, 3, 4, 5, 6, 7, 8, 9, 10)]
        if sow[1] != sow[0] + 6 or any(sow[i + 1] != sow[i] + 3 for i in range(1, 8)):
            return
        toe_sow = p[7].u(80, 2, 90, 15) * 8.0
        toc_sow = p[1].u(77, 5, 90, 12) * 8.0
        if toe_sow != toc_sow:
            return
        row = np.zeros(E.NCOL)
        row[E.URA] = URA_M[p[1].u(60, 4)]
        row[E.IODC], row[E.IODE] = p[1].u(47, 5), p[4].u(91, 5)
        row[E.TGD1] = p[1].s(102, 10) * 0.1e-9
        row[E.TGD2] = p[1].s(120, 10) * 0.1e-9
        row[E.AF0] = p[3].s(100, 12, 120, 12) * 2.0 ** -33
        row[E.AF1] = _signed((p[3].u(132, 4) << 18) | p[4].u(46, 6, 60, 12), 22) * 2.0 ** -50
        row[E.AF2] = p[4].s(72, 10, 90, 1) * 2.0 ** -66
        row[E.DELTAN] = p[4].s(96, 16) * 2.0 ** -43 * PI
        row[E.CUC] = _signed((p[4].u(120, 14) << 4) | p[5].u(46, 4), 18) * 2.0 ** -31
        row[E.M0] = p[5].s(50, 2, 60, 22, 90, 8) * 2.0 ** -31 * PI
        row[E.CUS] = p[5].s(98, 14, 120, 4) * 2.0 ** -31
        row[E.ECC] = ((p[5].u(124, 10) << 22) | p[6].u(46, 6, 60, 16)) * 2.0 ** -33
        row[E.SQRTA] = p[6].u(76, 6, 90, 22, 120, 4) * 2.0 ** -19
        row[E.CIC] = _signed((p[6].u(124, 10) << 8) | p[7].u(46, 6, 60, 2), 18) * 2.0 ** -31
        row[E.CIS] = p[7].s(62, 18) * 2.0 ** -31
        row[E.I0] = _signed((p[7].u(105, 7, 120, 14) << 11) | p[8].u(46, 6, 60, 5), 32) * 2.0 ** -31 * PI
        row[E.CRC] = p[8].s(65, 17, 90, 1) * 2.0 ** -6
        row[E.CRS] = p[8].s(91, 18) * 2.0 ** -6
        row[E.OMEGADOT] = _signed((p[8].u(109, 3, 120, 16) << 5) | p[9].u(46, 5), 24) * 2.0 ** -43 * PI
        row[E.OMEGA0] = p[9].s(51, 1, 60, 22, 90, 9) * 2.0 ** -31 * PI
        row[E.OMEGA] = _signed((p[9].u(99, 13, 120, 14) << 5) | p[10].u(46, 5), 32) * 2.0 ** -31 * PI
        row[E.IDOT] = p[10].s(51, 1, 60, 13) * 2.0 ** -43 * PI
        self._finish(prn, row, p[1].u(64, 13), toe_sow, toc_sow, p[1].u(46, 1), t_now)


def _near(t: float, t_now: float) -> float:
    """``t`` moved by whole weeks to within half a week of ``t_now``."""
    while t - t_now > SECONDS_PER_WEEK / 2:
        t -= SECONDS_PER_WEEK
    while t_now - t > SECONDS_PER_WEEK / 2:
        t += SECONDS_PER_WEEK
    return t


CPSTD_VALID = 5             # cpStdev (0.004 cycles per unit) above this: no carrier (RTKLIB's limit)


def _carrier_lli(lock: dict, key, lock_s: float, trk: int, tt: float) -> int:
    """The RINEX LLI of one RXM-RAWX carrier (u-blox F9 interface description, RXM-RAWX ``locktime`` and
    ``trkStat``; the rules of RTKLIB's ``decode_rxmrawx``): bit 0 (lost lock) when the lock time is 0, shorter than
    the time since the previous epoch ``tt`` (the loop relocked in between), or the half cycle the receiver
    subtracts (trkStat bit 3) changed; bit 1 (half-cycle ambiguity) while the half cycle is not resolved (trkStat
    bit 2 clear).  ``lock`` keeps each signal's state between epochs."""
    halfc = (trk >> 3) & 1
    prev = lock.get(key)
    slip = lock_s == 0.0 or (prev is not None and (lock_s < tt or halfc != prev[1]))
    lock[key] = (lock_s, halfc)
    return (1 if slip else 0) | (0 if trk & 4 else 2)


def _signed32(x: int) -> int:
    return x - (1 << 32) if x >> 31 else x


def read_ubx(path):
    """``(ObsData, NavData)`` of a UBX log: every RXM-RAWX epoch, the ephemerides of its RXM-SFRBX."""
    p = input_file(path, "UBX log")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise SinsError(f"{p}: cannot read the UBX log ({exc.strerror or type(exc).__name__})") from None
    skipped: dict[str, list] = {}
    epochs = []                 # (t, rows start)
    rec = {"sys": [], "prn": [], "code": [], "pr": [], "cp": [], "do": [], "cno": [], "lli": []}
    lock = {}                   # (gnssId, svId, sigId) -> (lock time s, half cycle subtracted) at the last epoch
    last = {"t": None, "week": None}
    lnav = _LnavCollector(skipped, str(p))
    inav = _InavCollector(skipped, str(p))
    bds = _BdsCollector(skipped, str(p))
    other_nav = {}
    n_raw = 0

    def last_epoch():
        return epoch_text(last["t"]) if last["t"] is not None else "the start of the log"

    meas_dtype = np.dtype([("pr", "<f8"), ("cp", "<f8"), ("do", "<f4"), ("gnss", "u1"), ("sv", "u1"),
                           ("sig", "u1"), ("freq", "u1"), ("lock", "<u2"), ("cno", "u1"), ("prs", "u1"),
                           ("cps", "u1"), ("dos", "u1"), ("trk", "u1"), ("res", "u1")])
    for cls, mid, pl in frames(data, str(p), skipped, last_epoch):
        if cls == 0x02 and mid == 0x15 and pl.size >= 16:            # RXM-RAWX
            tow = float(pl[0:8].view("<f8")[0])
            week = int(pl[8:10].view("<u2")[0])
            nmeas = int(pl[11])
            if pl.size != 16 + 32 * nmeas or not (0.0 <= tow < SECONDS_PER_WEEK + 1) or not math.isfinite(tow):
                skipped.setdefault("truncated", []).append(f"{p}: after {last_epoch()}")
                continue
            t = week * SECONDS_PER_WEEK + tow
            if last["t"] is not None and t <= last["t"]:
                continue
            tt = t - last["t"] if last["t"] is not None else 0.0
            last["t"], last["week"] = t, week
            n_raw += 1
            m = np.frombuffer(pl[16:].tobytes(), dtype=meas_dtype)
            epochs.append(t)
            for r in m:
                gid, sig = int(r["gnss"]), int(r["sig"])
                if gid not in GNSS_ID or (gid, sig) not in SIG_CODE or (gid == 6 and int(r["sv"]) > 32):
                    continue                      # other systems / signals; a GLONASS slot not yet known (255)
                trk = int(r["trk"])
                rec["sys"].append(GNSS_ID[gid])
                rec["prn"].append(int(r["sv"]) - (0 if gid != 1 else 100) if gid != 5 else int(r["sv"]))
                rec["code"].append(SIG_CODE[(gid, sig)])
                rec["pr"].append(float(r["pr"]) if trk & 1 else np.nan)
                cp_ok = trk & 2 and (int(r["cps"]) & 0x0F) <= CPSTD_VALID
                rec["cp"].append(float(r["cp"]) if cp_ok else np.nan)
                rec["do"].append(float(r["do"]))
                rec["cno"].append(float(r["cno"]))
                rec["lli"].append(_carrier_lli(lock, (gid, int(r["sv"]), sig), int(r["lock"]) * 1e-3, trk, tt))
                rec.setdefault("epoch", []).append(len(epochs) - 1)
        elif cls == 0x02 and mid == 0x13 and pl.size >= 8:           # RXM-SFRBX
            gid, sv, nwords = int(pl[0]), int(pl[1]), int(pl[4])
            if pl.size != 8 + 4 * nwords:
                skipped.setdefault("truncated", []).append(f"{p}: after {last_epoch()}")
                continue
            words = pl[8:].view("<u4")
            if gid in (0, 5) and last["t"] is not None:
                lnav.add(GNSS_ID[gid], sv, words, last["week"], last["t"])
            elif gid == 2 and last["t"] is not None and int(pl[2]) in (1, 5):     # E1-B or E5b-I I/NAV
                inav.add(sv, words, last["t"])
            elif gid == 3 and last["t"] is not None:
                bds.add(sv, words, last["t"])
            else:
                other_nav[gid] = other_nav.get(gid, 0) + 1
    report_skipped(skipped, "UBX messages or ephemerides")
    if not epochs:
        raise SinsError(f"{p}: no UBX-RXM-RAWX message: the log has no raw measurements (enable RXM-RAWX and "
                        f"RXM-SFRBX on the receiver)")
    obs = _assemble(np.array(epochs), rec, str(p))
    nav = NavData(eph=finish_table(lnav.rows + inav.rows + bds.rows), source=str(p),
                  skipped={k: (len(v), v[0]) for k, v in skipped.items()}, ion_gps=lnav.ion)
    return obs, nav


def _assemble(times, rec, source) -> ObsData:
    """Records of (epoch, satellite, code) -> one row per (epoch, satellite) with C/L/D/S columns per code."""
    ne = times.size
    if not rec["sys"]:
        return ObsData(time=times, start=np.zeros(ne + 1, np.int64), sys=np.zeros(0, np.int8),
                       prn=np.zeros(0, np.int16), values=np.zeros((0, 1)), lli=np.zeros((0, 1), np.int8),
                       types={}, source=source)
    sys = np.array(rec["sys"], np.int64)
    prn = np.array(rec["prn"], np.int64)
    ep = np.array(rec["epoch"], np.int64)
    codes = np.array(rec["code"])
    types = {}
    for s in np.unique(sys):
        cs = sorted(set(codes[sys == s].tolist()), key=lambda c: (c[0], c[1]))
        types[int(s)] = [k + c for c in cs for k in "CLDS"]
    key = ep * 100000 + sys * 1000 + prn
    uk, inv = np.unique(key, return_inverse=True)
    ncol = max(len(v) for v in types.values())
    values = np.full((uk.size, ncol), np.nan)
    lli = np.zeros((uk.size, ncol), np.int8)
    ssi = np.zeros((uk.size, ncol), np.int8)
    for i in range(sys.size):
        row = inv[i]
        t = types[int(sys[i])]
        base = t.index("C" + codes[i])
        values[row, base] = rec["pr"][i]
        values[row, base + 1] = rec["cp"][i]
        values[row, base + 2] = rec["do"][i]
        values[row, base + 3] = rec["cno"][i]
        lli[row, base + 1] = rec["lli"][i]
        # the RINEX signal strength of the signal's observations: C/N0 / 6, 1-9 (RINEX 3.04 5.7)
        ssi[row, base:base + 3] = min(max(int(rec["cno"][i] // 6), 1), 9)
    r_ep = uk // 100000
    r_sys = (uk // 1000) % 100
    r_prn = uk % 1000
    counts = np.bincount(r_ep, minlength=ne)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    obs = ObsData(time=times.astype(np.float64), start=start, sys=r_sys.astype(np.int8), prn=r_prn.astype(np.int16),
                  values=values, lli=lli, ssi=ssi, types=types, flag=np.zeros(ne, np.int8),
                  header={"version": 3.04, "marker": Path(source).stem, "receiver": "u-blox (UBX)"}, source=source)
    # pseudoranges outside the physical window are a receiver's invalid values: dropped (the flag said valid)
    for s, t in types.items():
        for j, c in enumerate(t):
            if c[0] == "C":
                v = obs.values[:, j]
                bad = (obs.sys == s) & ~np.isnan(v) & ((v < 1.0e7) | (v > 5.0e7))
                v[bad] = np.nan
    return obs
