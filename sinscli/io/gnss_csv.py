"""GNSS CSV reader and writer (FORMATS.md ``gnss.csv``), and the check of a GNSS log against the IMU's time."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..config import GNSS_NAMES
from ..errors import SinsError
from ..types import GnssLog
from .atomic import atomic_path
from .csvcore import check_positive, read_mapped_columns, write_table_csv
from .imu_csv import check_time
from .timebase import diagnose

log = logging.getLogger("sins")

REQUIRED = ["time", "lat", "lon", "height"]
GROUPS = {"vel_n": ["vel_e", "vel_n", "vel_u"], "std_pos": ["std_e", "std_n", "std_u"],
          "std_vel": ["std_vel_e", "std_vel_n", "std_vel_u"]}


def read_gnss_csv(path, cfg=None) -> GnssLog:
    """Read ``gnss.csv``: required time, lat, lon (deg), height (m); optional velocity and sigmas."""
    path = Path(path)
    data, mapping = read_mapped_columns(
        path, cfg or {}, GNSS_NAMES, REQUIRED, list(GROUPS.values()),
        f"expected {', '.join(GNSS_NAMES)} (map other names with the config's gnss.columns)",
        "expected time, lat, lon, height")
    check_time(path, data["time"], allow_gaps=True, what=mapping.get("time", "time"))
    lat = data["lat"]
    if np.any(np.abs(lat) > 90):
        k = int(np.argmax(np.abs(lat) > 90))
        raise SinsError(f"{path}: line {k + 2}, column 'lat': {lat[k]!r} is outside [-90, 90] degrees")
    check_positive(path, data, GROUPS["std_pos"] + GROUPS["std_vel"], mapping)
    out = GnssLog(data["time"], lat, data["lon"], data["height"], source=str(path))
    for name, group in GROUPS.items():
        if group[0] in data:
            setattr(out, name, np.column_stack([data[c] for c in group]))
    return out


def write_gnss_csv(path, gnss: GnssLog) -> None:
    """Write ``gnss.csv`` atomically with exact floats (optional groups when present)."""
    data = {"time": gnss.time, "lat": gnss.lat, "lon": gnss.lon, "height": gnss.height}
    for name, group in GROUPS.items():
        arr = getattr(gnss, name)
        if arr is not None and np.isnan(arr).any():
            log.warning("%s: %d of %d fixes have no %s; the %s columns are left out", path,
                        int(np.isnan(arr).any(axis=1).sum()), len(gnss), name, ", ".join(group))
            continue
        if arr is not None:
            for i, c in enumerate(group):
                data[c] = arr[:, i]
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data)


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
