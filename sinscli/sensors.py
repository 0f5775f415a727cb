"""The one description of an IMU's errors: ``sinscli/data/sensors/*.yaml`` presets or a user file.

The same YAML (schema of the presets: ``gyro``/``accel`` sections with ``bias_sigma``,
``bias_instability``, ``bias_tau``, ``arw``/``vrw``, ``scale_factor_sigma``,
``misalignment_sigma``, ``quantization``; units in the comments of each preset) serves
``sins simulate`` (the errors drawn), ``sins align`` (the sigma budget) and the fusion filter
(process noise).  Presets are package data, read through :mod:`importlib.resources`, so they are
found from any working directory once the package is installed.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from .errors import SinsError, num, quote
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
MAX_VALUE = 1.0e9            # any value of a sensor description, in its units (squares stay finite)
MIN_TAU = 1.0e-6             # s: shortest Gauss-Markov correlation time


def preset_text(name: str) -> str:
    """The YAML text of a shipped preset (``navigation``, ``tactical``, ``mems``), from the package data."""
    return resources.files("sinscli").joinpath("data", "sensors", f"{name.lower()}.yaml").read_text(encoding="utf-8")


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
            raise SinsError(f"{src}: {key}: no sensor preset or file {spec!r} "
                            f"(presets: {', '.join(PRESETS)})")
        data = (parse_yaml(preset_text(spec), str(path)) if preset else load_yaml(path, "sensor file")) or {}
        where = str(path)
        if not isinstance(data, dict):
            raise SinsError(f"{path}: expected a mapping with 'gyro' and 'accel'")
    else:
        raise SinsError(f"{src}: {key}: expected a preset name, a file or a mapping; got {spec!r}")
    out = {}
    for which, units in (("gyro", GYRO_UNITS), ("accel", ACCEL_UNITS)):
        for part, name in ((data.get(which), where), ((overrides or {}).get(which), src)):
            if part is not None and not isinstance(part, dict):
                raise SinsError(f"{name}: {which}: expected a mapping of error terms, got {quote(part, 40)}")
        merged = dict(data.get(which) or {})
        merged.update((overrides or {}).get(which) or {})
        out[which] = _convert(merged, units, where, which)
    for k in data:
        if k not in ("gyro", "accel", "name", "description"):
            raise SinsError(f"{where}: {k}: unknown key; expected gyro, accel, name, description")
    return out


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _convert(d: dict, units: dict, where: str, which: str) -> dict:
    out = {}
    for k, v in d.items():
        if k not in units:
            raise SinsError(f"{where}: {which}.{k}: unknown key; expected one of {', '.join(units)}")
        n = 6 if k.startswith("misalignment") else 3
        if isinstance(v, (list, tuple)):
            if len(v) != n or not all(_number(x) for x in v):
                raise SinsError(f"{where}: {which}.{k}: expected {n} numbers or one; got {quote(v, 60)}")
            arr = np.array(v, dtype=float)
        elif _number(v):
            arr = np.full(n, float(v))
        else:
            raise SinsError(f"{where}: {which}.{k}: expected a number; got {quote(v, 60)}")
        if not np.all(np.abs(arr) <= MAX_VALUE):
            raise SinsError(f"{where}: {which}.{k}: {num(arr[np.argmax(~(np.abs(arr) <= MAX_VALUE))])} is beyond "
                            f"+-{MAX_VALUE:g}")
        if k in ("bias_tau",) and np.any(arr < MIN_TAU):
            raise SinsError(f"{where}: {which}.{k}: must be at least {MIN_TAU:g} s")
        if (k.endswith("sigma") or k in ("arw", "vrw", "bias_instability", "quantization")) and np.any(arr < 0):
            raise SinsError(f"{where}: {which}.{k}: must be >= 0")
        out[k] = arr * units[k]
    if "bias_instability" in out and "bias_tau" not in out:
        raise SinsError(f"{where}: {which}.bias_tau: required with bias_instability (s)")
    return out
