"""``sins info``: what a ROS log holds (topics, counts, rates, gaps; mean IMU readings)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import SinsError
from ...nav.imu_stats import time_stats
from .containers import open_log
from .decode import ACCEL, GYRO, IMU_TYPE, imu_from_message, stamp_seconds


def _topic_stats(t_ns: np.ndarray) -> dict:
    return time_stats(stamp_seconds(t_ns // 1_000_000_000, t_ns % 1_000_000_000) if t_ns.size else
                      np.empty(0))


def log_summary(path, imu_window: float = 1.0) -> dict:
    """Topics, types, counts, rates, time span, gaps; for Imu topics the mean specific force and
    angular rate over the first ``imu_window`` seconds (at least 10 messages), message axes."""
    path = Path(path)
    with open_log(path) as lg:
        topics = []
        imu = {}
        for name, info in sorted(lg.topics.items()):
            t_ns = lg.log_times(name)
            row = {"topic": name, "type": info.msgtype, "count": int(t_ns.size)}
            row.update(_topic_stats(t_ns))
            topics.append(row)
            if info.msgtype == IMU_TYPE and t_ns.size:
                deser = lg.deserializer(name)
                t_end = t_ns[0] + int(imu_window * 1e9)
                vals, stamps = [], []
                for k, (ts, raw) in enumerate(lg.iter_raw(name)):
                    if ts > t_end and k >= 10:
                        break
                    s, ns, v = imu_from_message(deser(raw))
                    vals.append(v)
                    stamps.append((s, ns))
                if not vals:
                    raise SinsError(f"{path}: topic {name}: {t_ns.size} messages listed in the index but none "
                                    "could be read (the log's files disagree, or it is damaged)")
                vals = np.array(vals)
                acc = vals[:, ACCEL].mean(axis=0)
                gyr = vals[:, GYRO].mean(axis=0)
                imu[name] = {"messages": len(vals), "mean_accel": acc.tolist(), "mean_gyro": gyr.tolist(),
                             "accel_norm": float(np.linalg.norm(acc)), "gyro_norm": float(np.linalg.norm(gyr))}
        starts = [r["start"] for r in topics if r["start"] is not None]
        ends = [r["end"] for r in topics if r["end"] is not None]
    return {"path": str(path), "format": lg.kind,
            "start": min(starts) if starts else None, "end": max(ends) if ends else None,
            "duration": (max(ends) - min(starts)) if starts else None,
            "messages": int(sum(r["count"] for r in topics)), "topics": topics, "imu": imu}
