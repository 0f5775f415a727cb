"""Plain data containers passed between readers, pipeline stages and writers.

They hold numpy arrays only (no per-sample Python objects); kernels receive
the arrays, never these objects.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ImuLog:
    """IMU increments in the body frame (after units, axes and mounting are applied).

    ``time[k]`` is the end of interval k; interval 0 starts at ``t0`` (the time
    of the first rate sample for rate logs, or the initial state's time for
    increment logs, docs/formats.md).  ``t0`` is None when not yet known.
    """
    time: np.ndarray            # (N,) s
    dtheta_b: np.ndarray        # (N, 3) rad, integral of w_ib^b over the interval
    dvel_b: np.ndarray          # (N, 3) m/s, integral of f^b over the interval
    t0: float | None = None     # start of the first interval, s
    source: str = "<memory>"    # file (and topic) name for messages
    kind: str = "increments"    # "increments" or "rates" (what the file held)
    # the file's resolution: the smallest step between distinct values of the gyro and the accelerometer
    # columns (the largest of the three axes), in SI units of what the file held (rad/s and m/s^2 for rates,
    # rad and m/s for increments); 0 where not known (:func:`value_step`)
    resolution: tuple = (0.0, 0.0)

    def __len__(self) -> int:
        return int(self.time.shape[0])


def value_step(values) -> float:
    """The resolution of sampled values ``(N, k)``: per column the smallest gap between two distinct values
    (gaps under 1e-9 of the column's largest magnitude are rounding, not steps), the largest of the columns;
    0 when a column holds fewer than two distinct values."""
    v = np.asarray(values, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    out = 0.0
    for c in range(v.shape[1]):
        u = np.unique(v[:, c][np.isfinite(v[:, c])])
        if u.size < 2:
            continue
        d = np.diff(u)
        d = d[d > 1e-9 * max(float(np.max(np.abs(u))), 1e-300)]
        if d.size:
            out = max(out, float(d.min()))
    return out


def merged_resolution(parts) -> tuple:
    """The resolution of consecutive blocks: per sensor the smallest positive step among them."""
    out = []
    for k in range(2):
        steps = [p[k] for p in parts if p[k] > 0.0]
        out.append(min(steps) if steps else 0.0)
    return tuple(out)


@dataclass
class GnssLog:
    """GNSS fixes: position, optional ENU velocity and 1-sigma.

    ``std_pos`` rows are NaN for fixes whose sigma is unknown while others have
    one (a NavSatFix with COVARIANCE_TYPE_UNKNOWN among known ones): use
    :meth:`position_sigma` with the configured value.  Every other value is finite
    and every sigma positive (the readers check it).
    """
    time: np.ndarray                    # (N,) s
    lat: np.ndarray                     # (N,) deg
    lon: np.ndarray                     # (N,) deg
    height: np.ndarray                  # (N,) m
    vel_n: np.ndarray | None = None     # (N, 3) m/s ENU
    std_pos: np.ndarray | None = None   # (N, 3) m ENU
    std_vel: np.ndarray | None = None   # (N, 3) m/s ENU
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(self.time.shape[0])

    def position_sigma(self, default_enu) -> np.ndarray:
        """``(N, 3)`` position 1-sigma (m, ENU): the fix's own, else ``default_enu`` (3 values)."""
        default = np.broadcast_to(np.asarray(default_enu, dtype=np.float64), (len(self), 3))
        if self.std_pos is None:
            return default.copy()
        return np.where(np.isnan(self.std_pos), default, self.std_pos)


@dataclass
class BodyVelLog:
    time: np.ndarray        # (N,) s
    vel_b: np.ndarray       # (N, 3) m/s, velocity of the vehicle in body axes (after mounting)
    std: np.ndarray | None  # (N, 3) m/s 1-sigma
    source: str = "<memory>"


@dataclass
class NavState:
    """One navigation state: position, ENU velocity and attitude ``Cbn``."""
    time: float            # s
    lat: float             # rad
    lon: float             # rad
    height: float          # m
    vel_n: np.ndarray      # (3,) m/s ENU
    Cbn: np.ndarray        # (3, 3) body -> ENU
    extra: dict = field(default_factory=dict)   # e.g. sigmas and biases from alignment


@dataclass
class Trajectory:
    """A trajectory as arrays (docs/formats.md trajectory CSV columns)."""
    time: np.ndarray       # (N,)
    lat: np.ndarray        # (N,) rad
    lon: np.ndarray        # (N,) rad
    height: np.ndarray     # (N,) m
    vel_n: np.ndarray      # (N, 3) m/s
    Cbn: np.ndarray        # (N, 3, 3)
    extra: dict = field(default_factory=dict)   # extra columns name -> (N,) array
    source: str = "<memory>"
    body: int | None = None    # body convention of Cbn (FLU 0, RFU 1, FRD 2) as read from a file; None: not known
    body_from: str = ""        # how it was known: "marker" (body column, Parquet metadata) or "angles"

    def __len__(self) -> int:
        return int(self.time.shape[0])


def time_tolerance(t: float) -> float:
    """Tolerance for "the same time stamp": a few float64 spacings of ``t`` (s).

    Relative to the value's float resolution, not to its size: UNIX-epoch stamps
    (~1.4e9 s, resolution 2.4e-7 s) get ~2e-6 s, never a whole second.
    """
    return 8.0 * float(np.spacing(max(abs(float(t)), 1.0)))
