"""``sins info`` on an IMU CSV log: rate, gaps, rest windows, the mean readings at the start (the same summary
as :func:`sinscli.io.ros.summary.log_summary` gives for ROS logs, so one formatter prints both)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fusion.options import FusionOptions
from ..fusion.standstill import StandstillDetector
from ..io.readers import read_imu
from ..nav.imu_stats import start_means, time_stats
from ..units import G0


def rest_windows(time, dtheta_b, dvel_b, t0: float) -> list[list[float]]:
    """The stretches at rest, ``[start, end]`` s: the fused navigation's standstill detector
    (:class:`sinscli.fusion.standstill.StandstillDetector`) with its default thresholds."""
    o = FusionOptions()
    det = StandstillDetector(o.standstill_window, o.standstill_rate_std, o.standstill_accel_std,
                             o.standstill_accel_mag, G0)   # g: its 0.3 m/s^2 tolerance covers any latitude
    det.feed(time, dtheta_b, dvel_b, t_start=t0)
    return [[float(a), float(b)] for a, b in det.intervals]


def csv_summary(path, cfg: dict, imu_window: float = 1.0) -> dict:
    """The :func:`~sinscli.io.ros.summary.log_summary` dict of an IMU CSV (read with the config: columns,
    units, mounting), plus ``rest``: the windows at rest."""
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
