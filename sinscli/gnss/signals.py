"""GNSS systems, signal bands and carrier frequencies (RINEX 3.04 section 5.1, table 4-5; ICDs).

Systems are small integers so that kernels take them in plain arrays: ``SYS_GPS`` ... ``SYS_IRN``;
``SYS_CHARS[s]`` is the RINEX letter.  A signal is named by its RINEX code ``C1C`` (type, band,
attribute); its band digit and the system give the carrier frequency (:func:`frequency`).
"""
from __future__ import annotations

C_LIGHT = 299792458.0                       # m/s (IS-GPS-200 20.3.4.3)

SYS_GPS, SYS_GLO, SYS_GAL, SYS_BDS, SYS_QZS, SYS_SBS, SYS_IRN = range(7)
SYS_CHARS = "GRECJSI"
SYS_NAMES = ("GPS", "GLONASS", "Galileo", "BeiDou", "QZSS", "SBAS", "NavIC")
N_SYS = len(SYS_CHARS)

# the systems whose broadcast ephemerides are Keplerian (GPS LNAV, Galileo I/NAV and F/NAV, BeiDou D1/D2,
# QZSS LNAV): the only ones the positioning uses (GLONASS is read and summarised, not positioned)
KEPLER_SYSTEMS = (SYS_GPS, SYS_GAL, SYS_BDS, SYS_QZS)

# carrier frequencies (Hz) by system and RINEX band digit
_FREQ = {
    SYS_GPS: {1: 1575.42e6, 2: 1227.60e6, 5: 1176.45e6},
    SYS_QZS: {1: 1575.42e6, 2: 1227.60e6, 5: 1176.45e6, 6: 1278.75e6},
    SYS_GAL: {1: 1575.42e6, 5: 1176.45e6, 7: 1207.14e6, 8: 1191.795e6, 6: 1278.75e6},
    SYS_BDS: {1: 1575.42e6, 2: 1561.098e6, 5: 1176.45e6, 7: 1207.14e6, 8: 1191.795e6, 6: 1268.52e6},
    SYS_SBS: {1: 1575.42e6, 5: 1176.45e6},
    SYS_IRN: {5: 1176.45e6, 9: 2492.028e6},
}
GLO_F1, GLO_DF1, GLO_F2, GLO_DF2 = 1602.0e6, 0.5625e6, 1246.0e6, 0.4375e6   # GLONASS ICD 3.3.1.4

# pseudorange codes tried in this order for the first (primary) and second frequency of each system
PRIMARY_CODES = {
    SYS_GPS: ("C1C", "C1W", "C1P", "C1X", "C1L"),
    SYS_QZS: ("C1C", "C1X", "C1L"),
    SYS_GAL: ("C1C", "C1X", "C1B", "C1A"),
    SYS_BDS: ("C2I", "C1I", "C2X", "C2Q"),        # B1I (RINEX 3.02+ C2I; 3.01 wrote C1I)
}
SECONDARY_CODES = {
    SYS_GPS: ("C2W", "C2P", "C2L", "C2X", "C2S", "C2D", "C5Q", "C5X", "C5I"),
    SYS_QZS: ("C2L", "C2X", "C5Q", "C5X"),
    SYS_GAL: ("C5Q", "C5X", "C5I", "C7Q", "C7X", "C7I"),
    SYS_BDS: ("C7I", "C7X", "C6I", "C6X"),
}


def sys_index(letter: str) -> int:
    """The system number of a RINEX letter (``'G'`` -> 0); -1 when unknown."""
    return SYS_CHARS.find(letter) if len(letter) == 1 else -1


def frequency(sys: int, code: str, glo_k: int = 0) -> float:
    """Carrier frequency (Hz) of RINEX code ``code`` (e.g. ``'C1C'``, ``'L5X'``) of system ``sys``;
    0.0 when unknown.  ``glo_k`` is the GLONASS frequency channel."""
    band = int(code[1]) if len(code) > 1 and code[1].isdigit() else 0
    if sys == SYS_GLO:
        return {1: GLO_F1 + glo_k * GLO_DF1, 2: GLO_F2 + glo_k * GLO_DF2, 3: 1202.025e6,
                4: 1600.995e6, 6: 1248.06e6}.get(band, 0.0)
    if sys == SYS_BDS and band == 1 and code[2:3] == "I":    # RINEX 3.01 B1I written as band 1
        return 1561.098e6
    return _FREQ.get(sys, {}).get(band, 0.0)


def sat_name(sys: int, prn: int) -> str:
    """``'G05'``."""
    return f"{SYS_CHARS[sys]}{prn:02d}"


def bds_geo(prn: int) -> bool:
    """BeiDou GEO satellites (BDS-SIS-ICD 5.2.4.12: D2 navigation message, rotated orbit frame)."""
    return prn <= 5 or 59 <= prn <= 63


def high_orbit(sys: int, prn: int) -> bool:
    """Satellites whose range from the ground exceeds the MEO 15,000-30,000 km window: BeiDou GEO and
    IGSO, QZSS, SBAS, NavIC (geostationary or inclined geosynchronous orbits, 35,800-42,000 km)."""
    if sys in (SYS_QZS, SYS_SBS, SYS_IRN):
        return True
    return sys == SYS_BDS and (prn <= 10 or prn in (13, 16, 31, 38, 39, 40, 56) or 59 <= prn <= 63)
