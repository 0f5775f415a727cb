"""`sins navigate` from files: round trips, outputs, and every bad input of the issue."""
import math

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.imu_csv import read_imu_csv, rates_to_increments
from sinscli.io.trajectory import read_trajectory
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sim import motions, write_sim


@pytest.fixture(scope="module")
def simdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim")
    write_sim(motions.drive(duration=20.0, rate=100.0), d)
    return d


def run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


def test_navigate_csv_matches_truth_and_round_trips(simdir, tmp_path):
    out = tmp_path / "nav.csv"
    r = run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    nav = read_trajectory(out)
    truth = read_trajectory(simdir / "truth.csv")
    s = compare_trajectories(truth, nav)
    assert nav.time[0] == truth.time[0] and len(nav) == len(truth)
    assert math.degrees(s.angle_rad.max()) < 1e-8 and np.abs(s.pos_enu_m).max() < 1e-5
    header = out.read_text().splitlines()[0].split(",")
    assert header[:14] == ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "roll", "pitch",
                           "heading", "qw", "qx", "qy", "qz"] and "c33" in header
    # init from a trajectory CSV gives the same result
    out2 = tmp_path / "nav2.parquet"
    r = run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "truth.csv"), "-o", str(out2), "-q",
             "--every", "10"])
    assert r.exit_code == 0, r.output
    nav2 = read_trajectory(out2)
    assert len(nav2) == 201 and np.array_equal(nav2.Cbn[1:], nav.Cbn[10::10])


def test_floats_round_trip_exactly(simdir, tmp_path):
    out = tmp_path / "nav.csv"
    run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "-o", str(out), "-q"])
    import pandas as pd
    df = pd.read_csv(out, engine="c")
    nav = read_trajectory(out)
    assert np.array_equal(df["c12"].to_numpy(), nav.Cbn[:, 0, 1])


def test_rate_file_and_units(tmp_path):
    t = np.arange(0, 2.0001, 0.01)
    w = np.column_stack([0.1 * np.sin(t), 0.2 * np.ones_like(t), 0.05 * t])
    f = np.column_stack([np.zeros_like(t), np.zeros_like(t), 9.8 * np.ones_like(t)])
    p = tmp_path / "rates.csv"
    cols = np.column_stack([t, np.degrees(w), f / 9.80665])
    p.write_text("stamp,wx,wy,wz,ax,ay,az\n" + "\n".join(",".join(repr(float(x)) for x in row) for row in cols))
    cfg = {"columns": {"time": "stamp", "gyro_x": "wx", "gyro_y": "wy", "gyro_z": "wz",
                       "accel_x": "ax", "accel_y": "ay", "accel_z": "az"},
           "units": {"gyro": "deg/s", "accel": "g"}}
    imu = read_imu_csv(p, cfg)
    tend, dth, dv, t0 = rates_to_increments(t, w, f)
    assert imu.t0 == 0.0 and imu.kind == "rates"
    np.testing.assert_allclose(imu.dtheta_b, dth, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(imu.dvel_b, dv, rtol=1e-14)
    # trapezoid of a linear rate is exact
    np.testing.assert_allclose(imu.dtheta_b[:, 2], 0.05 * (tend ** 2 - (tend - 0.01) ** 2) / 2, rtol=1e-9)


# ---------------------------------------------------------------- bad input

def _imu_text(rows, header="time,dtheta_x,dtheta_y,dtheta_z,dvel_x,dvel_y,dvel_z"):
    return header + "\n" + "\n".join(rows) + "\n"


GOOD = [f"{0.01 * k:.2f},0,0,0,0,0,0.098" for k in range(1, 11)]
INIT = "time: 0.0\nlat: 30\nlon: 114\nheight: 10\nvel_e: 0\nvel_n: 0\nvel_u: 0\nroll: 0\npitch: 0\nheading: 0\n"

CASES = {
    "missing_file": (None, INIT, "file not found"),
    "empty": ("", INIT, "file is empty"),
    "missing_column": (_imu_text(GOOD, "time,dtheta_x,dtheta_y,dtheta_z,dvel_x,dvel_y,speed"), INIT,
                       "unknown column"),
    "missing_only": ("time,dtheta_x,dtheta_y,dtheta_z,dvel_x,dvel_y\n0.01,0,0,0,0,0\n", INIT,
                     "missing column(s) dvel_z"),
    "non_numeric": (_imu_text(GOOD[:3] + ["0.04,0,abc,0,0,0,0.098"] + GOOD[4:]), INIT,
                    "line 5, column 'dtheta_y': 'abc' is not a number"),
    "nan": (_imu_text(GOOD[:3] + ["0.04,0,nan,0,0,0,0.098"] + GOOD[4:]), INIT,
            "line 5, column 'dtheta_y': value nan is not a finite number"),
    "inf": (_imu_text(GOOD[:3] + ["0.04,0,0,inf,0,0,0.098"] + GOOD[4:]), INIT, "is not a finite number"),
    "repeat": (_imu_text(GOOD[:3] + ["0.03,0,0,0,0,0,0.098"] + GOOD[4:]), INIT, "line 5, column 'time': time 0.03 repeats"),
    "backwards": (_imu_text(GOOD[:3] + ["0.02,0,0,0,0,0,0.098"] + GOOD[4:]), INIT, "goes backwards"),
    "gap": (_imu_text(GOOD[:5] + ["0.20,0,0,0,0,0,0.098", "0.21,0,0,0,0,0,0.098", "0.22,0,0,0,0,0,0.098"]),
            INIT, "gap of 0.15 s"),
    "init_outside": (_imu_text(GOOD), INIT.replace("time: 0.0", "time: 5.0"), "outside the log"),
    "init_before": (_imu_text(GOOD), INIT.replace("time: 0.0", "time: -5.0"), "before the log starts"),
    "init_missing_key": (_imu_text(GOOD), INIT.replace("heading: 0\n", ""), "missing key(s) heading"),
    "latitude": (_imu_text(GOOD), INIT.replace("lat: 30", "lat: 95"), "outside [-90, 90]"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input(case, tmp_path):
    imu_text, init_text, msg = CASES[case]
    imu = tmp_path / "imu.csv"
    if imu_text is not None:
        imu.write_text(imu_text)
    init = tmp_path / "init.yaml"
    init.write_text(init_text)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(main, ["navigate", str(imu), "--init", str(init), "-o", str(out), "-q"])
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("sins: error: ") and msg in lines[0], r.output
    assert "Traceback" not in r.output
    assert not out.exists() and not list(tmp_path.glob(".out.csv*"))


def test_allow_gaps_bridges_with_warning(tmp_path, caplog):
    imu = tmp_path / "imu.csv"
    imu.write_text(_imu_text(GOOD[:5] + ["0.20,0,0,0,0,0,0.098", "0.21,0,0,0,0,0,0.098"]))
    init = tmp_path / "init.yaml"
    init.write_text(INIT)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(main, ["navigate", str(imu), "--init", str(init), "-o", str(out), "-q", "--allow-gaps"])
    assert r.exit_code == 0 and out.exists()
    assert "bridging a gap of 0.15 s from time 0.05 to 0.2" in caplog.text


def test_unit_and_axis_warnings(tmp_path, caplog):
    t = np.arange(0, 1.0001, 0.01)
    rows = [f"{float(x)!r},10.0,0.0,0.0,0,0,-9.79" for x in t]   # deg/s-like rate, z pointing down
    imu = tmp_path / "imu.csv"
    imu.write_text(_imu_text(rows, "time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"))
    init = tmp_path / "init.yaml"
    init.write_text(INIT)
    r = CliRunner().invoke(main, ["navigate", str(imu), "--init", str(init), "-o", str(tmp_path / "o.csv"), "-q",
                                  "--static-start"])
    assert r.exit_code == 0
    assert "probably holds deg/s" in caplog.text
    assert "FRD axes? set imu.body: frd" in caplog.text


def test_config_errors_name_the_key(tmp_path, simdir):
    cfg = tmp_path / "nav.yaml"
    cfg.write_text("navigation:\n  coning: 5\n")
    r = CliRunner().invoke(main, ["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"),
                                  "--config", str(cfg), "-o", str(tmp_path / "o.csv"), "-q"])
    assert r.exit_code == 2 and "navigation.coning: expected one of 1, 2, 3, 4, got 5" in r.output
    cfg.write_text("navigation:\n  colour: red\n")
    r = CliRunner().invoke(main, ["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"),
                                  "--config", str(cfg), "-o", str(tmp_path / "o.csv"), "-q"])
    assert r.exit_code == 2 and "navigation.colour: unknown key" in r.output
    assert not (tmp_path / "o.csv").exists()


def test_shipped_config_is_valid():
    from pathlib import Path
    from sinscli.config import load_config
    cfg = load_config(Path(__file__).resolve().parents[1] / "configs" / "navigation.yaml")
    assert cfg["navigation"]["attitude"] == "quat"


def test_unwired_attitude_methods_are_refused(simdir, tmp_path):
    """Never a silently wrong trajectory: a method that is not in the loop is refused, not replaced."""
    out = tmp_path / "o.csv"
    r = CliRunner().invoke(main, ["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"),
                                  "--attitude", "dcm", "--angles", "-o", str(out), "-q"])
    assert r.exit_code == 2 and "--angles" in r.output and not out.exists()


def test_unix_epoch_time_base(simdir, tmp_path):
    """Stamps of ~1.4e9 s: every sample after the initial time is applied (no tolerance of whole seconds)."""
    import yaml
    base = 1432235497.988949
    imu = (simdir / "imu.csv").read_text().splitlines()
    rows = [imu[0]] + [",".join([repr(float(r.split(",")[0]) + base)] + r.split(",")[1:]) for r in imu[1:]]
    (tmp_path / "imu.csv").write_text("\n".join(rows) + "\n")
    init = yaml.safe_load((simdir / "init.yaml").read_text())
    init["time"] = init["time"] + base
    (tmp_path / "init.yaml").write_text(yaml.safe_dump(init))
    out = tmp_path / "nav.csv"
    r = run(["navigate", str(tmp_path / "imu.csv"), "--init", str(tmp_path / "init.yaml"), "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    nav = read_trajectory(out)
    ref = read_trajectory(simdir / "truth.csv")
    assert len(nav) == len(rows)          # header -> initial row, then one row per sample
    assert np.abs(nav.time - (ref.time + base)).max() < 1e-6
    assert np.abs(np.degrees(nav.lat - ref.lat)).max() < 1e-9


def test_one_config_serves_align_and_navigate(simdir, tmp_path):
    """A config with an align: section (configs/align/*.yaml) is accepted by sins navigate."""
    cfg = tmp_path / "both.yaml"
    cfg.write_text("imu:\n  body: flu\nalign:\n  method: static\n  duration: 30\n")
    out = tmp_path / "o.csv"
    r = run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "--config", str(cfg),
             "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    cfg.write_text("imu:\n  body: flu\nalignment:\n  method: static\n")
    r = CliRunner().invoke(main, ["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"),
                                  "--config", str(cfg), "-o", str(out), "-q"])
    assert r.exit_code == 2 and "alignment: unknown section" in r.output


def test_gap_rule_applies_to_ros_logs(tmp_path):
    """The CSV gap rule holds for bags too: refused by default (file, topic, message named), bridged
    with --allow-gaps."""
    from sinscli.io.ros import write_log
    t = np.concatenate([np.arange(0, 1, 0.01), np.arange(1.5, 2, 0.01)]) + 1000.0
    n = len(t)
    bag = tmp_path / "gap.bag"
    write_log(bag, imu={"time": t, "gyro": np.zeros((n, 3)), "accel": np.tile([0.0, 0.0, 9.8], (n, 1))})
    init = tmp_path / "init.yaml"
    init.write_text(INIT.replace("time: 0.0", "time: 1000.0"))
    out = tmp_path / "o.csv"
    r = CliRunner().invoke(main, ["navigate", str(bag), "--init", str(init), "-o", str(out), "-q"])
    assert r.exit_code == 2 and "topic /imu/data: message 100: gap of 0.51 s" in r.output and not out.exists()
    r = CliRunner().invoke(main, ["navigate", str(bag), "--init", str(init), "-o", str(out), "-q",
                                  "--allow-gaps"])
    assert r.exit_code == 0 and len(read_trajectory(out)) == n
