"""The receiver's own solution in a u-blox UBX log: UBX-NAV-PVT (position, NED velocity, accuracies, fix type,
carrier solution), with UBX-NAV-HPPOSLLH's full-precision position where the log has it (u-blox F9 interface
description: NAV-PVT 92-byte payload, NAV-HPPOSLLH 36-byte payload).  Frames are found and checked with
:func:`sinscli.io.ubx_frames.find_frames`; payloads are decoded with numpy structured types.

Time: NAV-PVT's ``iTOW`` (GPS time of week, ms) with the week of its UTC date and time (``valid`` bits
validDate, validTime), then into the IMU's time system (:func:`sinscli.io.timebase.from_gps`).

Accuracy: ``hAcc`` for the east and north 1-sigma, ``vAcc`` for up, ``sAcc`` for each velocity component (as the
ROS u-blox driver does); an accuracy of 0 (below the field's resolution) is taken as the resolution (1 mm, 1 mm/s,
0.1 mm for NAV-HPPOSLLH).  Epochs without a usable solution are skipped and counted: ``gnssFixOK`` not set, fix
types 0 (no fix), 1 (dead reckoning only) and 5 (time only), ``invalidLlh`` set, no valid date and time.
"""
from __future__ import annotations


import numpy as np

from .solutions import Solutions
from ..types import GnssLog
from .timebase import GPS_EPOCH_UNIX, WEEK, days_from_ymd, from_gps, gps_minus_utc
from .atomic import atomic_path
from .ubx_frames import build_frames, find_frames

NAV, PVT, HPPOSLLH = 0x01, 0x07, 0x14
PVT_DTYPE = np.dtype([("iTOW", "<u4"), ("year", "<u2"), ("month", "u1"), ("day", "u1"), ("hour", "u1"),
                      ("min", "u1"), ("sec", "u1"), ("valid", "u1"), ("tAcc", "<u4"), ("nano", "<i4"),
                      ("fixType", "u1"), ("flags", "u1"), ("flags2", "u1"), ("numSV", "u1"), ("lon", "<i4"),
                      ("lat", "<i4"), ("height", "<i4"), ("hMSL", "<i4"), ("hAcc", "<u4"), ("vAcc", "<u4"),
                      ("velN", "<i4"), ("velE", "<i4"), ("velD", "<i4"), ("gSpeed", "<i4"), ("headMot", "<i4"),
                      ("sAcc", "<u4"), ("headAcc", "<u4"), ("pDOP", "<u2"), ("flags3", "<u2"),
                      ("reserved0", "<u4"), ("headVeh", "<i4"), ("magDec", "<i2"), ("magAcc", "<u2")])
HP_DTYPE = np.dtype([("version", "u1"), ("reserved0", "u1", (2,)), ("flags", "u1"), ("iTOW", "<u4"), ("lon", "<i4"),
                     ("lat", "<i4"), ("height", "<i4"), ("hMSL", "<i4"), ("lonHp", "i1"), ("latHp", "i1"),
                     ("heightHp", "i1"), ("hMSLHp", "i1"), ("hAcc", "<u4"), ("vAcc", "<u4")])
assert PVT_DTYPE.itemsize == 92 and HP_DTYPE.itemsize == 36
FIX_TYPES = {0: "no fix", 1: "dead reckoning only", 2: "2D", 3: "3D", 4: "GNSS + dead reckoning", 5: "time only"}
CARRIER = {0: "none", 1: "float", 2: "fixed"}
USABLE_FIX = (2, 3, 4)


def nav_pvt(buf: np.ndarray):
    """``(records of PVT_DTYPE, byte offsets, bad checksums, truncated)`` of every NAV-PVT frame in ``buf``."""
    pl, off, bad, cut = find_frames(buf, NAV, PVT, PVT_DTYPE.itemsize)
    return pl.reshape(-1).view(PVT_DTYPE), off, bad, cut


def _gps_time(r: np.ndarray) -> np.ndarray:
    """GPS time (s since 1980-01-06) of NAV-PVT records: ``iTOW`` in the week of their UTC date and time."""
    ymd = r["year"].astype(np.int64) * 10000 + r["month"].astype(np.int64) * 100 + r["day"].astype(np.int64)
    t_utc = (days_from_ymd(ymd) * 86400 + r["hour"].astype(np.int64) * 3600 + r["min"].astype(np.int64) * 60
             + r["sec"].astype(np.int64)) + r["nano"] * 1e-9
    tow = r["iTOW"].astype(np.int64)
    approx = t_utc - GPS_EPOCH_UNIX + gps_minus_utc(np.floor(t_utc))
    week = np.round((approx - tow / 1000.0) / WEEK).astype(np.int64)
    return (week * 604800000 + tow) / 1000.0


def _valid_dates(r: np.ndarray) -> np.ndarray:
    """validDate and validTime set, and a calendar date numpy can read."""
    ok = (r["valid"] & 0x03) == 0x03
    ok &= (r["month"] >= 1) & (r["month"] <= 12) & (r["day"] >= 1) & (r["day"] <= 31) & (r["year"] >= 1980)
    ok &= (r["hour"] <= 23) & (r["min"] <= 59) & (r["sec"] <= 60) & (np.abs(r["nano"]) <= 1_000_000_000)
    return ok


def solutions(buf: np.ndarray, source: str, time_system: str) -> Solutions | None:
    """The NAV-PVT solutions of a UBX log (NAV-HPPOSLLH's position where present), or None when the log holds no
    NAV-PVT message with a valid checksum."""
    r, off, bad, cut = nav_pvt(buf)
    if r.size == 0:
        return None
    skipped = {}
    if bad or cut:
        skipped["damaged NAV-PVT frames (bad checksum or cut)"] = bad + cut
    ok_time = _valid_dates(r)
    fix = ((r["flags"] & 0x01) == 1) & np.isin(r["fixType"], USABLE_FIX)
    llh = (r["flags3"] & 0x01) == 0
    for code, name in FIX_TYPES.items():
        n = int((ok_time & (r["fixType"] == code) & ~np.isin(code, USABLE_FIX)).sum())
        if n:
            skipped[f"fix type {name}"] = n
    n = int((ok_time & np.isin(r["fixType"], USABLE_FIX) & ((r["flags"] & 0x01) == 0)).sum())
    if n:
        skipped["gnssFixOK not set"] = n
    n = int((ok_time & fix & ~llh).sum())
    if n:
        skipped["invalidLlh set"] = n
    n = int((~ok_time).sum())
    if n:
        skipped["no valid UTC date and time"] = n
    keep = ok_time & fix & llh
    r, off = r[keep], off[keep]
    t_gps = _gps_time(r)
    _, first = np.unique(t_gps, return_index=True)        # time order; a repeated epoch once
    if first.size < t_gps.size:
        skipped["repeated epochs"] = int(t_gps.size - first.size)
    r, off, t_gps = r[first], off[first], t_gps[first]
    lat = r["lat"] / 1e7
    lon = r["lon"] / 1e7
    height = r["height"] / 1e3
    h_acc = np.maximum(r["hAcc"], 1) / 1e3
    v_acc = np.maximum(r["vAcc"], 1) / 1e3
    hp = _hpposllh(buf, r["iTOW"], off)
    if hp is not None:
        has, h = hp
        lat[has] = (h["lat"].astype(np.int64) * 100 + h["latHp"]) / 1e9
        lon[has] = (h["lon"].astype(np.int64) * 100 + h["lonHp"]) / 1e9
        height[has] = (h["height"].astype(np.int64) * 10 + h["heightHp"]) / 1e4
        h_acc[has] = np.maximum(h["hAcc"], 1) / 1e4
        v_acc[has] = np.maximum(h["vAcc"], 1) / 1e4
    vel = np.column_stack([r["velE"], r["velN"], -r["velD"].astype(np.int64)]) / 1e3
    s_acc = np.maximum(r["sAcc"], 1) / 1e3
    return Solutions(time=from_gps(t_gps, time_system), lat=lat, lon=lon, height=height, vel=vel,
                     std_pos=np.column_stack([h_acc, h_acc, v_acc]), std_vel=np.column_stack([s_acc] * 3),
                     where=off, row="byte", source=source, kind="UBX-NAV-PVT", skipped=skipped,
                     total=int(keep.size), notes=[])


def _hpposllh(buf, itow: np.ndarray, pvt_off: np.ndarray):
    """NAV-HPPOSLLH records matched to the NAV-PVT epochs by ``iTOW`` (the nearest in the file of that
    ``iTOW``); ``(has (n,) bool, records of the epochs that have one)`` or None when the log has none."""
    pl, off, _, _ = find_frames(buf, NAV, HPPOSLLH, HP_DTYPE.itemsize)
    if pl.shape[0] == 0:
        return None
    h = pl.reshape(-1).view(HP_DTYPE)
    valid = (h["flags"] & 0x01) == 0
    h, off = h[valid], off[valid]
    if h.size == 0:
        return None
    order = np.lexsort((off, h["iTOW"]))
    keys, hoff = h["iTOW"][order].astype(np.int64), off[order]
    lo = np.searchsorted(keys, itow, side="left")
    hi = np.searchsorted(keys, itow, side="right")
    has = hi > lo
    pick = np.zeros(itow.size, np.int64)
    for i in np.flatnonzero(has & (hi - lo > 1)):          # one iTOW more than once (a log over a week): nearest
        pick[i] = lo[i] + int(np.argmin(np.abs(hoff[lo[i]:hi[i]] - pvt_off[i])))
    single = has & (hi - lo == 1)
    pick[single] = lo[single]
    return has, h[order][pick[has]]


def summary(buf: np.ndarray) -> dict | None:
    """What a UBX log's own solutions are (``sins info``): NAV-PVT epochs per fix type and carrier solution,
    differential ones, the rate and span, and the NAV-HPPOSLLH count; None without NAV-PVT."""
    r, off, bad, cut = nav_pvt(buf)
    if r.size == 0:
        return None
    ok = _valid_dates(r)
    usable = ok & ((r["flags"] & 0x01) == 1) & np.isin(r["fixType"], USABLE_FIX) & ((r["flags3"] & 0x01) == 0)
    t = np.unique(_gps_time(r[ok])) if ok.any() else np.zeros(0)
    dt = np.diff(t)
    carr = (r["flags"] >> 6) & 0x03
    hp, _, _, _ = find_frames(buf, NAV, HPPOSLLH, HP_DTYPE.itemsize)
    return {"messages": int(r.size), "damaged": bad + cut, "usable": int(usable.sum()),
            "fix_types": {FIX_TYPES.get(int(c), f"type {int(c)}"): int((r["fixType"] == c).sum())
                          for c in np.unique(r["fixType"])},
            "carrier_solution": {CARRIER.get(int(c), f"code {int(c)}"): int((usable & (carr == c)).sum())
                                 for c in np.unique(carr[usable])},
            "differential": int((usable & ((r["flags"] & 0x02) != 0)).sum()),
            "rate_hz": float(1.0 / np.median(dt)) if dt.size and np.median(dt) > 0 else None,
            "start_gps": float(t[0]) if t.size else None, "end_gps": float(t[-1]) if t.size else None,
            "hpposllh": int(hp.shape[0])}


# ----------------------------------------------------------------------------------------- writing

def _hp_split(x: np.ndarray, scale: float, sub: int):
    """A value as u-blox's integer and high-precision parts: ``total = round(x * scale * sub)``,
    ``main = round(total / sub)``, ``hp = total - main * sub`` (|hp| <= sub / 2)."""
    total = np.round(np.asarray(x, dtype=np.float64) * scale * sub).astype(np.int64)
    main = np.round(total / sub).astype(np.int64)
    return main, total - main * sub


def solution_frames(gnss: GnssLog, t_gps: np.ndarray, *, hpposllh: bool = True, carrier: int = 0,
                    num_sv: int = 20, default_acc: float = 0.01) -> bytes:
    """NAV-PVT (and NAV-HPPOSLLH) frames of each fix at GPS times ``t_gps`` (s since 1980-01-06), with the
    fields' rounding: ``iTOW`` 1 ms, position 1e-7 deg and 1 mm (1e-9 deg and 0.1 mm in NAV-HPPOSLLH), velocity
    1 mm/s, accuracies 1 mm (0.1 mm) and 1 mm/s: ``hAcc`` the larger of the east and north sigma, ``sAcc`` the
    largest velocity sigma; without sigmas ``default_acc`` (m, m/s).  Fix type 3D, gnssFixOK, ``carrier`` as
    carrSoln (0 none, 1 float, 2 fixed).  UTC date and time from ``t_gps`` less the leap seconds."""
    n = len(gnss)
    t_gps = np.asarray(t_gps, dtype=np.float64)
    ms = np.round(t_gps * 1000.0).astype(np.int64)
    t_utc_ms = ms + int(GPS_EPOCH_UNIX) * 1000 - 1000 * gps_minus_utc(np.floor(ms / 1000.0) + GPS_EPOCH_UNIX)
    day, ms_day = np.divmod(t_utc_ms, 86400000)
    ymd = np.datetime64("1970-01-01", "D") + day.astype("timedelta64[D]")
    y = ymd.astype("datetime64[Y]").astype(np.int64) + 1970
    mo = ymd.astype("datetime64[M]").astype(np.int64) % 12 + 1
    d = (ymd - ymd.astype("datetime64[M]")).astype(np.int64) + 1
    r = np.zeros(n, PVT_DTYPE)
    r["iTOW"] = ms % 604800000
    r["year"], r["month"], r["day"] = y, mo, d
    r["hour"], r["min"], r["sec"] = ms_day // 3600000, ms_day // 60000 % 60, ms_day // 1000 % 60
    r["nano"] = (ms_day % 1000) * 1000000
    r["valid"] = 0x07
    r["tAcc"] = 20
    r["fixType"] = 3
    r["flags"] = 0x01 | ((carrier & 0x03) << 6) | (0x02 if carrier else 0)
    r["numSV"] = num_sv
    lat, lat_hp = _hp_split(gnss.lat, 1e7, 100)
    lon_v = (np.asarray(gnss.lon, dtype=np.float64) + 180.0) % 360.0 - 180.0
    lon, lon_hp = _hp_split(lon_v, 1e7, 100)
    h, h_hp = _hp_split(gnss.height, 1e3, 10)
    r["lat"], r["lon"], r["height"], r["hMSL"] = lat, lon, h, h
    sp = gnss.std_pos if gnss.std_pos is not None else np.full((n, 3), default_acc)
    sp = np.where(np.isfinite(sp), sp, default_acc)
    h_acc, v_acc = np.maximum(sp[:, 0], sp[:, 1]), sp[:, 2]
    r["hAcc"], r["vAcc"] = np.round(h_acc * 1e3), np.round(v_acc * 1e3)
    v = gnss.vel_n if gnss.vel_n is not None else np.zeros((n, 3))
    r["velN"], r["velE"], r["velD"] = np.round(v[:, 1] * 1e3), np.round(v[:, 0] * 1e3), np.round(-v[:, 2] * 1e3)
    r["gSpeed"] = np.round(np.hypot(v[:, 0], v[:, 1]) * 1e3)
    r["headMot"] = np.round(np.degrees(np.arctan2(v[:, 0], v[:, 1])) % 360.0 * 1e5)
    sv = gnss.std_vel if gnss.std_vel is not None else np.full((n, 3), default_acc)
    r["sAcc"] = np.round(np.nanmax(np.where(np.isfinite(sv), sv, default_acc), axis=1) * 1e3)
    r["headAcc"] = np.round(np.degrees(np.arctan2(sv[:, 0], np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-3)))
                            .clip(0, 180) * 1e5)
    r["pDOP"] = 150
    frames = [build_frames(NAV, PVT, r.view(np.uint8).reshape(n, -1))]
    if hpposllh:
        q = np.zeros(n, HP_DTYPE)
        q["iTOW"] = r["iTOW"]
        q["lat"], q["lon"], q["height"], q["hMSL"] = lat, lon, h, h
        q["latHp"], q["lonHp"], q["heightHp"], q["hMSLHp"] = lat_hp, lon_hp, h_hp, h_hp
        q["hAcc"], q["vAcc"] = np.round(h_acc * 1e4), np.round(v_acc * 1e4)
        frames.append(build_frames(NAV, HPPOSLLH, q.view(np.uint8).reshape(n, -1)))
    return np.hstack(frames).tobytes()


def write_ubx_solutions(path, gnss: GnssLog, t_gps: np.ndarray, **kw) -> None:
    """A UBX log of the fixes' NAV-PVT (and NAV-HPPOSLLH) frames (:func:`solution_frames`), atomically."""
    data = solution_frames(gnss, t_gps, **kw)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
