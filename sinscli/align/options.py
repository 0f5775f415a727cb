"""Alignment options: the ``align:`` section of a config or scenario file, validated, in SI units.

Every key, its unit and default is listed in :data:`ALIGN_DEFAULTS` (and
documented in ``docs/align.md``); errors name the file and the key.  The rest
of a config file (``imu``, ``gnss``, ``ros``...) is the navigation config of
:mod:`sinscli.config` and is validated there.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import config as config_mod
from .. import schema as sc
from ..conventions import ALIGN_EPOCHS, ALIGN_METHODS, CONING_ORDERS
from ..errors import SinsError
from ..sensors import load_sensor
from ..units import DEG, UG_DECIMAL as UG

METHODS = ALIGN_METHODS
EPOCHS = ALIGN_EPOCHS
VECTORS = ("auto", "cumulative", "increments")
COARSE_METHODS = ("auto", "static", "inertial", "gnss-inertial")
# Recommended shortest interval of each method, s (``align.min_duration.<method>``): the static mean
# needs a few seconds of averaging, the inertial-frame fit some earth rotation between its epochs, the
# filter a coarse stage and updates.  A shorter interval runs with a warning naming this length.
MIN_DURATION = {"static": 10.0, "inertial": 30.0, "gnss-inertial": 20.0, "kf": 60.0}
LEGACY_SENSOR_KEYS = ("gyro_bias", "gyro_arw", "accel_bias", "accel_vrw")

ALIGN_DEFAULTS = {
    "method": "inertial",          # static | inertial | gnss-inertial | kf
    "start": None,                 # s, log time of the alignment start (default: the log's start)
    "duration": None,              # s (default: the rest of the log)
    "position": None,              # [lat deg, lon deg, height m] (else from the GNSS log)
    "roll_window": None,           # s: roll from the first S seconds (seed 001 improvement)
    "epoch": "end",                # end: the state where navigation goes on after the interval;
                                   # start: the attitude at the interval start, Cbn(0) (navigate through it)
    "heading": None,               # deg: use this heading (e.g. from a compass or a survey)
    "heading_sigma": None,         # deg: its 1-sigma, written to the output
    "coning": 2,                   # coning/sculling order of the body integration (1-4)
    "observation_interval": 1.0,   # s between the Wahba epochs of the inertial method
    "vectors": "auto",             # Wahba pairs: cumulative (eq 17-18 as they are) | increments (the integrals
                                   # over each observation interval) | auto (increments at rest, cumulative with GNSS)
    "estimate_v0": True,           # gnss-inertial: solve for v^n(0) with Cbn(0) instead of taking one noisy fix
    "sensor": {                    # the sensor description (1-sigma); null: estimated from the data.
                                   # Also: a preset name (mems | tactical | navigation), the path of a
                                   # sensor YAML (schema of sinscli/data/sensors/*.yaml), or such a
                                   # mapping inline ({gyro: {...}, accel: {...}})
        "gyro_bias": None,         # deg/h
        "gyro_arw": None,          # deg/sqrt(h)
        "accel_bias": None,        # micro-g
        "accel_vrw": None,         # micro-g/sqrt(Hz)
    },
    "min_duration": dict(MIN_DURATION),   # s: recommended shortest interval per method (shorter: a warning)
    "motion_check": {              # inertial without GNSS: the base translates (refused) when the velocity
                                   # integral in the inertial frame, less what sensor errors explain, moves it
        "displacement": 5.0,       # m horizontally (a swaying base stays within this), or 4 sigma of the
                                   # noise-driven displacement when that is larger
    },
    "static_check": {              # the base counts as moving above these (1 s block means)
        "rate": 0.2,               # deg/s deviation of the block-mean angular rate
        "accel": 0.1,              # m/s^2 deviation of the block-mean specific force
        "block": 1.0,              # s
    },
    "max_heading_sigma": 5.0,      # deg: a heading less certain than this is not observable
    "course": {                    # heading from the GNSS course (land vehicles, no sideslip)
        "min_speed": 0.5,          # m/s
        "sigma_floor": 2.0,        # deg added for sideslip and mounting
    },
    "kf": {
        "coarse": "auto",          # auto | static | inertial | gnss-inertial: the stage the filter starts
                                   # from (auto: gnss-inertial with a GNSS log, else inertial)
        "coarse_duration": None,   # s (default: half the interval, at most 120 s)
        "update_interval": 1.0,    # s between velocity updates at rest
        "zupt_sigma": 0.01,        # m/s: zero-velocity measurement 1-sigma at rest
        "vel_sigma": None,         # m/s: GNSS velocity 1-sigma (default: the file's std_vel, else 0.1)
    },
}


@dataclass
class SensorSpec:
    """The sensor description, 1-sigma per axis, SI (None: unknown, estimated from the data).

    From the legacy ``align.sensor`` mapping only the first four are given; from a sensor YAML
    (:func:`from_sensor`) every term, absent ones being 0.
    """
    gyro_bias: float | None = None     # rad/s: constant over the interval (fixed, turn-on, instability)
    gyro_arw: float | None = None      # rad/sqrt(s)
    accel_bias: float | None = None    # m/s^2
    accel_vrw: float | None = None     # m/s/sqrt(s)
    gyro_sf: float | None = None       # scale factor (-)
    accel_sf: float | None = None
    gyro_mis: float | None = None      # misalignment (rad)
    accel_mis: float | None = None
    gyro_bias_rw: float | None = None  # rad/s/sqrt(s): bias instability as a random walk
    accel_bias_rw: float | None = None
    gyro_quant: float | None = None    # rad per count
    accel_quant: float | None = None   # m/s per count
    name: str | None = None

    @property
    def given(self) -> bool:
        return any(getattr(self, k) is not None for k in LEGACY_SENSOR_KEYS)


def _rss_max(d: dict, keys, n=3) -> float:
    tot = np.zeros(n)
    for k in keys:
        if k in d:
            tot = tot + np.asarray(d[k], dtype=float) ** 2
    return float(np.sqrt(tot).max())


def from_sensor(sensor: dict, name: str | None = None) -> SensorSpec:
    """:class:`SensorSpec` from a resolved sensor description (:func:`sinscli.sensors.load_sensor`): per
    term the largest axis of the root sum square of the fixed value, the turn-on spread and (for the
    bias) the instability; the instability also as a random walk ``sqrt(2 sigma^2 / tau)``."""
    out = {}
    for which, noise in (("gyro", "arw"), ("accel", "vrw")):
        d = sensor.get(which, {})
        out[f"{which}_bias"] = _rss_max(d, ("bias", "bias_sigma", "bias_instability"))
        out[f"{which}_arw" if which == "gyro" else "accel_vrw"] = _rss_max(d, (noise,))
        out[f"{which}_sf"] = _rss_max(d, ("scale_factor", "scale_factor_sigma"))
        out[f"{which}_mis"] = _rss_max(d, ("misalignment", "misalignment_sigma"), 6)
        if "bias_instability" in d:
            rw = np.sqrt(2.0 * np.asarray(d["bias_instability"]) ** 2 / np.asarray(d["bias_tau"]))
            out[f"{which}_bias_rw"] = float(rw.max())
        else:
            out[f"{which}_bias_rw"] = 0.0
        out[f"{which}_quant"] = _rss_max(d, ("quantization",))
    return SensorSpec(name=name, **out)


@dataclass
class AlignOptions:
    """All alignment choices, SI units and radians."""
    method: str = "inertial"
    start: float | None = None
    duration: float | None = None
    position: tuple | None = None          # (lat rad, lon rad, h m)
    roll_window: float | None = None
    epoch: str = "end"
    heading: float | None = None           # rad
    heading_sigma: float | None = None     # rad
    coning: int = 2
    obs_interval: float = 1.0
    vectors: str = "auto"
    estimate_v0: bool = True
    conv: int = 0
    lever_arm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sensor: SensorSpec = field(default_factory=SensorSpec)
    min_duration: dict = field(default_factory=lambda: dict(MIN_DURATION))
    motion_displacement: float = 5.0
    static_rate: float = 0.2 * DEG
    static_accel: float = 0.1
    static_block: float = 1.0
    max_heading_sigma: float = 5.0 * DEG
    course_min_speed: float = 0.5
    course_sigma_floor: float = 2.0 * DEG
    kf_coarse: str = "auto"
    kf_coarse_duration: float | None = None
    kf_update_interval: float = 1.0
    kf_zupt_sigma: float = 0.01
    kf_vel_sigma: float | None = None


# the one validator family (sinscli.schema), keys under ``align.``
def _fail(src, key, msg):
    sc.fail(src, f"align.{key}", msg)


def _num(src, key, v, *, gt=None, ge=None, allow_none=True):
    if v is None and allow_none:
        return None
    return sc.number(src, f"align.{key}", v, gt=gt, ge=ge, limit=math.inf)     # log times can be UNIX seconds


def _choice(src, key, v, choices):
    return sc.choice(src, f"align.{key}", v, choices)


def _flag(src, key, v):
    return sc.boolean(src, f"align.{key}", v)


def merge_section(section, src: str) -> dict:
    """The defaults overlaid with a user ``align:`` mapping (unknown keys refused)."""
    out = copy.deepcopy(ALIGN_DEFAULTS)
    for k, v in sc.mapping(src, "align", section, out).items():
        if k == "sensor" and (isinstance(v, str) or (isinstance(v, dict) and set(v) & {"gyro", "accel"})):
            out[k] = v                 # a preset name, a sensor YAML path or an inline sensor mapping
        elif isinstance(out[k], dict):
            out[k].update(sc.mapping(src, f"align.{k}", v, out[k]))
        else:
            out[k] = v
    return out


def parse_position(v, src: str, key: str = "position"):
    """``(lat rad, lon rad, h m)`` from ``[lat, lon, h]`` degrees/metres or a ``"LAT,LON,H"`` string."""
    if v is None:
        return None
    if isinstance(v, str):
        parts = [p.strip() for p in v.split(",")]
        try:
            v = [float(p) for p in parts]
        except ValueError:
            raise SinsError(f"{src}: {key}: expected LAT,LON,H in degrees and metres, got {v!r}") from None
    if not isinstance(v, (list, tuple)) or len(v) != 3 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v):
        raise SinsError(f"{src}: {key}: expected LAT,LON,H in degrees and metres, got {v!r}")
    lat, lon, h = (float(x) for x in v)
    if not -90.0 < lat < 90.0:
        raise SinsError(f"{src}: {key}: latitude {lat:g} deg is outside (-90, 90)")
    if abs(lat) > 89.0:
        raise SinsError(f"{src}: {key}: latitude {lat:g} deg is within 1 deg of a pole, where the "
                        "heading of an ENU alignment is undefined")
    return (math.radians(lat), math.radians(lon), h)


def sensor_spec(v, src: str, base_dir=None) -> SensorSpec:
    """The ``align.sensor`` value as a :class:`SensorSpec`: the legacy mapping (deg/h, deg/sqrt(h),
    micro-g, micro-g/sqrt(Hz)), or a preset name, a sensor YAML path (relative to ``base_dir``) or an
    inline mapping in the sensor YAML schema, all read by :func:`sinscli.sensors.load_sensor`."""

    if isinstance(v, str) or (isinstance(v, dict) and set(v) & {"gyro", "accel"}):
        base = Path(base_dir) if base_dir is not None else Path(".")
        sensor = load_sensor(v, None, src, base, key="align.sensor")
        return from_sensor(sensor, v if isinstance(v, str) else "inline")
    if not isinstance(v, dict):
        _fail(src, "sensor", f"expected a preset name, a sensor YAML path or a mapping, got {v!r}")

    def scaled(key, unit):
        x = _num(src, f"sensor.{key}", v.get(key), ge=0.0)
        return None if x is None else x * unit
    return SensorSpec(gyro_bias=scaled("gyro_bias", DEG / 3600.0), gyro_arw=scaled("gyro_arw", DEG / 60.0),
                      accel_bias=scaled("accel_bias", UG), accel_vrw=scaled("accel_vrw", UG))


def build_options(d: dict, src: str, conv: int = 0, lever_arm=None, base_dir=None) -> AlignOptions:
    """:class:`AlignOptions` from a merged ``align`` mapping (see :func:`merge_section`); ``base_dir``:
    where a relative sensor YAML path is looked up (the config file's folder)."""
    method = _choice(src, "method", d["method"], METHODS)
    st, co, kf = d["static_check"], d["course"], d["kf"]
    kf_coarse = _choice(src, "kf.coarse", kf["coarse"], COARSE_METHODS)
    coning = _choice(src, "coning", d["coning"], CONING_ORDERS)

    def scaled(key, v, unit, **kw):
        x = _num(src, key, v, **kw)
        return None if x is None else x * unit

    heading = _num(src, "heading", d["heading"])
    return AlignOptions(
        method=method,
        start=_num(src, "start", d["start"]),
        duration=_num(src, "duration", d["duration"], gt=0.0),
        position=parse_position(d["position"], src, "align.position"),
        roll_window=_num(src, "roll_window", d["roll_window"], gt=0.0),
        epoch=_choice(src, "epoch", d["epoch"], EPOCHS),
        heading=None if heading is None else math.radians(heading % 360.0),
        heading_sigma=scaled("heading_sigma", d["heading_sigma"], DEG, ge=0.0),
        coning=int(coning),
        obs_interval=_num(src, "observation_interval", d["observation_interval"], gt=0.0, allow_none=False),
        vectors=_choice(src, "vectors", d["vectors"], VECTORS),
        estimate_v0=_flag(src, "estimate_v0", d["estimate_v0"]),
        conv=conv,
        lever_arm=np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float),
        sensor=sensor_spec(d["sensor"], src, base_dir),
        min_duration={m: _num(src, f"min_duration.{m}", d["min_duration"].get(m, MIN_DURATION[m]), ge=0.0,
                              allow_none=False) for m in METHODS},
        motion_displacement=_num(src, "motion_check.displacement", d["motion_check"]["displacement"], gt=0.0,
                                 allow_none=False),
        static_rate=scaled("static_check.rate", st["rate"], DEG, gt=0.0, allow_none=False),
        static_accel=_num(src, "static_check.accel", st["accel"], gt=0.0, allow_none=False),
        static_block=_num(src, "static_check.block", st["block"], gt=0.0, allow_none=False),
        max_heading_sigma=scaled("max_heading_sigma", d["max_heading_sigma"], DEG, gt=0.0, allow_none=False),
        course_min_speed=_num(src, "course.min_speed", co["min_speed"], gt=0.0, allow_none=False),
        course_sigma_floor=scaled("course.sigma_floor", co["sigma_floor"], DEG, ge=0.0, allow_none=False),
        kf_coarse=kf_coarse,
        kf_coarse_duration=_num(src, "kf.coarse_duration", kf["coarse_duration"], gt=0.0),
        kf_update_interval=_num(src, "kf.update_interval", kf["update_interval"], gt=0.0, allow_none=False),
        kf_zupt_sigma=_num(src, "kf.zupt_sigma", kf["zupt_sigma"], gt=0.0, allow_none=False),
        kf_vel_sigma=_num(src, "kf.vel_sigma", kf["vel_sigma"], gt=0.0),
    )


def load_align_config(path) -> tuple[config_mod.Config, dict]:
    """A config YAML with an optional ``align:`` section: ``(navigation config, merged align mapping)``.

    The navigation part is loaded and validated by :func:`sinscli.config.load_config`.
    """
    cfg = config_mod.load_config(path)
    return cfg, merge_section(cfg.align, str(path) if path is not None else "config")
