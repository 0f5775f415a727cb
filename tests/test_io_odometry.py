"""Odometry is body-frame velocity: nav_msgs/Odometry and the body-velocity CSV as a BodyVelLog (frames, body
conventions, mounting, sigmas, bad input), never an ENU GNSS velocity; the real Husky odometry against its GNSS
and its IMU."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG

from sinscli.config import load_config, override
from sinscli.errors import SinsError
from sinscli.io import ros
from sinscli.io.body_vel_csv import read_body_velocity_csv, write_body_velocity_csv
from sinscli.io.readers import read_body_velocity, read_gnss, read_imu
from sinscli.io.ros.odometry import read_body_velocity as read_ros_body_velocity
from sinscli.nav.earth import lla_to_local_enu
from sinscli.types import BodyVelLog

ROOT = Path(__file__).resolve().parents[1]
HUSKY = HUSKY_BAG
HUSKY_CFG = ROOT / "configs" / "align" / "husky.yaml"
SINS = Path(sys.executable).with_name("sins")
# the Husky's mounting (configs/align/husky.yaml): forward = -z_imu, left = -x_imu, up = +y_imu
MOUNT = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _imu(n=40, t0=100.0):
    t = t0 + 0.01 * np.arange(n)
    return {"time": t, "gyro": np.zeros((n, 3)), "accel": np.tile([0.0, 9.8, 0.0], (n, 1))}


def _odom(n=20, t0=100.0, child="base_link", v=(1.0, 0.1, -0.05), std=(0.02, 0.03, 0.04)):
    t = t0 + 0.02 + 0.02 * np.arange(n)
    out = {"time": t, "vel": np.tile(v, (n, 1)), "child_frame_id": child,
           "orientation": np.tile([0.0, 0.0, math.sin(0.6), math.cos(0.6)], (n, 1))}   # pose yaw: irrelevant
    if std is not None:
        out["std"] = np.tile(std, (n, 1))
    return out


def _cfg(tmp_path, text=""):
    p = tmp_path / "cfg.yaml"
    p.write_text(text)
    return load_config(p)


# --------------------------------------------------------------------------- Odometry -> body axes

@pytest.mark.parametrize("name", ["o.bag", "o.mcap", "o.db3"])
@pytest.mark.parametrize("body,expected", [("flu", (1.0, 0.1, -0.05)), ("rfu", (-0.1, 1.0, -0.05)),
                                           ("frd", (1.0, -0.1, 0.05))])
def test_base_link_twist_is_the_vehicle_velocity_in_the_body_convention(tmp_path, name, body, expected):
    """child_frame_id base_link (REP-103: x forward, y left, z up): 1 m/s forward, 0.1 left, 0.05 down;
    in RFU that is x = right = -0.1, y = forward = 1; in FRD y = right = -0.1, z = down = +0.05.
    The pose orientation (odom frame) plays no part."""
    path = tmp_path / name
    ros.write_log(path, imu=_imu(), odom=_odom())
    bv = read_body_velocity(path, _cfg(tmp_path, f"imu:\n  body: {body}\n"))
    assert isinstance(bv, BodyVelLog) and bv.source == f"{path}:/odom"
    np.testing.assert_allclose(bv.time, 100.02 + 0.02 * np.arange(20), atol=1e-9)
    np.testing.assert_allclose(bv.vel_b, np.tile(expected, (20, 1)), atol=1e-15)
    std = {"flu": (0.02, 0.03, 0.04), "rfu": (0.03, 0.02, 0.04), "frd": (0.02, 0.03, 0.04)}[body]
    np.testing.assert_allclose(bv.std, np.tile(std, (20, 1)), rtol=1e-14)


@pytest.mark.parametrize("child", ["imu_link", "/imu_link"])
def test_twist_in_the_imu_frame_gets_the_mounting(tmp_path, child):
    """child_frame_id equal to the Imu messages' frame_id (ROS 1 may write it with a leading /): the twist is
    in the sensor axes, v_b = C_sensor^body v: sensor -z (1 m/s) is forward, sensor +y is up."""
    path = tmp_path / "s.bag"
    ros.write_log(path, imu=_imu(), odom=_odom(child=child, v=(0.0, 0.2, -1.0), std=(0.1, 0.2, 0.3)))
    cfg = override(load_config(HUSKY_CFG), "ros", imu_topic="/imu/data")
    bv = read_body_velocity(path, cfg)
    np.testing.assert_allclose(bv.vel_b, np.tile([1.0, 0.0, 0.2], (20, 1)), atol=1e-15)
    np.testing.assert_allclose(bv.std, np.tile([0.3, 0.1, 0.2], (20, 1)), rtol=1e-14)
    # the same twist said to be in vehicle axes by the config is taken as it is
    cfg = override(cfg, "odometry", frame="vehicle")
    np.testing.assert_allclose(read_body_velocity(path, cfg).vel_b, np.tile([0.0, 0.2, -1.0], (20, 1)), atol=1e-15)


def test_frame_choice_rules(tmp_path):
    path = tmp_path / "e.mcap"
    ros.write_log(path, imu=_imu(), odom=_odom(child=""))
    with pytest.raises(SinsError, match=r"topic /odom: the velocity frame name \(child_frame_id\) is empty.*"
                                        r"odometry\.frame"):
        read_ros_body_velocity(path)
    np.testing.assert_allclose(read_ros_body_velocity(path, frame="sensor", mounting=MOUNT).vel_b[0],
                               MOUNT @ [1.0, 0.1, -0.05], atol=1e-15)
    np.testing.assert_allclose(read_ros_body_velocity(path, frame="body", conv=1).vel_b[0], [1.0, 0.1, -0.05])
    # without an IMU topic in the log, a named frame is the vehicle's
    ros.write_log(tmp_path / "n.bag", odom=_odom(child="imu_link"))
    np.testing.assert_allclose(read_ros_body_velocity(tmp_path / "n.bag", mounting=MOUNT).vel_b[0],
                               [1.0, 0.1, -0.05], atol=1e-15)


def test_odometry_sigmas_and_bad_messages(tmp_path):
    ros.write_log(tmp_path / "z.bag", odom=_odom(std=None))
    assert read_ros_body_velocity(tmp_path / "z.bag").std is None            # all-zero covariance: not given
    ros.write_log(tmp_path / "neg.bag", odom=_odom(std=(0.1, 0.0, 0.1)))
    with pytest.raises(SinsError, match=r"neg\.bag: topic /odom: message 0, column 'twist velocity variance \[1\]': "
                                        r"0.0 is not a positive finite variance"):
        read_ros_body_velocity(tmp_path / "neg.bag")
    o = _odom()
    o["vel"] = o["vel"].copy()
    o["vel"][7, 1] = np.nan
    ros.write_log(tmp_path / "nan.mcap", odom=o)
    with pytest.raises(SinsError, match=r"nan\.mcap: topic /odom: message 7 has a non-finite twist velocity"):
        read_ros_body_velocity(tmp_path / "nan.mcap")
    with pytest.raises(SinsError, match=r"no nav_msgs/msg/Odometry topic for odometry"):
        read_ros_body_velocity(ros.write_log(tmp_path / "i.bag", imu=_imu()) or tmp_path / "i.bag")


# --------------------------------------------------------------------------- never an ENU velocity

def test_odometry_is_refused_as_gnss_velocity(tmp_path):
    g = {"time": 100.0 + 0.1 * np.arange(4), "lat": np.full(4, 30.0), "lon": np.full(4, 114.0),
         "height": np.zeros(4)}
    path = tmp_path / "g.bag"
    ros.write_log(path, gnss=g, odom=_odom())
    with pytest.raises(SinsError, match=r"topic /odom is nav_msgs/msg/Odometry: its twist is the vehicle's velocity in "
                                        r"its own body frame \(child_frame_id\), not an ENU velocity"):
        ros.read_gnss(path, vel_topic="/odom")


def test_gnss_twist_stays_enu_and_a_body_frame_name_is_flagged(tmp_path, caplog):
    g = {"time": 100.0 + 0.1 * np.arange(4), "lat": np.full(4, 30.0), "lon": np.full(4, 114.0),
         "height": np.zeros(4)}
    vel = {"time": g["time"], "vel": np.tile([1.0, 2.0, 0.5], (4, 1))}
    out = ros.read_gnss(ros.write_log(tmp_path / "a.bag", gnss=g, vel=vel) or tmp_path / "a.bag",
                        vel_topic="/fix_velocity")
    np.testing.assert_array_equal(out.vel_n, vel["vel"])             # east, north, up as published
    assert "body frame" not in caplog.text
    with caplog.at_level("WARNING", logger="sins"):
        ros.read_gnss(ros.write_log(tmp_path / "b.bag", gnss=g, vel={**vel, "frame_id": "base_link"})
                      or tmp_path / "b.bag", vel_topic="/fix_velocity")
    assert "frame_id base_link names a vehicle body frame" in caplog.text


def test_align_vel_topic_odometry_is_refused(tmp_path):
    """`sins align --vel-topic` on an Odometry topic: one error line, exit 2, no output (installed script)."""
    n = 300
    t = 100.0 + 0.02 * np.arange(n)
    imu = {"time": t, "gyro": np.zeros((n, 3)), "accel": np.tile([0.0, 0.0, 9.79], (n, 1))}
    g = {"time": t[::25], "lat": np.full(12, 30.0), "lon": np.full(12, 114.0), "height": np.zeros(12)}
    ros.write_log(tmp_path / "log.bag", imu=imu, gnss=g, odom=_odom(n=100))
    res = subprocess.run([str(SINS), "align", "log.bag", "--gnss", "log.bag", "--vel-topic", "/odom", "--method",
                          "static", "-q", "-o", "init.yaml"], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sins: error: log.bag: topic /odom is nav_msgs/msg/Odometry")
    assert not (tmp_path / "init.yaml").exists()


# --------------------------------------------------------------------------- body-velocity CSV

def _csv(tmp_path, data, name="odom.csv"):
    """The columns as CSV text (not through the writer, whose guard refuses the non-finite values made here)."""
    path = tmp_path / name
    rows = zip(*(np.asarray(v, dtype=np.float64).tolist() for v in data.values()))
    path.write_text(",".join(data) + "\n" + "".join(",".join(repr(x) for x in r) + "\n" for r in rows))
    return path


def _odom_data(n=6):
    return {"time": 10.0 + 0.1 * np.arange(n), "vel_x": np.full(n, 2.0), "vel_y": np.full(n, 0.01),
            "vel_z": np.full(n, -0.02), "std_x": np.full(n, 0.05), "std_y": np.full(n, 0.1), "std_z": np.full(n, 0.1)}


def test_body_velocity_csv_round_trip_and_frames(tmp_path):
    bv = BodyVelLog(10.0 + 0.1 * np.arange(6), np.random.default_rng(1).normal(0, 2, (6, 3)),
                    np.exp(np.random.default_rng(2).normal(-3, 1, (6, 3))), source="x")
    write_body_velocity_csv(tmp_path / "b.csv", bv)
    back = read_body_velocity_csv(tmp_path / "b.csv")
    assert np.array_equal(back.time, bv.time) and np.array_equal(back.vel_b, bv.vel_b) and np.array_equal(back.std, bv.std)
    path = _csv(tmp_path, _odom_data())
    cfg = override(load_config(HUSKY_CFG), "odometry", frame="sensor")                     # columns in the IMU's axes: v_b = C v
    s = read_body_velocity(path, cfg)
    np.testing.assert_allclose(s.vel_b[0], MOUNT @ [2.0, 0.01, -0.02], atol=1e-15)
    np.testing.assert_allclose(s.std[0], [0.1, 0.05, 0.1], rtol=1e-14)
    v = read_body_velocity(path, _cfg(tmp_path, "imu:\n  body: rfu\nodometry:\n  frame: vehicle\n"))
    np.testing.assert_allclose(v.vel_b[0], [-0.01, 2.0, -0.02], atol=1e-15)
    plain = read_body_velocity(_csv(tmp_path, {k: _odom_data()[k] for k in ("time", "vel_x", "vel_y", "vel_z")},
                                    "p.csv"), _cfg(tmp_path))
    assert plain.std is None and np.array_equal(plain.vel_b[:, 0], np.full(6, 2.0))
    mapped = _csv(tmp_path, {"t": _odom_data()["time"], "vf": np.ones(6), "vl": np.zeros(6), "vu": np.zeros(6),
                             "flag": np.ones(6)}, "m.csv")
    got = read_body_velocity(mapped, _cfg(tmp_path, "odometry:\n  columns: {time: t, vel_x: vf, vel_y: vl, "
                                                    "vel_z: vu}\n  ignore_columns: [flag]\n"))
    assert np.array_equal(got.vel_b, np.tile([1.0, 0.0, 0.0], (6, 1)))


@pytest.mark.parametrize("edit,message", [
    (lambda d: d.pop("vel_z"), r"missing column\(s\) vel_z; expected time, vel_x, vel_y, vel_z"),
    (lambda d: d.update(speed=np.ones(6)), r"unknown column\(s\) 'speed'; expected a body-velocity CSV"),
    (lambda d: d.pop("std_y"), r"has std_x, std_z but not all of std_x, std_y, std_z"),
    (lambda d: d["std_y"].__setitem__(2, 0.0), r"line 4, column 'std_y': 0.0 is not a positive finite 1-sigma"),
    (lambda d: d["std_z"].__setitem__(4, -0.1), r"line 6, column 'std_z': -0.1 is not a positive finite 1-sigma"),
    (lambda d: d["vel_x"].__setitem__(1, np.inf), r"line 3, column 'vel_x': value inf is not a finite number"),
    (lambda d: d["time"].__setitem__(3, 10.0), r"line 5, column 'time'.*(backwards|repeat)"),
])
def test_malformed_body_velocity_csv(tmp_path, edit, message):
    d = _odom_data()
    d = {k: v.copy() for k, v in d.items()}
    edit(d)
    with pytest.raises(SinsError, match=r"odom\.csv: " + message):
        read_body_velocity(_csv(tmp_path, d), _cfg(tmp_path))


def test_body_velocity_csv_non_numeric(tmp_path):
    path = _csv(tmp_path, _odom_data())
    lines = path.read_text().splitlines()
    cells = lines[3].split(",")
    cells[1] = "fast"
    lines[3] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(SinsError, match=r"odom\.csv: line 4, column 'vel_x': 'fast' is not a number"):
        read_body_velocity_csv(path)
    with pytest.raises(SinsError, match=r"nope\.csv: file not found"):
        read_body_velocity(tmp_path / "nope.csv", _cfg(tmp_path))


# --------------------------------------------------------------------------- real data: the Husky

@pytest.fixture(scope="module")
def husky():
    if not HUSKY.is_file():
        pytest.skip(f"real data {HUSKY} is absent (tests/data)")
    cfg = load_config(HUSKY_CFG)
    return cfg, read_body_velocity(HUSKY, cfg), read_gnss(HUSKY, cfg), read_imu(HUSKY, cfg)


def test_husky_odometry_is_forward_body_velocity(husky):
    """/husky_velocity_controller/odom (child base_link, ~10 Hz): a forward speed, no lateral or vertical one."""
    _cfg_, bv, _g, _imu = husky
    assert bv.source.endswith(":/husky_velocity_controller/odom") and bv.vel_b.shape == (3952, 3)
    assert np.all(np.diff(bv.time) > 0) and 9.5 < 1.0 / np.median(np.diff(bv.time)) < 10.5
    assert bv.vel_b[:, 0].min() > -0.01 and 0.9 < np.percentile(bv.vel_b[:, 0], 75) < 1.1   # drives forward ~1 m/s
    assert np.abs(bv.vel_b[:, 1:]).max() < 1e-6                                              # skid-steer model
    np.testing.assert_allclose(bv.std, math.sqrt(0.001), rtol=1e-12)                          # its covariance 0.001


def test_husky_odometry_speed_against_gnss(husky):
    """10 s windows every 5 s: the odometer's mean forward speed against the GNSS chord speed (fix sigma 0.9 m,
    so about 0.13 m/s of noise per window; chords are shorter than arcs in turns)."""
    _cfg_, bv, g, _imu = husky
    enu = lla_to_local_enu(np.radians(g.lat), np.radians(g.lon), g.height, math.radians(g.lat[0]),
                           math.radians(g.lon[0]), float(g.height[0]))
    T = 10.0
    ts = np.arange(g.time[0], g.time[-1] - T, 5.0)
    p0 = np.column_stack([np.interp(ts, g.time, enu[:, i]) for i in range(2)])
    p1 = np.column_stack([np.interp(ts + T, g.time, enu[:, i]) for i in range(2)])
    v_gnss = np.linalg.norm(p1 - p0, axis=1) / T
    dist = np.concatenate([[0.0], np.cumsum(0.5 * (bv.vel_b[1:, 0] + bv.vel_b[:-1, 0]) * np.diff(bv.time))])
    v_odo = (np.interp(ts + T, bv.time, dist) - np.interp(ts, bv.time, dist)) / T
    assert np.corrcoef(v_gnss, v_odo)[0, 1] > 0.6                # measured 0.76
    assert abs(np.median(v_odo - v_gnss)) < 0.1                  # measured 0.037 m/s
    assert np.sqrt(np.mean((v_odo - v_gnss) ** 2)) < 0.25        # measured 0.17 m/s


def test_husky_odometry_forward_axis_is_the_imu_forward_axis(husky):
    """Independent of the GNSS: changes of the odometer's forward speed over 2 s against the IMU's forward
    velocity increment (body x after the mounting) regress with slope ~1 (measured 0.88, corr 0.39; a
    reversed axis would give about -0.9); the lateral axis does not follow them."""
    _cfg_, bv, _g, imu = husky
    T = 2.0
    ts = np.arange(bv.time[0] + 1.0, bv.time[-1] - T - 1.0, 1.0)
    dv_odo = np.interp(ts + T, bv.time, bv.vel_b[:, 0]) - np.interp(ts, bv.time, bv.vel_b[:, 0])
    t_imu = np.concatenate([[imu.t0], imu.time])
    cum = np.vstack([np.zeros(3), np.cumsum(imu.dvel_b, axis=0)])
    dv_imu = np.stack([np.interp(ts + T, t_imu, cum[:, i]) - np.interp(ts, t_imu, cum[:, i]) for i in range(3)], -1)
    slope = np.polyfit(dv_odo, dv_imu[:, 0], 1)[0]
    assert 0.6 < slope < 1.3 and np.corrcoef(dv_odo, dv_imu[:, 0])[0, 1] > 0.25
    assert abs(np.corrcoef(dv_odo, dv_imu[:, 1])[0, 1]) < 0.15
