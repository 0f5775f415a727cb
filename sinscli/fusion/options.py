"""The ``fusion:`` config section: every filter choice, validated, in SI units.

Every key with its default and unit is in :data:`FUSION_DEFAULTS` (and documented in
``configs/navigation.yaml``).  Errors name the file and the key, e.g.
``nav.yaml: key fusion.zupt.sigma: expected a number > 0, got 0``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..config import MAX_COUNT, MAX_LEVER_ARM
from .. import schema as sc
from ..conventions import BIAS_MODELS, ESTIMABLE, FUSION_STATES, VEHICLES
from ..sensors import SensorDescription, read_sensor
from ..units import DEG

MAX_VALUE = sc.MAX_VALUE    # any number of the section: its square stays far from overflow
MAX_POS = 1.0e7             # m: a position sigma (the size of the earth)
MAX_VEL = 1.0e4             # m/s: a velocity sigma or a speed (the physical speed limit)
MAX_TIME = 1.0e6            # s: a window, interval or correlation time
MAX_RATE_DEG = 1.0e4        # deg/s: an angular-rate sigma (beyond the 100 rad/s rate limit)


FUSION_DEFAULTS = {
    "vehicle": "none",               # car | robot | pedestrian | aircraft | none: the constraints of the
                                     # platform (VEHICLE_PRESETS), under the keys set explicitly
    "states": 15,                    # 15 | 21 (+ gyro and accelerometer scale factors)
    "sensor": None,                  # preset (consumer | mems | tactical | navigation) or sensor YAML; null:
                                     # the conservative default (the mems preset), said in the summary
    "noise_from_data": True,         # white noise and bias magnitudes from the log's standstill windows
                                     # where the description is missing, optimistic or far off (docs/fusion.md)
    "bias_model": "gm-noise",        # gm-noise: F = 0, GM density 2 sigma^2/tau | gm-decay: F = -1/tau too
    "propagation_interval": 0.0,     # s between covariance propagations; 0: every attitude update; <= 0.1
    "gate_probability": 0.9999,      # chi-square innovation gate (of the whole measurement vector)
    "robust_probability": 0.999,     # IGG-III: full weight below this chi-square quantile, the noise
                                     # inflated smoothly up to the gate; null: off
    "gnss_pos_sigma": [1.5, 1.5, 3.0],   # m E N U, for fixes without std columns
    "gnss_vel_sigma": [0.1, 0.1, 0.2],   # m/s E N U, for velocities without std columns
    "use_gnss_velocity": True,       # use the log's GNSS velocity when it has one
    "gnss_error": {                  # the fixes' time-correlated error as Gauss-Markov states (docs/fusion.md)
        "tau": "auto",               # s (horizontal, vertical or one for both); auto: from a first pass's
                                     # innovations when they are correlated; 0: the fixes' errors taken as white
        "sigma": None,               # m [horizontal, vertical]: its steady 1-sigma; null: from the first pass
    },
    "lever_arm": None,               # antenna in body axes, m; null: gnss.lever_arm
    "estimate": [],                  # parameters estimated as filter states: lever_arm, time_offset
    "estimate_sigma": {"lever_arm": 0.5, "time_offset": 0.1},    # m, s: their initial 1-sigma
    "init_sigma": {                  # initial 1-sigma when the init file gives none
        "position": [2.0, 2.0, 4.0],     # m E N U
        "velocity": [0.1, 0.1, 0.1],     # m/s
        "roll": 1.0, "pitch": 1.0,       # deg
        "heading": 5.0,                  # deg
    },
    "zupt": {"enabled": False, "sigma": 0.02, "max_speed": 0.5},   # m/s; no ZUPT above max_speed
    "zaru": {"enabled": False, "sigma": None},                     # deg/s; null: ARW / sqrt(window)
    "standstill": {                  # detector on the IMU: windows of `window` s
        "window": 1.0,               # s
        "lowpass": 0.0,              # s: statistics of the means over bins of this length (engine vibration
                                     # averages out); 0: of the raw samples
        "rate_std": 0.5,             # deg/s: std of each gyro axis in the window under this
        "accel_std": 0.3,            # m/s^2: std of each accelerometer axis under this
        "accel_mag": 0.3,            # m/s^2: | |mean f| - g | under this
    },
    "nhc": {"enabled": False, "sigma": [0.1, 0.1], "interval": 0.1},   # m/s lateral, vertical; s
    "odometry": {"enabled": True, "sigma": None, "sigma_floor": 0.1},   # m/s; null: the log's, else the floor
    "heading_init": {
        "max_sigma": 20.0,           # deg: a heading less certain than this is held out of the filter
        "max_course_sigma": 10.0,    # deg: the GNSS course sets the heading once its sigma is under this
        "max_baseline_time": 30.0,   # s: longest span of fixes whose displacement gives the course
        "min_speed": 0.0,            # m/s: and the GNSS speed is above this (0: the sigma alone decides)
        "sigma_floor": 2.0,          # deg added to the course's sigma (sideslip, mounting)
    },
    "rejection_run": 10,             # consecutive rejected fixes that inflate P and re-accept
    "outage": 3.0,                   # a GNSS gap over this many nominal fix intervals is an outage
    "adapt": {
        "enabled": True,             # every adaptive mechanism below (false: none of them)
        "measurement_noise": True,   # online measurement-noise scale per kind (consecutive innovations' differences)
        "outage_exits": True,        # drift process noise raised by an outage exit far outside its prediction
        "widen": True,               # covariance widened when consistent fixes drift away from the prediction
        "passes": True,              # calibration passes: bias priors, drift and measurement noise, GNSS error
        "window": 20,                # measurements per window
        "max_scale": 1.0e4,          # largest measurement-noise variance scale
        "max_bias_scale": 100.0,     # largest scale of the bias process noise raised at outage exits
        "exit_ratio": 4.0,           # outage-exit innovation^2 / predicted variance that raises it
        "decay": 600.0,              # s: time constant of its decay back to 1
    },
    "scale_factor_tau": 10.0,        # s: correlation time of unestimated scale-factor/misalignment noise
    "smoother_interval": 1.0,        # s: the smoother stores an epoch at least this often
    "raw": {                         # raw GNSS observations (--gnss-raw: tightly coupled; docs/raw_gnss.md)
        "systems": None,             # letters of GECJ; null: every one observed
        "elevation_mask": 15.0,      # deg
        "code_sigma": 0.3,           # m: a = b of sigma^2 = a^2 + b^2 / sin^2 el, scaled up below cn0_ref
        "doppler_sigma": 0.1,        # m/s: range-rate sigma at the zenith and cn0_ref
        "cn0_ref": 45.0,             # dB-Hz: C/N0 under which the variances grow as 10^((cn0_ref - C/N0)/10)
        "iono": "auto",              # auto | klobuchar | iflc | off (auto: ionosphere-free where two frequencies)
        "tropo": True,               # Saastamoinen + DO-229 mapping
        "use_ura": True,             # the broadcast URA in the pseudorange variance
        "iono_var": 0.5,             # the Klobuchar residual's 1-sigma as a share of its delay
        "tropo_sigma": 0.1,          # m: troposphere residual at the zenith (times the mapping function)
        "smooth_code": 0.0,          # s: carrier smoothing (Hatch) of the pseudoranges; 0: raw
        "tdcp": False,               # time-differenced carrier phase between consecutive epochs (--tdcp)
        "carrier_sigma": 0.003,      # m: carrier-phase sigma at cn0_ref (above it; growing as 1/C/N0 below)
        "slip_test": 5.0,            # the INS-aided slip test's threshold on |w| (standard normal without a slip)
        "slip_doppler": 1.0,         # m: the carrier's change this far from the Doppler's (and 6 sigma): a slip
        "slip_gf": 0.05,             # m: the geometry-free combination's change beyond this: a slip
    },
    "clock": {                       # the receiver clock states (raw GNSS), defaults of a TCXO
        "h0": 2.0e-19,               # s: white frequency noise, Allan h_0 (Brown & Hwang table 9.1, TCXO)
        "h_2": 2.0e-20,              # 1/s: random-walk frequency noise, Allan h_-2
        "bias_sigma": 30.0,          # m: 1-sigma of the clock bias after its first estimate from the data
        "drift_sigma": 1.0,          # m/s: the same of the drift
        "isb_sigma": 10.0,           # m: the same of each inter-system bias
        "isb_walk": 0.001,           # m/sqrt(s): random walk of the inter-system biases
        "jump": 10000.0,             # m: an epoch's clock this far (and 10 sigma) from the filter's: a clock jump
    },
}

# --vehicle / fusion.vehicle: the constraints a user of the platform expects, under the keys the user
# sets explicitly (docs/fusion.md)
VEHICLE_PRESETS = {
    "none": {},
    "aircraft": {"heading_init": {"sigma_floor": 5.0}},      # crab angle: the course is not the heading
    "car": {"zupt": {"enabled": True}, "zaru": {"enabled": True},
            "nhc": {"enabled": True, "sigma": [0.1, 0.1]},
            "standstill": {"lowpass": 0.2}},
    "robot": {"zupt": {"enabled": True}, "zaru": {"enabled": True},
              "nhc": {"enabled": True, "sigma": [0.2, 0.1]},       # skid steering slips sideways
              "standstill": {"lowpass": 0.2},
              "heading_init": {"sigma_floor": 5.0}},
    "pedestrian": {"zupt": {"enabled": True, "sigma": 0.05, "max_speed": 0.3}, "zaru": {"enabled": True},
                   "standstill": {"lowpass": 0.0, "accel_std": 0.2, "rate_std": 2.0},
                   "heading_init": {"sigma_floor": 5.0}},           # a handheld device points off the path
}


@dataclass(frozen=True)
class FusionOptions:
    vehicle: str = "none"
    states: int = 15
    sensor: SensorDescription | None = None      # read once (sinscli.sensors.read_sensor); None: the default
    noise_from_data: bool = True
    bias_model: str = "gm-noise"
    propagation_interval: float = 0.0
    gate_probability: float = 0.9999
    robust_probability: float | None = 0.999
    gnss_pos_sigma: np.ndarray = field(default_factory=lambda: np.array([1.5, 1.5, 3.0]))
    gnss_vel_sigma: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.1, 0.2]))
    use_gnss_velocity: bool = True
    gnss_error_tau: np.ndarray | None = None     # s [horizontal, vertical]; None: auto; zeros: off
    gnss_error_sigma: np.ndarray | None = None   # m [horizontal, vertical]; None: from the data
    lever_arm: np.ndarray | None = None
    estimate: tuple = ()
    lever_arm_sigma: float = 0.5
    time_offset_sigma: float = 0.1
    init_pos_sigma: np.ndarray = field(default_factory=lambda: np.array([2.0, 2.0, 4.0]))
    init_vel_sigma: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.1, 0.1]))
    init_att_sigma: np.ndarray = field(default_factory=lambda: np.radians([1.0, 1.0, 5.0]))
    zupt: bool = False
    zupt_sigma: float = 0.02
    zupt_max_speed: float = 0.5
    zaru: bool = False
    zaru_sigma: float | None = None          # rad/s
    standstill_window: float = 1.0
    standstill_lowpass: float = 0.0
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
    heading_max_course_sigma: float = 10.0 * DEG
    heading_max_baseline_time: float = 30.0
    heading_min_speed: float = 0.0
    heading_sigma_floor: float = 2.0 * DEG
    rejection_run: int = 10
    outage: float = 3.0
    adapt: bool = True
    adapt_measurement_noise: bool = True
    adapt_outage_exits: bool = True
    adapt_widen: bool = True
    adapt_passes: bool = True
    adapt_window: int = 20
    adapt_max_scale: float = 1.0e4
    adapt_max_bias_scale: float = 100.0
    adapt_exit_ratio: float = 4.0
    adapt_decay: float = 600.0
    scale_factor_tau: float = 10.0
    smoother_interval: float = 1.0
    raw_systems: str | None = None           # raw GNSS (--gnss-raw): letters of GECJ
    raw_elevation_mask: float = 15.0         # deg
    raw_code_sigma: float = 0.3              # m
    raw_doppler_sigma: float = 0.1           # m/s
    raw_cn0_ref: float = 45.0                # dB-Hz
    raw_iono: str = "auto"
    raw_tropo: bool = True
    raw_use_ura: bool = True
    raw_iono_var: float = 0.5
    raw_tropo_sigma: float = 0.1             # m
    raw_smooth_code: float = 0.0             # s
    raw_tdcp: bool = False
    raw_carrier_sigma: float = 0.003         # m
    raw_slip_test: float = 5.0
    raw_slip_doppler: float = 1.0            # m
    raw_slip_gf: float = 0.05                # m
    clock_h0: float = 2.0e-19                # s
    clock_h_2: float = 2.0e-20               # 1/s
    clock_bias_sigma: float = 30.0           # m
    clock_drift_sigma: float = 1.0           # m/s
    clock_isb_sigma: float = 10.0            # m
    clock_isb_walk: float = 0.001            # m/sqrt(s)
    clock_jump: float = 10000.0              # m

    def spp_options(self):
        """The options vector of :func:`sinscli.gnss.spp.solve_epochs` / :func:`sinscli.gnss.tc.tc_records`
        from the ``fusion.raw`` keys."""
        from ..gnss.spp import spp_options  # the raw-GNSS path (gnss/ numba kernels) only with --gnss-raw
        return spp_options(elev_mask_deg=self.raw_elevation_mask, iono=self.raw_iono, tropo=self.raw_tropo,
                           code_a=self.raw_code_sigma, code_b=self.raw_code_sigma, cn0_ref=self.raw_cn0_ref,
                           doppler_sigma=self.raw_doppler_sigma, iono_var=self.raw_iono_var,
                           tropo_sigma=self.raw_tropo_sigma, use_ura=self.raw_use_ura)

    def clock_densities(self):
        """``(S_f, S_g)``: the clock bias (m^2/s) and drift ((m/s)^2/s) noise densities of the Allan
        coefficients, ``S_f = c^2 h_0 / 2``, ``S_g = c^2 2 pi^2 h_-2`` (Brown & Hwang 9.3)."""
        c2 = 299792458.0 ** 2
        return c2 * self.clock_h0 / 2.0, c2 * 2.0 * math.pi ** 2 * self.clock_h_2


# the one validator family (sinscli.schema), keys under ``fusion.``
def _fail(src, key, msg):
    sc.fail(src, f"fusion.{key}", msg)


def _num(src, key, v, **bounds):
    """A finite number within the bounds given, and at most :data:`MAX_VALUE` in size."""
    return sc.number(src, f"fusion.{key}", v, **bounds)


def _vec(src, key, v, n, **kw):
    return np.array(sc.vector(src, f"fusion.{key}", v, n, **kw))


def _bool(src, key, v):
    return sc.boolean(src, f"fusion.{key}", v)


def _merge(defaults: dict, data, src, prefix=""):
    return sc.merge(defaults, data, src, f"fusion{'.' + prefix.rstrip('.') if prefix else ''}", raw=("sensor",))


def build_fusion_options(section, src: str, base_dir=None, vehicle: str | None = None) -> FusionOptions:
    """Validate the raw ``fusion:`` mapping (None: defaults) into :class:`FusionOptions`.

    ``vehicle`` (``--vehicle``) overrides ``fusion.vehicle``; the vehicle's preset
    (:data:`VEHICLE_PRESETS`) fills the keys the section does not set.  ``fusion.sensor`` is read here, once
    (a relative path from ``base_dir``), into the typed :class:`~sinscli.sensors.SensorDescription`."""
    section = sc.mapping(src, "fusion", section)
    veh = sc.choice("command line" if vehicle is not None else src, "fusion.vehicle",
                    vehicle if vehicle is not None else section.get("vehicle", "none"), VEHICLES)
    d = _merge(_merge(FUSION_DEFAULTS, VEHICLE_PRESETS[veh], "<vehicle preset>"), section, src)
    kw = {"vehicle": veh}
    kw["states"] = int(sc.choice(src, "fusion.states", d["states"], FUSION_STATES))
    if d["sensor"] is not None and not isinstance(d["sensor"], (str, dict)):
        sc.expected(src, "fusion.sensor", "a preset name, a sensor YAML path or a mapping", d["sensor"])
    kw["sensor"] = None if d["sensor"] is None else read_sensor(d["sensor"], src, base_dir)
    kw["noise_from_data"] = _bool(src, "noise_from_data", d["noise_from_data"])
    kw["bias_model"] = sc.choice(src, "fusion.bias_model", d["bias_model"], BIAS_MODELS)
    kw["propagation_interval"] = _num(src, "propagation_interval", d["propagation_interval"], ge=0.0, le=0.1)
    kw["gate_probability"] = _num(src, "gate_probability", d["gate_probability"], gt=0.0, lt=1.0)
    if d["robust_probability"] is not None:
        kw["robust_probability"] = _num(src, "robust_probability", d["robust_probability"], gt=0.5,
                                        lt=kw["gate_probability"])
    else:
        kw["robust_probability"] = None
    kw["gnss_pos_sigma"] = _vec(src, "gnss_pos_sigma", d["gnss_pos_sigma"], 3, gt=0.0, le=MAX_POS)
    kw["gnss_vel_sigma"] = _vec(src, "gnss_vel_sigma", d["gnss_vel_sigma"], 3, gt=0.0, le=MAX_VEL)
    kw["use_gnss_velocity"] = _bool(src, "use_gnss_velocity", d["use_gnss_velocity"])
    ge = d["gnss_error"]
    if ge["tau"] != "auto":
        tau = ge["tau"] if isinstance(ge["tau"], (list, tuple)) else [ge["tau"], ge["tau"]]
        kw["gnss_error_tau"] = _vec(src, "gnss_error.tau", tau, 2, ge=0.0, le=MAX_TIME)
        if np.count_nonzero(kw["gnss_error_tau"]) == 1:
            _fail(src, "gnss_error.tau", f"expected both correlation times > 0 or both 0, got {list(tau)}")
    if ge["sigma"] is not None:
        kw["gnss_error_sigma"] = _vec(src, "gnss_error.sigma", ge["sigma"], 2, gt=0.0, le=MAX_POS)
    if d["lever_arm"] is not None:
        kw["lever_arm"] = _vec(src, "lever_arm", d["lever_arm"], 3, ge=-MAX_LEVER_ARM, le=MAX_LEVER_ARM)
    est = d["estimate"]
    if not isinstance(est, (list, tuple)) or any(e not in ESTIMABLE for e in est) or len(set(est)) != len(est):
        sc.expected(src, "fusion.estimate", f"a list of distinct names from {', '.join(ESTIMABLE)}", est)
    kw["estimate"] = tuple(e for e in ESTIMABLE if e in est)
    es = d["estimate_sigma"]
    kw["lever_arm_sigma"] = _num(src, "estimate_sigma.lever_arm", es["lever_arm"], gt=0.0, le=MAX_LEVER_ARM)
    kw["time_offset_sigma"] = _num(src, "estimate_sigma.time_offset", es["time_offset"], gt=0.0, le=MAX_TIME)
    s = d["init_sigma"]
    kw["init_pos_sigma"] = _vec(src, "init_sigma.position", s["position"], 3, gt=0.0, le=MAX_POS)
    kw["init_vel_sigma"] = _vec(src, "init_sigma.velocity", s["velocity"], 3, gt=0.0, le=MAX_VEL)
    kw["init_att_sigma"] = np.radians([_num(src, f"init_sigma.{k}", s[k], gt=0.0, le=180.0)
                                       for k in ("roll", "pitch", "heading")])
    kw["zupt"] = _bool(src, "zupt.enabled", d["zupt"]["enabled"])
    kw["zupt_sigma"] = _num(src, "zupt.sigma", d["zupt"]["sigma"], gt=0.0, le=MAX_VEL)
    kw["zupt_max_speed"] = _num(src, "zupt.max_speed", d["zupt"]["max_speed"], gt=0.0, le=MAX_VEL)
    kw["zaru"] = _bool(src, "zaru.enabled", d["zaru"]["enabled"])
    if d["zaru"]["sigma"] is not None:
        kw["zaru_sigma"] = _num(src, "zaru.sigma", d["zaru"]["sigma"], gt=0.0, le=MAX_RATE_DEG) * DEG
    ss = d["standstill"]
    kw["standstill_window"] = _num(src, "standstill.window", ss["window"], gt=0.0, le=MAX_TIME)
    kw["standstill_lowpass"] = _num(src, "standstill.lowpass", ss["lowpass"], ge=0.0, le=kw["standstill_window"] / 3)
    kw["standstill_rate_std"] = _num(src, "standstill.rate_std", ss["rate_std"], gt=0.0, le=MAX_RATE_DEG) * DEG
    kw["standstill_accel_std"] = _num(src, "standstill.accel_std", ss["accel_std"], gt=0.0)
    kw["standstill_accel_mag"] = _num(src, "standstill.accel_mag", ss["accel_mag"], gt=0.0)
    kw["nhc"] = _bool(src, "nhc.enabled", d["nhc"]["enabled"])
    kw["nhc_sigma"] = _vec(src, "nhc.sigma", d["nhc"]["sigma"], 2, gt=0.0, le=MAX_VEL)
    kw["nhc_interval"] = _num(src, "nhc.interval", d["nhc"]["interval"], gt=0.0, le=MAX_TIME)
    kw["odometry"] = _bool(src, "odometry.enabled", d["odometry"]["enabled"])
    if d["odometry"]["sigma"] is not None:
        kw["odometry_sigma"] = _num(src, "odometry.sigma", d["odometry"]["sigma"], gt=0.0, le=MAX_VEL)
    kw["odometry_sigma_floor"] = _num(src, "odometry.sigma_floor", d["odometry"]["sigma_floor"], ge=0.0, le=MAX_VEL)
    hi = d["heading_init"]
    kw["heading_max_sigma"] = _num(src, "heading_init.max_sigma", hi["max_sigma"], gt=0.0, le=180.0) * DEG
    kw["heading_max_course_sigma"] = _num(src, "heading_init.max_course_sigma", hi["max_course_sigma"], gt=0.0,
                                          le=90.0) * DEG
    kw["heading_max_baseline_time"] = _num(src, "heading_init.max_baseline_time", hi["max_baseline_time"], gt=0.0,
                                           le=MAX_TIME)
    kw["heading_min_speed"] = _num(src, "heading_init.min_speed", hi["min_speed"], ge=0.0, le=MAX_VEL)
    kw["heading_sigma_floor"] = _num(src, "heading_init.sigma_floor", hi["sigma_floor"], gt=0.0, le=180.0) * DEG
    kw["rejection_run"] = sc.integer(src, "fusion.rejection_run", d["rejection_run"], 1, MAX_COUNT)
    kw["outage"] = _num(src, "outage", d["outage"], gt=1.0, le=MAX_TIME)
    ad = d["adapt"]
    kw["adapt"] = _bool(src, "adapt.enabled", ad["enabled"])
    for k in ("measurement_noise", "outage_exits", "widen", "passes"):
        kw[f"adapt_{k}"] = _bool(src, f"adapt.{k}", ad[k])
    kw["adapt_window"] = sc.integer(src, "fusion.adapt.window", ad["window"], 2, MAX_COUNT)
    kw["adapt_max_scale"] = _num(src, "adapt.max_scale", ad["max_scale"], ge=1.0)
    kw["adapt_max_bias_scale"] = _num(src, "adapt.max_bias_scale", ad["max_bias_scale"], ge=1.0)
    kw["adapt_exit_ratio"] = _num(src, "adapt.exit_ratio", ad["exit_ratio"], gt=1.0)
    kw["adapt_decay"] = _num(src, "adapt.decay", ad["decay"], gt=0.0, le=MAX_TIME)
    kw["scale_factor_tau"] = _num(src, "scale_factor_tau", d["scale_factor_tau"], ge=0.0, le=MAX_TIME)
    kw["smoother_interval"] = _num(src, "smoother_interval", d["smoother_interval"], gt=0.0, le=MAX_TIME)
    _raw_clock(src, d, kw)
    return FusionOptions(**kw)


def _raw_clock(src, d, kw) -> None:
    """The ``fusion.raw`` and ``fusion.clock`` keys into ``kw``."""
    rw = d["raw"]
    if rw["systems"] is not None:
        if not isinstance(rw["systems"], str) or not rw["systems"] or any(c not in "GECJ" for c in rw["systems"]):
            _fail(src, "raw.systems", f"expected letters of GECJ, got {rw['systems']!r}")
        kw["raw_systems"] = rw["systems"]
    kw["raw_elevation_mask"] = _num(src, "raw.elevation_mask", rw["elevation_mask"], ge=0.0, le=90.0)
    kw["raw_code_sigma"] = _num(src, "raw.code_sigma", rw["code_sigma"], gt=0.0, le=MAX_POS)
    kw["raw_doppler_sigma"] = _num(src, "raw.doppler_sigma", rw["doppler_sigma"], gt=0.0, le=MAX_VEL)
    kw["raw_cn0_ref"] = _num(src, "raw.cn0_ref", rw["cn0_ref"], ge=0.0, le=100.0)
    if rw["iono"] not in ("auto", "klobuchar", "iflc", "off"):
        _fail(src, "raw.iono", f"expected auto, klobuchar, iflc or off, got {rw['iono']!r}")
    kw["raw_iono"] = rw["iono"]
    kw["raw_tropo"] = _bool(src, "raw.tropo", rw["tropo"])
    kw["raw_use_ura"] = _bool(src, "raw.use_ura", rw["use_ura"])
    kw["raw_iono_var"] = _num(src, "raw.iono_var", rw["iono_var"], ge=0.0, le=10.0)
    kw["raw_tropo_sigma"] = _num(src, "raw.tropo_sigma", rw["tropo_sigma"], ge=0.0, le=MAX_POS)
    kw["raw_smooth_code"] = _num(src, "raw.smooth_code", rw["smooth_code"], ge=0.0, le=3600.0)
    kw["raw_tdcp"] = _bool(src, "raw.tdcp", rw["tdcp"])
    kw["raw_carrier_sigma"] = _num(src, "raw.carrier_sigma", rw["carrier_sigma"], gt=0.0, le=1.0)
    kw["raw_slip_test"] = _num(src, "raw.slip_test", rw["slip_test"], gt=0.0, le=1e3)
    kw["raw_slip_doppler"] = _num(src, "raw.slip_doppler", rw["slip_doppler"], gt=0.0, le=MAX_POS)
    kw["raw_slip_gf"] = _num(src, "raw.slip_gf", rw["slip_gf"], gt=0.0, le=MAX_POS)
    ck = d["clock"]
    kw["clock_h0"] = _num(src, "clock.h0", ck["h0"], ge=0.0, le=1e-12)
    kw["clock_h_2"] = _num(src, "clock.h_2", ck["h_2"], ge=0.0, le=1e-12)
    kw["clock_bias_sigma"] = _num(src, "clock.bias_sigma", ck["bias_sigma"], gt=0.0, le=MAX_POS)
    kw["clock_drift_sigma"] = _num(src, "clock.drift_sigma", ck["drift_sigma"], gt=0.0, le=MAX_VEL)
    kw["clock_isb_sigma"] = _num(src, "clock.isb_sigma", ck["isb_sigma"], gt=0.0, le=MAX_POS)
    kw["clock_isb_walk"] = _num(src, "clock.isb_walk", ck["isb_walk"], ge=0.0, le=MAX_VEL)
    kw["clock_jump"] = _num(src, "clock.jump", ck["jump"], gt=0.0, le=MAX_POS)
