"""Navigation frame and angle units of the init, GNSS and truth files (config ``init``, ``gnss``, ``truth``
sections: ``frame: enu | ned``, ``units: {angle: deg | rad}``; configs/navigation.yaml).

docs/formats.md files are ENU with angles in degrees.  A NED file names its vertical velocity ``vel_d`` (and its
sigmas ``std_d``, ``std_vel_d``) in place of ``vel_u`` (``std_u``, ``std_vel_u``), positive down, and its
attitude (``c11..c33``, the quaternion) is body -> NED; the readers turn it into ENU.  With ``rad``,
``lat``, ``lon``, ``roll``, ``pitch`` and ``heading`` are radians.  The physical Euler angles are the same in
both frames (heading from north, clockwise), and the body axes are the file's own (FRD usual with NED:
docs/io_formats.md).
"""
from __future__ import annotations

import math

import numpy as np

FRAMES = ("enu", "ned")
ANGLE_UNITS = {"deg": 1.0, "rad": 180.0 / math.pi}          # factor to degrees
C_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])   # v_enu = C v_ned (its own inverse)
# vertical names: ENU name -> NED name
NED_NAMES = {"vel_u": "vel_d", "std_u": "std_d", "std_vel_u": "std_vel_d"}
ANGLE_COLUMNS = ("lat", "lon", "roll", "pitch", "heading")


def convention(section: dict | None) -> tuple[str, float]:
    """``(frame, factor to degrees)`` of a validated config section (defaults: ENU, degrees)."""
    section = section or {}
    return section.get("frame", "enu"), ANGLE_UNITS[(section.get("units") or {}).get("angle", "deg")]


def file_name(name: str, frame: str) -> str:
    """The column or key name a file of ``frame`` uses for the docs/formats.md (ENU) ``name``."""
    return NED_NAMES.get(name, name) if frame == "ned" else name


def to_enu(data: dict, frame: str, to_deg: float) -> dict:
    """docs/formats.md values (ENU, degrees) from a file's columns or keys (names already the ENU ones; the NED
    vertical velocity negated); non-numeric values are left alone."""
    out = dict(data)
    if to_deg != 1.0:
        for k in ANGLE_COLUMNS:
            if k in out and not isinstance(out[k], (bool, str)) and out[k] is not None:
                out[k] = out[k] * to_deg
    if frame == "ned" and "vel_u" in out and not isinstance(out["vel_u"], (bool, str)) and out["vel_u"] is not None:
        out["vel_u"] = -out["vel_u"]
    return out


def cbn_to_enu(cbn: np.ndarray, frame: str) -> np.ndarray:
    """Body -> ENU attitude from a file's body -> ``frame`` one ((N, 3, 3) or (3, 3))."""
    return cbn if frame != "ned" else np.matmul(C_NED_ENU, cbn)


def validate_section(section: dict, name: str, fail) -> None:
    """Check ``frame`` and ``units`` of a config section (``fail(key, message)`` raises)."""
    frame = section.get("frame", "enu")
    if isinstance(frame, str):
        frame = frame.lower()
        section["frame"] = frame
    if frame not in FRAMES:
        fail(f"{name}.frame", f"expected one of {', '.join(FRAMES)}, got {frame!r}")
    units = section.get("units") or {}
    if not isinstance(units, dict):
        fail(f"{name}.units", "expected a mapping like {angle: rad}")
    for k, v in units.items():
        if k != "angle":
            fail(f"{name}.units.{k}", "unknown quantity; expected angle")
        if not isinstance(v, str) or v not in ANGLE_UNITS:
            fail(f"{name}.units.{k}", f"expected one of {', '.join(ANGLE_UNITS)}, got {v!r}")
    section["units"] = {"angle": units.get("angle", "deg")}
