"""GNSS CSV reader and writer (docs/formats.md ``gnss.csv``), and the check of a GNSS log against the IMU's time."""
from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..config import GNSS_NAMES, GnssSection, Limits
from ..errors import SinsError
from ..nav.earth import lla_to_ecef
from ..types import GnssLog
from .atomic import atomic_path, output_lon_lat
from . import limits as limits_mod
from .csvcore import read_mapped_columns, write_table_csv
from ..frames import NED_NAMES, convention, file_name, to_enu
from .imu_csv import check_time
from .timebase import diagnose

log = logging.getLogger("sins")

REQUIRED = ["time", "lat", "lon", "height"]
# a fix within 0.01 deg of a pole (limits.check_near_pole): what to do instead
POLE_USE = "; such fixes cannot aid the ENU navigation: leave them out of the GNSS log"
GROUPS = {"vel_n": ["vel_e", "vel_n", "vel_u"], "std_pos": ["std_e", "std_n", "std_u"],
          "std_vel": ["std_vel_e", "std_vel_n", "std_vel_u"]}
# groups that may come horizontal only (east, north; speed and course as receivers give them): the vertical
# component is NaN in the GnssLog, and the filter uses the east and north components alone
HORIZONTAL = [GROUPS["vel_n"], GROUPS["std_vel"]]


def read_gnss_csv(path, cfg: GnssSection | None = None, limits: Limits | None = None) -> GnssLog:
    """Read ``gnss.csv``: required time, lat, lon (deg), height (m); optional velocity and sigmas.

    The velocity (and its sigma) may be horizontal only, ``vel_e, vel_n`` without ``vel_u``: its vertical
    column of the GnssLog is then NaN.

    ``cfg`` (the config's ``gnss`` section) may say the file is NED or in radians (:mod:`sinscli.frames`).

    Values beyond the physical ``limits`` (the config's section; default: the defaults) and sigmas that
    are not positive are refused naming the line and column.
    """
    lim = limits_mod.resolve(limits)
    path = Path(path)
    section = cfg if cfg is not None else GnssSection()
    frame, to_deg = convention(section)
    cols = dict(section.columns)
    if frame == "ned":                 # the vertical columns of a NED file: vel_d, std_d, std_vel_d
        for name in NED_NAMES:
            cols.setdefault(name, file_name(name, frame))
    from .spp_csv import SPP_COLUMNS    # the extra columns of `sins gnss spp` output: known, not read
    section = replace(section, columns=cols, ignore_columns=(*section.ignore_columns, *SPP_COLUMNS))
    data, mapping = read_mapped_columns(
        path, section, GNSS_NAMES, REQUIRED, list(GROUPS.values()),
        f"expected {', '.join(GNSS_NAMES)} (map other names with the config's gnss.columns)",
        "expected time, lat, lon, height", horizontal=HORIZONTAL)
    names = {c: mapping.get(c, c) for c in data}
    data = to_enu(data, frame, to_deg)
    limits_mod.check_time(path, data["time"], lim, names["time"], 2)
    check_time(path, data["time"], allow_gaps=True, what=names["time"], warn_gaps=False)   # outages: the summary
    limits_mod.check_position(path, data["lat"], data["lon"], data["height"], lim,
                              (names["lat"], names["lon"], names["height"]), 2)
    limits_mod.check_near_pole(path, data["lat"], names["lat"], 2, use=POLE_USE)
    if "vel_e" in data:
        have = [c for c in GROUPS["vel_n"] if c in data]
        limits_mod.check_velocity(path, np.column_stack([data[c] for c in have]), lim, [names[c] for c in have], 2)
    for c in GROUPS["std_pos"] + GROUPS["std_vel"]:
        if c in data:
            limits_mod.check_sigma(path, data[c], names[c], 2)
    out = GnssLog(data["time"], data["lat"], data["lon"], data["height"], source=str(path))
    n = len(out)
    for name, group in GROUPS.items():
        if group[0] in data:
            setattr(out, name, np.column_stack([data.get(c, np.full(n, np.nan)) for c in group]))
    return out


def horizontal_only(arr) -> bool:
    """An (N, 3) velocity or velocity sigma whose east and north are finite and whose up is NaN throughout."""
    return arr is not None and len(arr) > 0 and bool(np.isnan(arr[:, 2]).all() and np.isfinite(arr[:, :2]).all())


def write_gnss_csv(path, gnss: GnssLog) -> None:
    """Write ``gnss.csv`` atomically with exact floats (optional groups when present; a horizontal-only
    velocity or velocity sigma as its east and north columns)."""
    lat, lon = output_lon_lat(path, gnss.lat, gnss.lon, gnss.time)      # lon in [-180, 180), lat within +-90
    data = {"time": gnss.time, "lat": lat, "lon": lon, "height": gnss.height}
    for name, group in GROUPS.items():
        arr = getattr(gnss, name)
        if group in HORIZONTAL and horizontal_only(arr):
            group, arr = group[:2], arr[:, :2]
        if arr is not None and np.isnan(arr).any():
            log.warning("%s: %d of %d fixes have no %s; the %s columns are left out", path,
                        int(np.isnan(arr).any(axis=1).sum()), len(gnss), name, ", ".join(group))
            continue
        if arr is not None:
            for i, c in enumerate(group):
                data[c] = arr[:, i]
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data, sigmas=GROUPS["std_pos"] + GROUPS["std_vel"])


INIT_FIX_SLACK_M = 1000.0     # m: an init and the nearest fix farther apart than this plus the travel allowed


def check_init_against_gnss(init, gnss: GnssLog, speed_limit: float, init_src: str) -> None:
    """SinsError (one line naming the init) when the initial position is farther from the GNSS fix nearest
    in time than a platform could have travelled: ``INIT_FIX_SLACK_M`` plus 3 of the fix's sigmas plus the
    ``limits.speed`` times the time between them (straight-line ECEF distance).  An init 10,000 km above
    the fixes is a wrong file or a wrong datum: the filter would otherwise fight it until its covariance
    broke."""
    if len(gnss) == 0:
        return
    k = int(np.argmin(np.abs(np.asarray(gnss.time, dtype=float) - float(init.time))))
    fix = lla_to_ecef(np.radians(float(gnss.lat[k])), np.radians(float(gnss.lon[k])), float(gnss.height[k]))
    ini = lla_to_ecef(float(init.lat), float(init.lon), float(init.height))
    d = float(np.linalg.norm(fix - ini))
    sig = 0.0
    if gnss.std_pos is not None and np.all(np.isfinite(gnss.std_pos[k])):
        sig = float(np.linalg.norm(gnss.std_pos[k]))
    dt = abs(float(gnss.time[k]) - float(init.time))
    bound = INIT_FIX_SLACK_M + 3.0 * sig + float(speed_limit) * dt
    if d > bound:
        raise SinsError(f"{init_src}: the initial position is {d:,.0f} m from the GNSS fix at t = {float(gnss.time[k])!r} s "
                        f"({gnss.source}), more than the {bound:,.0f} m a platform within limits.speed could cover in "
                        f"{dt:.3g} s: check the init's position and height against the GNSS log")


def check_gnss_against_imu(gnss: GnssLog, t_imu0: float, t_imu1: float) -> None:
    """SinsError (one line naming the GNSS source) when the GNSS log cannot go with an IMU spanning
    ``[t_imu0, t_imu1]`` s: no overlap, or a different time base (seconds from the start against an
    absolute epoch, GPS seconds of week, GPS against UNIX time, GPS against UTC by the leap seconds,
    milliseconds against seconds; :func:`sinscli.io.timebase.diagnose` says which bases it sees)."""
    if len(gnss) == 0:
        raise SinsError(f"{gnss.source}: no GNSS fixes")
    t = np.asarray(gnss.time, dtype=np.float64)
    step = float(np.median(np.diff(t))) if t.shape[0] > 1 else 1.0
    msg = diagnose("the IMU log", (float(t_imu0), float(t_imu1)), str(gnss.source), (float(t[0]), float(t[-1])),
                   other_step=step)
    if msg is not None:
        raise SinsError(msg)
