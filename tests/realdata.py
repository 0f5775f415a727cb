"""Test helpers that turn shipped real logs into the project's input files.

``comma2k19_gnss_hv``: the comma2k19 example segment (a car on a highway; phone-grade IMU; u-blox fixes with
speed and bearing, no vertical velocity, no accuracy) as ``imu.csv`` (rates, FRD body axes), ``gnss_hv.csv``
(``vel_e, vel_n`` from speed and bearing: the horizontal-only GNSS CSV), ``gnss_pos.csv`` (the same fixes without
velocity) and ``nav.yaml``.  Every stream's time is the phone's boot time; the u-blox fixes carry UTC too, and
UTC minus boot time is constant over the segment (9 ms scatter), so the files are written in UTC UNIX seconds
(boot time + the median offset).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sinscli.io.gnss_csv import write_gnss_csv
from sinscli.io.imu_csv import write_imu_rates_csv
from sinscli.types import GnssLog

COMMA2K19 = "comma2k19_ex1"


def comma2k19_dir() -> Path | None:
    """The comma2k19 example segment: ``$SINS_REALDATA/comma2k19_ex1``, else ``tests/data/comma2k19_ex1``; None
    when neither exists."""
    for base in (os.environ.get("SINS_REALDATA"), Path(__file__).parent / "data"):
        if base and (Path(base) / COMMA2K19 / "processed_log").is_dir():
            return Path(base) / COMMA2K19
    return None


def comma2k19_gnss_hv(out_dir, data_dir=None) -> dict:
    """Write ``imu.csv``, ``gnss_hv.csv``, ``gnss_pos.csv`` and ``nav.yaml`` of the comma2k19 example into
    ``out_dir``; returns their paths and ``utc_offset`` (s added to the boot times)."""
    d = Path(data_dir) if data_dir is not None else comma2k19_dir()
    if d is None:
        raise FileNotFoundError("comma2k19_ex1 not found (set SINS_REALDATA)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log = d / "processed_log"
    g = np.load(log / "GNSS" / "live_gnss_ublox" / "value")
    tg = np.load(log / "GNSS" / "live_gnss_ublox" / "t")
    offset = float(np.median(g[:, 3] / 1000.0 - tg))      # UTC - boot time
    t_imu = np.load(log / "IMU" / "accelerometer" / "t")
    accel = np.load(log / "IMU" / "accelerometer" / "value")
    gyro = np.load(log / "IMU" / "gyro" / "value")
    assert np.array_equal(t_imu, np.load(log / "IMU" / "gyro" / "t"))
    write_imu_rates_csv(out / "imu.csv", t_imu + offset, gyro, accel)
    speed, bearing = g[:, 2], np.radians(g[:, 5])
    vel = np.column_stack([speed * np.sin(bearing), speed * np.cos(bearing), np.full(len(g), np.nan)])
    fixes = GnssLog(time=tg + offset, lat=g[:, 0].copy(), lon=g[:, 1].copy(), height=g[:, 4].copy(), vel_n=vel)
    write_gnss_csv(out / "gnss_hv.csv", fixes)
    write_gnss_csv(out / "gnss_pos.csv", GnssLog(fixes.time, fixes.lat, fixes.lon, fixes.height))
    (out / "nav.yaml").write_text(
        "imu:\n  body: frd                # the phone's axes: forward, right, down\n"
        "fusion:\n  vehicle: car\n  sensor: consumer\n")
    return {"imu": out / "imu.csv", "gnss_hv": out / "gnss_hv.csv", "gnss_pos": out / "gnss_pos.csv",
            "config": out / "nav.yaml", "utc_offset": offset}


def comma2k19_hv_reference_heading(utc_offset: float, data_dir=None):
    """``(t, heading deg)`` of comma.ai's reference trajectory (``global_pose``: the camera's pose, 20 Hz): the
    camera's forward axis (the first column of the rotation of the Hamilton quaternion ``frame_orientations``,
    camera -> ECEF) in the local ENU frame, at UTC times (boot time + ``utc_offset``).  The camera's mounting
    against the IMU is not given: compare the scatter, not the mean."""
    from sinscli.nav.earth import ecef_to_lla, enu_rotation
    from sinscli.nav.rotation import quat_to_dcm
    d = (Path(data_dir) if data_dir is not None else comma2k19_dir()) / "global_pose"
    t = np.load(d / "frame_times") + utc_offset
    q = np.load(d / "frame_orientations")
    lat, lon, _ = ecef_to_lla(np.load(d / "frame_positions"))
    fwd_e = np.stack([quat_to_dcm(x)[:, 0] for x in q])             # camera forward axis, ECEF
    fwd_n = np.einsum("nij,nj->ni", enu_rotation(lat, lon), fwd_e)   # ENU
    return t, np.degrees(np.arctan2(fwd_n[:, 0], fwd_n[:, 1]))
