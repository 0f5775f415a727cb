"""Navigation config: YAML, every key documented in ``configs/navigation.yaml``, validated on load.

Errors name the file and the offending key, e.g.
``nav.yaml: navigation.coning: expected one of 1, 2, 3, 4, got 5``.
Command-line options override the config (the CLI passes them to :func:`merge`).
"""
from __future__ import annotations

import copy
import math
import warnings
from pathlib import Path

import numpy as np

from .errors import SinsError, num, quote
from .frames import validate_section
from .inputs import load_yaml
from .units import DEG, DEG_PER_H, G0, MG

GYRO_UNITS = {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG_PER_H}
ACCEL_UNITS = {"m/s^2": 1.0, "g": G0, "mg": MG}
ANGLE_UNITS = {"rad": 1.0, "deg": DEG}
VEL_UNITS = {"m/s": 1.0}
IMU_NAMES = ["time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
             "dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z"]
GNSS_NAMES = ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u",
              "std_e", "std_n", "std_u", "std_vel_e", "std_vel_n", "std_vel_u"]
ODOMETRY_NAMES = ["time", "vel_x", "vel_y", "vel_z", "std_x", "std_y", "std_z"]

DEFAULTS = {
    "imu": {
        "columns": {},            # FORMATS name -> column name in the file
        "ignore_columns": [],     # extra file columns to ignore
        "units": {"gyro": "rad/s", "accel": "m/s^2", "dtheta": "rad", "dvel": "m/s"},
        "body": "flu",            # flu | rfu | frd: the body axes after mounting
        "mounting": None,         # sensor -> body: {roll, pitch, yaw} deg, a 3x3 matrix, or auto (estimated
                                  # from the log by navigate --gnss)
        "static_start": False,    # the log starts at rest (enables the specific-force check)
        "time_offset": 0.0,       # s added to every IMU time on reading (a logging delay on the IMU side: the
                                  # output is then on the GNSS clock)
    },
    "gnss": {
        "columns": {},
        "ignore_columns": [],
        "lever_arm": [0.0, 0.0, 0.0],   # antenna position in body axes, m
        "time_offset": 0.0,             # s added to every GNSS time on reading (e.g. -18: GPS time -> UTC)
        "frame": "enu",                 # enu | ned: velocity columns (NED: vel_d, std_d, std_vel_d; frames.py)
        "units": {"angle": "deg"},      # lat, lon in deg | rad
    },
    "init": {                     # the --init file (init YAML or trajectory)
        "frame": "enu",           # enu | ned (NED: key/column vel_d, attitude columns body -> NED)
        "units": {"angle": "deg"},    # lat, lon, roll, pitch, heading in deg | rad
    },
    "truth": {                    # the truth trajectory of sins compare --config
        "frame": "enu",
        "units": {"angle": "deg"},
        "time_offset": 0.0,       # s added to every truth time on reading (as gnss.time_offset; --time-offset)
    },
    "odometry": {
        "columns": {},            # FORMATS name (time, vel_x.., std_x..) -> column name in the CSV
        "ignore_columns": [],
        "frame": "auto",          # auto | body | vehicle | sensor: axes of the velocity (configs/navigation.yaml)
    },
    "navigation": {
        "attitude": "quat",       # dcm | quat | krylov | euler
        "dcm_variant": "exact",   # exact (Savage eq 26) | seed000 (seed 000 eqs 12-14)
        "coning": 2,              # 1 | 2 | 3 | 4
        "subsamples": 1,          # fast IMU samples per attitude update
        "every": 1,               # write every K-th state
        "frame": "enu",           # enu | launch-inertial
        "allow_gaps": False,      # bridge gaps > 5 nominal intervals with a warning
        "euler_integrator": "rk4",          # euler | rk4 (3-angle baseline)
        "singularity_threshold": 0.01,      # |cos psi| under which the 3-angle method warns
        "on_singularity": "continue",       # continue | stop
        "krylov_substep_tol": 1.0e-9,       # krylov: RK4 truncation allowed per interval / its rotation
        "launch": None,           # {lat, lon, height, azimuth} deg/m for launch-inertial
    },
    "limits": {                   # physically impossible inputs are refused at the reader (line, column)
        "rate": 100.0,            # rad/s: angular rate, or an increment's |dtheta| / dt
        "specific_force": 980.665,    # m/s^2 (100 g): specific force, or |dvel| / dt
        "speed": 10000.0,         # m/s: GNSS, init and trajectory velocity (each component and the norm)
        "height_min": -20000.0,   # m: ellipsoidal height range of GNSS, init and trajectory rows
        "height_max": 1.0e8,
        "time": 1.0e10,           # s: largest time stamp magnitude (a stamp in ns instead of s is refused)
    },
    "ros": {
        "imu_topic": None,
        "gnss_topic": None,
        "vel_topic": None,
        "odom_topic": None,       # body velocity: nav_msgs/Odometry (or a body-frame Twist*) topic
        "time": "header",         # header | log
    },
}

CHOICES = {
    ("imu", "body"): ["flu", "rfu", "frd"],
    ("navigation", "attitude"): ["dcm", "quat", "krylov", "euler"],
    ("navigation", "dcm_variant"): ["exact", "seed000"],
    ("navigation", "coning"): [1, 2, 3, 4],
    ("navigation", "frame"): ["enu", "launch-inertial"],
    ("navigation", "euler_integrator"): ["euler", "rk4"],
    ("navigation", "on_singularity"): ["continue", "stop"],
    ("ros", "time"): ["header", "log"],
    ("odometry", "frame"): ["auto", "body", "vehicle", "sensor"],
}
MAX_COUNT = 2 ** 31 - 1          # largest subsamples / every (the kernels count in int64)
MAX_LEVER_ARM = 1000.0           # m, each lever-arm component
UNIT_CHOICES = {"gyro": GYRO_UNITS, "accel": ACCEL_UNITS, "dtheta": ANGLE_UNITS, "dvel": VEL_UNITS}


# sections that belong to another stage, which validates them itself (`sins align`); one config
# file can then serve every command
STAGE_SECTIONS = ("align", "fusion")


def load_config(path=None, extra_sections=STAGE_SECTIONS) -> dict:
    """Load and validate a config YAML (or the defaults when ``path`` is None).

    ``extra_sections`` (default: the ``align`` and ``fusion`` sections) are accepted and returned raw
    under their name (None when absent) for the stage that validates them.
    """
    cfg = copy.deepcopy(DEFAULTS)
    for name in extra_sections:
        cfg[name] = None
    if path is None:
        return cfg
    path = Path(path)
    data = load_yaml(path, "config file")
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise SinsError(f"{path}: expected a mapping of sections {sorted(DEFAULTS)}")
    for section, values in data.items():
        if section in extra_sections:
            cfg[section] = values
            continue
        if section not in DEFAULTS:
            raise SinsError(f"{path}: {section}: unknown section; expected one of "
                            f"{', '.join(sorted([*DEFAULTS, *extra_sections]))}")
        if values is None:
            continue
        if not isinstance(values, dict):
            raise SinsError(f"{path}: {section}: expected a mapping of keys")
        for key, value in values.items():
            if key not in DEFAULTS[section]:
                raise SinsError(f"{path}: {section}.{key}: unknown key; expected one of "
                                f"{', '.join(sorted(DEFAULTS[section]))}")
            cfg[section][key] = value
    validate(cfg, str(path))
    return cfg


def merge(cfg: dict, section: str, **overrides) -> dict:
    """Command-line options (not None) override config keys; validated again."""
    out = copy.deepcopy(cfg)
    for key, value in overrides.items():
        if value is not None:
            out[section][key] = value
    validate(out, "command line")
    return out


def _fail(src, key, msg):
    raise SinsError(f"{src}: {key}: {msg}")


def validate(cfg: dict, src: str) -> None:
    """Check every key's type and range; raise SinsError naming the key."""
    for (section, key), choices in CHOICES.items():
        v = cfg[section][key]
        if isinstance(v, str):
            v = v.lower()
            cfg[section][key] = v
        if v not in choices:
            _fail(src, f"{section}.{key}", f"expected one of {', '.join(map(str, choices))}, got {v!r}")
    nav = cfg["navigation"]
    for key in ("subsamples", "every"):
        v = nav[key]
        if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= MAX_COUNT:
            _fail(src, f"navigation.{key}", f"expected a whole number from 1 to {MAX_COUNT}, got {num(v)}")
    if not isinstance(nav["allow_gaps"], bool):
        _fail(src, "navigation.allow_gaps", f"expected true or false, got {nav['allow_gaps']!r}")
    thr = nav["singularity_threshold"]
    if not isinstance(thr, (int, float)) or not 0 < thr < 1:
        _fail(src, "navigation.singularity_threshold", f"expected a number in (0, 1), got {thr!r}")
    tol = nav["krylov_substep_tol"]
    if not isinstance(tol, (int, float)) or isinstance(tol, bool) or not 0 < tol < 1:
        _fail(src, "navigation.krylov_substep_tol", f"expected a number in (0, 1), got {tol!r}")
    if nav["launch"] is not None:
        launch = nav["launch"]
        if not isinstance(launch, dict) or set(launch) - {"lat", "lon", "height", "azimuth"}:
            _fail(src, "navigation.launch", "expected a mapping with keys lat, lon, height, azimuth")
        for k, v in launch.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                _fail(src, f"navigation.launch.{k}", f"expected a number, got {v!r}")
    imu = cfg["imu"]
    units = imu["units"]
    if not isinstance(units, dict):
        _fail(src, "imu.units", "expected a mapping like {gyro: deg/s, accel: g}")
    for k, v in units.items():
        if k not in UNIT_CHOICES:
            _fail(src, f"imu.units.{k}", f"unknown quantity; expected one of {', '.join(UNIT_CHOICES)}")
        if not isinstance(v, str) or v not in UNIT_CHOICES[k]:
            _fail(src, f"imu.units.{k}", f"expected one of {', '.join(UNIT_CHOICES[k])}, got {quote(v, 40)}")
    for k, v in DEFAULTS["imu"]["units"].items():
        units.setdefault(k, v)
    for section, names in (("imu", IMU_NAMES), ("gnss", GNSS_NAMES), ("odometry", ODOMETRY_NAMES)):
        cols = cfg[section]["columns"]
        if not isinstance(cols, dict):
            _fail(src, f"{section}.columns", "expected a mapping {FORMATS name: file column}")
        for k, v in cols.items():
            if k not in names:
                _fail(src, f"{section}.columns.{k}", f"unknown column name; expected one of {', '.join(names)}")
            if not isinstance(v, str):
                _fail(src, f"{section}.columns.{k}", f"expected a column name, got {v!r}")
        ign = cfg[section]["ignore_columns"]
        if not isinstance(ign, list) or not all(isinstance(x, str) for x in ign):
            _fail(src, f"{section}.ignore_columns", "expected a list of column names")
    if not isinstance(imu["static_start"], bool):
        _fail(src, "imu.static_start", f"expected true or false, got {imu['static_start']!r}")
    mounting_matrix(imu["mounting"], src)
    lim = cfg["limits"]
    for k, v in lim.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
                (k != "height_min" and v <= 0):
            hint = " (YAML reads 1.0e8 as text: write 1.0e+8)" if isinstance(v, str) and "e" in v.lower() else ""
            _fail(src, f"limits.{k}", f"expected a finite number{'' if k == 'height_min' else ' > 0'}, "
                                      f"got {v!r}{hint}")
        lim[k] = float(v)
    if not lim["height_min"] < lim["height_max"]:
        _fail(src, "limits.height_min", f"must be below limits.height_max ({lim['height_max']!r})")
    arm = cfg["gnss"]["lever_arm"]
    if (not isinstance(arm, (list, tuple)) or len(arm) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and abs(x) <= MAX_LEVER_ARM
                       for x in arm)):
        _fail(src, "gnss.lever_arm", f"expected three numbers [x, y, z] in metres (at most {MAX_LEVER_ARM:g} "
                                     f"each), got {arm!r}")
    for section in ("imu", "gnss", "truth"):
        off = cfg[section]["time_offset"]
        if not isinstance(off, (int, float)) or isinstance(off, bool) or not abs(off) <= lim["time"]:
            _fail(src, f"{section}.time_offset", f"expected a number of seconds within +-{lim['time']:g} (the "
                                                 f"config's limits.time), got {off!r}")
    for section in ("gnss", "init", "truth"):
        validate_section(cfg[section], section, lambda key, msg: _fail(src, key, msg))


def mounting_angles(c: np.ndarray) -> dict:
    """The ``{roll, pitch, yaw}`` (degrees) of ``imu.mounting`` giving the rotation ``c`` (the inverse of
    :func:`mounting_matrix`: ``c = Rz(yaw) Ry(pitch) Rx(roll)``); pitch in [-90, 90], and at pitch +-90 the
    roll folded into the yaw (roll 0)."""
    # scipy.spatial (0.56 s to import) only when a mounting is suggested or given (tests/test_cli_startup.py)
    from scipy.spatial.transform import Rotation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)         # gimbal lock: the roll is set to 0, as documented
        yaw, pitch, roll = Rotation.from_matrix(np.asarray(c, dtype=float)).as_euler("ZYX", degrees=True)
    return {k: float(np.round(v, 6)) + 0.0 for k, v in (("roll", roll), ("pitch", pitch), ("yaw", yaw))}


def mounting_matrix(mounting, src: str = "config") -> np.ndarray:
    """``C_sensor^body`` from the config's ``imu.mounting`` (None -> identity).

    ``{roll, pitch, yaw}`` in degrees means ``C = Rz(yaw) Ry(pitch) Rx(roll)``
    with ``v_body = C v_sensor`` (active rotations about the body x, y, z axes);
    a 3x3 list is taken as the matrix itself and must be a rotation.
    """
    if mounting is None or mounting == "auto":     # auto: read in sensor axes, estimated by the fused run
        return np.eye(3)
    if isinstance(mounting, dict):
        bad = set(mounting) - {"roll", "pitch", "yaw"}
        if bad:
            _fail(src, f"imu.mounting.{sorted(map(str, bad))[0]}", "unknown key; expected roll, pitch, yaw (degrees)")
        ang = {}
        for k in ("roll", "pitch", "yaw"):
            v = mounting.get(k, 0.0)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not abs(v) <= 360.0:
                _fail(src, f"imu.mounting.{k}", f"expected a number of degrees in [-360, 360], got {v!r}")
            ang[k] = math.radians(v)
        # scipy.spatial (0.56 s to import) only for a config with a mounting (tests/test_cli_startup.py)
        from scipy.spatial.transform import Rotation
        return Rotation.from_euler("ZYX", [ang["yaw"], ang["pitch"], ang["roll"]]).as_matrix()
    try:
        m = np.array(mounting, dtype=float)
    except (TypeError, ValueError):
        m = None
    if m is None or m.shape != (3, 3):
        _fail(src, "imu.mounting", "expected {roll, pitch, yaw} in degrees, a 3x3 rotation matrix or auto")
    if not np.all(np.abs(m) <= 1.0 + 1e-6) or not np.abs(m @ m.T - np.eye(3)).max() <= 1e-6 \
            or not np.linalg.det(m) > 0:
        _fail(src, "imu.mounting", "the 3x3 matrix is not a rotation (orthonormal, det +1) within 1e-6")
    return m
