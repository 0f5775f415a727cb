"""Which time base a file's times are in, and whether two files share one (no I/O).

docs/formats.md allows any epoch "as long as all files of one run use the same
one".  Real logs break that in a few typical ways, which show in the
magnitudes and offsets of the time spans:

- seconds from the start of the recording against an absolute epoch;
- GPS seconds of week (0 .. 604800) against UNIX or GPS time;
- GPS time (seconds since 1980-01-06) against UNIX time (offset 315964800 s
  minus the GPS-UTC leap seconds);
- GPS time written on the UNIX epoch against UTC-based UNIX time: both
  absolute, the spans shifted at both ends by exactly the GPS-UTC leap
  seconds of the date (18 s since 2017);
- milliseconds (or micro-, nanoseconds) against seconds.

:func:`diagnose` names the bases it believes each file uses and, where a
constant shift repairs it, the shift.
"""
from __future__ import annotations

import calendar
import functools
from importlib import resources

import numpy as np

from .. import conventions as cv
from ..inputs import parse_yaml

GPS_EPOCH_UNIX = 315964800.0     # 1980-01-06 00:00:00 UTC in UNIX seconds
WEEK = 604800.0                  # s in a GPS week
ABSOLUTE_MIN = 1.0e8             # s: an absolute epoch (1973 onwards in UNIX time)
ABSOLUTE_MAX = 4.0e9             # s: beyond 2096 in UNIX time: not seconds

# the IMU's time system (config imu.time_system): UTC-based UNIX time, or GPS time read as POSIX seconds (UNIX
# time + GPS - UTC, as some loggers write): the time base NMEA and UBX receiver times are turned into
TIME_SYSTEMS = cv.TIME_SYSTEMS


@functools.lru_cache(maxsize=1)
def leap_table() -> tuple[np.ndarray, np.ndarray]:
    """``(UNIX time of each UTC date from which GPS - UTC changes, GPS - UTC from then on)``: the package data
    ``sinscli/data/gnss/leap_seconds.yaml`` (IERS Bulletin C / IS-GPS-200)."""
    text = resources.files("sinscli").joinpath("data", "gnss", "leap_seconds.yaml").read_text(encoding="utf-8")
    rows = parse_yaml(text, "sinscli/data/gnss/leap_seconds.yaml")
    start = np.array([float(calendar.timegm((d.year, d.month, d.day, 0, 0, 0))) for d, _ in rows])
    return start, np.array([int(n) for _, n in rows], dtype=np.int64)


def gps_minus_utc(unix_time):
    """GPS - UTC in whole seconds at a UTC-based UNIX time (0 before 1981-07-01); a scalar gives an int, an
    array an int64 array."""
    start, n = leap_table()
    k = np.searchsorted(start, unix_time, side="right")
    out = np.where(k > 0, n[np.maximum(k - 1, 0)], 0)
    return int(out) if np.ndim(out) == 0 else out


def days_from_ymd(ymd) -> np.ndarray:
    """Days from 1970-01-01 of Gregorian dates written as integers ``yyyymmdd``."""
    from ..gnss.timesys import days_from_civil_py   # its module loads numba: only when a receiver log is dated
    ymd = np.asarray(ymd, dtype=np.int64)
    return days_from_civil_py(ymd // 10000, (ymd // 100) % 100, ymd % 100)


def from_utc(t_utc, system: str) -> np.ndarray:
    """UTC-based UNIX times (s) in the time system ``system`` (:data:`TIME_SYSTEMS`)."""
    t = np.asarray(t_utc, dtype=np.float64)
    return t + gps_minus_utc(np.floor(t)) if system == "gps" else t


def from_gps(t_gps, system: str) -> np.ndarray:
    """GPS times (s since 1980-01-06 00:00:00 GPS) in the time system ``system``: ``gps`` the same instant as
    POSIX seconds (``t + GPS_EPOCH_UNIX``), ``utc`` less the GPS - UTC leap seconds of the date."""
    t = np.asarray(t_gps, dtype=np.float64) + GPS_EPOCH_UNIX
    if system == "gps":
        return t
    approx = np.floor(t) - gps_minus_utc(np.floor(t))          # UTC within a second: the leap count of that date
    return t - gps_minus_utc(approx)


def to_utc(t, system: str) -> np.ndarray:
    """Times in the time system ``system`` as UTC-based UNIX times (the inverse of :func:`from_utc`)."""
    t = np.asarray(t, dtype=np.float64)
    if system != "gps":
        return t
    return t - gps_minus_utc(np.floor(t) - gps_minus_utc(np.floor(t)))


def to_gps(t, system: str) -> np.ndarray:
    """Times in the time system ``system`` as GPS times (s since 1980-01-06; the inverse of :func:`from_gps`)."""
    t = np.asarray(t, dtype=np.float64)
    if system == "gps":
        return t - GPS_EPOCH_UNIX
    return t - GPS_EPOCH_UNIX + gps_minus_utc(np.floor(t))


SCALES = ((1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds"))


def kind(t0: float, t1: float) -> str:
    """The base a span ``[t0, t1]`` (s) looks like: absolute | absolute-scaled | from-start | week | other."""
    span = max(t1 - t0, 0.0)
    if ABSOLUTE_MIN <= abs(t0) < ABSOLUTE_MAX:
        return "absolute"
    if abs(t0) >= ABSOLUTE_MAX:
        return "absolute-scaled"
    if abs(t0) <= 1.0 + span:
        return "from-start"
    if 0.0 <= t0 <= WEEK and t1 <= WEEK + span:
        return "week"
    return "other"


def describe(t0: float, t1: float) -> str:
    """Words for :func:`kind` of a span."""
    k = kind(t0, t1)
    if k == "absolute-scaled":
        for s, word in SCALES:
            if ABSOLUTE_MIN <= abs(t0) / s < ABSOLUTE_MAX:
                return f"absolute {word}"
        return "numbers too large for seconds"
    return {"absolute": "absolute seconds (UNIX or GPS time)", "from-start": "seconds from the start",
            "week": "seconds of a GPS week or another origin", "other": "seconds from another origin"}[k]


def _overlap(a0, a1, b0, b1, slack=0.0) -> bool:
    return b0 <= a1 + slack and b1 >= a0 - slack


def _scaled_inside(u0, u1, v0, v1, scale) -> bool:
    """``[u0, u1] / scale`` lies inside ``[v0, v1]`` (1 s + 1 % slack) and covers at least 5 % of it."""
    slack = 1.0 + 0.01 * (v1 - v0)
    return v0 - slack <= u0 / scale and u1 / scale <= v1 + slack and (u1 - u0) / scale >= 0.05 * (v1 - v0)


def _fmt_span(t0, t1) -> str:
    return f"{t0!r} .. {t1!r} s"


def diagnose(ref_name: str, ref: tuple[float, float], other_name: str, other: tuple[float, float],
             other_step: float = 1.0) -> str | None:
    """None when ``other`` (e.g. the GNSS) and ``ref`` (the IMU) share a time base and overlap; else why not.

    ``other_step`` is the nominal interval of ``other`` (s), the slack of the
    leap-second test.  The text names the base each file seems to use and,
    when a constant shift would repair it, the shift to add to ``other``.
    """
    a0, a1 = float(ref[0]), float(ref[1])
    b0, b1 = float(other[0]), float(other[1])
    spans = f"{other_name} spans {_fmt_span(b0, b1)}, {ref_name} spans {_fmt_span(a0, a1)}"
    ka, kb = kind(a0, a1), kind(b0, b1)
    tol = max(float(other_step), 0.5) + 0.05
    da, db = a1 - a0, b1 - b0
    if _overlap(a0, a1, b0, b1):
        # milliseconds against seconds from the start: the spans overlap near 0, and scaled they coincide
        for s, word in SCALES:
            for name_s, name_u, (u0, u1, du), (v0, v1, dv) in ((other_name, ref_name, (b0, b1, db), (a0, a1, da)),
                                                               (ref_name, other_name, (a0, a1, da), (b0, b1, db))):
                if dv > 0 and du > 100 * dv and abs(u0 / s - v0) <= 0.1 * dv and abs(u1 / s - v1) <= 0.1 * dv:
                    return (f"{other_name}: different time units: {name_s} seems to be in {word}, {name_u} in "
                            f"seconds ({spans}); write the times of {name_s} in seconds")
        if ka == kb == "absolute":
            leap = gps_minus_utc(min(a0, b0))
            for sign, (ahead, behind) in ((1, (other_name, ref_name)), (-1, (ref_name, other_name))):
                if leap and abs(b0 - a0 - sign * leap) <= tol and abs(b1 - a1 - sign * leap) <= tol:
                    return (f"{other_name}: times are {leap} s {'ahead of' if sign > 0 else 'behind'} those of "
                            f"{ref_name} at both ends, the GPS-UTC leap seconds of that date: {ahead} seems to be in "
                            f"GPS time, {behind} in UTC-based UNIX time ({spans}); shift the GNSS times by "
                            f"{-sign * leap} s (config gnss.time_offset: {-sign * leap})")
        return None
    slack = 1.0 + 0.01 * max(da, db)
    head = f"{other_name}: does not overlap {ref_name} in time: "
    # milliseconds (micro-, nanoseconds) against seconds
    for s, word in SCALES:
        if _scaled_inside(b0, b1, a0, a1, s):
            return (head + f"different time units: {other_name} seems to be in {word}, {ref_name} in seconds "
                    f"({spans}); write the times of {other_name} in seconds")
        if _scaled_inside(a0, a1, b0, b1, s):
            return (head + f"different time units: {ref_name} seems to be in {word}, {other_name} in seconds "
                    f"({spans}); write the times of {ref_name} in seconds")
    if ka == kb == "absolute":
        # GPS seconds since 1980 against UNIX time
        for sign, gps_name, unix_name in ((1, other_name, ref_name), (-1, ref_name, other_name)):
            unix_t = a0 if sign > 0 else b0
            shift = GPS_EPOCH_UNIX - gps_minus_utc(unix_t)
            if _overlap(a0, a1, b0 + sign * shift, b1 + sign * shift, slack):
                return (head + f"different time bases: {gps_name} seems to be in GPS time (seconds since "
                        f"1980-01-06), {unix_name} in UNIX time (GPS = UNIX - {shift:.0f} s at that date; {spans}); "
                        f"shift the GNSS times by {sign * shift:.0f} s (config gnss.time_offset: {sign * shift:.0f})")
        gap = max(b0 - a1, a0 - b1)
        return (head + f"the time spans are apart ({spans}; "
                f"{other_name} {'starts' if b0 > a1 else 'ends'} {gap:.6g} s {'after' if b0 > a1 else 'before'} "
                f"{ref_name} {'ends' if b0 > a1 else 'starts'})")
    # GPS seconds of week against an absolute epoch
    for week_name, wk, abs_name, ab, sign in ((other_name, (b0, b1), ref_name, (a0, a1), 1),
                                             (ref_name, (a0, a1), other_name, (b0, b1), -1)):
        if kind(*wk) in ("week", "from-start") and kind(*ab) == "absolute" and 0.0 <= wk[0] < WEEK:
            for label, gps0 in (("UNIX time", ab[0] - GPS_EPOCH_UNIX + gps_minus_utc(ab[0])),
                                ("GPS time", ab[0])):
                week_no, sow0 = divmod(gps0, WEEK)
                if _overlap(sow0, sow0 + (ab[1] - ab[0]), wk[0], wk[1], slack):
                    shift = sign * (ab[0] - sow0)
                    return (head + f"different time bases: {week_name} seems to be in GPS seconds of week "
                            f"(week {int(week_no)}), {abs_name} in {label} ({spans}); shift the GNSS times by "
                            f"{shift:.0f} s (config gnss.time_offset: {shift:.0f})")
    gap = max(b0 - a1, a0 - b1)
    if (ka == "absolute") != (kb == "absolute") or (ka != kb and gap > 10.0 * max(da, db, 1.0)):
        return (head + f"different time bases: {other_name} seems to be in {describe(b0, b1)}, {ref_name} in "
                f"{describe(a0, a1)} ({spans}); write both with the same time origin")
    return (head + f"the time spans are apart ({spans}; the gap is "
            f"{gap:.6g} s)")
