"""Trajectory writers: MCAP (Foxglove + ROS Odometry), TUM, GeoJSON, KML: closed-form values,
round trips through their readers, the Odometry bulk encoding against the library, atomic failure."""
from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from sinscli.errors import SinsError
from sinscli.io import foxglove, geo, tum
from sinscli.io.trajectory import write_trajectory
from sinscli.nav.earth import A
from sinscli.nav.rotation import euler_to_dcm_many
from sinscli.types import Trajectory


def _traj(n=400, conv=0, t0=100.0):
    t = t0 + 0.01 * np.arange(n)
    lat = np.radians(30.5 + 2e-4 * np.sin(t / 3))
    lon = np.radians(114.3 + 2e-4 * np.cos(t / 3))
    h = 20.0 + np.sin(t)
    vel = np.column_stack([np.sin(t), np.cos(t), 0.1 * np.ones(n)])
    cbn = euler_to_dcm_many(0.1 * np.sin(t), 0.05 * np.cos(t), np.mod(t, 2 * np.pi), conv)
    return Trajectory(t, lat, lon, h, vel, cbn, source="test")


def _simple(heading_deg, conv, lat=(0.0, 0.0, 0.0), lon=(0.0, 1e-4, 0.0), h=(0.0, 0.0, 10.0)):
    n = len(lat)
    cbn = euler_to_dcm_many(np.zeros(n), np.zeros(n), np.full(n, math.radians(heading_deg)), conv)
    return Trajectory(np.array([0.0, 1.0, 2.0]), np.radians(lat), np.radians(lon), np.array(h),
                      np.tile([1.0, 0.0, 0.0], (n, 1)), cbn, source="simple")


# --------------------------------------------------------------------------- TUM

def test_tum_closed_form(tmp_path):
    """Equator origin: a point 1e-4 deg east is at (a sin dl, 0, a (cos dl - 1)) in ENU; 10 m up is (0, 0, 10).
    Heading 90 deg (east) in FLU: body axes = ENU axes, q = (0, 0, 0, 1)."""
    path = tmp_path / "t.tum"
    write_trajectory(path, _simple(90.0, 0), conv=0)
    lines = [ln.split() for ln in path.read_text().splitlines() if not ln.startswith("#")]
    assert all(len(ln) == 8 for ln in lines)                       # evo's TUM reader: 8 columns
    a = np.array(lines, dtype=float)
    dl = math.radians(1e-4)
    np.testing.assert_allclose(a[:, 0], [0.0, 1.0, 2.0], rtol=0, atol=0)
    np.testing.assert_allclose(a[1, 1:4], [A * math.sin(dl), 0.0, A * (math.cos(dl) - 1.0)], atol=1e-8)
    np.testing.assert_allclose(a[2, 1:4], [0.0, 0.0, 10.0], atol=1e-8)
    np.testing.assert_allclose(np.abs(a[:, 4:8]), np.tile([0, 0, 0, 1.0], (3, 1)), atol=1e-15)


@pytest.mark.parametrize("conv", [0, 1, 2])
def test_tum_quaternion_is_the_flu_body_whatever_the_convention(tmp_path, conv):
    """Heading 0 (forward = north): the FLU body is ENU turned +90 deg about up, q = (0, 0, sin 45, cos 45)."""
    path = tmp_path / "t.tum"
    tum.write_tum(path, _simple(0.0, conv), conv)
    _t, _enu, q, origin = tum.read_tum(path)
    s = math.sqrt(0.5)
    np.testing.assert_allclose(q * np.sign(q[:, 3:4]), np.tile([0, 0, s, s], (3, 1)), atol=1e-15)
    assert origin == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("conv", [0, 1, 2])
def test_tum_round_trip(tmp_path, conv):
    tr = _traj(conv=conv)
    path = tmp_path / "t.tum"
    tum.write_tum(path, tr, conv)
    back = tum.read_tum_trajectory(path, conv)
    assert np.array_equal(back.time, tr.time)
    np.testing.assert_allclose(back.lat, tr.lat, atol=1e-14)
    np.testing.assert_allclose(back.lon, tr.lon, atol=1e-14)
    np.testing.assert_allclose(back.height, tr.height, atol=1e-7)
    np.testing.assert_allclose(back.Cbn, tr.Cbn, atol=1e-14)


# --------------------------------------------------------------------------- MCAP

@pytest.mark.parametrize("conv", [0, 1, 2])
def test_mcap_round_trip(tmp_path, conv):
    tr = _traj(conv=conv)
    path = tmp_path / "t.mcap"
    write_trajectory(path, tr, conv=conv)
    back = foxglove.read_trajectory_mcap(path, conv)
    np.testing.assert_allclose(back.time, tr.time, atol=1e-12)
    np.testing.assert_allclose(back.lat, tr.lat, rtol=1e-15, atol=0)
    np.testing.assert_allclose(back.lon, tr.lon, rtol=1e-15, atol=0)
    assert np.array_equal(back.height, tr.height)
    np.testing.assert_allclose(back.Cbn, tr.Cbn, atol=1e-14)
    np.testing.assert_allclose(back.vel_n, tr.vel_n, atol=1e-14)


def test_mcap_schemas_and_messages(tmp_path):
    """What Foxglove and ROS tools see: the two foxglove JSON schemas and nav_msgs/Odometry in CDR."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    tr = _simple(90.0, 0)
    path = tmp_path / "t.mcap"
    foxglove.write_trajectory_mcap(path, tr, 0)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        kinds = {ch.topic: (summary.schemas[ch.schema_id].name, summary.schemas[ch.schema_id].encoding,
                            ch.message_encoding) for ch in summary.channels.values()}
        assert kinds == {"/sins/fix": ("foxglove.LocationFix", "jsonschema", "json"),
                         "/sins/pose": ("foxglove.PoseInFrame", "jsonschema", "json"),
                         "/sins/odom": ("nav_msgs/msg/Odometry", "ros2msg", "cdr")}
        for sch in summary.schemas.values():
            if sch.encoding == "jsonschema":
                assert json.loads(sch.data)["title"] == sch.name
        msgs = {}
        for _s, ch, msg in reader.iter_messages():
            msgs.setdefault(ch.topic, []).append((msg, None))
        msgs["/sins/odom"] = [(m, d) for _s, _c, m, d in reader.iter_decoded_messages(topics=["/sins/odom"])]
    fix = [json.loads(m.data) for m, _ in msgs["/sins/fix"]]
    assert [f["timestamp"] for f in fix] == [{"sec": k, "nsec": 0} for k in range(3)]
    assert fix[1]["longitude"] == 1e-4 and fix[2]["altitude"] == 10.0
    pose = [json.loads(m.data) for m, _ in msgs["/sins/pose"]]
    assert pose[0]["frame_id"] == "enu"
    assert pose[2]["pose"]["position"]["z"] == pytest.approx(10.0, abs=1e-8)
    odom = [d for _, d in msgs["/sins/odom"]]
    assert odom[0].child_frame_id == "base_link" and odom[0].header.frame_id == "enu"
    # heading east, moving east at 1 m/s: 1 m/s along body x
    v = odom[1].twist.twist.linear
    assert (v.x, v.y, v.z) == pytest.approx((1.0, 0.0, 0.0), abs=1e-15)
    assert odom[1].pose.pose.position.x == pytest.approx(A * math.sin(math.radians(1e-4)), abs=1e-8)
    assert [m.log_time for m, _ in msgs["/sins/odom"]] == [0, 1_000_000_000, 2_000_000_000]


def test_odometry_bulk_encoding_equals_library():
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(3)
    n = 50
    sec = rng.integers(0, 2**31 - 1, n)
    nsec = rng.integers(0, 10**9, n)
    pos, q, v = rng.normal(0, 1e3, (n, 3)), rng.normal(0, 1, (n, 4)), rng.normal(0, 10, (n, 3))
    q[7] = [-0.0, np.nan, np.inf, 5e-324]
    block = foxglove.odometry_cdr_block(ts, sec, nsec, pos, q, v)
    for k in range(n):
        ref = bytes(ts.serialize_cdr(foxglove.odometry_message(ts, sec[k], nsec[k], pos[k], q[k], v[k]),
                                     "nav_msgs/msg/Odometry"))
        assert block[k].tobytes() == ref, k


# --------------------------------------------------------------------------- GeoJSON, KML

def test_geojson_and_kml(tmp_path):
    tr = _traj(n=50)
    write_trajectory(tmp_path / "t.geojson", tr)
    doc = json.loads((tmp_path / "t.geojson").read_text())
    feat = doc["features"][0]
    assert doc["type"] == "FeatureCollection" and feat["geometry"]["type"] == "LineString"
    coords = np.array(feat["geometry"]["coordinates"])
    assert np.array_equal(coords[:, 0], np.degrees(tr.lon)) and np.array_equal(coords[:, 1], np.degrees(tr.lat))
    assert np.array_equal(coords[:, 2], tr.height)
    t, lat, lon, h = geo.read_geojson(tmp_path / "t.geojson")
    assert np.array_equal(t, tr.time) and np.array_equal(lat, np.degrees(tr.lat)) and np.array_equal(h, tr.height)

    write_trajectory(tmp_path / "t.kml", tr)
    root = ET.parse(tmp_path / "t.kml").getroot()
    assert root.tag == f"{{{geo.KML_NS}}}kml"
    lat, lon, h = geo.read_kml(tmp_path / "t.kml")
    assert np.array_equal(lat, np.degrees(tr.lat)) and np.array_equal(lon, np.degrees(tr.lon))
    assert np.array_equal(h, tr.height)


# --------------------------------------------------------------------------- failures leave nothing

@pytest.mark.parametrize("suffix", [".mcap", ".tum", ".geojson", ".kml"])
def test_bad_trajectory_leaves_no_file(tmp_path, suffix):
    tr = _traj(n=10)
    tr.lat = tr.lat.copy()
    tr.lat[4] = np.nan
    tr.time = tr.time - 1000.0                   # also negative times (MCAP needs t >= 0)
    path = tmp_path / f"out{suffix}"
    with pytest.raises(SinsError):
        write_trajectory(path, tr)
    assert list(tmp_path.iterdir()) == []
    empty = Trajectory(np.empty(0), np.empty(0), np.empty(0), np.empty(0), np.empty((0, 3)),
                       np.empty((0, 3, 3)), source="empty")
    with pytest.raises(SinsError, match="empty"):
        write_trajectory(path, empty)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("failing_call", [1, 3])
def test_parquet_row_group_failing_on_the_writer_thread_leaves_no_file(tmp_path, monkeypatch, failing_call):
    """Parquet row groups are written on a thread; a failure there (here the disk filling up on the 1st
    or the last row group) surfaces in the caller as the one-line write error naming the target (issue 22),
    and no output or temporary file is left."""
    import pyarrow.parquet as pq
    from sinscli.io.trajectory import TrajectoryWriter, read_trajectory
    calls = []
    real = pq.ParquetWriter.write_table

    def write_table(self, table, *a, **k):
        calls.append(table.num_rows)
        if len(calls) == failing_call:
            raise OSError(28, "No space left on device")
        return real(self, table, *a, **k)

    monkeypatch.setattr(pq.ParquetWriter, "write_table", write_table)
    tr = _traj(n=30)
    parts = [Trajectory(tr.time[a:a + 10], tr.lat[a:a + 10], tr.lon[a:a + 10], tr.height[a:a + 10],
                        tr.vel_n[a:a + 10], tr.Cbn[a:a + 10], source="test") for a in (0, 10, 20)]
    path = tmp_path / "out.parquet"
    with pytest.raises(SinsError, match=r"^\S*out\.parquet: cannot write the output \(No space left on device\)$"):
        with TrajectoryWriter(path) as w:
            for p in parts:
                w.write(p)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(pq.ParquetWriter, "write_table", real)
    with TrajectoryWriter(path) as w:                     # and without the failure: all three, in order
        for p in parts:
            w.write(p)
    back = read_trajectory(path)
    assert np.array_equal(back.time, tr.time) and np.array_equal(back.lat, tr.lat)
