"""The one description of an IMU's errors: ``sinscli/data/sensors/*.yaml`` presets or a user file.

The same YAML (schema of the presets: ``gyro``/``accel`` sections with ``bias_sigma``,
``bias_instability``, ``bias_tau``, ``arw``/``vrw``, ``scale_factor_sigma``,
``misalignment_sigma``, ``quantization``; units in the comments of each preset) serves
``sins simulate`` (the errors drawn), ``sins align`` (the sigma budget) and the fusion filter
(process noise).  Presets are package data, read through :mod:`importlib.resources`, so they are
found from any working directory once the package is installed.

Every value is finite; the sigmas are >= 0 and the white noise (``arw``, ``vrw``) and ``bias_instability``
> 0 (:data:`POSITIVE`); a bad term is refused in one line naming the file and the key.
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from . import schema as sc
from .errors import SinsError
from .inputs import load_yaml, parse_yaml
from .units import ARCSEC, DEG_PER_H, DEG_PER_SQRT_H, G0, PPM, UG  # noqa: F401  (G0: sensors.G0 of fusion/)

# key -> factor to SI (rad/s, rad/sqrt(s), m/s^2, m/s/sqrt(s), dimensionless, rad, s)
GYRO_UNITS = {
    "bias": DEG_PER_H,                     # deg/h, fixed value(s)
    "bias_sigma": DEG_PER_H,               # deg/h, turn-on bias drawn per run
    "bias_instability": DEG_PER_H,         # deg/h, Gauss-Markov steady-state sigma
    "bias_tau": 1.0,                       # s, Gauss-Markov correlation time
    "arw": DEG_PER_SQRT_H,                 # deg/sqrt(h) -> rad/sqrt(s)
    "scale_factor": PPM,                   # ppm
    "scale_factor_sigma": PPM,             # ppm
    "misalignment": ARCSEC,                # arcsec (6 values or one)
    "misalignment_sigma": ARCSEC,          # arcsec
    "quantization": 1.0,                   # rad per count
}
ACCEL_UNITS = {
    "bias": UG,                            # micro-g
    "bias_sigma": UG,                      # micro-g
    "bias_instability": UG,                # micro-g
    "bias_tau": 1.0,                       # s
    "vrw": UG,                             # micro-g/sqrt(Hz) -> m/s/sqrt(s)
    "scale_factor": PPM,                   # ppm
    "scale_factor_sigma": PPM,             # ppm
    "misalignment": ARCSEC,                # arcsec
    "misalignment_sigma": ARCSEC,          # arcsec
    "quantization": 1.0,                   # m/s per count
}
PRESETS = ("navigation", "tactical", "mems", "consumer")
# terms that must be > 0 when given (a 0 would claim a perfect sensor, and the filters divide by them), and why;
# a 0 is allowed for: bias_sigma (written by `sins allan`, which cannot observe the turn-on bias: the stages take
# it as unknown), scale_factor_sigma and misalignment_sigma (a perfectly calibrated axis), quantization (none)
POSITIVE = {"arw": "white noise: every sensor has some; leave the key out when unknown",
            "vrw": "white noise: every sensor has some; leave the key out when unknown",
            "bias_instability": "every sensor's bias wanders; leave the key out when unknown"}
MAX_VALUE = 1.0e9            # any value of a sensor description, in its units (squares stay finite)
MIN_TAU = 1.0e-6             # s: shortest Gauss-Markov correlation time


def preset_text(name: str) -> str:
    """The YAML text of a shipped preset (``navigation``, ``tactical``, ``mems``), from the package data."""
    return resources.files("sinscli").joinpath("data", "sensors", f"{name.lower()}.yaml").read_text(encoding="utf-8")


@dataclass(frozen=True)
class SensorDescription:
    """An IMU's error description, read once and passed on as a typed value: ``gyro`` and ``accel`` map the
    keys of :data:`GYRO_UNITS` / :data:`ACCEL_UNITS` to SI values (read-only arrays); ``source`` says where it
    was read (``<preset mems>``, a file, ``FILE: fusion.sensor`` for an inline mapping)."""
    gyro: sc.FrozenMap
    accel: sc.FrozenMap
    source: str

    def as_dict(self) -> dict:
        """``{"gyro": {...}, "accel": {...}}`` of writable copies (the form :func:`load_sensor` returns)."""
        return {"gyro": {k: v.copy() for k, v in self.gyro.items()},
                "accel": {k: v.copy() for k, v in self.accel.items()}}


def read_sensor(spec, src: str, base_dir, key: str = "fusion.sensor") -> SensorDescription:
    """The :class:`SensorDescription` of a spec (preset name, sensor YAML path relative to ``base_dir``
    (None: the working directory), or an inline mapping); errors name ``src`` and ``key``."""
    sens = load_sensor(spec, None, src, Path(base_dir) if base_dir is not None else Path.cwd(), key=key)
    if isinstance(spec, dict):
        where = f"{src}: {key}"
    elif spec.lower() in ("mems", "tactical", "navigation"):
        where = f"<preset {spec}>"
    else:
        where = str(spec)

    def frozen(d):
        out = {}
        for k, v in d.items():
            v = np.array(v, dtype=float)
            v.flags.writeable = False
            out[k] = v
        return sc.FrozenMap(out)
    return SensorDescription(frozen(sens["gyro"]), frozen(sens["accel"]), where)


def load_sensor(spec, overrides: dict | None, src: str, base_dir: Path, key: str = "imu.sensor") -> dict:
    """Resolve a sensor spec (None, preset name, YAML path or mapping) plus overrides.

    Returns ``{"gyro": {key: SI value(s)}, "accel": {...}}``; ``key`` names the config key in errors.
    """
    data: dict = {}
    where = src
    if spec is None:
        data = {}
    elif isinstance(spec, dict):
        data = spec
    elif isinstance(spec, str):
        preset = spec.lower() in PRESETS
        path = Path(f"<preset {spec.lower()}>") if preset else Path(spec)
        if not preset and not path.is_absolute():
            path = base_dir / path
        if not preset and not path.exists():
            sc.fail(src, key, f"no sensor preset or file {spec!r} (presets: {', '.join(PRESETS)})")
        data = (parse_yaml(preset_text(spec), str(path)) if preset else load_yaml(path, "sensor file")) or {}
        where = str(path)
        if not isinstance(data, dict):
            raise SinsError(f"{path}: expected a mapping with 'gyro' and 'accel'")
    else:
        sc.expected(src, key, "a preset name, a file or a mapping", spec)
    out = {}
    for which, units in (("gyro", GYRO_UNITS), ("accel", ACCEL_UNITS)):
        for part, name in ((data.get(which), where), ((overrides or {}).get(which), src)):
            if part is not None and not isinstance(part, dict):
                sc.expected(name, which, "a mapping of error terms", part)
        merged = dict(data.get(which) or {})
        merged.update((overrides or {}).get(which) or {})
        out[which] = _convert(merged, units, where, which)
    for k in data:
        if k not in ("gyro", "accel", "name", "description"):
            sc.fail(where, k, "unknown key; expected one of accel, description, gyro, name")
    return out


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _convert(d: dict, units: dict, where: str, which: str) -> dict:
    out = {}
    for k, v in d.items():
        if k not in units:
            sc.fail(where, f"{which}.{k}", f"unknown key; expected one of {', '.join(units)}")
        n = 6 if k.startswith("misalignment") else 3
        if isinstance(v, (list, tuple)):
            if len(v) != n or not all(_number(x) for x in v):
                sc.expected(where, f"{which}.{k}", f"{n} numbers or one", v)
            arr = np.array(v, dtype=float)
        elif _number(v):
            arr = np.full(n, float(v))
        else:
            sc.expected(where, f"{which}.{k}", "a number", v)
        if not np.all(np.isfinite(arr)):
            sc.expected(where, f"{which}.{k}", "finite numbers", arr[np.argmax(~np.isfinite(arr))])
        if not np.all(np.abs(arr) <= MAX_VALUE):
            sc.expected(where, f"{which}.{k}", f"numbers within +-{MAX_VALUE:g}",
                        arr[np.argmax(~(np.abs(arr) <= MAX_VALUE))])
        if k in ("bias_tau",) and np.any(arr < MIN_TAU):
            sc.expected(where, f"{which}.{k}", f"at least {MIN_TAU:g} s", float(np.min(arr)))
        if k in POSITIVE and np.any(arr <= 0):
            sc.expected(where, f"{which}.{k}", f"numbers > 0 ({POSITIVE[k]})", float(np.min(arr)))
        if (k.endswith("sigma") or k == "quantization") and np.any(arr < 0):
            sc.expected(where, f"{which}.{k}", "numbers >= 0", float(np.min(arr)))
        out[k] = arr * units[k]
    if "bias_instability" in out and "bias_tau" not in out:
        sc.fail(where, f"{which}.bias_tau", "required with bias_instability (s)")
    return out
