"""NMEA 0183 logs (GGA, RMC, VTG, GST, GSA of any talker: GP, GN, GL, GA, GB, GQ ...) as receiver solutions, and
NMEA text written from a :class:`GnssLog` (the simulator's receiver output).

Sentences are found and parsed by the numba kernels of :mod:`sinscli.io.nmea_kernels` (checksum checked; a bad
checksum, a truncated or a garbled sentence is skipped and counted in one warning).  One epoch per GGA time:

* **time**: GGA's UTC time of day, dated by the RMC sentences (each RMC date anchors the epochs around it;
  a time of day that falls back by more than 12 hours is the next day) or, without any RMC date, by the
  config's ``gnss.date`` (the UTC date of the first fix); then into the IMU's time system
  (:func:`sinscli.io.timebase.from_utc`).
* **height**: GGA's altitude above mean sea level plus its geoid separation: ellipsoidal.  A log without the
  separation is taken as it is (one warning: the heights are then above mean sea level); epochs without it
  in a log that has it take the nearest epoch's.
* **velocity**: RMC's speed and course (else VTG's): horizontal only.  Below :data:`MIN_COURSE_SPEED`, or with
  an empty course, the course is noise (receivers freeze or blank it at low speed): the velocity is then
  (0, 0) with a 1-sigma of the speed (at least :data:`MIN_COURSE_SPEED`) on each axis.
* **accuracy**: GST's latitude, longitude and altitude 1-sigma; without them, HDOP (GGA, else GSA) and VDOP
  (GSA, else twice HDOP) times the per-quality range error :data:`UERE`, ``sigma_e = sigma_n = HDOP u / sqrt 2``,
  ``sigma_u = VDOP u``, which the filter's innovations then calibrate.

Epochs without a fix (GGA quality 0) and of qualities that are not a GNSS fix (6 estimated, 7 manual, 8
simulator) are skipped and counted.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import SinsError
from ..types import GnssLog
from . import nmea_kernels as K
from .atomic import atomic_path
from .solutions import Solutions, line_of
from .timebase import days_from_ymd, from_utc

KNOT = 1852.0 / 3600.0            # m/s per knot
MIN_COURSE_SPEED = 0.2            # m/s: below it an NMEA course is not used (module docstring)
# per GGA quality: 1-sigma range error (m) that HDOP and VDOP multiply when there is no GST
UERE = {1: 3.0, 2: 1.0, 3: 3.0, 4: 0.02, 5: 0.5}
QUALITY_NAMES = {0: "without a fix (GGA quality 0)", 1: "autonomous", 2: "DGPS", 3: "PPS", 4: "RTK fixed",
                 5: "RTK float", 6: "estimated (dead reckoning, quality 6)", 7: "manual input (quality 7)",
                 8: "simulator (quality 8)"}
FIX_QUALITIES = (1, 2, 3, 4, 5)
MIN_VELOCITY_SHARE = 0.9          # the velocity is used when this share of the fixes has one (module docstring)
DATE_KEY = "gnss.date"


class Sentences:
    """The parsed sentences of a buffer: per formatter the table of :func:`nmea_kernels.parse` (valid rows only)
    and the byte offsets; ``damaged`` counts and the offset of the first (bad checksum, truncated/garbled)."""

    def __init__(self, buf: np.ndarray):
        start, end, kind, counts = K.scan(buf)
        self.table, self.offset, self.index = {}, {}, {}
        self.count = int(start.shape[0])
        garbled, first_garbled = int(counts[K.C_GARBLED]), int(counts[K.C_FIRST_GARBLED])
        for k in (K.K_GGA, K.K_RMC, K.K_VTG, K.K_GST, K.K_GSA):
            sel = np.flatnonzero(kind == k)                   # in file order
            out, ok = K.parse(buf, start[sel], end[sel], k)
            off = start[sel]
            if not ok.all():
                garbled += int((~ok).sum())
                f = int(off[~ok][0])
                first_garbled = f if first_garbled < 0 else min(first_garbled, f)
            if ok.all():
                self.table[k], self.offset[k], self.index[k] = out, off, sel
            else:
                self.table[k], self.offset[k], self.index[k] = out[ok], off[ok], sel[ok]
        self.checksum = (int(counts[K.C_CHECKSUM]), int(counts[K.C_FIRST_CHECKSUM]))
        self.garbled = (garbled, first_garbled)
        self.valid = int(counts[K.C_VALID]) - (garbled - int(counts[K.C_GARBLED]))
        self.other = int(counts[K.C_OTHER])


def damaged_note(buf: np.ndarray, s: Sentences, source: str) -> str | None:
    """The one warning line for damaged sentences, or None."""
    parts = []
    for (n, first), what in ((s.checksum, "with a bad checksum"), (s.garbled, "truncated or garbled")):
        if n:
            parts.append(f"{n:,} {what} (the first at line {line_of(buf, first)})")
    if not parts:
        return None
    return f"{source}: skipped {sum(x[0] for x in (s.checksum, s.garbled)):,} damaged NMEA sentences: " + \
        ", ".join(parts)


def _match(keys: np.ndarray, epoch_keys: np.ndarray) -> np.ndarray:
    """Index into ``keys`` (first occurrence) of each epoch key, -1 where none."""
    if keys.size == 0:
        return np.full(epoch_keys.size, -1, np.int64)
    uk, first = np.unique(keys, return_index=True)
    i = np.clip(np.searchsorted(uk, epoch_keys), 0, uk.size - 1)
    return np.where(uk[i] == epoch_keys, first[i], -1)


def _match_times(t: np.ndarray, epoch_keys: np.ndarray) -> np.ndarray:
    """Row of a formatter's table (its times ``t``, NaN without one) at each epoch key, -1 where none."""
    ok = np.flatnonzero(np.isfinite(t))
    if ok.size == 0:
        return np.full(epoch_keys.size, -1, np.int64)
    i = _match(_ms(t[ok]), epoch_keys)
    return np.where(i >= 0, ok[np.maximum(i, 0)], -1)


def _ms(t: np.ndarray) -> np.ndarray:
    return np.round(t * 1000.0).astype(np.int64)


def _utc_times(s: Sentences, date: str | None, source: str):
    """UTC (UNIX s) of the timed sentences (GGA, RMC, GST), dated by RMC or ``date``: the times of each formatter's
    rows (NaN without a time of day), and for VTG and GSA the key of the timed sentence each follows."""
    kinds = (K.K_GGA, K.K_RMC, K.K_GST)
    tod = np.full(s.count, np.nan)                        # every sentence in file order
    ymd = np.full(s.count, np.nan)
    for k in kinds:
        tod[s.index[k]] = s.table[k][:, 0]
    ymd[s.index[K.K_RMC]] = s.table[K.K_RMC][:, 6]
    timed = np.flatnonzero(np.isfinite(tod))
    tod_o = tod[timed]
    roll = np.concatenate([[0], np.cumsum(np.diff(tod_o) < -43200.0)]) if tod_o.size else np.zeros(0, np.int64)
    has_date = np.isfinite(ymd[timed])
    dated = np.flatnonzero(has_date)
    if dated.size:
        ymd_d = ymd[timed][dated].astype(np.int64)
        change = np.flatnonzero(np.concatenate([[True], ymd_d[1:] != ymd_d[:-1]]))    # dates change rarely
        days = days_from_ymd(ymd_d[change])[np.cumsum(np.isin(np.arange(ymd_d.size), change)) - 1]
        anchor = days - roll[dated]
        pick = np.maximum(np.cumsum(has_date) - 1, 0)     # the last RMC date at or before; the first before it
        day = anchor[pick] + roll
    elif date is not None:
        y, m, d = (int(x) for x in date.split("-"))
        day = days_from_ymd(np.array([y * 10000 + m * 100 + d]))[0] + roll
    else:
        raise SinsError(f"{source}: the NMEA log has no RMC sentence with a date, so its UTC times of day cannot "
                        f"be dated: give the UTC date of its first fix as the config's {DATE_KEY} (YYYY-MM-DD)")
    t_all = np.full(s.count, np.nan)
    t_all[timed] = day * 86400.0 + tod_o
    times = {k: t_all[s.index[k]] for k in kinds}
    keys = np.full(s.count, -1, np.int64)
    keys[timed] = _ms(t_all[timed])
    last_timed = np.maximum.accumulate(np.where(np.isfinite(t_all), np.arange(s.count), -1)) if s.count else \
        np.zeros(0, np.int64)

    def follows(k):
        """The epoch key of the timed sentence before each untimed one (-1: none)."""
        i = last_timed[s.index[k]]
        return np.where(i >= 0, keys[np.maximum(i, 0)], -1)
    return times, follows(K.K_VTG), follows(K.K_GSA)


def solutions(buf: np.ndarray, source: str, date: str | None, time_system: str) -> Solutions | None:
    """The epochs of the NMEA sentences in ``buf`` (module docstring), or None when it holds no valid GGA."""
    s = Sentences(buf)
    gga = s.table[K.K_GGA]
    if gga.shape[0] == 0:
        return None
    notes = [n for n in (damaged_note(buf, s, source),) if n]
    skipped = {}
    total = int(gga.shape[0])
    q = gga[:, 3].astype(np.int64)
    no_time = ~np.isfinite(gga[:, 0])
    for code in sorted(set(q.tolist()) - set(FIX_QUALITIES)):
        skipped[QUALITY_NAMES.get(code, f"GGA quality {code}")] = int((q == code).sum())
    n = int((no_time & np.isin(q, FIX_QUALITIES)).sum())
    if n:
        skipped["without a time of day"] = n
    keep = np.isin(q, FIX_QUALITIES) & ~no_time
    if not keep.any():
        return Solutions(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), None, None, None, np.zeros(0, np.int64),
                         "line", source, "NMEA", skipped, total, notes)
    times, vtg_key, gsa_key = _utc_times(s, date, source)
    t_gga = times[K.K_GGA]
    idx = np.flatnonzero(keep)
    uk, first = np.unique(_ms(t_gga[idx]), return_index=True)    # one GGA per time (GPGGA and GNGGA: the first)
    if uk.size < idx.size:
        skipped["repeated epochs"] = int(idx.size - uk.size)
    idx = idx[first]
    g = gga[idx]
    t_utc = t_gga[idx]
    quality = q[idx]
    # height: altitude + geoid separation
    sep = g[:, 7].copy()
    known = np.isfinite(sep)
    if not known.any():
        notes.append(f"{source}: GGA has no geoid separation: the heights are taken as given (above mean sea "
                     f"level, not the ellipsoidal heights docs/formats.md asks for)")
        sep[:] = 0.0
    elif not known.all():
        sep = np.interp(np.arange(sep.size), np.flatnonzero(known), sep[known])
    height = g[:, 6] + sep
    # velocity: RMC, else VTG
    rmc, vtg = s.table[K.K_RMC], s.table[K.K_VTG]
    ir = _match_times(times[K.K_RMC], uk)
    speed = np.full(idx.size, np.nan)
    course = np.full(idx.size, np.nan)
    has = ir >= 0
    r = rmc[ir[has]]
    usable = (r[:, 1] == 1.0) & (r[:, 7] != 78)            # status A, mode not N (not valid)
    speed[np.flatnonzero(has)[usable]] = r[usable, 4] * KNOT
    course[np.flatnonzero(has)[usable]] = r[usable, 5]
    if vtg.shape[0]:
        iv = _match(vtg_key, uk)
        need = np.isnan(speed) & (iv >= 0)
        v = vtg[iv[need]]
        ok = v[:, 3] != 78
        sp = np.where(np.isfinite(v[:, 1]), v[:, 1] * KNOT, v[:, 2] / 3.6)
        tgt = np.flatnonzero(need)[ok]
        speed[tgt], course[tgt] = sp[ok], v[ok, 0]
    vel = std_vel = None
    with_vel = np.isfinite(speed)
    keep_e = np.ones(idx.size, dtype=bool)
    if with_vel.any():
        if with_vel.mean() >= MIN_VELOCITY_SHARE:
            keep_e = with_vel
            if (~with_vel).any():
                skipped["without speed and course (RMC/VTG) in a log that has them"] = int((~with_vel).sum())
            c = np.radians(course)
            slow = ~(np.isfinite(c) & (speed >= MIN_COURSE_SPEED))
            vel = np.column_stack([np.where(slow, 0.0, speed * np.sin(np.where(slow, 0.0, c))),
                                   np.where(slow, 0.0, speed * np.cos(np.where(slow, 0.0, c))),
                                   np.full(idx.size, np.nan)])
            sig = np.where(slow, np.maximum(np.nan_to_num(speed), MIN_COURSE_SPEED), np.nan)
            if np.isfinite(sig[with_vel]).any():          # else the configured sigma throughout
                std_vel = np.column_stack([sig, sig, np.full(idx.size, np.nan)])
        else:
            notes.append(f"{source}: only {int(with_vel.sum()):,} of {idx.size:,} fixes have speed and course "
                         f"(RMC/VTG in the epoch): the velocity is not used")
    # accuracy: GST, else DOP x UERE
    std = np.full((idx.size, 3), np.nan)
    gst = s.table[K.K_GST]
    if gst.shape[0]:
        ig = _match_times(times[K.K_GST], uk)
        has = ig >= 0
        sg = gst[ig[has]][:, [2, 1, 3]]                       # lon, lat, alt sigma -> E, N, U
        good = np.isfinite(sg).all(axis=1) & (sg > 0).all(axis=1)
        std[np.flatnonzero(has)[good]] = sg[good]
    hdop = g[:, 5].copy()
    vdop = np.full(idx.size, np.nan)
    gsa = s.table[K.K_GSA]
    if gsa.shape[0]:
        ia = _match(gsa_key, uk)
        has = ia >= 0
        hdop[has] = np.where(np.isfinite(hdop[has]), hdop[has], gsa[ia[has], 2])
        vdop[has] = gsa[ia[has], 3]
    vdop = np.where(np.isfinite(vdop) & (vdop > 0), vdop, 2.0 * hdop)
    uere = np.array([UERE.get(int(x), np.nan) for x in range(9)])[quality]
    dop_ok = np.isnan(std[:, 0]) & np.isfinite(hdop) & (hdop > 0)
    std[dop_ok, 0] = std[dop_ok, 1] = hdop[dop_ok] * uere[dop_ok] / math.sqrt(2.0)
    std[dop_ok, 2] = vdop[dop_ok] * uere[dop_ok]
    sel = keep_e
    return Solutions(time=from_utc(t_utc[sel], time_system), lat=g[sel, 1], lon=g[sel, 2], height=height[sel],
                     vel=None if vel is None else vel[sel], std_pos=std[sel],
                     std_vel=None if std_vel is None else std_vel[sel], where=s.offset[K.K_GGA][idx][sel],
                     row="line", source=source, kind="NMEA", skipped=skipped, total=total, notes=notes)


def summary(buf: np.ndarray) -> dict | None:
    """What an NMEA log holds (``sins info``): sentences per formatter, damaged ones, GGA epochs per quality, the
    rate and the span of the times of day; None without any sentence."""
    s = Sentences(buf)
    n = {K.KIND_NAMES[k]: int(s.table[k].shape[0]) for k in (K.K_GGA, K.K_RMC, K.K_VTG, K.K_GST, K.K_GSA)}
    if not sum(n.values()) and not s.checksum[0] and not s.garbled[0]:
        return None
    gga = s.table[K.K_GGA]
    q = gga[:, 3].astype(np.int64)
    tod = gga[:, 0][np.isfinite(gga[:, 0])]
    dt = np.diff(tod)
    dt = dt[dt > 0]
    rmc = s.table[K.K_RMC]
    dates = rmc[:, 6][np.isfinite(rmc[:, 6])] if rmc.shape[0] else np.zeros(0)
    return {"sentences": n, "other_sentences": s.other, "bad_checksum": s.checksum[0], "garbled": s.garbled[0],
            "qualities": {QUALITY_NAMES.get(int(c), f"quality {int(c)}"): int((q == c).sum()) for c in np.unique(q)},
            "rate_hz": float(1.0 / np.median(dt)) if dt.size else None,
            "first_date": f"{int(dates[0]) // 10000:04d}-{int(dates[0]) // 100 % 100:02d}-{int(dates[0]) % 100:02d}"
            if dates.size else None,
            "geoid_separation": bool(np.isfinite(gga[:, 7]).any()) if gga.shape[0] else False}


# ----------------------------------------------------------------------------------------- writing

def _checksum(body: str) -> str:
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return f"{cs:02X}"


def _dm(value: float, deg_digits: int, decimals: int) -> str:
    """``(d)ddmm.mmmm`` of |value| (deg) with the minutes rounded to ``decimals`` (carrying into the degrees)."""
    a = abs(value)
    deg = int(math.floor(a))
    minutes = round((a - deg) * 60.0, decimals)
    if minutes >= 60.0:
        deg, minutes = deg + 1, 0.0
    return f"{deg:0{deg_digits}d}{minutes:0{decimals + 3}.{decimals}f}"


def format_sentences(gnss: GnssLog, t_utc: np.ndarray, *, talker: str = "GN", quality: int = 1,
                     geoid_separation: float = 0.0, high_precision: bool = False, gst: bool = True,
                     hdop: float = 1.0, satellites: int = 12) -> list[str]:
    """GGA, RMC (speed and course) and GST (when ``gnss.std_pos``) sentences of each fix, at the UTC times
    ``t_utc`` (UNIX s), with the format's rounding: times to 0.01 s, minutes of arc to 5 decimals (7 with
    ``high_precision``), altitude and separation to 0.1 m (0.001 m), speed to 0.001 knot, course to 0.01 deg, GST
    sigmas to 0.001 m.  The altitude is ``height - geoid_separation`` (mean sea level)."""
    dec, hdec = (7, 3) if high_precision else (5, 1)
    out = []
    t_cs = np.round(np.asarray(t_utc, dtype=np.float64) * 100.0).astype(np.int64)     # centiseconds
    for k in range(len(gnss)):
        cs = int(t_cs[k])
        day, cs_day = divmod(cs, 8640000)
        hh, rem = divmod(cs_day, 360000)
        mm, rem = divmod(rem, 6000)
        hms = f"{hh:02d}{mm:02d}{rem // 100:02d}.{rem % 100:02d}"
        lon_v = (float(gnss.lon[k]) + 180.0) % 360.0 - 180.0
        lat, lon = _dm(float(gnss.lat[k]), 2, dec), _dm(lon_v, 3, dec)
        ns, ew = "N" if gnss.lat[k] >= 0 else "S", "E" if lon_v >= 0 else "W"
        alt = float(gnss.height[k]) - geoid_separation
        body = (f"{talker}GGA,{hms},{lat},{ns},{lon},{ew},{quality},{satellites:02d},{hdop:.1f},"
                f"{alt:.{hdec}f},M,{geoid_separation:.{hdec}f},M,,")
        out.append(f"${body}*{_checksum(body)}")
        date = np.datetime64(int(day), "D").astype(object)
        ddmmyy = f"{date.day:02d}{date.month:02d}{date.year % 100:02d}"
        sog = cog = ""
        if gnss.vel_n is not None:
            ve, vn = float(gnss.vel_n[k, 0]), float(gnss.vel_n[k, 1])
            sog = f"{math.hypot(ve, vn) / KNOT:.3f}"
            cog = f"{math.degrees(math.atan2(ve, vn)) % 360.0:.2f}"
        body = f"{talker}RMC,{hms},A,{lat},{ns},{lon},{ew},{sog},{cog},{ddmmyy},,,{'D' if quality == 2 else 'A'},V"
        out.append(f"${body}*{_checksum(body)}")
        if gst and gnss.std_pos is not None and np.isfinite(gnss.std_pos[k]).all():
            se, sn, su = (float(x) for x in gnss.std_pos[k])
            body = (f"{talker}GST,{hms},{math.hypot(se, sn):.3f},{max(se, sn):.3f},{min(se, sn):.3f},"
                    f"{0.0 if sn >= se else 90.0:.1f},{sn:.3f},{se:.3f},{su:.3f}")
            out.append(f"${body}*{_checksum(body)}")
    return out


def write_nmea(path, gnss: GnssLog, t_utc: np.ndarray, **kw) -> None:
    """An NMEA log of ``gnss`` (:func:`format_sentences`), one sentence per line, CR LF, atomically."""
    text = "\r\n".join(format_sentences(gnss, t_utc, **kw)) + "\r\n"
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(text.encode("ascii"))
