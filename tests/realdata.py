"""Real logs as the project's files (docs/formats.md), for tests: not part of the package.

The recordings ship in ``tests/data`` with their licences (``tests/data/README.md``): the comma2k19 example
segment (MIT), the Husky bag of robot_localization's test data (BSD-3-Clause) and one hour of a static CORS
station's RINEX (MIT repositories, public data).  ``SINS_REALDATA`` may point at another folder holding them.

``comma2k19_csvs(out_dir, gyro="uncalibrated", outages=())`` writes the comma2k19 example segment
(the highway car with a phone IMU and a u-blox receiver, ``tests/data/comma2k19_ex1``, its
README) as ``imu.csv`` (rates, FRD axes: read it with ``imu.body: frd``), ``gnss.csv``, ``truth.csv``
(the segment's own pose, FRD) and ``config.yaml`` (``imu.body: frd``), and returns their paths.

* Time: every file on the phone's boot clock (the IMU's ``t``).  The u-blox fixes are stamped at their
  epoch, not at their arrival (0.1-0.24 s later): UTC -> GPS time (18 leap seconds in 2018) -> boot time
  through the pose's ``frame_gps_times``/``frame_times`` pairs (a straight line: they fit one to 1e-10 s,
  and some fixes come before the first frame).  Fixes less than 10 ms after the one
  before (a repeated message) are left out.
* IMU: ``gyro="uncalibrated"`` the raw rates (turn-on biases up to 3.9 deg/s), ``"calibrated"`` with the
  phone's own bias estimate removed; the specific force as logged (m/s^2).
* GNSS: position as logged; horizontal velocity from speed and bearing (``vel_e = v sin b``,
  ``vel_n = v cos b``), vertical velocity the slope of a straight line through the heights within +-1 s
  (the receiver gives none); no ``std_*`` columns (the log states no accuracy).  ``outages``: pairs
  ``(start, end)`` in s since the IMU's first sample, fixes inside left out.
* Truth: the camera's pose (``global_pose``, comma.ai's own optimizer, accuracy not stated) at the frame
  times; the camera frame is forward-right-down, its misalignment to the IMU and its lever arm are not
  given (the fixes sit about 1.8 m from it).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from sinscli.conventions import FRD
from sinscli.io.gnss_csv import write_gnss_csv
from sinscli.io.imu_csv import write_imu_rates_csv
from sinscli.io.trajectory import write_trajectory
from sinscli.nav.earth import ecef_to_lla, enu_rotation
from sinscli.types import GnssLog, Trajectory

ROOT = Path(__file__).resolve().parents[1]


def data_dir() -> Path:
    """The folder of the real recordings: ``$SINS_REALDATA`` when set, else ``tests/data``."""
    env = os.environ.get("SINS_REALDATA")
    return Path(env) if env else Path(__file__).resolve().parent / "data"


COMMA2K19 = data_dir() / "comma2k19_ex1"
HUSKY_BAG = data_dir() / "ros1_husky" / "husky_imu_gps.bag"
RINEX_STATIC = data_dir() / "rinex_static"
GPS_UTC_LEAP = 18.0            # s, GPS - UTC in 2018
GPS_EPOCH_UNIX = 315964800.0   # s, 1980-01-06 in UNIX time
MIN_FIX_STEP = 0.01            # s: a fix closer than this to the one before is a repeated message
VERTICAL_HALF_WINDOW = 1.0     # s: the vertical velocity's line fit spans +-this


def _load(rel):
    return np.load(COMMA2K19 / rel)


def _quat_to_dcm(q):
    """(N, 4) Hamilton quaternions ``w, x, y, z`` -> (N, 3, 3) rotation matrices."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def _slope(t, y, half):
    """Least-squares slope of ``y`` against ``t`` over the samples within +-``half`` of each sample."""
    out = np.empty_like(y)
    for k in range(t.shape[0]):
        m = np.abs(t - t[k]) <= half
        tt = t[m] - t[m].mean()
        out[k] = float((tt * (y[m] - y[m].mean())).sum() / max((tt * tt).sum(), 1e-12))
    return out


def comma2k19_fixes(outages=()):
    """The u-blox fixes as a :class:`GnssLog` on the boot clock (see the module docstring)."""
    v = _load("processed_log/GNSS/live_gnss_ublox/value")
    frame_t = _load("global_pose/frame_times")
    frame_gps = _load("global_pose/frame_gps_times")
    week = float(frame_gps[0, 0])
    tow = v[:, 3] / 1000.0 - GPS_EPOCH_UNIX + GPS_UTC_LEAP - week * 604800.0
    c = np.polyfit(frame_gps[:, 1] - frame_gps[0, 1], frame_t, 1)     # the two clocks agree to 1e-10 s
    t = np.polyval(c, tow - frame_gps[0, 1])
    keep = np.concatenate([[True], np.diff(t) >= MIN_FIX_STEP])
    t0 = float(_load("processed_log/IMU/accelerometer/t")[0])
    for a, b in outages:
        keep &= ~((t >= t0 + a) & (t <= t0 + b))
    v, t = v[keep], t[keep]
    bearing = np.radians(v[:, 5])
    vel_u = _slope(t, v[:, 4], VERTICAL_HALF_WINDOW)
    vel = np.stack([v[:, 2] * np.sin(bearing), v[:, 2] * np.cos(bearing), vel_u], axis=-1)
    return GnssLog(t, v[:, 0].copy(), v[:, 1].copy(), v[:, 4].copy(), vel_n=vel, source="comma2k19 u-blox")


def comma2k19_truth() -> Trajectory:
    """The segment's pose (camera, FRD) as a :class:`Trajectory` on the boot clock."""
    t = _load("global_pose/frame_times")
    p = _load("global_pose/frame_positions")
    v_e = _load("global_pose/frame_velocities")
    c_cam_e = _quat_to_dcm(_load("global_pose/frame_orientations"))
    lat, lon, h = ecef_to_lla(p)
    c_e_n = enu_rotation(lat, lon)
    return Trajectory(t.copy(), lat, lon, h, np.einsum("nij,nj->ni", c_e_n, v_e), c_e_n @ c_cam_e,
                      source="comma2k19 global_pose", body=FRD)


def comma2k19_csvs(out_dir, gyro: str = "uncalibrated", outages=()) -> dict:
    """Write the segment's ``imu.csv``, ``gnss.csv``, ``truth.csv`` and ``config.yaml`` into ``out_dir``
    (module docstring); returns ``{"imu", "gnss", "truth", "config"}`` paths."""
    if gyro not in ("uncalibrated", "calibrated"):
        raise ValueError(f"gyro: 'uncalibrated' or 'calibrated', got {gyro!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = _load("processed_log/IMU/accelerometer/t")
    accel = _load("processed_log/IMU/accelerometer/value")
    w = _load("processed_log/IMU/gyro_uncalibrated/value" if gyro == "uncalibrated" else "processed_log/IMU/gyro/value")
    paths = {k: out / f"{k}.csv" for k in ("imu", "gnss", "truth")}
    paths["config"] = out / "config.yaml"
    write_imu_rates_csv(paths["imu"], t, w, accel)
    write_gnss_csv(paths["gnss"], comma2k19_fixes(outages))
    write_trajectory(paths["truth"], comma2k19_truth(), FRD)
    paths["config"].write_text("imu:\n  body: frd\n", encoding="utf-8")
    return paths



def comma2k19_dir() -> Path | None:
    """The comma2k19 example segment (:data:`COMMA2K19`); None when it is absent."""
    return COMMA2K19 if (COMMA2K19 / "processed_log").is_dir() else None


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
