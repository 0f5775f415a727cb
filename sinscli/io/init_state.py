"""Initial state: an init YAML (docs/formats.md keys) or a row of a trajectory file."""
from __future__ import annotations

import difflib
import math
from pathlib import Path

import numpy as np
import yaml

from ..errors import SinsError, num, quote
from ..nav.rotation import dcm_to_euler, euler_to_dcm
from ..types import NavState, time_tolerance
from ..units import UG
from .atomic import atomic_path, check_finite, output_lon_lat
from . import limits as limits_mod
from ..frames import convention, file_name, to_enu
from ..inputs import input_file, load_yaml

INIT_KEYS = ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "roll", "pitch", "heading"]


def read_init(path, t_start: float | None = None, conv: int = 0, limits=None, section=None) -> NavState:
    """Read the initial state.

    A YAML file must hold every key of docs/formats.md (extra keys from ``sins
    align`` are kept in ``extra``).  A trajectory CSV/Parquet gives the row at
    the IMU start ``t_start``: the last row at or before it, its attitude turned
    from the file's body axes (its marker or its angles) into those of ``conv``.  Values beyond the
    physical ``limits`` (the config's section) are refused naming the key or row.  ``section`` (the
    config's ``init`` section) may say the file is NED or in radians (:mod:`sinscli.frames`).
    """
    path = input_file(path, "init file")
    lim = limits_mod.resolve(limits)
    frame, to_deg = convention(section)
    if path.suffix.lower() in (".yaml", ".yml"):
        return _read_init_yaml(path, conv, lim, frame, to_deg)
    from .trajectory import read_trajectory
    traj = read_trajectory(path, lim, frame, to_deg)
    if t_start is None:
        k = 0
    else:
        idx = np.nonzero(traj.time <= t_start + time_tolerance(t_start))[0]
        if idx.size == 0:
            raise SinsError(f"{path}: no row at or before the IMU start time {num(t_start)} "
                            f"(the trajectory starts at {num(traj.time[0])})")
        k = int(idx[-1])
    _check_lat(path, math.degrees(traj.lat[k]), f"row {k + 1}, column 'lat'")
    cbn = traj.Cbn[k].copy()
    if traj.body is not None and traj.body != conv:      # the file's body axes -> those of the run
        from ..nav.rotation import body_flu_in_enu, cbn_from_flu
        cbn = cbn_from_flu(body_flu_in_enu(cbn[None], traj.body), conv)[0]
    return NavState(float(traj.time[k]), float(traj.lat[k]), float(traj.lon[k]), float(traj.height[k]),
                    traj.vel_n[k].copy(), cbn)


def _check_lat(path, lat_deg, where):
    if not -90.0 <= lat_deg <= 90.0:
        raise SinsError(f"{path}: {where}: latitude {num(lat_deg)} deg is outside [-90, 90]")
    limits_mod.check_near_pole(f"{path}: {where}", lat_deg, use="; use --frame launch-inertial")


def _read_init_yaml(path: Path, conv: int, lim: dict, frame: str = "enu", to_deg: float = 1.0) -> NavState:
    data = load_yaml(path, "init file")
    keys = [file_name(k, frame) for k in INIT_KEYS]
    if not isinstance(data, dict):
        raise SinsError(f"{path}: expected a mapping with keys {', '.join(keys)}")
    missing = [k for k in keys if k not in data]
    if missing:
        stray = [str(k) for k in data if k not in keys and not (k == "vel_d" and frame != "ned") and
                 difflib.get_close_matches(str(k), missing, n=1, cutoff=0.6)]
        hint = f" (found {', '.join(quote(k, 30) for k in stray)}: misspelt?)" if stray else ""
        frame_hint = " (a NED init has vel_d: config init.frame: ned)" if "vel_d" in data and frame != "ned" \
            else ""
        raise SinsError(f"{path}: missing key(s) {', '.join(missing)}{hint}; an init file needs "
                        f"{', '.join(keys)}{frame_hint}")
    vals = {}
    for k, fk in zip(INIT_KEYS, keys):
        v = data[fk]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise SinsError(f"{path}: {fk}: expected a finite number, got {quote(v, 40)}")
        vals[k] = float(v)
    vals = to_enu(vals, frame, to_deg)
    row = np.array
    limits_mod.check_time(path, row([vals["time"]]), lim, "time", row="")
    _check_lat(path, vals["lat"], "lat")
    limits_mod.check_position(path, row([vals["lat"]]), row([vals["lon"]]), row([vals["height"]]), lim,
                              row="")
    limits_mod.check_velocity(path, row([[vals["vel_e"], vals["vel_n"], vals["vel_u"]]]), lim,
                              ["vel_e", "vel_n", "vel_u"], row="")
    if not -90.0 <= vals["pitch"] <= 90.0:
        raise SinsError(f"{path}: pitch: {num(vals['pitch'])} deg is outside [-90, 90]")
    for k in ("roll", "heading"):
        limits_mod.check_range(path, row([vals[k]]), -limits_mod.ANGLE_RANGE, limits_mod.ANGLE_RANGE, k, None,
                               " deg", k, row="")
    r = math.radians
    cbn = euler_to_dcm(r(vals["roll"]), r(vals["pitch"]), r(vals["heading"]), conv)
    extra = {k: v for k, v in data.items() if k not in keys}
    return NavState(vals["time"], r(vals["lat"]), r(vals["lon"]), vals["height"],
                    np.array([vals["vel_e"], vals["vel_n"], vals["vel_u"]]), cbn, extra)


def align_estimates(state: NavState, where, limits=None) -> tuple[dict, dict | None]:
    """The 1-sigma (``{"attitude": rad (3,)}``, heading inf when ``sigma_heading`` is null) and the sensor
    estimates (``{"gyro": rad/s (3,), "accel": m/s^2 (3,)}`` or None) that a ``sins align`` init YAML
    carries in its extra keys (deg, deg/h, micro-g).  A sigma that is not positive, a bias that is not three
    numbers or lies beyond the physical ``limits`` is refused naming the key."""
    lim = limits_mod.resolve(limits)
    x = state.extra
    sig = {}
    if "sigma_roll" in x and "sigma_pitch" in x:
        deg = []
        for k in ("sigma_roll", "sigma_pitch", "sigma_heading"):
            v = x.get(k)
            if k == "sigma_heading" and v is None:
                deg.append(math.inf)                 # unobservable heading
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise SinsError(f"{where}: {k}: expected a 1-sigma in degrees, got {quote(v, 40)}")
            limits_mod.check_sigma(where, np.array([v], dtype=np.float64), k, row="")
            deg.append(float(v))
        sig["attitude"] = np.radians(deg)
    bias = None
    if "gyro_bias" in x and "accel_bias" in x:
        vals = {}
        for k in ("gyro_bias", "accel_bias"):
            v = x[k]
            if not (isinstance(v, list) and len(v) == 3 and
                    all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in v)):
                raise SinsError(f"{where}: {k}: expected three numbers [x, y, z], got {quote(v, 60)}")
            vals[k] = np.asarray(v, dtype=np.float64)
        bias = {"gyro": np.radians(vals["gyro_bias"]) / 3600.0, "accel": vals["accel_bias"] * UG}
        limits_mod.check_abs(where, bias["gyro"], lim["rate"], "gyro bias", "rate", " rad/s", "gyro_bias", row="")
        limits_mod.check_abs(where, bias["accel"], lim["specific_force"], "accelerometer bias", "specific_force",
                             " m/s^2", "accel_bias", row="")
    return sig, bias


def init_dict(state: NavState, conv: int = 0) -> dict:
    """docs/formats.md init keys of a state (degrees), as plain floats (exact round trip)."""
    roll, pitch, heading = dcm_to_euler(np.ascontiguousarray(state.Cbn), conv)
    d = math.degrees
    return {"time": float(state.time), "lat": d(state.lat), "lon": d(state.lon), "height": float(state.height),
            "vel_e": float(state.vel_n[0]), "vel_n": float(state.vel_n[1]), "vel_u": float(state.vel_n[2]),
            "roll": d(roll), "pitch": d(pitch), "heading": d(heading)}


def write_init_yaml(path, state: NavState, conv: int = 0, extra: dict | None = None) -> None:
    """Write an init YAML (docs/formats.md keys first, then ``extra``), atomically."""
    data = init_dict(state, conv)
    data["lat"], data["lon"] = (float(x) for x in output_lon_lat(path, data["lat"], data["lon"], state.time))
    for k, v in {**state.extra, **(extra or {})}.items():
        data[k] = _plain(v)
    check_finite(path, {k: v for k, v in data.items() if isinstance(v, (int, float)) or
                        (isinstance(v, list) and all(isinstance(x, (int, float)) for x in v))})
    with atomic_path(path) as tmp:
        Path(tmp).write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=False))


def _plain(v):
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v
