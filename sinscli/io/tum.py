"""TUM trajectory format (``evo``, TUM RGB-D benchmark): ``time tx ty tz qx qy qz qw`` per line.

Position is in a local ENU frame whose origin is the trajectory's first point
(kept in a ``#`` comment line, which ``evo`` skips); the quaternion is the
attitude of the FLU body axes (x forward, y left, z up, REP-103) in that ENU
frame, scalar last as the format wants.  Floats are written in shortest
round-trip form.

The format is fixed at 8 columns (``evo`` and the TUM tools refuse more), so
it cannot carry the 1-sigma and bias columns of an aided trajectory: they are
left out (write ``.csv``, ``.parquet``, ``.mcap``, ``.geojson`` or ``.kml`` to
keep them).
"""
from __future__ import annotations

import logging
import re

import numpy as np

from ..errors import SinsError
from ..nav.earth import local_enu_to_lla
from ..nav.rotation import cbn_from_flu, quat_to_dcm_many
from ..types import Trajectory
from . import limits as limits_mod
from .atomic import atomic_path, output_lon_lat
from ..inputs import input_file
from .local_frame import trajectory_enu_quat

TUM_COLUMNS = ("time", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
_ORIGIN_RE = re.compile(r"origin_lat_deg=(\S+)\s+origin_lon_deg=(\S+)\s+origin_height_m=(\S+)")


def _fmt(a: np.ndarray) -> list[str]:
    return [repr(x) for x in np.asarray(a, dtype=np.float64).tolist()]


def write_tum(path, traj: Trajectory, conv: int = 0) -> None:
    """Write ``time tx ty tz qx qy qz qw`` lines (ENU about the first point, FLU body), atomically."""
    origin, enu, q = trajectory_enu_quat(traj, conv)
    if traj.extra:
        logging.getLogger("sins").warning("%s: the TUM format has 8 fixed columns; the column(s) %s are left out "
                                          "(write .csv, .parquet or .mcap to keep them)", path, ", ".join(traj.extra))
    cols = [_fmt(traj.time)] + [_fmt(enu[:, i]) for i in range(3)] + [_fmt(q[:, i]) for i in range(4)]
    lat0, lon0 = output_lon_lat(path, np.degrees(origin[0]), np.degrees(origin[1]), traj.time[:1])
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="ascii", newline="\n") as f:
            f.write("# sins trajectory, TUM format: time tx ty tz qx qy qz qw; position in a local ENU frame (m), "
                    "attitude of the FLU body axes in that frame\n")
            f.write(f"# origin_lat_deg={float(lat0)!r} "
                    f"origin_lon_deg={float(lon0)!r} origin_height_m={float(origin[2])!r}\n")
            f.writelines(" ".join(row) + "\n" for row in zip(*cols))


def read_tum(path, limits=None):
    """``(time, enu (N,3), q_xyzw (N,4), origin (lat rad, lon rad, h) or None)`` from a TUM file.

    Time stamps, positions (at most :data:`sinscli.io.limits.MAX_LOCAL_POSITION` from the origin) and the
    origin line beyond the physical ``limits`` (the config's section; default: the defaults) are refused
    naming the line and column.
    """
    lim = limits_mod.resolve(limits)
    path = input_file(path, "TUM file")
    origin = None
    rows = []
    lines = []
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise SinsError(f"{path}: cannot read TUM file ({type(exc).__name__})") from None
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            m = _ORIGIN_RE.search(s)
            if m:
                try:
                    o = [float(x) for x in m.groups()]
                except ValueError:
                    raise SinsError(f"{path}: line {lineno}: the origin line holds a value that is not a number") from None
                limits_mod.check_position(path, o[:1], o[1:2], o[2:], lim,
                                          ("origin_lat_deg", "origin_lon_deg", "origin_height_m"), lineno)
                origin = (np.radians(o[0]), np.radians(o[1]), o[2])
            continue
        parts = s.split()
        if len(parts) != 8:
            raise SinsError(f"{path}: line {lineno}: expected 8 numbers (time tx ty tz qx qy qz qw), got {len(parts)}")
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            raise SinsError(f"{path}: line {lineno}: not a number in {s[:60]!r}") from None
        lines.append(lineno)
    a = np.array(rows, dtype=np.float64).reshape(-1, 8)
    if a.shape[0] == 0:
        raise SinsError(f"{path}: no poses (expected lines of time tx ty tz qx qy qz qw)")
    bad = ~np.isfinite(a)
    if bad.any():
        k, c = (int(v[0]) for v in np.nonzero(bad))
        raise SinsError(f"{path}: line {lines[k]}, column '{TUM_COLUMNS[c]}': value is not a finite number")
    rows_at = np.asarray(lines)
    limits_mod.check_time(path, a[:, 0], lim, "time", rows_at)
    limits_mod.check_abs(path, a[:, 1:4], limits_mod.MAX_LOCAL_POSITION, "position", None, " m", ["tx", "ty", "tz"],
                         rows_at)
    limits_mod.check_abs(path, a[:, 4:8], 1.0 + 1e-3, "quaternion element", None, "", ["qx", "qy", "qz", "qw"],
                         rows_at)
    qn = np.linalg.norm(a[:, 4:8], axis=1)
    if np.any(np.abs(qn - 1.0) > 1e-3):
        k = int(np.argmax(np.abs(qn - 1.0) > 1e-3))
        raise SinsError(f"{path}: line {lines[k]}, column 'qw': the quaternion has norm {qn[k]:.6g}; "
                        "expected a unit quaternion")
    if a.shape[0] > 1 and np.any(np.diff(a[:, 0]) <= 0):
        k = int(np.argmax(np.diff(a[:, 0]) <= 0)) + 1
        raise SinsError(f"{path}: line {lines[k]}, column 'time': time {a[k, 0]!r} does not increase "
                        f"(previous {a[k - 1, 0]!r})")
    return a[:, 0], a[:, 1:4], a[:, 4:8], origin


def read_tum_trajectory(path, conv: int = 0) -> Trajectory:
    """A :class:`Trajectory` back from a TUM file written by :func:`write_tum` (needs the origin comment).

    Velocity is not in the format: it is left as zeros.
    """
    t, enu, q_xyzw, origin = read_tum(path)
    return tum_to_trajectory(t, enu, q_xyzw, origin, conv, str(path))


def tum_rotations(q_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of TUM quaternions ``qx qy qz qw`` (normalized)."""
    q = np.ascontiguousarray(np.asarray(q_xyzw, dtype=np.float64)[:, [3, 0, 1, 2]])
    return quat_to_dcm_many(q / np.linalg.norm(q, axis=1, keepdims=True))


def tum_to_trajectory(t, enu, q_xyzw, origin, conv: int, source: str) -> Trajectory:
    """The :class:`Trajectory` of TUM rows placed on the earth by their origin (velocity left as zeros)."""
    if origin is None:
        raise SinsError(f"{source}: no '# origin_lat_deg=... origin_lon_deg=... origin_height_m=...' line; "
                        "cannot place the local ENU frame on the earth")
    lat, lon, h = local_enu_to_lla(enu, *origin)
    return Trajectory(time=t, lat=lat, lon=lon, height=h, vel_n=np.zeros((t.shape[0], 3)),
                      Cbn=cbn_from_flu(tum_rotations(q_xyzw), conv), source=source)
