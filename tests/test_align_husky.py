"""Alignment on the real Husky log (tests/data/ros1_husky): roll and pitch against the IMU's own
orientation field, heading from the GNSS course (the MEMS gyro cannot see the earth rate)."""
import math
from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG
import yaml
from click.testing import CliRunner

from sinscli.align.options import build_options, load_align_config
from sinscli.align.pipeline import align
from sinscli.cli import main
from sinscli.io.readers import read_gnss, read_imu
from sinscli.nav.rotation import dcm_to_euler, dcm_to_euler_many, quat_to_dcm_many

ROOT = Path(__file__).resolve().parents[1]
BAG = HUSKY_BAG
CONFIG = ROOT / "configs" / "align" / "husky.yaml"

pytestmark = pytest.mark.skipif(not BAG.exists(), reason=f"real data not present: {BAG}")


@pytest.fixture(scope="module")
def reference():
    """The IMU's own orientation (sensor_msgs/Imu orientation, imu_link -> its level frame), read with
    rosbags, turned into the body axes of the config's mounting: ``C_b^w = C_imu^w C_b^imu``."""
    from rosbags.highlevel import AnyReader
    t, q = [], []
    with AnyReader([BAG]) as reader:
        conns = [c for c in reader.connections if c.topic == "/imu/data"]
        for c, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, c.msgtype)
            t.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec)
            q.append([m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z])
    cfg, _ = load_align_config(CONFIG)
    c_sb = np.array(cfg.imu.mounting, dtype=float)
    c = quat_to_dcm_many(np.ascontiguousarray(q, dtype=float)) @ c_sb.T
    return np.array(t), np.degrees(dcm_to_euler_many(c, 0))


@pytest.fixture(scope="module")
def logs():
    cfg, al = load_align_config(CONFIG)
    return read_imu(BAG, cfg), read_gnss(BAG, cfg), al


def _ref_at(reference, t):
    times, eul = reference
    return eul[int(np.argmin(np.abs(times - t)))]


@pytest.mark.parametrize("offset", [0.0, 100.0, 200.0, 300.0])
def test_roll_pitch_against_the_imu_orientation(logs, reference, offset):
    imu, gnss, al = logs
    d = dict(al, start=float(imu.t0) + offset)
    res = align(imu, build_options(d, "husky.yaml"), gnss)
    est = np.degrees(dcm_to_euler(res.state.Cbn, 0))
    ref = _ref_at(reference, res.state.time)
    assert abs(est[0] - ref[0]) < 1.0 and abs(est[1] - ref[1]) < 1.0, (est, ref)
    assert res.heading_source == "gnss-course"
    assert math.degrees(res.sigma[2]) < 10.0


def test_cli_end_to_end_on_the_bag(reference, tmp_path):
    out = tmp_path / "husky_init.yaml"
    res = CliRunner().invoke(main, ["align", str(BAG), "--gnss", str(BAG), "--config", str(CONFIG), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "heading is not observable from earth rate" in res.output
    assert "heading from the GNSS course" in res.output
    d = yaml.safe_load(out.read_text())
    assert d["heading_source"] == "gnss-course" and d["method"] == "gnss-inertial"
    ref = _ref_at(reference, d["time"])
    assert abs(d["roll"] - ref[0]) < 1.0 and abs(d["pitch"] - ref[1]) < 1.0
    assert abs(d["lat"] - 42.3758) < 0.001 and abs(d["lon"] + 71.147) < 0.001
    # without GNSS the heading has no source: refused, nothing written
    out2 = tmp_path / "none.yaml"
    res = CliRunner().invoke(main, ["align", str(BAG), "--config", str(CONFIG), "--method", "inertial",
                                    "--position", "42.3758,-71.147,7", "-o", str(out2)])
    assert res.exit_code == 2 and "not observable" in res.output and not out2.exists()
