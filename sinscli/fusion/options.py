"""The ``fusion:`` config section: every filter choice, validated, in SI units.

Every key with its default and unit is in :data:`FUSION_DEFAULTS` (and documented in
``configs/navigation.yaml``).  Errors name the file and the key, e.g.
``nav.yaml: fusion.zupt.sigma: expected a finite number > 0, got 0``.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from ..config import MAX_COUNT, MAX_LEVER_ARM
from ..errors import SinsError

DEG = math.pi / 180.0
MAX_VALUE = 1.0e9           # any number of the section: its square stays far from overflow
MAX_POS = 1.0e7             # m: a position sigma (the size of the earth)
MAX_VEL = 1.0e4             # m/s: a velocity sigma or a speed (the physical speed limit)
MAX_TIME = 1.0e6            # s: a window, interval or correlation time
MAX_RATE_DEG = 1.0e4        # deg/s: an angular-rate sigma (beyond the 100 rad/s rate limit)

FUSION_DEFAULTS = {
    "states": 15,                    # 15 | 21 (+ gyro and accelerometer scale factors)
    "sensor": None,                  # preset (mems | tactical | navigation) or sensor YAML; null: the
                                     # conservative default (the mems preset), said in the summary
    "bias_model": "gm-noise",        # gm-noise: F = 0, GM density 2 sigma^2/tau | gm-decay: F = -1/tau too
    "propagation_interval": 0.0,     # s between covariance propagations; 0: every attitude update; <= 0.1
    "gate_probability": 0.9999,      # chi-square innovation gate (of the whole measurement vector)
    "gnss_pos_sigma": [1.5, 1.5, 3.0],   # m E N U, for fixes without std columns
    "gnss_vel_sigma": [0.1, 0.1, 0.2],   # m/s E N U, for velocities without std columns
    "use_gnss_velocity": True,       # use the log's GNSS velocity when it has one
    "lever_arm": None,               # antenna in body axes, m; null: gnss.lever_arm
    "init_sigma": {                  # initial 1-sigma when the init file gives none
        "position": [2.0, 2.0, 4.0],     # m E N U
        "velocity": [0.1, 0.1, 0.1],     # m/s
        "roll": 1.0, "pitch": 1.0,       # deg
        "heading": 5.0,                  # deg
    },
    "zupt": {"enabled": True, "sigma": 0.02, "max_speed": 0.5},    # m/s; no ZUPT above max_speed
    "zaru": {"enabled": True, "sigma": None},                      # deg/s; null: ARW / sqrt(window)
    "standstill": {                  # detector on the IMU: windows of `window` s
        "window": 1.0,               # s
        "rate_std": 0.5,             # deg/s: std of each gyro axis in the window under this
        "accel_std": 0.3,            # m/s^2: std of each accelerometer axis under this
        "accel_mag": 0.3,            # m/s^2: | |mean f| - g | under this
    },
    "nhc": {"enabled": False, "sigma": [0.1, 0.1], "interval": 0.1},   # m/s lateral, vertical; s
    "odometry": {"enabled": True, "sigma": None, "sigma_floor": 0.1},   # m/s; null: the log's, else the floor
    "heading_init": {
        "max_sigma": 20.0,           # deg: a heading less certain than this is held out of the filter
        "min_speed": 2.0,            # m/s: GNSS speed from which the course gives the heading
        "sigma_floor": 2.0,          # deg added to the course's sigma (sideslip, mounting)
    },
    "rejection_run": 10,             # consecutive rejected fixes that inflate P and re-accept
    "outage": 3.0,                   # a GNSS gap over this many nominal fix intervals is an outage
    "adapt": {"enabled": True, "probability": 0.99999, "window": 10, "max_scale": 1.0e4},   # widens P, Q
    "scale_factor_tau": 10.0,        # s: correlation time of unestimated scale-factor/misalignment noise
    "smoother_interval": 1.0,        # s: the smoother stores an epoch at least this often
}


@dataclass
class FusionOptions:
    states: int = 15
    sensor: object = None
    bias_model: str = "gm-noise"
    propagation_interval: float = 0.0
    gate_probability: float = 0.9999
    gnss_pos_sigma: np.ndarray = field(default_factory=lambda: np.array([1.5, 1.5, 3.0]))
    gnss_vel_sigma: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.1, 0.2]))
    use_gnss_velocity: bool = True
    lever_arm: np.ndarray | None = None
    init_pos_sigma: np.ndarray = field(default_factory=lambda: np.array([2.0, 2.0, 4.0]))
    init_vel_sigma: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.1, 0.1]))
    init_att_sigma: np.ndarray = field(default_factory=lambda: np.radians([1.0, 1.0, 5.0]))
    zupt: bool = True
    zupt_sigma: float = 0.02
    zupt_max_speed: float = 0.5
    zaru: bool = True
    zaru_sigma: float | None = None          # rad/s
    standstill_window: float = 1.0
    standstill_rate_std: float = 0.5 * DEG
    standstill_accel_std: float = 0.3
    standstill_accel_mag: float = 0.3
    nhc: bool = False
    nhc_sigma: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.1]))
    nhc_interval: float = 0.1
    odometry: bool = True
    odometry_sigma: float | None = None
    odometry_sigma_floor: float = 0.1
    heading_max_sigma: float = 20.0 * DEG
    heading_min_speed: float = 2.0
    heading_sigma_floor: float = 2.0 * DEG
    rejection_run: int = 10
    outage: float = 3.0
    adapt: bool = True
    adapt_probability: float = 0.99999
    adapt_window: int = 10
    adapt_max_scale: float = 1.0e4
    scale_factor_tau: float = 10.0
    smoother_interval: float = 1.0
    base_dir: object = None                  # for a relative sensor path


def _fail(src, key, msg):
    raise SinsError(f"{src}: fusion.{key}: {msg}")


def _num(src, key, v, *, gt=None, ge=None, le=None, lt=None):
    """A finite number within the bounds given, and at most :data:`MAX_VALUE` in size."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _fail(src, key, f"expected a finite number, got {v!r}")
    v = float(v)
    if not abs(v) <= MAX_VALUE:
        _fail(src, key, f"expected a number within +-{MAX_VALUE:g}, got {v!r}")
    if gt is not None and not v > gt:
        _fail(src, key, f"expected a finite number > {gt:g}, got {v!r}")
    if ge is not None and not v >= ge:
        _fail(src, key, f"expected a finite number >= {ge:g}, got {v!r}")
    if le is not None and not v <= le:
        _fail(src, key, f"expected a number <= {le:g}, got {v!r}")
    if lt is not None and not v < lt:
        _fail(src, key, f"expected a number < {lt:g}, got {v!r}")
    return v


def _vec(src, key, v, n, **kw):
    if isinstance(v, (list, tuple)):
        if len(v) != n:
            _fail(src, key, f"expected {n} numbers, got {len(v)}")
        return np.array([_num(src, f"{key}[{i}]", x, **kw) for i, x in enumerate(v)])
    return np.full(n, _num(src, key, v, **kw))


def _bool(src, key, v):
    if not isinstance(v, bool):
        _fail(src, key, f"expected true or false, got {v!r}")
    return v


def _merge(defaults: dict, data, src, prefix=""):
    out = copy.deepcopy(defaults)
    if data is None:
        return out
    if not isinstance(data, dict):
        where = f"fusion.{prefix.rstrip('.')}" if prefix else "fusion"
        raise SinsError(f"{src}: {where}: expected a mapping of keys, got {data!r}")
    for k, v in data.items():
        if k not in defaults:
            _fail(src, f"{prefix}{k}", f"unknown key; expected one of {', '.join(sorted(defaults))}")
        if isinstance(defaults[k], dict) and k not in ("sensor",):
            out[k] = _merge(defaults[k], v, src, f"{prefix}{k}.")
        else:
            out[k] = v
    return out


def build_fusion_options(section, src: str, base_dir=None) -> FusionOptions:
    """Validate the raw ``fusion:`` mapping (None: defaults) into :class:`FusionOptions`."""
    d = _merge(FUSION_DEFAULTS, section, src)
    o = FusionOptions(base_dir=base_dir)
    if d["states"] not in (15, 21) or isinstance(d["states"], bool):
        _fail(src, "states", f"expected 15 or 21, got {d['states']!r}")
    o.states = int(d["states"])
    if d["sensor"] is not None and not isinstance(d["sensor"], (str, dict)):
        _fail(src, "sensor", f"expected a preset name, a sensor YAML path or a mapping, got {d['sensor']!r}")
    o.sensor = d["sensor"]
    if d["bias_model"] not in ("gm-noise", "gm-decay"):
        _fail(src, "bias_model", f"expected gm-noise or gm-decay, got {d['bias_model']!r}")
    o.bias_model = d["bias_model"]
    o.propagation_interval = _num(src, "propagation_interval", d["propagation_interval"], ge=0.0, le=0.1)
    o.gate_probability = _num(src, "gate_probability", d["gate_probability"], gt=0.0, lt=1.0)
    o.gnss_pos_sigma = _vec(src, "gnss_pos_sigma", d["gnss_pos_sigma"], 3, gt=0.0, le=MAX_POS)
    o.gnss_vel_sigma = _vec(src, "gnss_vel_sigma", d["gnss_vel_sigma"], 3, gt=0.0, le=MAX_VEL)
    o.use_gnss_velocity = _bool(src, "use_gnss_velocity", d["use_gnss_velocity"])
    if d["lever_arm"] is not None:
        o.lever_arm = _vec(src, "lever_arm", d["lever_arm"], 3, ge=-MAX_LEVER_ARM, le=MAX_LEVER_ARM)
    s = d["init_sigma"]
    o.init_pos_sigma = _vec(src, "init_sigma.position", s["position"], 3, gt=0.0, le=MAX_POS)
    o.init_vel_sigma = _vec(src, "init_sigma.velocity", s["velocity"], 3, gt=0.0, le=MAX_VEL)
    o.init_att_sigma = np.radians([_num(src, f"init_sigma.{k}", s[k], gt=0.0, le=180.0)
                                   for k in ("roll", "pitch", "heading")])
    o.zupt = _bool(src, "zupt.enabled", d["zupt"]["enabled"])
    o.zupt_sigma = _num(src, "zupt.sigma", d["zupt"]["sigma"], gt=0.0, le=MAX_VEL)
    o.zupt_max_speed = _num(src, "zupt.max_speed", d["zupt"]["max_speed"], gt=0.0, le=MAX_VEL)
    o.zaru = _bool(src, "zaru.enabled", d["zaru"]["enabled"])
    if d["zaru"]["sigma"] is not None:
        o.zaru_sigma = _num(src, "zaru.sigma", d["zaru"]["sigma"], gt=0.0, le=MAX_RATE_DEG) * DEG
    ss = d["standstill"]
    o.standstill_window = _num(src, "standstill.window", ss["window"], gt=0.0, le=MAX_TIME)
    o.standstill_rate_std = _num(src, "standstill.rate_std", ss["rate_std"], gt=0.0, le=MAX_RATE_DEG) * DEG
    o.standstill_accel_std = _num(src, "standstill.accel_std", ss["accel_std"], gt=0.0)
    o.standstill_accel_mag = _num(src, "standstill.accel_mag", ss["accel_mag"], gt=0.0)
    o.nhc = _bool(src, "nhc.enabled", d["nhc"]["enabled"])
    o.nhc_sigma = _vec(src, "nhc.sigma", d["nhc"]["sigma"], 2, gt=0.0, le=MAX_VEL)
    o.nhc_interval = _num(src, "nhc.interval", d["nhc"]["interval"], gt=0.0, le=MAX_TIME)
    o.odometry = _bool(src, "odometry.enabled", d["odometry"]["enabled"])
    if d["odometry"]["sigma"] is not None:
        o.odometry_sigma = _num(src, "odometry.sigma", d["odometry"]["sigma"], gt=0.0, le=MAX_VEL)
    o.odometry_sigma_floor = _num(src, "odometry.sigma_floor", d["odometry"]["sigma_floor"], ge=0.0, le=MAX_VEL)
    hi = d["heading_init"]
    o.heading_max_sigma = _num(src, "heading_init.max_sigma", hi["max_sigma"], gt=0.0, le=180.0) * DEG
    o.heading_min_speed = _num(src, "heading_init.min_speed", hi["min_speed"], gt=0.0, le=MAX_VEL)
    o.heading_sigma_floor = _num(src, "heading_init.sigma_floor", hi["sigma_floor"], gt=0.0, le=180.0) * DEG
    rr = d["rejection_run"]
    if isinstance(rr, bool) or not isinstance(rr, int) or not 1 <= rr <= MAX_COUNT:
        _fail(src, "rejection_run", f"expected a whole number from 1 to {MAX_COUNT}, got {rr!r}")
    o.rejection_run = rr
    o.outage = _num(src, "outage", d["outage"], gt=1.0, le=MAX_TIME)
    ad = d["adapt"]
    o.adapt = _bool(src, "adapt.enabled", ad["enabled"])
    o.adapt_probability = _num(src, "adapt.probability", ad["probability"], gt=0.5, lt=1.0)
    w = ad["window"]
    if isinstance(w, bool) or not isinstance(w, int) or not 2 <= w <= MAX_COUNT:
        _fail(src, "adapt.window", f"expected a whole number from 2 to {MAX_COUNT}, got {w!r}")
    o.adapt_window = w
    o.adapt_max_scale = _num(src, "adapt.max_scale", ad["max_scale"], ge=1.0)
    o.scale_factor_tau = _num(src, "scale_factor_tau", d["scale_factor_tau"], ge=0.0, le=MAX_TIME)
    o.smoother_interval = _num(src, "smoother_interval", d["smoother_interval"], gt=0.0, le=MAX_TIME)
    return o
