"""Scenario files: YAML loading and validation into a :class:`Scenario`.

Every refusal is one ``SinsError`` line that names the file and the key, e.g.
``vehicle.yaml: segments[3].type: unknown segment type 'fly'; expected one of ...``.
Units in files: degrees, metres, seconds, Hz, m/s, m/s^2 (docs/simulate.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import schema as sc
from ..config import mounting_matrix
from ..errors import SinsError
from ..inputs import load_yaml
from ..nav.rotation import BODY_CONVENTIONS
from ..sensors import ACCEL_UNITS, GYRO_UNITS
from ..units import G0, MG, UG
from .environment import Environment
from .flex import Flex
from .gait import Gait
from .imu_synth import GRAVITY_MODELS
from .segments import AXES

# Segment type -> (required keys, optional keys, groups of which exactly one is required)
SEGMENT_SCHEMA: dict[str, tuple[set, set, list]] = {
    "rest": (set(), set(), []),
    "cruise": (set(), set(), []),
    "accelerate": (set(), {"speed", "accel"}, [("speed", "accel")]),
    "decelerate": (set(), {"speed", "accel"}, [("speed", "accel")]),
    "turn": (set(), {"angle", "rate", "bank"}, [("angle", "rate")]),
    "climb": ({"pitch"}, {"transition"}, []),
    "descend": ({"pitch"}, {"transition"}, []),
    "pitch": (set(), {"angle", "rate"}, [("angle", "rate")]),
    "pull_up": (set(), {"angle", "rate"}, [("angle", "rate")]),
    "pitch_over": (set(), {"angle", "rate"}, [("angle", "rate")]),
    "loop": (set(), {"angle"}, []),
    "roll": (set(), {"angle", "rate"}, [("angle", "rate")]),
    "maneuver": (set(), {"heading", "pitch", "roll", "speed", "heading_rate", "pitch_rate", "roll_rate",
                         "accel", "bank"}, []),
    "coning": ({"half_angle", "freq"}, {"ramp"}, []),
    "sculling": ({"freq"}, {"angle", "accel", "axis", "accel_axis", "ramp"}, []),
    "boost": ({"accel"}, {"spin", "ramp", "pitch"}, []),
}
COMMON_SEGMENT_KEYS = {"type", "duration", "label"}
NON_NUMERIC = {"bank", "axis", "accel_axis", "label", "type"}
POSITIVE = {"freq", "half_angle"}
NONNEGATIVE = {"speed", "ramp", "transition"}

TOP_KEYS = {"name", "description", "seed", "duration", "start", "imu", "gnss", "gravity", "body", "segments",
            "vibration", "gait", "odometry", "temperature", "mount_flex", "vehicle"}
START_KEYS = {"time", "lat", "lon", "height", "heading", "pitch", "roll", "speed"}
IMU_KEYS = {"rate", "sensor", "gyro", "accel", "output", "stamp_jitter", "time_offset", "mounting",
            "quantization", "g_sensitivity", "vibration_rectification", "dropped"}
GNSS_KEYS = {"rate", "pos_noise", "vel_noise", "lever_arm", "outages", "velocity", "pos_tau", "vel_tau",
             "reported_pos_sigma", "reported_vel_sigma", "time_offset", "float", "jumps"}
QUANTIZATION_KEYS = {"gyro", "accel"}
DROPPED_KEYS = {"fraction", "run"}
TEMPERATURE_KEYS = {"rise", "tau", "swing", "period", "gyro", "accel"}
FLEX_KEYS = {"roll", "pitch", "yaw", "tau"}
VEHICLE_KEYS = {"sideslip"}
FLOAT_KEYS = {"windows", "sigma", "walk", "drift", "reported"}
JUMP_KEYS = {"start", "duration", "offset"}
MAX_SIDESLIP = 30.0              # deg/g: a larger slip gradient is no road vehicle's
VIBRATION_KEYS = {"gyro_rms", "accel_rms", "band", "lines", "seed", "ramp"}
GAIT_KEYS = {"speed", "step_freq", "bob", "surge", "sway", "wobble"}
ODOMETRY_KEYS = {"rate", "scale_factor", "noise", "reported_sigma"}
IMU_OUTPUTS = ("increments", "rates")
MAX_OFFSET = 1.0e4               # s: largest clock offset of a simulated log


@dataclass
class Scenario:
    """A validated scenario (SI units, radians)."""
    name: str
    source: str                    # name used in messages
    base_dir: Path                 # for relative sensor paths
    seed: int | None
    duration: float                # s, total
    t0: float                      # s, start epoch
    lat0: float                    # rad
    lon0: float                    # rad
    h0: float                      # m
    x_start: np.ndarray            # (heading, pitch, roll, speed) rad, m/s
    start_deg: dict                # the start as written: lat, lon (deg), height (m), heading (deg)
    imu_rate: float                # Hz
    sensor: object                 # None, preset name, path or mapping (resolved in errors.py)
    sensor_overrides: dict         # {"gyro": {...}, "accel": {...}}
    gnss: dict                     # normalized GNSS settings (see _gnss)
    gravity: str
    conv: int                      # output body convention code
    segments: list[dict]
    description: str = ""
    raw: dict = field(default_factory=dict)
    # issue 19 (all off by default; see docs/simulate.md)
    imu_output: str = "increments"                 # increments | rates
    stamp_jitter: float = 0.0                      # s, written IMU stamps uniform in [-j, j] of the true instant
    imu_time_offset: float = 0.0                   # s, written IMU stamps = true time + offset
    mounting: np.ndarray | None = None             # C_sensor^body (imu.mounting of the navigation config)
    mounting_raw: object = None                    # imu.mounting as written
    vibration: dict | None = None                  # validated vibration section (SI)
    gait: object = None                            # sim.gait.Gait or None
    odometry: dict | None = None                   # validated odometry section
    # realism terms of real logs (all off by default; docs/simulate.md "As hard as real logs")
    quantization: dict | None = None               # {"gyro": rad/s, "accel": m/s^2} step of the written values
    environment: Environment = field(default_factory=Environment)   # g-sensitivity, rectification, temperature
    dropped: dict | None = None                    # {"fraction", "run": (min, max)}
    flex: Flex | None = None                       # the mount's flex under the body's acceleration
    sideslip: float = 0.0                          # rad per m/s^2: slip angle per lateral acceleration


def load_scenario(scenario) -> Scenario:
    """A :class:`Scenario` from a mapping or a YAML file path; raises ``SinsError`` on bad input."""
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, dict):
        return validate(scenario, "<scenario>", Path.cwd())
    path = Path(scenario)
    data = load_yaml(path, "scenario")
    if not isinstance(data, dict):
        raise SinsError(f"{path}: expected a mapping of scenario keys at the top level")
    return validate(data, str(path), path.parent)


# the one validator family (sinscli.schema): ``SRC: key KEY: MESSAGE``
def _fail(src, key, msg):
    sc.fail(src, key, msg)


def _number(src, key, value, *, gt=None, ge=None):
    return sc.number(src, key, value, gt=gt, ge=ge, limit=math.inf)


def _vector(src, key, value, n=3, ge=None):
    """A scalar (broadcast) or a list of ``n`` numbers."""
    return np.array(sc.vector(src, key, value, n, ge=ge, limit=math.inf))


def _mapping(src, key, value, allowed):
    return sc.mapping(src, key, value, allowed)


def validate(data: dict, src: str, base_dir: Path) -> Scenario:
    """Check every key of a scenario mapping; return the :class:`Scenario`."""
    for k in data:
        if k not in TOP_KEYS:
            _fail(src, k, f"unknown key {k!r}; expected one of {', '.join(sorted(TOP_KEYS))}")
    deg = np.pi / 180.0
    start = _mapping(src, "start", data.get("start"), START_KEYS)
    for k in ("lat", "lon"):
        if k not in start:
            _fail(src, f"start.{k}", "required (degrees)")
    lat = _number(src, "start.lat", start["lat"])
    if abs(lat) >= 89.9:
        _fail(src, "start.lat", f"must be within (-89.9, 89.9) degrees (ENU is singular at the poles); got {lat:g}")
    lon = _number(src, "start.lon", start["lon"])
    h = _number(src, "start.height", start.get("height", 0.0))
    x_start = np.array([_number(src, "start.heading", start.get("heading", 0.0)) * deg,
                        _number(src, "start.pitch", start.get("pitch", 0.0)) * deg,
                        _number(src, "start.roll", start.get("roll", 0.0)) * deg,
                        _number(src, "start.speed", start.get("speed", 0.0), ge=0.0)])
    t0 = _number(src, "start.time", start.get("time", 0.0))

    imu = _mapping(src, "imu", data.get("imu"), IMU_KEYS)
    if "rate" not in imu:
        _fail(src, "imu.rate", "required (Hz)")
    rate = _number(src, "imu.rate", imu["rate"], ge=1.0)           # Hz
    overrides = {k: _mapping(src, f"imu.{k}", imu.get(k), _sensor_keys(k)) for k in ("gyro", "accel")}
    output = sc.choice(src, "imu.output", imu.get("output", "increments"), IMU_OUTPUTS)
    jitter = _number(src, "imu.stamp_jitter", imu.get("stamp_jitter", 0.0), ge=0.0)
    if not jitter < 0.5 / rate:
        _fail(src, "imu.stamp_jitter", f"must be below half the IMU interval ({0.5 / rate:g} s) so that the "
                                       f"stamps stay strictly increasing; got {jitter:g}")
    imu_offset = _offset(src, "imu.time_offset", imu.get("time_offset", 0.0))
    mounting = None
    if imu.get("mounting") is not None:
        mounting = mounting_matrix(imu["mounting"], src)

    gnss = _gnss(src, _mapping(src, "gnss", data.get("gnss", {}), GNSS_KEYS), rate)
    vibration = _vibration(src, _mapping(src, "vibration", data.get("vibration"), VIBRATION_KEYS), rate) \
        if data.get("vibration") is not None else None
    gait = _gait(src, _mapping(src, "gait", data.get("gait"), GAIT_KEYS)) if data.get("gait") is not None else None
    odometry = _odometry(src, _mapping(src, "odometry", data.get("odometry"), ODOMETRY_KEYS), rate) \
        if data.get("odometry") is not None else None
    quantization = _quantization(src, _mapping(src, "imu.quantization", imu.get("quantization"), QUANTIZATION_KEYS))
    environment = Environment(
        g_sensitivity=_g_sensitivity(src, imu.get("g_sensitivity")),
        rectification=_rectification(src, imu.get("vibration_rectification")),
        temperature=_temperature(src, _mapping(src, "temperature", data.get("temperature"), TEMPERATURE_KEYS)))
    dropped = _dropped(src, _mapping(src, "imu.dropped", imu.get("dropped"), DROPPED_KEYS))
    flex = _flex(src, _mapping(src, "mount_flex", data.get("mount_flex"), FLEX_KEYS))
    vehicle = _mapping(src, "vehicle", data.get("vehicle"), VEHICLE_KEYS)
    slip = _number(src, "vehicle.sideslip", vehicle.get("sideslip", 0.0))
    if abs(slip) > MAX_SIDESLIP:
        _fail(src, "vehicle.sideslip", f"expected a slip gradient within +-{MAX_SIDESLIP:g} deg/g; got {slip:g}")

    gravity = data.get("gravity", "normal")
    if gravity not in GRAVITY_MODELS:
        _fail(src, "gravity", f"unknown gravity model {gravity!r}; expected one of {', '.join(GRAVITY_MODELS)}")
    body = data.get("body", "flu")
    if not isinstance(body, str) or body.lower() not in BODY_CONVENTIONS:
        _fail(src, "body", f"unknown body convention {body!r}; expected one of {', '.join(BODY_CONVENTIONS)}")

    segs = data.get("segments")
    if not isinstance(segs, list) or not segs:
        _fail(src, "segments", "expected a non-empty list of motion segments")
    segments = [_segment(src, i, s) for i, s in enumerate(segs)]
    total = sum(s["duration"] for s in segments)
    duration = total
    if data.get("duration") is not None:
        duration = _number(src, "duration", data["duration"], gt=0.0)
        if duration > total * (1.0 + 1e-12):
            _fail(src, "duration", f"{duration:g} s is longer than the segments' total {total:g} s")
    if duration * rate < 1.0:
        _fail(src, "duration", f"{duration:g} s holds no IMU interval at {rate:g} Hz")
    seed = data.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        _fail(src, "seed", f"expected a non-negative integer; got {seed!r}")
    name = str(data.get("name", Path(src).stem if src != "<scenario>" else "scenario"))
    return Scenario(name=name, source=src, base_dir=base_dir, seed=seed, duration=duration, t0=t0,
                    lat0=lat * deg, lon0=lon * deg, h0=h, x_start=x_start,
                    start_deg={"lat": lat, "lon": lon, "height": h,
                               "heading": _number(src, "start.heading", start.get("heading", 0.0))},
                    imu_rate=rate,
                    sensor=imu.get("sensor"), sensor_overrides=overrides, gnss=gnss, gravity=gravity,
                    conv=BODY_CONVENTIONS[body.lower()], segments=segments,
                    description=str(data.get("description", "")), raw=data,
                    imu_output=output, stamp_jitter=jitter, imu_time_offset=imu_offset, mounting=mounting,
                    mounting_raw=imu.get("mounting"), vibration=vibration, gait=gait, odometry=odometry,
                    quantization=quantization, environment=environment, dropped=dropped, flex=flex,
                    sideslip=slip * deg / G0)


def _offset(src, key, value):
    v = _number(src, key, value)
    if abs(v) > MAX_OFFSET:
        _fail(src, key, f"expected a clock offset within +-{MAX_OFFSET:g} s; got {v:g}")
    return v


def _positive_vector(src, key, value, n=3):
    v = _vector(src, key, value, n, ge=0.0)
    if not np.all(v > 0):
        _fail(src, key, "must be > 0 (a file never carries a sigma of 0)")
    return v


def _vibration(src, v, imu_rate):
    """Engine vibration of the mount: rate / specific-force RMS per axis, band (Hz), lines per axis, seed."""
    deg = np.pi / 180.0
    band = v.get("band", [20.0, 40.0])
    if not isinstance(band, (list, tuple)) or len(band) != 2:
        _fail(src, "vibration.band", f"expected [low, high] in Hz; got {band!r}")
    lo = _number(src, "vibration.band[0]", band[0], gt=0.0)
    hi = _number(src, "vibration.band[1]", band[1], gt=0.0)
    if not hi >= lo:
        _fail(src, "vibration.band", f"high {hi:g} Hz must be at least low {lo:g} Hz")
    if hi > 0.5 * imu_rate:
        _fail(src, "vibration.band", f"{hi:g} Hz is above the IMU's Nyquist frequency {0.5 * imu_rate:g} Hz")
    lines = v.get("lines", 4)
    if isinstance(lines, bool) or not isinstance(lines, int) or not 1 <= lines <= 64:
        _fail(src, "vibration.lines", f"expected an integer 1..64 (sinusoids per axis); got {lines!r}")
    seed = v.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        _fail(src, "vibration.seed", f"expected a non-negative integer; got {seed!r}")
    return {"gyro_rms": _vector(src, "vibration.gyro_rms", v.get("gyro_rms", 0.0), ge=0.0) * deg,
            "accel_rms": _vector(src, "vibration.accel_rms", v.get("accel_rms", 0.0), ge=0.0),
            "band": (lo, hi), "lines": lines, "seed": seed,
            "ramp": _number(src, "vibration.ramp", v.get("ramp", 1.0), ge=0.0)}


def _gait(src, g):
    """Walker step dynamics (docs/simulate.md): amplitudes at the reference speed."""
    speed = _number(src, "gait.speed", g.get("speed", 1.3), gt=0.0)
    surge = _number(src, "gait.surge", g.get("surge", 0.15), ge=0.0)
    if not surge < speed:
        _fail(src, "gait.surge", f"must be below gait.speed ({speed:g} m/s) so that the walker never walks "
                                 f"backwards; got {surge:g}")
    return Gait(speed=speed, step_freq=_number(src, "gait.step_freq", g.get("step_freq", 1.9), gt=0.0),
                bob=_number(src, "gait.bob", g.get("bob", 0.03), ge=0.0), surge=surge,
                sway=_number(src, "gait.sway", g.get("sway", 0.02), ge=0.0),
                wobble=_vector(src, "gait.wobble", g.get("wobble", [2.0, 3.0, 2.0]), ge=0.0) * np.pi / 180.0)


def _odometry(src, o, imu_rate):
    """Wheel odometry: body velocity at ``rate`` (a divisor of the IMU rate) with scale error and noise."""
    rate = _number(src, "odometry.rate", o.get("rate", 10.0), gt=0.0)
    step = imu_rate / rate
    if rate > imu_rate or abs(step - round(step)) > 1e-9 * step:
        _fail(src, "odometry.rate", f"must divide the IMU rate {imu_rate:g} Hz (odometry at every k-th IMU "
                                    f"instant); got {rate:g}")
    out = {"rate": rate, "step": int(round(step)),
           "scale_factor": _number(src, "odometry.scale_factor", o.get("scale_factor", 0.0), gt=-0.5),
           "noise": _vector(src, "odometry.noise", o.get("noise", 0.0), ge=0.0), "reported_sigma": None}
    if out["scale_factor"] > 0.5:
        _fail(src, "odometry.scale_factor", f"expected a fraction within +-0.5 (0.02: reads 2 % fast); "
                                            f"got {out['scale_factor']:g}")
    if o.get("reported_sigma") is not None:
        out["reported_sigma"] = _positive_vector(src, "odometry.reported_sigma", o["reported_sigma"])
    return out


def _sensor_keys(which):
    return set(GYRO_UNITS if which == "gyro" else ACCEL_UNITS)


def _gnss(src, g, imu_rate):
    rate = _number(src, "gnss.rate", g.get("rate", 1.0), gt=0.0)
    if rate > imu_rate:
        _fail(src, "gnss.rate", f"{rate:g} Hz is above the IMU rate {imu_rate:g} Hz")
    outs = _windows(src, "gnss.outages", g.get("outages", []))
    velocity = g.get("velocity", True)
    if not isinstance(velocity, bool):
        _fail(src, "gnss.velocity", f"expected true or false; got {velocity!r}")
    out = {"rate": rate,
           "pos_noise": _vector(src, "gnss.pos_noise", g.get("pos_noise", 0.0), ge=0.0),
           "vel_noise": _vector(src, "gnss.vel_noise", g.get("vel_noise", 0.0), ge=0.0),
           "lever_arm": _vector(src, "gnss.lever_arm", g.get("lever_arm", 0.0)),
           "outages": outs, "velocity": velocity,
           "pos_tau": _vector(src, "gnss.pos_tau", g.get("pos_tau", 0.0), ge=0.0),
           "vel_tau": _vector(src, "gnss.vel_tau", g.get("vel_tau", 0.0), ge=0.0),
           "time_offset": _offset(src, "gnss.time_offset", g.get("time_offset", 0.0))}
    for k in ("reported_pos_sigma", "reported_vel_sigma"):
        out[k] = _positive_vector(src, f"gnss.{k}", g[k]) if g.get(k) is not None else None
    if out["reported_vel_sigma"] is not None and not velocity:
        _fail(src, "gnss.reported_vel_sigma", "given with gnss.velocity: false (no velocity columns)")
    out["float"] = None
    if g.get("float") is not None:
        if out["reported_pos_sigma"] is None and not np.all(out["pos_noise"] > 0):
            _fail(src, "gnss.float", "needs the fixed epochs' sigma: gnss.pos_noise > 0 on every axis or "
                                     "gnss.reported_pos_sigma")
        out["float"] = _float(src, _mapping(src, "gnss.float", g["float"], FLOAT_KEYS), out["pos_noise"])
    out["jumps"] = _jumps(src, g.get("jumps"))
    if out["jumps"] and out["reported_pos_sigma"] is None and not np.all(out["pos_noise"] > 0):
        _fail(src, "gnss.jumps", "needs the fixed epochs' sigma (the one a wrong fix reports): gnss.pos_noise > 0 "
                                 "on every axis or gnss.reported_pos_sigma")
    return out


def _windows(src, key, value):
    """``[[start, end], ...]`` (s since the start, end after start) as a list of pairs."""
    value = value or []
    if not isinstance(value, list):
        _fail(src, key, "expected a list of [start, end] pairs (s since the start)")
    outs = []
    for i, o in enumerate(value):
        if not isinstance(o, (list, tuple)) or len(o) != 2:
            _fail(src, f"{key}[{i}]", f"expected [start, end] in s since the start; got {o!r}")
        a = _number(src, f"{key}[{i}][0]", o[0], ge=0.0)
        b = _number(src, f"{key}[{i}][1]", o[1])
        if b <= a:
            _fail(src, f"{key}[{i}]", f"end {b:g} must be after start {a:g}")
        outs.append((a, b))
    return outs


def _float(src, f, pos_noise):
    """RTK float windows (:mod:`.rtk`): windows, sigma (m), walk (m/sqrt(s)), drift (m/s), reported (m)."""
    if "windows" not in f:
        _fail(src, "gnss.float.windows", "required: a list of [start, end] (s since the start)")
    sigma = _positive_vector(src, "gnss.float.sigma", f.get("sigma", [0.1, 0.1, 0.2]))
    rep = f.get("reported")
    return {"windows": _windows(src, "gnss.float.windows", f["windows"]), "sigma": sigma,
            "walk": _vector(src, "gnss.float.walk", f.get("walk", 0.0), ge=0.0),
            "drift": _vector(src, "gnss.float.drift", f.get("drift", 0.0), ge=0.0),
            "reported": np.sqrt(pos_noise ** 2 + sigma ** 2) if rep is None
            else _positive_vector(src, "gnss.float.reported", rep)}


def _jumps(src, value):
    """Wrong fixes (:mod:`.rtk`): a list of ``{start: s, duration: s, offset: [E, N, U] m}``."""
    if value is None:
        return []
    if not isinstance(value, list):
        _fail(src, "gnss.jumps", "expected a list of {start, duration, offset} (s, s, [E, N, U] m)")
    out = []
    for i, j in enumerate(value):
        key = f"gnss.jumps[{i}]"
        j = _mapping(src, key, j, JUMP_KEYS)
        for k in JUMP_KEYS:
            if k not in j:
                _fail(src, f"{key}.{k}", "required (start s since the start, duration s, offset [E, N, U] m)")
        out.append({"start": _number(src, f"{key}.start", j["start"], ge=0.0),
                    "duration": _number(src, f"{key}.duration", j["duration"], gt=0.0),
                    "offset": np.array(sc.vector(src, f"{key}.offset", j["offset"], 3, scalar=False,
                                                 limit=1.0e4))})
    return out


def _quantization(src, q):
    """Steps of the written values: gyro deg/s, accel mg (0 or absent: none); None when both are off."""
    gyro = _number(src, "imu.quantization.gyro", q.get("gyro", 0.0), ge=0.0)
    accel = _number(src, "imu.quantization.accel", q.get("accel", 0.0), ge=0.0)
    if gyro == 0.0 and accel == 0.0:
        return None
    return {"gyro": gyro * np.pi / 180.0, "accel": accel * MG}


def _g_sensitivity(src, v):
    """Gyro bias per specific force, deg/s per g: one number or three (diagonal), or a 3x3 matrix (row: gyro
    axis, column: specific-force axis; sensor axes); in rad/s per m/s^2."""
    if v is None:
        return None
    key = "imu.g_sensitivity"
    if isinstance(v, (list, tuple)) and v and all(isinstance(r, (list, tuple)) for r in v):
        if len(v) != 3:
            _fail(src, key, f"expected one number, three, or a 3x3 matrix (deg/s per g); got {len(v)} rows")
        m = np.array([sc.vector(src, f"{key}[{i}]", r, 3, scalar=False, limit=100.0) for i, r in enumerate(v)])
    else:
        m = np.diag(sc.vector(src, key, v, 3, limit=100.0))
    return m * (np.pi / 180.0) / G0


def _rectification(src, v):
    """The accelerometer's second-order coefficient K2, micro-g per g^2 (one number or three); in 1/(m/s^2)."""
    if v is None:
        return None
    k2 = np.array(sc.vector(src, "imu.vibration_rectification", v, 3, limit=1.0e6))
    return k2 * UG / (G0 * G0)


def _temperature(src, t):
    """Temperature drift (:mod:`.environment`): profile (K, s) and coefficients (gyro deg/s/K, accel mg/K)."""
    if not t:
        return None
    rise = _number(src, "temperature.rise", t.get("rise", 0.0))
    swing = _number(src, "temperature.swing", t.get("swing", 0.0), ge=0.0)
    return {"rise": rise, "tau": _number(src, "temperature.tau", t.get("tau", 600.0), gt=0.0),
            "swing": swing, "period": _number(src, "temperature.period", t.get("period", 1800.0), gt=0.0),
            "gyro": np.array(sc.vector(src, "temperature.gyro", t.get("gyro", 0.0), 3, limit=10.0)) * np.pi / 180.0,
            "accel": np.array(sc.vector(src, "temperature.accel", t.get("accel", 0.0), 3, limit=1.0e3)) * MG}


def _dropped(src, d):
    """Dropped IMU rows (:mod:`.recorder`): fraction in [0, 1), run lengths [min, max] (or one number)."""
    if not d:
        return None
    frac = sc.number(src, "imu.dropped.fraction", d.get("fraction", 0.0), ge=0.0, lt=1.0)
    run = d.get("run", 1)
    if isinstance(run, (list, tuple)):
        if len(run) != 2:
            _fail(src, "imu.dropped.run", f"expected a length or [min, max] (rows); got {run!r}")
        lo = sc.integer(src, "imu.dropped.run[0]", run[0], 1, 10 ** 6)
        hi = sc.integer(src, "imu.dropped.run[1]", run[1], 1, 10 ** 6)
        if hi < lo:
            _fail(src, "imu.dropped.run", f"max {hi} must be at least min {lo}")
    else:
        lo = hi = sc.integer(src, "imu.dropped.run", run, 1, 10 ** 6)
    return None if frac == 0.0 else {"fraction": frac, "run": (lo, hi)}


def _flex(src, f):
    """Mount flex (:mod:`.flex`): gains deg per m/s^2 (roll and yaw per lateral, pitch per longitudinal
    acceleration), time constant s."""
    if not f:
        return None
    deg = np.pi / 180.0
    gain = np.array([_number(src, f"mount_flex.{k}", f.get(k, 0.0)) for k in ("roll", "pitch", "yaw")])
    if np.any(np.abs(gain) > 5.0):
        _fail(src, "mount_flex", f"gains within +-5 deg per m/s^2 (a mount that turns by degrees per m/s^2 is "
                                 f"loose); got {gain.tolist()}")
    tau = _number(src, "mount_flex.tau", f.get("tau", 0.3), gt=0.0)
    return None if not np.any(gain) else Flex(gain * deg, tau)


def _segment(src, i, s):
    key = f"segments[{i}]"
    if not isinstance(s, dict):
        _fail(src, key, f"expected a mapping with a 'type'; got {s!r}")
    kind = s.get("type")
    if kind not in SEGMENT_SCHEMA:
        _fail(src, f"{key}.type", f"unknown segment type {kind!r}; expected one of {', '.join(sorted(SEGMENT_SCHEMA))}")
    required, optional, groups = SEGMENT_SCHEMA[kind]
    allowed = required | optional | COMMON_SEGMENT_KEYS
    for k in s:
        if k not in allowed:
            _fail(src, f"{key}.{k}", f"unknown key {k!r} for segment type {kind!r}; "
                                      f"expected one of {', '.join(sorted(allowed - {'type'}))}")
    if "duration" not in s:
        _fail(src, f"{key}.duration", "required (s)")
    out = {"type": kind, "duration": _number(src, f"{key}.duration", s["duration"], gt=0.0)}
    for k in required:
        if k not in s:
            _fail(src, f"{key}.{k}", f"required for segment type {kind!r}")
    for grp in groups:
        present = [k for k in grp if k in s]
        if len(present) != 1:
            _fail(src, f"{key}", f"segment type {kind!r} needs exactly one of {', '.join(grp)}")
    for k, v in s.items():
        if k in ("type", "duration"):
            continue
        if k in ("axis", "accel_axis"):
            if v not in AXES:
                _fail(src, f"{key}.{k}", f"expected one of x, y, z; got {v!r}")
            out[k] = v
        elif k == "bank":
            if v not in ("coordinated", "none", True, False):
                _fail(src, f"{key}.bank", f"expected 'coordinated' or 'none'; got {v!r}")
            out[k] = v
        elif k == "label":
            out[k] = str(v)
        else:
            out[k] = _number(src, f"{key}.{k}", v, gt=0.0 if k in POSITIVE else None,
                             ge=0.0 if k in NONNEGATIVE else None)
    if kind == "boost" and out["accel"] == 0.0:
        _fail(src, f"{key}.accel", "a boost needs a non-zero acceleration")
    return out
