"""GNSS CSV reader and writer (FORMATS.md ``gnss.csv``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..config import GNSS_NAMES
from ..errors import SinsError
from ..types import GnssLog
from .atomic import atomic_path
from . import limits as limits_mod
from .csvcore import name_list, read_header, read_numeric_columns, write_table_csv
from .imu_csv import check_time

REQUIRED = ["time", "lat", "lon", "height"]
GROUPS = {"vel_n": ["vel_e", "vel_n", "vel_u"], "std_pos": ["std_e", "std_n", "std_u"],
          "std_vel": ["std_vel_e", "std_vel_n", "std_vel_u"]}


def read_gnss_csv(path, cfg=None, limits=None) -> GnssLog:
    """Read ``gnss.csv``: required time, lat, lon (deg), height (m); optional velocity and sigmas.

    Values beyond the physical ``limits`` (the config's section; default: the defaults) and negative
    sigmas are refused naming the line and column.
    """
    cfg = cfg or {}
    lim = limits_mod.resolve(limits)
    path = Path(path)
    header = read_header(path)
    mapping = dict(cfg.get("columns") or {})
    inverse = {v: k for k, v in mapping.items()}
    ignored = set(cfg.get("ignore_columns") or [])
    known = [inverse.get(c, c) for c in header]
    unknown = [c for c, k in zip(header, known) if k not in GNSS_NAMES and c not in ignored]
    if unknown:
        raise SinsError(f"{path}: unknown column(s) {name_list(unknown)}; expected "
                        f"{', '.join(GNSS_NAMES)} (map other names with the config's gnss.columns)")
    missing = [c for c in REQUIRED if c not in known]
    if missing:
        raise SinsError(f"{path}: missing column(s) {', '.join(missing)}; expected time, lat, lon, height")
    for name, group in GROUPS.items():
        present = [c for c in group if c in known]
        if present and len(present) != 3:
            raise SinsError(f"{path}: has {', '.join(present)} but not all of {', '.join(group)}")
    wanted = [c for c in GNSS_NAMES if c in known]
    names = {c: mapping.get(c, c) for c in wanted}
    data = read_numeric_columns(path, names)
    limits_mod.check_time(path, data["time"], lim, names["time"], 2)
    check_time(path, data["time"], allow_gaps=True, what=names["time"])
    limits_mod.check_position(path, data["lat"], data["lon"], data["height"], lim,
                              (names["lat"], names["lon"], names["height"]), 2)
    if "vel_e" in data:
        limits_mod.check_velocity(path, np.column_stack([data[c] for c in GROUPS["vel_n"]]), lim,
                                  [names[c] for c in GROUPS["vel_n"]], 2)
    for c in GROUPS["std_pos"] + GROUPS["std_vel"]:
        if c in data:
            limits_mod.check_range(path, data[c], 0.0, 1e7, "1-sigma", None, "", names[c], 2)
    out = GnssLog(data["time"], data["lat"], data["lon"], data["height"], source=str(path))
    for name, group in GROUPS.items():
        if group[0] in data:
            setattr(out, name, np.column_stack([data[c] for c in group]))
    return out


def write_gnss_csv(path, gnss: GnssLog) -> None:
    """Write ``gnss.csv`` atomically with exact floats (optional groups when present)."""
    data = {"time": gnss.time, "lat": gnss.lat, "lon": gnss.lon, "height": gnss.height}
    for name, group in GROUPS.items():
        arr = getattr(gnss, name)
        if arr is not None:
            for i, c in enumerate(group):
                data[c] = arr[:, i]
    with atomic_path(path) as tmp:
        write_table_csv(tmp, data)
