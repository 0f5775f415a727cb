"""ROS 1 bag / ROS 2 bag / MCAP reading: real data in three formats, bulk decode = library decode,
closed-form increments, topic choice, GNSS, and every listed bad input through the CLI."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.io import ros
from sinscli.io.ros import decode, write

HUSKY = HUSKY_BAG

FORMATS = ["x.bag", "x_lz4.bag", "x.mcap", "x_ros1.mcap", "x.db3", "xdir", "xdir_mcap"]


def _write(path: Path, imu=None, gnss=None, vel=None, **kw):
    name = path.name
    if name.endswith("_lz4.bag"):
        kw.setdefault("bag_compression", "lz4")
    if name.endswith("_ros1.mcap"):
        kw.setdefault("mcap_encoding", "ros1")
    if name.endswith("dir_mcap"):
        kw.setdefault("storage", "mcap")
    ros.write_log(path, imu=imu, gnss=gnss, vel=vel, **kw)
    return path


def _imu(n=60, t0=1000.0, dt=0.005, seed=1):
    rng = np.random.default_rng(seed)
    t = t0 + dt * np.arange(n)
    return {"time": t, "gyro": rng.normal(0, 0.2, (n, 3)), "accel": rng.normal(0, 1.0, (n, 3)) + [0, 0, 9.8]}


def _gnss(n=6, t0=1000.0, dt=0.05):
    t = t0 + dt * np.arange(n)
    return {"time": t, "lat": 30.0 + 1e-5 * np.arange(n), "lon": 114.0 + 2e-5 * np.arange(n),
            "height": 20.0 + 0.1 * np.arange(n), "cov": np.tile([4.0, 0, 0, 0, 9.0, 0, 0, 0, 16.0], (n, 1)),
            "cov_type": np.full(n, 2)}


# --------------------------------------------------------------------------- real data, three formats

@pytest.fixture(scope="module")
def husky(tmp_path_factory):
    if not HUSKY.is_file():
        pytest.skip(f"real data {HUSKY} is absent (tests/data)")
    from rosbags.convert import convert
    d = tmp_path_factory.mktemp("husky")
    convert([HUSKY], d / "db", "sqlite3", 9, None, "file", None, None, (), (), (), ())
    convert([HUSKY], d / "mc", "mcap", 9, None, "file", None, None, (), (), (), ())
    return {"bag": HUSKY, "ros2_sqlite_dir": d / "db", "db3": d / "db" / "db.db3",
            "ros2_mcap_dir": d / "mc", "mcap": d / "mc" / "mc.mcap"}


def test_husky_three_formats_give_identical_samples(husky):
    ref_imu = ros.read_imu(husky["bag"])
    ref_gnss = ros.read_gnss(husky["bag"])
    assert len(ref_imu) == 11865 - 1 and len(ref_gnss) == 989
    for name, path in husky.items():
        imu = ros.read_imu(path)
        gnss = ros.read_gnss(path)
        assert imu.source == f"{path}:/imu/data"
        assert imu.t0 == ref_imu.t0, name
        for a, b in [(imu.time, ref_imu.time), (imu.dtheta_b, ref_imu.dtheta_b), (imu.dvel_b, ref_imu.dvel_b),
                     (gnss.time, ref_gnss.time), (gnss.lat, ref_gnss.lat), (gnss.lon, ref_gnss.lon),
                     (gnss.height, ref_gnss.height), (gnss.std_pos, ref_gnss.std_pos)]:
            assert np.array_equal(a, b), name
        _, _, block = ros.read_imu_block(path)
        assert block.n_bulk == 11865, name            # every message through the numpy path


def test_husky_against_rosbags_decode(husky):
    """Independent truth: rosbags' own deserializer on the first messages, increments by hand."""
    from rosbags.highlevel import AnyReader
    with AnyReader([HUSKY]) as r:
        conns = [c for c in r.connections if c.topic == "/imu/data"]
        msgs = []
        for c, _t, raw in r.messages(conns):
            msgs.append(r.deserialize(raw, c.msgtype))
            if len(msgs) == 3:
                break
        fconn = [c for c in r.connections if c.topic == "/fix"]
        fix0 = r.deserialize(next(r.messages(fconn))[2], fconn[0].msgtype)
    t = [m.header.stamp.sec + m.header.stamp.nanosec / 1e9 for m in msgs]
    w = [np.array([m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]) for m in msgs]
    f = [np.array([m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]) for m in msgs]
    imu = ros.read_imu(husky["mcap"])
    assert imu.t0 == pytest.approx(t[0], abs=1e-6)
    assert imu.time[:2] == pytest.approx(t[1:], abs=1e-6)
    for k in range(2):
        np.testing.assert_allclose(imu.dtheta_b[k], 0.5 * (w[k] + w[k + 1]) * (t[k + 1] - t[k]), rtol=1e-6, atol=1e-15)
        np.testing.assert_allclose(imu.dvel_b[k], 0.5 * (f[k] + f[k + 1]) * (t[k + 1] - t[k]), rtol=1e-6, atol=1e-15)
    gnss = ros.read_gnss(husky["db3"])
    assert gnss.lat[0] == fix0.latitude and gnss.lon[0] == fix0.longitude and gnss.height[0] == fix0.altitude
    np.testing.assert_allclose(gnss.std_pos[0], np.sqrt(fix0.position_covariance[[0, 4, 8]]), rtol=1e-15)
    # the README's description of the recording: imu_link has its y axis up, |f| about g
    f_mean = imu.dvel_b.sum(axis=0) / (imu.time[-1] - imu.t0)
    assert 9.7 < f_mean[1] < 9.9 and abs(f_mean[0]) < 0.5 and abs(f_mean[2]) < 0.5


# --------------------------------------------------------------------------- bulk = library, bit for bit

@pytest.mark.parametrize("name", FORMATS)
def test_bulk_decode_equals_library_decode(tmp_path, name):
    imu = _imu(n=300)
    ori = np.tile([0.1, -0.2, 0.3, 0.9], (300, 1))
    ori[5] = [np.nan, -0.0, np.inf, 5e-324]                # bit patterns that must survive
    imu["orientation"] = ori
    path = _write(tmp_path / name, imu=imu, gnss=_gnss(), log_delay=0.001)
    t_bulk, t_lib = ros.read_imu_block(path, bulk=True), ros.read_imu_block(path, bulk=False)
    (_, ln_b, b), (_, ln_l, lib) = t_bulk, t_lib
    assert b.n_bulk == 300 and lib.n_bulk == 0
    assert np.array_equal(ln_b, ln_l)
    assert np.array_equal(b.sec, lib.sec) and np.array_equal(b.nsec, lib.nsec)
    assert b.values.tobytes() == lib.values.tobytes()
    # and the library decode is what was written
    assert np.array_equal(lib.values[:, decode.GYRO], imu["gyro"])
    assert np.array_equal(lib.values[:, decode.ACCEL], imu["accel"])


@pytest.mark.parametrize("encoding", ["cdr", "ros1"])
def test_bulk_block_all_frame_id_alignments(encoding):
    """frame_id lengths 0..9 move the CDR payload through every 8-byte alignment; mixed lengths are
    decoded per same-length group, single odd messages by the library."""
    from rosbags.typesys import Stores, get_typestore
    ros1 = encoding == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    des = ts.deserialize_ros1 if ros1 else ts.deserialize_cdr
    frames = ["", "a", "ab", "abc", "abcd", "abcde", "abcdef", "abcdefg", "abcdefgh", "abcdefghi", "陀螺"]
    imu = _imu(n=4 * len(frames) + 1)
    msgs = list(write._imu_messages(ts, ros1, imu, "x"))
    raws = []
    for k, m in enumerate(msgs):
        fid = frames[k % len(frames)] if k < len(msgs) - 1 else "odd one out"
        m.header.frame_id = fid
        raws.append(bytes(ser(m, "sensor_msgs/msg/Imu")))
    out = decode.decode_imu_messages(raws, encoding, lambda r: des(r, "sensor_msgs/msg/Imu"))
    ref = decode.decode_imu_messages(raws, encoding, lambda r: des(r, "sensor_msgs/msg/Imu"), bulk=False)
    assert out.n_bulk == len(raws) - 1                     # all but the odd one out
    assert out.values.tobytes() == ref.values.tobytes()
    assert np.array_equal(out.sec, ref.sec) and np.array_equal(out.nsec, ref.nsec)
    assert np.array_equal(ref.values[:, decode.GYRO], imu["gyro"])
    # a group of one length per frame_id: each decodes in bulk on its own
    for fid in frames:
        group = [raws[k] for k in range(len(raws) - 1) if frames[k % len(frames)] == fid]
        blk = decode.decode_imu_block(np.frombuffer(b"".join(group), np.uint8).reshape(len(group), -1), encoding)
        assert blk is not None, fid
        lib = decode.decode_imu_messages(group, encoding, lambda r: des(r, "sensor_msgs/msg/Imu"), bulk=False)
        assert blk.values.tobytes() == lib.values.tobytes(), fid


def test_bulk_block_refuses_foreign_layouts():
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    raws = [bytes(ts.serialize_cdr(m, "sensor_msgs/msg/Imu"))
            for m in write._imu_messages(ts, False, _imu(n=4), "imu")]
    block = np.frombuffer(b"".join(raws), np.uint8).reshape(4, -1).copy()
    assert decode.decode_imu_block(block, "cdr") is not None
    be = block.copy()
    be[:, 1] = 0                                              # big-endian CDR: the library's job
    assert decode.decode_imu_block(be, "cdr") is None
    other = block.copy()
    other[2, 16] = ord("X")                                   # another frame_id of the same length: fine
    assert decode.decode_imu_block(other, "cdr") is not None
    other[2, 16] = 0xFF                                       # not UTF-8: the library's error, not ours
    assert decode.decode_imu_block(other, "cdr") is None
    other[2, 16] = ord("i")
    other[2, 19] = ord("X")                                   # the string's NUL terminator overwritten
    assert decode.decode_imu_block(other, "cdr") is None
    bad_ns = block.copy()
    bad_ns[1, 8:12] = np.frombuffer(np.uint32(2_000_000_000).tobytes(), np.uint8)
    assert decode.decode_imu_block(bad_ns, "cdr") is None
    assert decode.decode_imu_block(block[:, :-8], "cdr") is None


# --------------------------------------------------------------------------- increments and times

@pytest.mark.parametrize("name", ["x.bag", "x.mcap", "x.db3"])
def test_read_imu_increments_closed_form(tmp_path, name):
    """Rates linear in time: the trapezoid integral is exact, so increments have a closed form."""
    n, dt, t0 = 201, 0.005, 500.0
    t = t0 + dt * np.arange(n)
    a, b = np.array([0.1, -0.2, 0.3]), np.array([0.01, 0.02, -0.03])
    fa, fb = np.array([0.5, -0.1, 9.8]), np.array([-0.2, 0.05, 0.0])
    gyro, accel = a + np.outer(t - t0, b), fa + np.outer(t - t0, fb)
    path = _write(tmp_path / name, imu={"time": t, "gyro": gyro, "accel": accel}, log_delay=0.25)
    imu = ros.read_imu(path)
    assert imu.t0 == pytest.approx(t0, abs=1e-9) and len(imu) == n - 1 and imu.kind == "rates"
    s0, s1 = (t[:-1] - t0), (t[1:] - t0)
    exact_dth = np.outer(s1 - s0, a) + np.outer((s1 ** 2 - s0 ** 2) / 2, b)
    exact_dv = np.outer(s1 - s0, fa) + np.outer((s1 ** 2 - s0 ** 2) / 2, fb)
    np.testing.assert_allclose(imu.dtheta_b, exact_dth, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(imu.dvel_b, exact_dv, rtol=1e-9, atol=1e-15)
    # log time = header stamp + 0.25 s here
    imu_log = ros.read_imu(path, time_source="log")
    np.testing.assert_allclose(imu_log.time - imu.time, 0.25, atol=1e-9)
    assert np.array_equal(imu_log.dtheta_b, imu.dtheta_b)
    # an interval keeps the samples inside it
    part = ros.read_imu(path, start=t0 + 0.1, end=t0 + 0.2)
    assert part.t0 == pytest.approx(t0 + 0.1, abs=1e-9) and len(part) == 20


def test_gnss_fields_velocity_and_no_fix(tmp_path, caplog):
    g = _gnss(n=8)
    g["status"] = np.array([0, 0, -1, 0, 0, -1, 0, 0])
    g["lat"] = g["lat"].copy()
    g["lat"][5] = np.nan                                     # a "no fix" message may hold NaN
    vel = {"time": g["time"], "vel": np.column_stack([np.arange(8.0), -np.arange(8.0), 0.5 * np.ones(8)]),
           "std": np.tile([0.1, 0.2, 0.3], (8, 1))}
    path = _write(tmp_path / "g.mcap", imu=_imu(), gnss=g, vel=vel)
    with caplog.at_level("WARNING", logger="sins"):
        out = ros.read_gnss(path, vel_topic="/fix_velocity")
    keep = g["status"] >= 0
    assert "dropped 2 of 8" in caplog.text
    assert np.array_equal(out.lat, g["lat"][keep]) and np.array_equal(out.height, g["height"][keep])
    np.testing.assert_allclose(out.time, g["time"][keep], atol=1e-9)
    assert np.array_equal(out.std_pos, np.tile([2.0, 3.0, 4.0], (6, 1)))
    assert np.array_equal(out.vel_n, vel["vel"][keep])
    np.testing.assert_allclose(out.std_vel, np.tile([0.1, 0.2, 0.3], (6, 1)), rtol=1e-15)
    nostd = ros.read_gnss(_write(tmp_path / "u.bag", gnss={**_gnss(), "cov_type": np.zeros(6)}))
    assert nostd.std_pos is None and nostd.vel_n is None


# --------------------------------------------------------------------------- topic choice

def test_topic_choice(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "two.bag"
    with Writer(path) as w:
        c1 = w.add_connection("/imu_a", "sensor_msgs/msg/Imu", typestore=ts)
        c2 = w.add_connection("/imu_b", "sensor_msgs/msg/Imu", typestore=ts)
        imu = _imu(n=5)
        for k, m in enumerate(write._imu_messages(ts, True, imu, "imu")):
            raw = ts.serialize_ros1(m, "sensor_msgs/msg/Imu")
            w.write(c1, int(imu["time"][k] * 1e9), raw)
            w.write(c2, int(imu["time"][k] * 1e9), raw)
    with pytest.raises(SinsError, match=r"several sensor_msgs/msg/Imu topics \(/imu_a, /imu_b\).*--imu-topic"):
        ros.read_imu(path)
    assert len(ros.read_imu(path, topic="/imu_b")) == 4
    with pytest.raises(SinsError, match="topic /nope not found; topics: /imu_a .*, /imu_b"):
        ros.read_imu(path, topic="/nope")
    with pytest.raises(SinsError, match="no sensor_msgs/msg/NavSatFix topic"):
        ros.read_gnss(path)
    assert ros.is_log(path) and ros.is_log(tmp_path / "a.mcap") and ros.is_log(tmp_path / "b.db3")
    assert not ros.is_log(tmp_path / "imu.csv") and not ros.is_log(tmp_path)


# --------------------------------------------------------------------------- CLI: info, convert

def _run(args):
    return CliRunner().invoke(main, args)


def test_info_cli(husky):
    res = _run(["info", str(husky["bag"])])
    assert res.exit_code == 0, res.output
    out = res.output
    assert "ROS 1 bag" in out and "16806 messages" in out
    for line in ["/imu/data", "/fix", "/husky_velocity_controller/odom"]:
        assert line in out
    assert "11865" in out and "989" in out and "3952" in out
    assert "up axis is +y" in out
    res = _run(["info", "--json", str(husky["mcap"])])
    import json
    s = json.loads(res.output)
    imu_row = next(r for r in s["topics"] if r["topic"] == "/imu/data")
    assert imu_row["count"] == 11865 and abs(imu_row["rate_hz"] - 30.0) < 0.1 and imu_row["gaps"] == 0
    assert 9.7 < s["imu"]["/imu/data"]["mean_accel"][1] < 9.9


def test_convert_cli_writes_formats_csv(husky, tmp_path):
    from sinscli.io.gnss_csv import read_gnss_csv
    from sinscli.io.imu_csv import read_imu_csv
    out = tmp_path / "out"
    res = _run(["convert", str(husky["ros2_mcap_dir"]), "-o", str(out), "-q"])
    assert res.exit_code == 0, res.output
    imu, gnss = ros.read_imu(husky["bag"]), ros.read_gnss(husky["bag"])
    back = read_imu_csv(out / "imu.csv")
    assert np.array_equal(back.time, imu.time) and np.array_equal(back.dtheta_b, imu.dtheta_b)
    assert np.array_equal(back.dvel_b, imu.dvel_b)
    g = read_gnss_csv(out / "gnss.csv")
    assert np.array_equal(g.lat, gnss.lat) and np.array_equal(g.std_pos, gnss.std_pos)
    # the Odometry topic is body velocity: odom.csv, in the axes of its child frame base_link
    from sinscli.io.body_vel_csv import read_body_velocity_csv
    from sinscli.io.ros.odometry import read_body_velocity
    odom = read_body_velocity_csv(out / "odom.csv")
    ref = read_body_velocity(husky["bag"])
    assert np.array_equal(odom.time, ref.time) and np.array_equal(odom.vel_b, ref.vel_b)
    assert np.array_equal(odom.std, ref.std)
    # ... and never ENU GNSS velocity
    out2 = tmp_path / "out2"
    res = _run(["convert", str(husky["bag"]), "-o", str(out2), "-q", "--vel-topic", "/husky_velocity_controller/odom"])
    assert res.exit_code == 2 and "is nav_msgs/msg/Odometry" in res.output and "not an ENU velocity" in res.output
    assert not out2.exists()


# --------------------------------------------------------------------------- bad input through the CLI

def _flip_compression(path: Path, old: bytes, new: bytes):
    data = path.read_bytes()
    assert old in data
    path.write_bytes(data.replace(old, new))


def _case(tmp_path, kind):
    """(log path, extra CLI args, text the error must contain)."""
    t = tmp_path
    imu = _imu()
    if kind == "truncated_bag":
        p = _write(t / "x.bag", imu=imu, gnss=_gnss())
        p.write_bytes(p.read_bytes()[: p.stat().st_size * 2 // 3])
        return p, [], "x.bag"
    if kind == "truncated_mcap":
        p = _write(t / "x.mcap", imu=imu, gnss=_gnss())
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
        return p, [], "x.mcap"
    if kind == "truncated_db3":
        p = _write(t / "x.db3", imu=imu, gnss=_gnss())
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
        return p, [], "x.db3"
    if kind == "corrupt_mcap_chunk":
        p = _write(t / "x.mcap", imu=_imu(n=400), gnss=_gnss())
        b = bytearray(p.read_bytes())
        b[len(b) // 3: len(b) // 3 + 16] = bytes(range(16))
        p.write_bytes(bytes(b))
        return p, [], "x.mcap"
    if kind == "corrupt_bag_bz2":
        p = _write(t / "x.bag", imu=_imu(n=400), gnss=_gnss(), bag_compression="bz2")
        b = bytearray(p.read_bytes())
        b[len(b) // 3] ^= 0xFF
        p.write_bytes(bytes(b))
        return p, [], "x.bag"
    if kind == "missing_topic":
        return _write(t / "x.bag", imu=imu, gnss=_gnss()), ["--imu-topic", "/imu/raw"], \
            "topic /imu/raw not found; topics: /fix (sensor_msgs/msg/NavSatFix), /imu/data (sensor_msgs/msg/Imu)"
    if kind == "wrong_type":
        return _write(t / "x.mcap", imu=imu, gnss=_gnss()), ["--imu-topic", "/fix"], \
            "topic /fix is sensor_msgs/msg/NavSatFix, expected sensor_msgs/msg/Imu"
    if kind == "wrong_vel_type":
        return _write(t / "x.bag", imu=imu, gnss=_gnss()), ["--vel-topic", "/imu/data"], \
            "topic /imu/data is sensor_msgs/msg/Imu, expected geometry_msgs/msg/TwistStamped"
    if kind == "empty_interval":
        return _write(t / "x.db3", imu=imu, gnss=_gnss()), ["--start", "2000", "--end", "2001"], \
            "topic /imu/data: no messages between 2000.0 and 2001.0 s"
    if kind in ("stamps_backwards", "stamps_repeat"):
        bad = dict(imu)
        bad["time"] = imu["time"].copy()
        bad["log_time"] = imu["time"]                    # log order stays increasing
        if kind == "stamps_backwards":
            bad["time"][10] = bad["time"][8]
            text = "header stamp goes backwards at message 10"
        else:
            bad["time"][10] = bad["time"][9]
            text = "header stamp repeats at message 10"
        return _write(t / "x.mcap", imu=bad), [], "topic /imu/data: " + text
    if kind == "navsat_nan":
        g = _gnss()
        g["lat"] = g["lat"].copy()
        g["lat"][3] = np.nan
        return _write(t / "x.bag", imu=imu, gnss=g), [], "topic /fix: message 3 has a fix with NaN"
    if kind == "navsat_zero_cov":
        g = _gnss()
        g["cov"] = g["cov"].copy()
        g["cov"][2] = 0.0
        return _write(t / "x.db3", imu=imu, gnss=g), [], ("topic /fix: message 2, column 'position variance [0] "
                                                          "(covariance type known)': 0.0 is not a positive finite "
                                                          "variance")
    if kind == "compression_bag":
        p = _write(t / "x.bag", imu=imu, gnss=_gnss(), bag_compression="bz2")
        _flip_compression(p, b"compression=bz2", b"compression=xz9")
        return p, [], "Compression 'xz9' is not supported"
    if kind == "compression_mcap":
        from mcap.writer import CompressionType, Writer
        p = t / "x.mcap"
        with open(p, "wb") as f:
            w = Writer(f, compression=CompressionType.LZ4)
            w.start()
            sid = w.register_schema("sensor_msgs/msg/Imu", "ros2msg", b"")
            cid = w.register_channel("/imu/data", "cdr", sid)
            w.add_message(cid, log_time=1, data=b"\x00\x01\x00\x00", publish_time=1)
            w.finish()
        _flip_compression(p, b"\x03\x00\x00\x00lz4", b"\x03\x00\x00\x00lzq")
        return p, [], "unknown chunk compression 'lzq'"
    if kind == "compression_ros2_dir":
        p = _write(t / "xdir", imu=imu, gnss=_gnss())
        meta = (p / "metadata.yaml").read_text()
        meta = meta.replace("compression_format: ''", "compression_format: brotli")
        meta = meta.replace("compression_mode: ''", "compression_mode: FILE")
        (p / "metadata.yaml").write_text(meta)
        return p, [], "Compression format 'brotli' is not supported"
    raise AssertionError(kind)


BAD = ["truncated_bag", "truncated_mcap", "truncated_db3", "corrupt_mcap_chunk", "corrupt_bag_bz2",
       "missing_topic", "wrong_type", "wrong_vel_type", "empty_interval", "stamps_backwards", "stamps_repeat",
       "navsat_nan", "navsat_zero_cov", "compression_bag", "compression_mcap", "compression_ros2_dir"]


@pytest.mark.parametrize("kind", BAD)
def test_bad_input_cli(tmp_path, kind):
    path, args, text = _case(tmp_path, kind)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["convert", str(path), "-o", str(out), "-q", *args])
    assert res.exit_code == 2, (res.output, res.exception)
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sins: error: "), res.stderr
    assert str(path) in err[0] and text in err[0], err[0]
    assert not out.exists() or not any(out.iterdir())
