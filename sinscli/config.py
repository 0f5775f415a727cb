"""Navigation config: YAML, every key documented in ``configs/navigation.yaml``, validated once on load into
typed, frozen sections (:class:`Config`: :class:`ImuSection`, :class:`GnssSection`, :class:`Limits`, ...).

Every key is checked by the one validator family of :mod:`sinscli.schema`, and a refusal names the file and
the key in one line, e.g. ``nav.yaml: key navigation.coning: expected one of 1, 2, 3, 4, got 5``.
Readers take their section; command-line options override keys with :func:`override`
(``dataclasses.replace`` of a section, each value checked as the YAML's).  The ``align`` and ``fusion``
sections belong to their stages, which validate them (:mod:`sinscli.align.options`,
:mod:`sinscli.fusion.options`); they are kept raw here.
"""
from __future__ import annotations

import copy
import datetime
import math
import warnings
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from . import conventions as cv
from . import schema as sc
from .frames import ANGLE_UNITS as FRAME_ANGLE_UNITS, FRAMES
from .inputs import load_yaml
from .schema import MAX_COUNT  # noqa: F401  (config.MAX_COUNT of the stages' sections)
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
MAX_LEVER_ARM = 1000.0           # m, each lever-arm component
UNIT_CHOICES = {"gyro": GYRO_UNITS, "accel": ACCEL_UNITS, "dtheta": ANGLE_UNITS, "dvel": VEL_UNITS}
LAUNCH_KEYS = ("lat", "lon", "height", "azimuth")

# sections that belong to another stage, which validates them itself (`sins align`); one config
# file can then serve every command
STAGE_SECTIONS = ("align", "fusion")


def _columns(names):
    def check(src, key, v):
        v = sc.mapping(src, key, v, names)
        for k, col in v.items():
            if not isinstance(col, str):
                sc.expected(src, f"{key}.{k}", "a column name", col)
        return sc.frozen(v)
    return check


def _imu_units(src, key, v):
    v = sc.mapping(src, key, v, UNIT_CHOICES)
    for k, unit in v.items():
        sc.choice(src, f"{key}.{k}", unit, tuple(UNIT_CHOICES[k]))
    return sc.frozen({**{"gyro": "rad/s", "accel": "m/s^2", "dtheta": "rad", "dvel": "m/s"}, **v})


def _angle_units(src, key, v):
    v = sc.mapping(src, key, v, ("angle",))
    return sc.frozen({"angle": sc.choice(src, f"{key}.angle", v.get("angle", "deg"), tuple(FRAME_ANGLE_UNITS))})


def _mounting(src, key, v):
    if isinstance(v, str) and v.lower() == "auto":
        return "auto"
    mounting_matrix(v, src)              # refuses what is not a rotation
    return copy.deepcopy(v)


def _lever_arm(src, key, v):
    return sc.vector(src, key, v, 3, scalar=False, ge=-MAX_LEVER_ARM, le=MAX_LEVER_ARM)


def _launch(src, key, v):
    if v is None:
        return None
    v = sc.mapping(src, key, v, LAUNCH_KEYS)
    return sc.frozen({k: sc.number(src, f"{key}.{k}", x, limit=math.inf) for k, x in v.items()})


def _time_offset(src, key, v):
    return sc.number(src, key, v, limit=math.inf)      # within limits.time: checked with the section's limits


def _limit(positive=True):
    def check(src, key, v):
        if isinstance(v, str) and "e" in v.lower():
            sc.fail(src, key, f"expected a finite number{' > 0' if positive else ''}, got {sc.got(v)} "
                              f"(YAML reads 1.0e8 as text: write 1.0e+8)")
        return sc.number(src, key, v, gt=0.0 if positive else None, limit=math.inf)
    return check


def _date(src, key, v):
    """A UTC calendar date ``YYYY-MM-DD`` (YAML reads it unquoted as a date) or null; kept as its ISO text."""
    if v is None:
        return None
    if isinstance(v, datetime.date) and not isinstance(v, datetime.datetime):
        return v.isoformat()
    if isinstance(v, str) and len(v.strip()) == 10:
        try:
            return datetime.date.fromisoformat(v.strip()).isoformat()
        except ValueError:
            pass
    sc.expected(src, key, "a UTC date YYYY-MM-DD (the day of the GNSS log's first fix) or null", v)


def _text(src, key, v):
    return sc.optional_text(src, key, v)


def _ch(choices):
    return lambda src, key, v: sc.choice(src, key, v, choices)


def _count(src, key, v):
    return sc.integer(src, key, v, 1, MAX_COUNT)


def _names(src, key, v):
    return sc.names(src, key, v)


# every key of every section: (default, check); the defaults are configs/navigation.yaml's
SCHEMA = {
    "imu": {
        "columns": ({}, _columns(IMU_NAMES)),       # FORMATS name -> column name in the file
        "ignore_columns": ([], _names),             # extra file columns to ignore
        "units": ({}, _imu_units),                  # gyro, accel, dtheta, dvel (UNIT_CHOICES)
        "body": ("flu", _ch(cv.BODY_NAMES)),        # the body axes after mounting
        "mounting": (None, _mounting),              # sensor -> body: {roll, pitch, yaw} deg, a 3x3 matrix, or
                                                    # auto (estimated from the log by navigate --gnss)
        "static_start": (False, sc.boolean),        # the log starts at rest (the specific-force check)
        "time_offset": (0.0, _time_offset),         # s added to every IMU time on reading
        "time_system": ("utc", _ch(cv.TIME_SYSTEMS)),    # the time NMEA and UBX receiver times are turned into
    },
    "gnss": {
        "columns": ({}, _columns(GNSS_NAMES)),
        "ignore_columns": ([], _names),
        "lever_arm": ([0.0, 0.0, 0.0], _lever_arm),     # antenna position in body axes, m
        "time_offset": (0.0, _time_offset),             # s added to every GNSS time on reading
        "frame": ("enu", _ch(FRAMES)),                  # velocity columns (NED: vel_d, std_d, std_vel_d)
        "units": ({}, _angle_units),                    # lat, lon in deg | rad
        "date": (None, _date),                          # UTC date of an NMEA log without RMC sentences
    },
    "init": {                                   # the --init file (init YAML or trajectory)
        "frame": ("enu", _ch(FRAMES)),
        "units": ({}, _angle_units),            # lat, lon, roll, pitch, heading in deg | rad
    },
    "truth": {                                  # the truth trajectory of sins compare --config
        "frame": ("enu", _ch(FRAMES)),
        "units": ({}, _angle_units),
        "time_offset": (0.0, _time_offset),
    },
    "odometry": {
        "columns": ({}, _columns(ODOMETRY_NAMES)),
        "ignore_columns": ([], _names),
        "frame": ("auto", _ch(cv.ODOMETRY_FRAMES)),
    },
    "navigation": {
        "attitude": ("quat", _ch(cv.ATTITUDES)),
        "dcm_variant": ("exact", _ch(cv.DCM_VARIANTS)),
        "coning": (2, _ch(cv.CONING_ORDERS)),
        "subsamples": (1, _count),
        "every": (1, _count),
        "frame": ("enu", _ch(cv.NAV_FRAMES)),
        "allow_gaps": (False, sc.boolean),
        "euler_integrator": ("rk4", _ch(cv.EULER_INTEGRATORS)),
        "singularity_threshold": (0.01, lambda src, key, v: sc.number(src, key, v, gt=0.0, lt=1.0)),
        "on_singularity": ("continue", _ch(cv.ON_SINGULARITY)),
        "krylov_substep_tol": (1.0e-9, lambda src, key, v: sc.number(src, key, v, gt=0.0, lt=1.0)),
        "launch": (None, _launch),              # {lat, lon, height, azimuth} deg/m for launch-inertial
    },
    "limits": {                                 # physically impossible inputs are refused at the reader
        "rate": (100.0, _limit()),              # rad/s
        "specific_force": (980.665, _limit()),  # m/s^2 (100 g)
        "speed": (10000.0, _limit()),           # m/s
        "height_min": (-20000.0, _limit(False)),    # m
        "height_max": (1.0e8, _limit()),
        "time": (1.0e10, _limit()),             # s: largest |time stamp|
    },
    "ros": {
        "imu_topic": (None, _text),
        "gnss_topic": (None, _text),
        "vel_topic": (None, _text),
        "odom_topic": (None, _text),
        "time": ("header", _ch(cv.ROS_TIMES)),
    },
}
# the raw default values, section by section (configs/navigation.yaml)
DEFAULTS = {name: {k: copy.deepcopy(d) for k, (d, _) in keys.items()} for name, keys in SCHEMA.items()}


@dataclass(frozen=True)
class ImuSection:
    columns: sc.FrozenMap = field(default_factory=lambda: sc.frozen({}))
    ignore_columns: tuple = ()
    units: sc.FrozenMap = field(default_factory=lambda: _imu_units("", "", {}))
    body: str = "flu"
    mounting: object = None
    static_start: bool = False
    time_offset: float = 0.0
    time_system: str = "utc"


@dataclass(frozen=True)
class GnssSection:
    columns: sc.FrozenMap = field(default_factory=lambda: sc.frozen({}))
    ignore_columns: tuple = ()
    lever_arm: tuple = (0.0, 0.0, 0.0)
    time_offset: float = 0.0
    frame: str = "enu"
    units: sc.FrozenMap = field(default_factory=lambda: sc.frozen({"angle": "deg"}))
    date: str | None = None


@dataclass(frozen=True)
class InitSection:
    frame: str = "enu"
    units: sc.FrozenMap = field(default_factory=lambda: sc.frozen({"angle": "deg"}))


@dataclass(frozen=True)
class TruthSection:
    frame: str = "enu"
    units: sc.FrozenMap = field(default_factory=lambda: sc.frozen({"angle": "deg"}))
    time_offset: float = 0.0


@dataclass(frozen=True)
class OdometrySection:
    columns: sc.FrozenMap = field(default_factory=lambda: sc.frozen({}))
    ignore_columns: tuple = ()
    frame: str = "auto"


@dataclass(frozen=True)
class NavigationSection:
    attitude: str = "quat"
    dcm_variant: str = "exact"
    coning: int = 2
    subsamples: int = 1
    every: int = 1
    frame: str = "enu"
    allow_gaps: bool = False
    euler_integrator: str = "rk4"
    singularity_threshold: float = 0.01
    on_singularity: str = "continue"
    krylov_substep_tol: float = 1.0e-9
    launch: sc.FrozenMap | None = None


@dataclass(frozen=True)
class Limits:
    """Physical limits (``limits:``): a value beyond them is refused where it is read (:mod:`sinscli.io.limits`)."""
    rate: float = 100.0                 # rad/s: angular rate, or an increment's |dtheta| / dt
    specific_force: float = 980.665     # m/s^2 (100 g): specific force, or |dvel| / dt
    speed: float = 10000.0              # m/s: each velocity component and the norm
    height_min: float = -20000.0        # m: ellipsoidal height range
    height_max: float = 1.0e8
    time: float = 1.0e10                # s: largest time stamp magnitude


@dataclass(frozen=True)
class RosSection:
    imu_topic: str | None = None
    gnss_topic: str | None = None
    vel_topic: str | None = None
    odom_topic: str | None = None       # body velocity: nav_msgs/Odometry (or a body-frame Twist*) topic
    time: str = "header"


SECTIONS = {"imu": ImuSection, "gnss": GnssSection, "init": InitSection, "truth": TruthSection,
            "odometry": OdometrySection, "navigation": NavigationSection, "limits": Limits, "ros": RosSection}


@dataclass(frozen=True)
class Config:
    """The whole navigation config, built once per run (:func:`load_config`)."""
    imu: ImuSection = field(default_factory=ImuSection)
    gnss: GnssSection = field(default_factory=GnssSection)
    init: InitSection = field(default_factory=InitSection)
    truth: TruthSection = field(default_factory=TruthSection)
    odometry: OdometrySection = field(default_factory=OdometrySection)
    navigation: NavigationSection = field(default_factory=NavigationSection)
    limits: Limits = field(default_factory=Limits)
    ros: RosSection = field(default_factory=RosSection)
    align: object = None            # the raw ``align:`` mapping (sinscli.align.options validates it)
    fusion: object = None           # the raw ``fusion:`` mapping (sinscli.fusion.options validates it)
    source: str = "config"          # the file it was read from


def _check(section: str, values: dict, src) -> dict:
    spec = SCHEMA[section]
    return {k: spec[k][1](src, f"{section}.{k}", v) for k, v in values.items()}


def _cross_checks(cfg: Config, src) -> None:
    lim = cfg.limits
    if not lim.height_min < lim.height_max:
        sc.expected(src, "limits.height_min", f"a number below limits.height_max ({sc.num(lim.height_max)})",
                    lim.height_min)
    for name in ("imu", "gnss", "truth"):
        off = getattr(cfg, name).time_offset
        if not abs(off) <= lim.time:
            sc.expected(src, f"{name}.time_offset", f"a number of seconds within +-{lim.time:g} (the config's "
                                                    f"limits.time)", off)


def build_config(data, src: str = "config", extra_sections=STAGE_SECTIONS) -> Config:
    """Validate a config mapping (the YAML's document; None: the defaults) into a :class:`Config`."""
    if data is not None and not isinstance(data, dict):
        sc.expected(src, "(document)", f"a mapping of sections {', '.join(sorted(SCHEMA))}", data)
    data = data or {}
    kw = {"source": str(src)}
    for name in data:
        if name not in SCHEMA and name not in extra_sections:
            sc.fail(src, name, f"unknown section; expected one of {', '.join(sorted([*SCHEMA, *extra_sections]))}")
    for name in extra_sections:
        kw[name] = data.get(name)
    for name, cls in SECTIONS.items():
        values = sc.mapping(src, name, data.get(name), SCHEMA[name])
        kw[name] = cls(**_check(name, {k: values.get(k, d) for k, (d, _) in SCHEMA[name].items()}, src))
    cfg = Config(**kw)
    _cross_checks(cfg, src)
    return cfg


def load_config(path=None, extra_sections=STAGE_SECTIONS) -> Config:
    """Load and validate a config YAML (the defaults when ``path`` is None) into a :class:`Config`, once per run.

    ``extra_sections`` (default: the ``align`` and ``fusion`` sections) are accepted and kept raw for the
    stage that validates them.
    """
    if path is None:
        return build_config(None, "config", extra_sections)
    path = Path(path)
    return build_config(load_yaml(path, "config file"), str(path), extra_sections)


def override(cfg: Config, section: str, src: str = "command line", **values) -> Config:
    """``cfg`` with the keys given (not None) of ``section`` replaced (``dataclasses.replace``), each value
    checked as the YAML's would be."""
    given = {k: v for k, v in values.items() if v is not None}
    if not given:
        return cfg
    for k in given:
        if k not in SCHEMA[section]:
            sc.fail(src, f"{section}.{k}", f"unknown key; expected one of {', '.join(sorted(SCHEMA[section]))}")
    new = replace(cfg, **{section: replace(getattr(cfg, section), **_check(section, given, src))})
    _cross_checks(new, src)
    return new


def section_values(section) -> dict:
    """The keys and values of a section (a plain dict, for a record of the run)."""
    return {f.name: getattr(section, f.name) for f in fields(section)}


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
            sc.fail(src, f"imu.mounting.{sorted(map(str, bad))[0]}", "unknown key; expected roll, pitch, yaw (degrees)")
        ang = {}
        for k in ("roll", "pitch", "yaw"):
            v = mounting.get(k, 0.0)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not abs(v) <= 360.0:
                sc.expected(src, f"imu.mounting.{k}", "a number of degrees in [-360, 360]", v)
            ang[k] = math.radians(v)
        # scipy.spatial (0.56 s to import) only for a config with a mounting (tests/test_cli_startup.py)
        from scipy.spatial.transform import Rotation
        return Rotation.from_euler("ZYX", [ang["yaw"], ang["pitch"], ang["roll"]]).as_matrix()
    try:
        m = np.array(mounting, dtype=float)
    except (TypeError, ValueError):
        m = None
    if m is None or m.shape != (3, 3):
        sc.expected(src, "imu.mounting", "{roll, pitch, yaw} in degrees, a 3x3 rotation matrix or auto", mounting)
    if not np.all(np.abs(m) <= 1.0 + 1e-6) or not np.abs(m @ m.T - np.eye(3)).max() <= 1e-6 \
            or not np.linalg.det(m) > 0:
        sc.expected(src, "imu.mounting", "a rotation (orthonormal, det +1 within 1e-6)", mounting)
    return m
