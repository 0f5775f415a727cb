"""``sins info`` on an IMU CSV log: rate, gaps, rest windows, the mean readings at the start (the same summary
as :func:`sinscli.io.ros.summary.log_summary` gives for ROS logs, so one formatter prints both)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

G0 = 9.80665          # m/s^2: the rest detector's gravity (its 0.3 m/s^2 tolerance covers any latitude)


def time_stats(t: np.ndarray) -> dict:
    """Start, end, rate, median interval, largest interval and the number of gaps (intervals longer than
    5 median intervals) of the time stamps ``t`` (s)."""
    out = {"start": None, "end": None, "rate_hz": None, "median_dt": None, "max_gap": None, "gaps": 0}
    if t.size == 0:
        return out
    out["start"], out["end"] = float(t[0]), float(t[-1])
    if t.size > 1:
        dt = np.diff(t)
        med = float(np.median(dt))
        out["median_dt"] = med
        out["rate_hz"] = (t.size - 1) / (t[-1] - t[0]) if t[-1] > t[0] else None
        out["max_gap"] = float(dt.max())
        out["gaps"] = int((dt > 5.0 * med).sum()) if med > 0 else 0
    return out


def start_means(time, dtheta_b, dvel_b, t0: float, window: float = 1.0) -> dict:
    """Mean specific force and angular rate over the first ``window`` s (at least 10 samples)."""
    n = max(int(np.searchsorted(time, t0 + window, side="right")), min(10, len(time)))
    span = float(time[n - 1] - t0)
    acc = dvel_b[:n].sum(axis=0) / span
    gyr = dtheta_b[:n].sum(axis=0) / span
    return {"messages": n, "mean_accel": acc.tolist(), "mean_gyro": gyr.tolist(),
            "accel_norm": float(np.linalg.norm(acc)), "gyro_norm": float(np.linalg.norm(gyr))}


def rest_windows(time, dtheta_b, dvel_b, t0: float) -> list[list[float]]:
    """The stretches at rest, ``[start, end]`` s: the fused navigation's standstill detector
    (:class:`sinscli.fusion.standstill.StandstillDetector`) with its default thresholds."""
    from ..fusion.options import FusionOptions
    from ..fusion.standstill import StandstillDetector
    o = FusionOptions()
    det = StandstillDetector(o.standstill_window, o.standstill_rate_std, o.standstill_accel_std,
                             o.standstill_accel_mag, G0)
    det.feed(time, dtheta_b, dvel_b, t_start=t0)
    return [[float(a), float(b)] for a, b in det.intervals]


def csv_summary(path, cfg: dict, imu_window: float = 1.0) -> dict:
    """The :func:`~sinscli.io.ros.summary.log_summary` dict of an IMU CSV (read with the config: columns,
    units, mounting), plus ``rest``: the windows at rest."""
    from ..io.readers import read_imu
    imu = read_imu(path, cfg, allow_gaps=True)
    t = np.asarray(imu.time, dtype=np.float64)
    t0 = imu.t0 if imu.t0 is not None else float(t[0] - (t[1] - t[0]) if t.size > 1 else t[0])
    row = {"topic": Path(path).name, "type": f"IMU CSV ({imu.kind})", "count": int(t.size)}
    row.update(time_stats(t))
    name = f"{Path(path).name} (body axes)" if cfg["imu"].get("mounting") is not None else Path(path).name
    return {"path": str(path), "format": "IMU CSV", "body": cfg["imu"]["body"], "start": row["start"], "end": row["end"],
            "duration": (row["end"] - row["start"]) if t.size else None, "messages": int(t.size), "topics": [row],
            "imu": {name: start_means(t, imu.dtheta_b, imu.dvel_b, t0, imu_window)} if t.size else {},
            "rest": rest_windows(t, imu.dtheta_b, imu.dvel_b, t0) if t.size > 2 else []}
