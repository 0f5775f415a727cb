"""GPS time: seconds since 1980-01-06 00:00:00 GPST, the one time scale of the raw-GNSS code.

Galileo system time is aligned to it (OS-SIS-ICD 5.1.2); BeiDou time is 14 s behind
(BDS-SIS-ICD 5.1.2: BDT = GPST - 14 s); UTC = GPST - leap seconds (18 s since 2017).
"""
from __future__ import annotations

import numpy as np
from numba import njit

SECONDS_PER_WEEK = 604800.0
BDT_OFFSET = 14.0                     # GPST - BDT, s
GPS_EPOCH_DAYS = 3657                 # days from 1970-01-01 to 1980-01-06
UNIX_GPS_OFFSET = 315964800.0         # UNIX time of the GPS epoch (without leap seconds)
DEFAULT_LEAP = 18.0                   # GPST - UTC since 2017-01-01


def days_from_civil_py(y, m, d):
    """Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm; arrays work)."""
    y = y - (m <= 2)
    era = (y if np.all(y >= 0) else y - 399) // 400
    yoe = y - era * 400
    mp = (m + 9) % 12
    doy = (153 * mp + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


@njit(cache=True)
def days_from_civil(y, m, d):
    """Scalar :func:`days_from_civil_py` for kernels (years after 0)."""
    if m <= 2:
        y -= 1
    era = y // 400
    yoe = y - era * 400
    mp = (m + 9) % 12
    doy = (153 * mp + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def gps_seconds(year, month, day, hour=0, minute=0, second=0.0) -> float:
    """GPS seconds of a calendar epoch given in GPS time."""
    days = days_from_civil(int(year), int(month), int(day)) - GPS_EPOCH_DAYS
    return days * 86400.0 + int(hour) * 3600.0 + int(minute) * 60.0 + float(second)


def week_tow(t):
    """``(week, seconds of week)`` of GPS seconds."""
    t = np.asarray(t, dtype=np.float64)
    week = np.floor(t / SECONDS_PER_WEEK)
    return week.astype(np.int64), t - week * SECONDS_PER_WEEK


def calendar(t: float):
    """``(year, month, day, hour, minute, second)`` of GPS seconds ``t`` (the second a float)."""
    days = int(np.floor(t / 86400.0))
    sod = t - days * 86400.0
    z = days + GPS_EPOCH_DAYS + 719468
    era = z // 146097
    doe = z - era * 146097
    yoe = (doe - doe // 1460 + doe // 36524 - doe // 146096) // 365
    y = yoe + era * 400
    doy = doe - (365 * yoe + yoe // 4 - yoe // 100)
    mp = (5 * doy + 2) // 153
    d = doy - (153 * mp + 2) // 5 + 1
    m = mp + 3 if mp < 10 else mp - 9
    y += m <= 2
    hour = int(sod // 3600.0)
    minute = int((sod - hour * 3600.0) // 60.0)
    return int(y), int(m), int(d), hour, minute, sod - hour * 3600.0 - minute * 60.0


def epoch_text(t: float) -> str:
    """``2020-05-14 22:00:00.000 GPST`` for messages."""
    y, mo, d, h, mi, s = calendar(float(t))
    return f"{y:04d}-{mo:02d}-{d:02d} {h:02d}:{mi:02d}:{s:06.3f} GPST"
