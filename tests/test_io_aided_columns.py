"""The 1-sigma and bias columns of an aided trajectory in every writer: CSV/Parquet exact round trips and
checks, MCAP covariances (closed form and round trip), GeoJSON/KML per-point values, TUM left out."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sinscli.errors import SinsError
from sinscli.io import aided_columns as ac
from sinscli.io import foxglove, geo, tum
from sinscli.io.trajectory import read_trajectory, write_trajectory
from sinscli.nav.rotation import euler_to_dcm_many
from sinscli.types import Trajectory

SINS = Path(sys.executable).with_name("sins")


def _aided(n=200, conv=0, t0=50.0, seed=4):
    """A wandering trajectory with every aided column, sigmas spanning orders of magnitude."""
    rng = np.random.default_rng(seed)
    t = t0 + 0.1 * np.arange(n)
    lat = np.radians(42.3 + 1e-4 * np.sin(t / 7))
    lon = np.radians(-71.1 + 1e-4 * np.cos(t / 5))
    h = 10.0 + np.sin(t / 3)
    vel = np.column_stack([np.sin(t), np.cos(t), 0.05 * np.sin(t / 2)])
    cbn = euler_to_dcm_many(0.2 * np.sin(t / 4), 0.1 * np.cos(t / 3), np.mod(t / 2, 2 * np.pi), conv)
    extra = {}
    for names, lo, hi in ((ac.POS_STD, 0.01, 30.0), (ac.VEL_STD, 0.001, 2.0), (ac.ATT_STD, 0.001, 5.0)):
        for c in names:
            extra[c] = np.exp(rng.uniform(np.log(lo), np.log(hi), n))
    for c in ac.BIAS_COLUMNS:
        extra[c] = rng.normal(0, 100.0, n)
    return Trajectory(t, lat, lon, h, vel, cbn, extra, source="aided")


# --------------------------------------------------------------------------- CSV, Parquet

@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_csv_parquet_round_trip_exact(tmp_path, suffix):
    tr = _aided()
    path = tmp_path / f"a{suffix}"
    write_trajectory(path, tr)
    back = read_trajectory(path)
    assert set(back.extra) == set(tr.extra)
    for c, v in tr.extra.items():
        assert np.array_equal(back.extra[c], v), c


@pytest.mark.parametrize("bad", [0.0, -1.0])
def test_reader_refuses_a_sigma_that_is_not_positive(tmp_path, bad):
    tr = _aided(n=20)
    path = tmp_path / "a.csv"
    write_trajectory(path, tr)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    j = header.index("heading_std")
    row = lines[7].split(",")                      # line 8 of the file
    row[j] = repr(bad)
    lines[7] = ",".join(row)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(SinsError, match=rf"a.csv: line 8, column 'heading_std': {bad!r} is not a positive finite "
                                        r"1-sigma"):
        read_trajectory(path)


def test_parquet_reader_refuses_a_zero_sigma(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    tr = _aided(n=20)
    path = tmp_path / "a.parquet"
    write_trajectory(path, tr)
    table = pq.read_table(path)
    col = table.column("vel_n_std").to_numpy().copy()
    col[3] = 0.0
    table = table.set_column(table.column_names.index("vel_n_std"), "vel_n_std", pa.array(col))
    pq.write_table(table, path)
    with pytest.raises(SinsError, match=r"row 4, column 'vel_n_std': 0.0 is not a positive finite 1-sigma"):
        read_trajectory(path)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".mcap", ".geojson", ".kml"])
@pytest.mark.parametrize("bad", [np.nan, 0.0, -2.0, np.inf])
def test_writers_refuse_bad_sigmas_and_leave_nothing(tmp_path, suffix, bad):
    tr = _aided(n=30)
    tr.extra["pos_n_std"] = tr.extra["pos_n_std"].copy()
    tr.extra["pos_n_std"][11] = bad
    path = tmp_path / f"a{suffix}"
    # the writer guard (atomic.check_finite) counts rows from 1, with the epoch
    with pytest.raises(SinsError, match=r"row 12 \(time 51.1 s\), column 'pos_n_std': .* is not a positive finite "
                                        r"1-sigma"):
        write_trajectory(path, tr)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".mcap", ".geojson", ".kml"])
def test_writers_refuse_a_non_finite_bias(tmp_path, suffix):
    tr = _aided(n=30)
    tr.extra["accel_bias_y"] = tr.extra["accel_bias_y"].copy()
    tr.extra["accel_bias_y"][5] = np.nan
    with pytest.raises(SinsError, match=r"row 6 \(time 50.5 s\), column 'accel_bias_y': nan is not a finite number"):
        write_trajectory(tmp_path / f"a{suffix}", tr)
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------- MCAP

def _mcap_messages(path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
        js = {}
        for _s, ch, msg in reader.iter_messages(topics=["/sins/fix", "/sins/imu_bias"]):
            js.setdefault(ch.topic, []).append(json.loads(msg.data))
        odom = [d for _s, _c, _m, d in reader.iter_decoded_messages(topics=["/sins/odom"])]
    return schemas, js, odom


@pytest.mark.parametrize("conv", [0, 1, 2])
def test_mcap_covariances_closed_form(tmp_path, conv):
    """Level, heading east (FLU body x = east, y = north): roll turns about east, pitch about the right axis
    (south), heading about down; a velocity sigma east is a sigma along body x."""
    n = 3
    cbn = euler_to_dcm_many(np.zeros(n), np.zeros(n), np.full(n, math.radians(90.0)), conv)
    extra = {"pos_e_std": np.full(n, 1.0), "pos_n_std": np.full(n, 2.0), "pos_u_std": np.full(n, 3.0),
             "vel_e_std": np.full(n, 0.1), "vel_n_std": np.full(n, 0.2), "vel_u_std": np.full(n, 0.3),
             "roll_std": np.full(n, 1.0), "pitch_std": np.full(n, 2.0), "heading_std": np.full(n, 4.0),
             "gyro_bias_x": np.array([1.0, 2.0, 3.0])}
    tr = Trajectory(np.arange(n, dtype=float), np.zeros(n), np.zeros(n), np.zeros(n), np.tile([1.0, 0, 0], (n, 1)),
                    cbn, extra, source="s")
    path = tmp_path / "c.mcap"
    foxglove.write_trajectory_mcap(path, tr, conv)
    schemas, js, odom = _mcap_messages(path)
    assert schemas["/sins/imu_bias"] == "sins.ImuBias"
    fix = js["/sins/fix"][1]
    assert fix["position_covariance_type"] == 2                       # DIAGONAL_KNOWN
    assert fix["position_covariance"] == [1.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0]
    assert [b["gyro_bias_x"] for b in js["/sins/imu_bias"]] == [1.0, 2.0, 3.0]
    pose = np.asarray(odom[1].pose.covariance).reshape(6, 6)
    d = math.radians(1.0) ** 2
    np.testing.assert_allclose(np.diag(pose), [1.0, 4.0, 9.0, 1.0 * d, 4.0 * d, 16.0 * d], rtol=1e-13)
    np.testing.assert_allclose(pose - np.diag(np.diag(pose)), 0.0, atol=1e-15 * d)   # cos 90 deg = 6e-17
    twist = np.asarray(odom[1].twist.covariance).reshape(6, 6)
    # body FLU: x = east, y = north, z = up
    np.testing.assert_allclose(np.diag(twist)[:3], [0.01, 0.04, 0.09], rtol=1e-13)
    np.testing.assert_allclose(twist[3:, 3:], 0.0, atol=0)


@pytest.mark.parametrize("conv", [0, 2])
def test_mcap_round_trip_of_sigma_and_bias_columns(tmp_path, conv):
    tr = _aided(conv=conv)
    path = tmp_path / "a.mcap"
    write_trajectory(path, tr, conv)
    back = foxglove.read_trajectory_mcap(path, conv)
    assert set(back.extra) == set(tr.extra)
    for c in ac.POS_STD + ac.BIAS_COLUMNS:
        assert np.array_equal(back.extra[c], tr.extra[c]), c          # exact: squares and JSON floats
    for c in ac.VEL_STD + ac.ATT_STD:                                  # through rotations: to rounding
        np.testing.assert_allclose(back.extra[c], tr.extra[c], rtol=1e-9, err_msg=c)


def test_mcap_without_sigmas_is_unchanged(tmp_path):
    tr = _aided()
    tr.extra = {}
    path = tmp_path / "p.mcap"
    write_trajectory(path, tr)
    schemas, js, odom = _mcap_messages(path)
    assert "/sins/imu_bias" not in schemas
    assert js["/sins/fix"][0]["position_covariance_type"] == 0
    assert not np.any(odom[0].pose.covariance) and not np.any(odom[0].twist.covariance)
    assert foxglove.read_trajectory_mcap(path).extra == {}


def test_odometry_bulk_encoding_with_covariances_equals_library():
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(5)
    n = 30
    sec, nsec = rng.integers(0, 2**31 - 1, n), rng.integers(0, 10**9, n)
    pos, q, v = rng.normal(0, 1e3, (n, 3)), rng.normal(0, 1, (n, 4)), rng.normal(0, 10, (n, 3))
    pc, tc = rng.normal(0, 1, (n, 36)), rng.normal(0, 1, (n, 36))
    pc[3, 5] = np.nan
    tc[4, 0] = -0.0
    for pose_cov, twist_cov in ((pc, tc), (pc, None), (None, tc)):
        block = foxglove.odometry_cdr_block(ts, sec, nsec, pos, q, v, pose_cov, twist_cov)
        for k in range(n):
            msg = foxglove.odometry_message(ts, sec[k], nsec[k], pos[k], q[k], v[k],
                                            None if pose_cov is None else pose_cov[k],
                                            None if twist_cov is None else twist_cov[k])
            assert block[k].tobytes() == bytes(ts.serialize_cdr(msg, "nav_msgs/msg/Odometry")), k


# --------------------------------------------------------------------------- GeoJSON, KML, TUM

def test_geojson_and_kml_carry_per_point_columns(tmp_path):
    tr = _aided(n=40)
    write_trajectory(tmp_path / "a.geojson", tr)
    write_trajectory(tmp_path / "a.kml", tr)
    gj = geo.read_geojson_columns(tmp_path / "a.geojson")
    km = geo.read_kml_columns(tmp_path / "a.kml")
    for cols in (gj, km):
        assert np.array_equal(cols["time"], tr.time)
        for c, v in tr.extra.items():
            assert np.array_equal(cols[c], v), c
    doc = json.loads((tmp_path / "a.geojson").read_text())
    assert doc["features"][0]["properties"]["units"]["pos_e_std"] == "m"
    assert doc["features"][0]["properties"]["units"]["accel_bias_x"] == "micro-g"
    assert 'displayName>heading_std (deg)<' in (tmp_path / "a.kml").read_text()
    t, lat, lon, h = geo.read_geojson(tmp_path / "a.geojson")         # the track itself reads as before
    assert np.array_equal(t, tr.time) and np.array_equal(lat, np.degrees(tr.lat))


def test_tum_cannot_carry_sigmas_and_says_so(tmp_path, caplog):
    tr = _aided(n=10)
    with caplog.at_level("WARNING", logger="sins"):
        write_trajectory(tmp_path / "a.tum", tr)
    assert "8 fixed columns" in caplog.text and "pos_e_std" in caplog.text
    rows = [ln.split() for ln in (tmp_path / "a.tum").read_text().splitlines() if not ln.startswith("#")]
    assert {len(r) for r in rows} == {8}


# --------------------------------------------------------------------------- installed console script

def test_installed_sins_refuses_a_zero_sigma_in_compare(tmp_path):
    """`sins compare` on a trajectory whose sigma column holds 0: one error line, exit 2, no report."""
    tr = _aided(n=20)
    truth = Trajectory(tr.time, tr.lat, tr.lon, tr.height, tr.vel_n, tr.Cbn, source="t")
    write_trajectory(tmp_path / "truth.csv", truth)
    tr.extra["roll_std"] = tr.extra["roll_std"].copy()
    path = tmp_path / "nav.csv"
    write_trajectory(path, tr)
    text = path.read_text().splitlines()
    j = text[0].split(",").index("roll_std")
    row = text[3].split(",")
    row[j] = "0"
    text[3] = ",".join(row)
    path.write_text("\n".join(text) + "\n")
    res = subprocess.run([str(SINS), "compare", "--truth", "truth.csv", "nav.csv", "-o", "rep", "-q"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        "sins: error: nav.csv: line 4, column 'roll_std': 0.0 is not a positive finite 1-sigma (docs/formats.md: a "
        "sigma column holds a positive finite number on every row)"]
    assert not (tmp_path / "rep").exists()
