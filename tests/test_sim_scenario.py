"""Scenario validation and the ``sins simulate`` command: bad inputs, outputs, shipped scenarios."""
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.gnss_csv import read_gnss_csv
from sinscli.io.imu_csv import read_imu_csv
from sinscli.io.init_state import read_init
from sinscli.io.trajectory import read_trajectory
from sinscli.sim import simulate
from sinscli.sim.run import prepare

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = sorted((ROOT / "configs" / "scenarios").glob("*.yaml"))

SMALL = {"name": "small", "seed": 3,
         "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 45.0},
         "imu": {"rate": 50, "sensor": "tactical"},
         "gnss": {"rate": 2, "pos_noise": 1.0, "vel_noise": 0.05, "lever_arm": [0.5, 0.0, 1.0]},
         "segments": [{"type": "rest", "duration": 2}, {"type": "accelerate", "speed": 10, "duration": 3},
                      {"type": "turn", "angle": 45, "duration": 3}]}


def _write(tmp_path, data, name="scenario.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def _run(args):
    return CliRunner().invoke(main, args)


def _bad(tmp_path, mutate):
    data = yaml.safe_load(yaml.safe_dump(SMALL))
    mutate(data)
    p = _write(tmp_path, data)
    out = tmp_path / "out"
    res = _run(["simulate", str(p), "-o", str(out), "--quiet"])
    return res, out


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["segments"].insert(3, {"type": "fly", "duration": 3}),
     r"scenario\.yaml: segments\[3\]\.type: unknown segment type 'fly'; expected one of accelerate, boost"),
    (lambda d: d["segments"][1].update(sped=3),
     r"scenario\.yaml: segments\[1\]\.sped: unknown key 'sped' for segment type 'accelerate'"),
    (lambda d: d["segments"][2].update(duration=-4),
     r"scenario\.yaml: segments\[2\]\.duration: must be > 0; got -4"),
    (lambda d: d["imu"].update(rate=0.5), r"scenario\.yaml: imu\.rate: must be at least 1 Hz; got 0\.5"),
    (lambda d: d["gnss"].update(rate=100), r"scenario\.yaml: gnss\.rate: 100 Hz is above the IMU rate 50 Hz"),
    (lambda d: d.update(colour="red"), r"scenario\.yaml: colour: unknown key 'colour'"),
    (lambda d: d["segments"][1].pop("speed"),
     r"segments\[1\]: segment type 'accelerate' needs exactly one of speed, accel"),
    (lambda d: d["segments"].append({"type": "rest", "duration": 1}),
     r"segments\[3\]: 'rest' needs the vehicle at rest at its start \(speed 10 m/s"),
    (lambda d: d["segments"].append({"type": "decelerate", "accel": -5, "duration": 6}),
     r"segments\[3\]: the speed would become negative"),
    (lambda d: d["imu"].update(sensor="phone"), r"imu\.sensor: no sensor preset or file 'phone'"),
    (lambda d: d["start"].update(lat=91), r"start\.lat: must be within \(-89\.9, 89\.9\) degrees"),
    (lambda d: d["segments"].insert(1, {"type": "coning", "half_angle": 1, "freq": 1, "duration": 4,
                                        "ramp": 0}), r"segments\[1\]\.ramp: 0 is allowed only for the first"),
    (lambda d: d["gnss"].update(outages=[[10, 5]]), r"gnss\.outages\[0\]: end 5 must be after start 10"),
])
def test_bad_scenarios_are_refused_with_the_key_named(tmp_path, mutate, message):
    res, out = _bad(tmp_path, mutate)
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("sins: error: ")
    import re
    assert re.search(message, lines[0]), lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_unreadable_and_invalid_yaml(tmp_path):
    res = _run(["simulate", str(tmp_path / "missing.yaml"), "-o", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and "missing.yaml: scenario not found" in res.output
    p = tmp_path / "broken.yaml"
    p.write_text("segments: [ {type: rest\n")
    res = _run(["simulate", str(p), "-o", str(tmp_path / "o"), "--quiet"])
    assert res.exit_code == 2 and re.search(r"broken.yaml: line \d+, column \d+: not valid YAML", res.output)
    assert not (tmp_path / "o").exists()


def test_cli_writes_files_that_read_back_exactly(tmp_path):
    p = _write(tmp_path, SMALL)
    out = tmp_path / "run"
    res = _run(["simulate", str(p), "-o", str(out), "--quiet"])
    assert res.exit_code == 0, res.output
    assert sorted(x.name for x in out.iterdir()) == ["gnss.csv", "imu.csv", "init.yaml", "sim_truth.yaml", "truth.csv"]
    ref = simulate(SMALL)                                    # the scenario's seed 3
    imu = read_imu_csv(out / "imu.csv")
    assert np.array_equal(imu.time, ref.imu.time)
    assert np.array_equal(imu.dtheta_b, ref.imu.dtheta_b) and np.array_equal(imu.dvel_b, ref.imu.dvel_b)
    tr = read_trajectory(out / "truth.csv")
    assert np.array_equal(tr.time, ref.truth.time) and np.array_equal(tr.vel_n, ref.truth.vel_n)
    assert np.abs(tr.lat - ref.truth.lat).max() < 1e-15        # degrees on file, radians in memory
    assert np.abs(tr.Cbn - ref.truth.Cbn).max() < 1e-15
    gn = read_gnss_csv(out / "gnss.csv")
    assert np.array_equal(gn.time, ref.gnss.time) and np.array_equal(gn.height, ref.gnss.height)
    init = read_init(out / "init.yaml")
    assert init.time == 0.0 and abs(init.lat - np.radians(30.0)) < 1e-15
    assert np.abs(init.Cbn - ref.truth.Cbn[0]).max() < 1e-15
    extra = yaml.safe_load((out / "init.yaml").read_text())
    assert extra["launch"] == {"time": 0.0, "lat": 30.0, "lon": 114.0, "height": 50.0, "azimuth": 45.0}
    assert extra["seed"] == 3 and extra["perfect"] is False


def test_cli_seed_reproducible_and_perfect(tmp_path):
    p = _write(tmp_path, SMALL)
    for name in ("a", "b"):
        assert _run(["simulate", str(p), "-o", str(tmp_path / name), "--seed", "9", "--quiet"]).exit_code == 0
    assert _run(["simulate", str(p), "-o", str(tmp_path / "c"), "--seed", "10", "--quiet"]).exit_code == 0
    assert _run(["simulate", str(p), "-o", str(tmp_path / "p"), "--perfect", "--quiet"]).exit_code == 0
    for f in ("imu.csv", "gnss.csv", "truth.csv"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
    assert (tmp_path / "a" / "imu.csv").read_bytes() != (tmp_path / "c" / "imu.csv").read_bytes()
    assert (tmp_path / "a" / "truth.csv").read_bytes() == (tmp_path / "p" / "truth.csv").read_bytes()
    perfect = read_imu_csv(tmp_path / "p" / "imu.csv")
    assert np.array_equal(perfect.dtheta_b, simulate(SMALL, perfect=True).imu.dtheta_b)
    assert "std_e" not in (tmp_path / "p" / "gnss.csv").read_text().splitlines()[0]


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_shipped_scenarios_validate_and_start_consistently(path):
    data = yaml.safe_load(path.read_text())
    p = prepare(str(path))
    rate = p.scenario.imu_rate
    assert rate in (100.0, 200.0)                           # 100 Hz; the tactical RTK drive 200 Hz
    assert p.n_imu >= 600 * rate                            # every shipped run is 10 min or more
    short = simulate(dict(data, duration=3.0))
    assert len(short.imu) == 3 * rate
    assert np.array_equal(short.truth.Cbn[0], short.init.Cbn)
    # the first seconds of the full-length run and of the cut one are the same motion
    if data.get("imu", {}).get("sensor") is None:
        assert np.all(np.isfinite(short.imu.dvel_b))
    assert abs(np.linalg.norm(short.imu.dvel_b[0]) * rate - 9.8) < 40.0


def test_cli_duration_cuts_the_run_and_is_checked(tmp_path):
    p = _write(tmp_path, SMALL)
    res = _run(["simulate", str(p), "-o", str(tmp_path / "cut"), "--duration", "3", "--quiet"])
    assert res.exit_code == 0, res.output
    imu = read_imu_csv(tmp_path / "cut" / "imu.csv")
    assert len(imu) == 150 and imu.time[-1] == 3.0
    full = simulate(SMALL)
    assert np.array_equal(imu.dtheta_b, full.imu.dtheta_b[:150])       # the same motion, cut
    res = _run(["simulate", str(p), "-o", str(tmp_path / "long"), "--duration", "100", "--quiet"])
    assert res.exit_code == 2 and "--duration: must be > 0" in res.output and "scenario's 8 s" in res.output
    assert not (tmp_path / "long").exists()
