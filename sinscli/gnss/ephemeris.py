"""The broadcast ephemeris table that every reader (RINEX nav, UBX RXM-SFRBX) fills and every kernel reads.

One row per ephemeris, one float64 column per parameter (indices below), so that kernels take the table as a
plain 2-D array.  Times are GPS seconds (``timesys``): a BeiDou ``toe``/``toc`` given in BDT is stored + 14 s,
so that ``t - toe`` is the same difference in either scale.  Angles in radians, ``sqrtA`` in sqrt(m), clock
terms in s, s/s, s/s^2, group delays in s.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .signals import SYS_BDS, SYS_GAL, SYS_GPS, SYS_QZS

(SYS, PRN, TOC, TOE, WEEK, SQRTA, ECC, I0, OMEGA0, OMEGA, M0, DELTAN, IDOT, OMEGADOT, CUC, CUS, CRC, CRS,
 CIC, CIS, AF0, AF1, AF2, TGD1, TGD2, IODE, IODC, HEALTH, URA, SOURCE, TTR) = range(31)
NCOL = 31
NAMES = ("sys prn toc toe week sqrtA e i0 Omega0 omega M0 deltan idot OmegaDot cuc cus crc crs cic cis "
         "af0 af1 af2 tgd1 tgd2 iode iodc health ura source ttr").split()

# SOURCE of a Galileo ephemeris (RINEX 3.04 table A8 'data sources'): bit 0 I/NAV E1-B, bit 1 F/NAV E5a-I,
# bit 2 I/NAV E5b-I; for the others 0.  TGD1/TGD2: GPS/QZSS TGD, -; Galileo BGD(E1,E5a), BGD(E1,E5b);
# BeiDou TGD1 (B1I), TGD2 (B2I).
GAL_INAV_BITS = 0b101
GAL_FNAV_BIT = 0b010

# largest |t - toe| for which an ephemeris is used (s): RTKLIB's MAXDTOE values
MAX_AGE = {SYS_GPS: 7200.0, SYS_QZS: 7200.0, SYS_GAL: 14400.0, SYS_BDS: 21600.0}


@njit(cache=True)
def max_age(sys):
    """:data:`MAX_AGE` of a system, for kernels."""
    if sys == SYS_GAL:
        return 14400.0
    if sys == SYS_BDS:
        return 21600.0
    return 7200.0


@dataclass
class NavData:
    """Broadcast navigation data: the ephemeris table and the header's ionosphere and time parameters."""
    eph: np.ndarray                                   # (N, NCOL) float64, sorted by sys, prn, toe
    ion_gps: np.ndarray | None = None                 # Klobuchar alpha0..3, beta0..3 (IS-GPS-200 20.3.3.5.1.7)
    ion_bds: np.ndarray | None = None                 # BeiDou Klobuchar (BDS-SIS-ICD 5.2.4.7)
    ion_gal: np.ndarray | None = None                 # NeQuick-G ai0..ai2 (read, not used: Klobuchar instead)
    leap_seconds: float | None = None
    source: str = "<memory>"
    skipped: dict = field(default_factory=dict)       # reason -> (count, first text)
    glonass: int = 0                                  # GLONASS records read (not positioned)

    def __len__(self) -> int:
        return int(self.eph.shape[0])

    def systems(self) -> list[int]:
        return sorted({int(s) for s in self.eph[:, SYS]}) if len(self) else []


def empty_table() -> np.ndarray:
    return np.zeros((0, NCOL))


def finish_table(rows) -> np.ndarray:
    """Rows (sequences of NCOL floats) -> the table sorted by system, PRN, toe, with exact duplicates removed."""
    if not len(rows):
        return empty_table()
    eph = np.asarray(rows, dtype=np.float64).reshape(-1, NCOL)
    order = np.lexsort((eph[:, SOURCE], eph[:, TOE], eph[:, PRN], eph[:, SYS]))
    eph = eph[order]
    keep = np.ones(eph.shape[0], dtype=bool)
    keep[1:] = np.any(eph[1:, [SYS, PRN, TOE, IODE, SOURCE, AF0]] != eph[:-1, [SYS, PRN, TOE, IODE, SOURCE, AF0]],
                      axis=1)
    return eph[keep]


def healthy_py(row) -> bool:
    """The health word of an ephemeris says the signal may be used (GPS/QZSS: all 6 bits 0; Galileo: the
    signal-health and data-validity bits 0, IS/OS-SIS-ICD 5.1.9.3; BeiDou: SatH1 0)."""
    sys, h = int(row[SYS]), int(row[HEALTH])
    if sys == SYS_GAL:
        return (h & 0b111111111) == 0
    return h == 0


@njit(cache=True)
def select_ephemeris(eph, sys, prn, t, max_age, prefer_source):
    """Row of ``eph`` for satellite (sys, prn) at GPS time ``t`` (s): the one with the nearest toe within
    ``max_age`` s (a Galileo row whose SOURCE has a bit of ``prefer_source`` wins a tie of nearness class);
    -1 when none.  The table is sorted by sys, prn, toe (:func:`finish_table`)."""
    n = eph.shape[0]
    lo, hi = 0, n
    while lo < hi:                         # first row of (sys, prn)
        mid = (lo + hi) // 2
        if eph[mid, SYS] < sys or (eph[mid, SYS] == sys and eph[mid, PRN] < prn):
            lo = mid + 1
        else:
            hi = mid
    best = -1
    best_score = 1e300
    k = lo
    while k < n and eph[k, SYS] == sys and eph[k, PRN] == prn:
        dt = abs(t - eph[k, TOE])
        if dt <= max_age:
            score = dt
            if prefer_source != 0 and (int(eph[k, SOURCE]) & prefer_source) == 0:
                score += 1e6              # the other Galileo message only when the preferred is absent
            if score < best_score:
                best_score = score
                best = k
        k += 1
    return best


def merge_nav(navs: list[NavData]) -> NavData:
    """One navigation table from several (the ionosphere parameters of the first that has them)."""
    navs = [n for n in navs if n is not None]
    if len(navs) == 1:
        return navs[0]
    out = NavData(eph=finish_table(np.concatenate([n.eph for n in navs])) if navs else np.zeros((0, 31)),
                  source=", ".join(n.source for n in navs))
    for key in ("ion_gps", "ion_bds", "ion_gal", "leap_seconds"):
        for n in navs:
            if getattr(n, key) is not None:
                setattr(out, key, getattr(n, key))
                break
    return out
