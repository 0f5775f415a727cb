"""Every 1-sigma ``sins align`` writes is honest (issue 10, "Honest alignment").

Monte Carlo over >= 50 seeds of simulated static and moving logs (exact truth), each method told the
sensor description right, not told it, and told one ten times too optimistic: the fraction of runs
whose error lies inside the reported 3-sigma is >= 95 % for roll, pitch and heading, and no sigma is
below the Cramer-Rao-like floor of the true sensor noise and the duration (computed here, in closed
form at rest and as the Fisher information of the GNSS velocities on the move, independently of the
code).  Then the issue's cases: the low-grade IMU on a moving base, the shipped sample data with
``kf``, a translating base without GNSS, an earth-rate heading the log makes unobservable whatever
the description says, GNSS glitches, the sensor description in all its forms, and the outputs.
"""
import copy
import math
import os
import shutil
import sys
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.align import observability, sway
from sinscli.align.montecarlo import coverage_runs
from sinscli.align.options import AlignOptions, SensorSpec, build_options, merge_section
from sinscli.align.pipeline import align
from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.io.trajectory import read_trajectory
from sinscli.nav.earth import gravity
from sinscli.nav.rotation import dcm_to_euler
from sinscli.sensors import load_sensor

ROOT = Path(__file__).resolve().parents[1]
SEEDS = range(50)
LAT = math.radians(30.0)
G = float(gravity(math.sin(LAT), 50.0))

STATIC = {"name": "static", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 40, "pitch": 1.0, "roll": -2.0},
          "imu": {"rate": 10, "sensor": "navigation"}, "gnss": {"rate": 1},
          "segments": [{"type": "rest", "duration": 60}]}
# a MEMS rover driving from the first sample (no rest to read the biases from), GNSS 1 Hz
MOVING = {"name": "moving", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30, "speed": 5},
          "imu": {"rate": 25, "sensor": "mems"},
          "gnss": {"rate": 1, "vel_noise": 0.05, "pos_noise": 1.5, "lever_arm": [0.8, 0.2, 1.5]},
          "segments": [{"type": "accelerate", "speed": 12, "duration": 8},
                       {"type": "turn", "angle": 90, "duration": 10, "bank": "none"},
                       {"type": "cruise", "duration": 5}, {"type": "decelerate", "speed": 8, "duration": 5},
                       {"type": "turn", "angle": -60, "duration": 8, "bank": "none"},
                       {"type": "accelerate", "speed": 12, "duration": 9}]}


def _true_sensor(scenario):
    s = scenario["imu"]["sensor"]
    return load_sensor(s, None, "test", ROOT)


def _static_floor(scenario, T, method):
    """Noise-only 1-sigma (deg) at rest from the true densities: tilt ``VRW / (g sqrt T)``, heading
    ``ARW / (sqrt T W cos L)`` (plus the accelerometer term of the inertial-frame method)."""
    s = _true_sensor(scenario)
    arw, vrw = float(s["gyro"]["arw"].min()), float(s["accel"]["vrw"].min())
    tilt = vrw / (G * math.sqrt(T))
    head = observability.earth_rate_heading_sigma(LAT, T, 0.0, arw, 0.0, G, vrw if method == "inertial" else 0.0)
    return np.degrees([tilt, tilt, head])


def _moving_floor(truth, gnss_times, t0, t1, sigma_v):
    """Fisher information of the GNSS velocities (white, ``sigma_v``) about a constant attitude error
    ``phi`` and an unknown initial velocity: ``dv_j = S_j x phi + d`` with ``S_j`` the specific force
    integrated from the truth (``v_j - v_0 + g t_j up``).  The floor (deg) of roll, pitch (the tilt's
    smaller axis) and heading; the IMU noise, which adds to it, is left out."""
    k = [int(np.argmin(np.abs(truth.time - t))) for t in gnss_times if t0 < t <= t1 + 1e-9]
    k0 = int(np.argmin(np.abs(truth.time - t0)))
    info = np.zeros((6, 6))
    for j in k:
        S = truth.vel_n[j] - truth.vel_n[k0] + np.array([0.0, 0.0, G * (truth.time[j] - truth.time[k0])])
        H = np.hstack([-np.array([[0, -S[2], S[1]], [S[2], 0, -S[0]], [-S[1], S[0], 0]]), np.eye(3)])
        info += H.T @ H / sigma_v ** 2
    cov = np.linalg.inv(info)[:3, :3]
    tilt = math.sqrt(min(cov[0, 0], cov[1, 1]))
    return np.degrees([tilt, tilt, math.sqrt(cov[2, 2])])


def _report(cov, label):
    lines = [f"{label}: fraction of runs within 3 sigma (roll, pitch, heading), refused"]
    for (m, c), v in sorted(cov.items()):
        med = [float(np.median(col[np.isfinite(col)])) if np.isfinite(col).any() else math.nan for col in v.sigma.T]
        lines.append(f"  {m:14s} {c:10s} n={len(v.seeds):3d} in3s={np.round(v.inside(), 3)} refused={len(v.refused)} "
                     f"rms err={np.round(np.sqrt((v.err ** 2).mean(axis=0)), 4)} median sigma={np.round(med, 4)}")
    print("\n".join(lines))


# --------------------------------------------------------------------------- Monte Carlo: static base

@pytest.fixture(scope="module")
def static_cov():
    cov = coverage_runs(STATIC, ("static", "inertial", "kf"), SEEDS, with_gnss=False)
    _report(cov, "static base, navigation grade, 60 s at 10 Hz")
    return cov


@pytest.mark.parametrize("case", ["right", "absent", "optimistic"])
@pytest.mark.parametrize("method", ["static", "inertial", "kf"])
def test_monte_carlo_static_base(static_cov, method, case):
    v = static_cov[(method, case)]
    assert len(v.seeds) + len(v.refused) == len(SEEDS)
    # a navigation-grade gyro sees the earth rate: every run gives a heading
    assert not v.refused, v.refused[:3]
    assert np.all(v.inside() >= 0.95), (v.inside(), method, case)
    floor = _static_floor(STATIC, 60.0, method)
    assert np.all(v.sigma >= floor * (1.0 - 1e-9)), (v.sigma.min(axis=0), floor)
    assert np.all(v.sigma > 0.0) and np.all(np.isfinite(v.sigma))


MEMS_STATIC = dict(copy.deepcopy(STATIC), imu={"rate": 10, "sensor": "mems"})


@pytest.fixture(scope="module")
def mems_static_cov():
    # a MEMS gyro cannot see the earth rate: the heading is the user's; roll and pitch are checked
    cov = coverage_runs(MEMS_STATIC, ("static", "inertial", "kf"), SEEDS, with_gnss=False, heading=math.radians(40.0))
    _report(cov, "static base, MEMS, user heading")
    return cov


@pytest.mark.parametrize("case", ["right", "absent", "optimistic"])
@pytest.mark.parametrize("method", ["static", "inertial", "kf"])
def test_monte_carlo_static_base_mems_tilt(mems_static_cov, method, case):
    v = mems_static_cov[(method, case)]
    assert len(v.refused) <= 1, v.refused
    assert np.all(v.inside()[:2] >= 0.95), (v.inside(), method, case)
    assert np.all(v.sigma[:, :2] >= _static_floor(MEMS_STATIC, 60.0, method)[:2] * (1.0 - 1e-9))


SWAYING = {"name": "sway", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30},
           "imu": {"rate": 10, "sensor": "tactical"}, "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}]}
SWAY_WAVES = {"roll": {"amplitude": 5, "freq": 0.15}, "pitch": {"amplitude": 5, "freq": 0.11, "phase": 60},
              "heading": {"amplitude": 1, "freq": 0.07}, "heave": {"amplitude": 0.5, "freq": 0.12}}


def test_monte_carlo_swaying_base_tilt():
    """A moored base (+-5 deg roll and pitch, 0.5 m heave), tactical grade, user heading: the inertial
    method's tilt.  With no stretch at rest a description ten times too optimistic is caught only by the
    gyro's sample-rate noise (the accelerometer's hides under its quantization): the closest case, 0.96."""
    cov = coverage_runs(SWAYING, ("inertial",), SEEDS, sway=SWAY_WAVES, with_gnss=False, heading=math.radians(30.0))
    _report(cov, "swaying base, tactical, user heading")
    for case in ("right", "absent", "optimistic"):
        v = cov[("inertial", case)]
        assert not v.refused and np.all(v.inside()[:2] >= 0.95), (case, v.inside())
        assert np.all(v.sigma[:, :2] >= _static_floor(SWAYING, 60.0, "inertial")[:2] * (1.0 - 1e-9))


def test_mems_earth_rate_heading_is_refused_whatever_the_description_says():
    """The MEMS log with a navigation-grade description: the bias the log shows at rest makes the
    earth-rate heading unobservable: refused, naming the data."""
    r = sway.ScenarioRuns(sway.prepare_scenario(copy.deepcopy(MEMS_STATIC), None, "t", None)).run(3)
    nav = SensorSpec(0.005 * math.pi / 180 / 3600, 0.002 * math.pi / 180 / 60, 25 * 9.80665e-6, 5 * 9.80665e-6)
    for method in ("static", "inertial", "kf"):
        with pytest.raises(SinsError, match="heading is not observable from earth rate"):
            align(r.imu, AlignOptions(method=method, position=(LAT, math.radians(114.0), 50.0), sensor=nav))


# --------------------------------------------------------------------------- Monte Carlo: moving base

@pytest.fixture(scope="module")
def moving_cov():
    cov = coverage_runs(MOVING, ("gnss-inertial", "kf"), SEEDS)
    _report(cov, "moving MEMS rover with GNSS, 45 s at 25 Hz, no rest")
    return cov


@pytest.fixture(scope="module")
def moving_truth():
    p = sway.prepare_scenario(copy.deepcopy(MOVING), None, "t", None)
    return sway.ScenarioRuns(p).run(0)


@pytest.mark.parametrize("case", ["right", "absent", "optimistic"])
@pytest.mark.parametrize("method", ["gnss-inertial", "kf"])
def test_monte_carlo_moving_base(moving_cov, moving_truth, method, case):
    v = moving_cov[(method, case)]
    assert not v.refused, v.refused[:3]
    assert np.all(v.inside() >= 0.95), (v.inside(), method, case)
    r = moving_truth
    floor = _moving_floor(r.truth, r.gnss.time, r.imu.t0, float(r.imu.time[-1]), 0.05)
    assert np.all(v.sigma >= floor * (1.0 - 1e-9)), (v.sigma.min(axis=0), floor)


def test_monte_carlo_the_right_description_is_not_wasted(static_cov, moving_cov):
    """Told the right sensor, the 1-sigma is of the size of the errors (not inflated to be safe):
    the rms error is at least a third of the median 1-sigma for every angle the motion determines."""
    for key in (("static", "right"), ("inertial", "right"), ("gnss-inertial", "right")):
        v = (static_cov if key[0] != "gnss-inertial" else moving_cov)[key]
        rms = np.sqrt((v.err ** 2).mean(axis=0))
        assert np.all(rms > np.median(v.sigma, axis=0) / 3.0), (key, rms, np.median(v.sigma, axis=0))


# --------------------------------------------------------------------------- the low-grade IMU

LOW = copy.deepcopy(MOVING)
LOW["name"] = "low-grade"
LOW["imu"] = {"rate": 25, "sensor": {"gyro": {"bias": 720.0, "bias_sigma": 100.0, "arw": 0.5},     # 0.2 deg/s
                                     "accel": {"bias": 10197.0, "bias_sigma": 1000.0, "vrw": 200}}}  # 0.1 m/s^2
LOW["segments"] = [{"type": "rest", "duration": 5}] + MOVING["segments"]
LOW["start"] = dict(MOVING["start"], speed=0.0)


@pytest.mark.parametrize("sensor", [None, "mems"])
def test_low_grade_imu_on_a_moving_base_every_heading_within_3_sigma_or_refused(sensor):
    """0.2 deg/s gyro and 0.1 m/s^2 accelerometer bias (twice the MEMS preset): without a description
    and with the too-optimistic 'mems' one, every method either refuses or writes a heading within
    3 sigma of the truth (the moving-base methods must write one)."""
    p = sway.prepare_scenario(copy.deepcopy(LOW), None, "t", None)
    runs = sway.ScenarioRuns(p)
    spec = build_options(merge_section({"sensor": sensor} if sensor else {}, "t"), "t").sensor
    arm = np.array(LOW["gnss"]["lever_arm"])
    written = {m: 0 for m in ("static", "inertial", "gnss-inertial", "kf")}
    for seed in range(12):
        r = runs.run(seed)
        for method in written:
            try:
                res = align(r.imu, AlignOptions(method=method, sensor=spec, lever_arm=arm), r.gnss)
            except SinsError:
                continue
            k = int(np.argmin(np.abs(r.truth.time - res.state.time)))
            e = (math.degrees(dcm_to_euler(res.state.Cbn, 0)[2] - dcm_to_euler(r.truth.Cbn[k], 0)[2]) + 180) % 360 - 180
            assert abs(e) <= 3.0 * math.degrees(res.sigma[2]), (seed, method, e, math.degrees(res.sigma[2]))
            written[method] += 1
    assert written["static"] == 0 and written["inertial"] == 0      # the base moves: refused
    assert written["gnss-inertial"] == 12 and written["kf"] == 12


# --------------------------------------------------------------------------- the shipped sample data

def _sample_kf_figures(d):
    truth = read_trajectory(ROOT / "sample_data" / "truth.csv")
    k = int(np.argmin(np.abs(truth.time - d["time"])))
    true = np.degrees(dcm_to_euler(truth.Cbn[k], 0))
    err = np.array([d["roll"], d["pitch"], (d["heading"] - true[2] + 180) % 360 - 180 + true[2]]) - true
    return err, np.array([d["sigma_roll"], d["sigma_pitch"], d["sigma_heading"]])


def test_sample_data_kf_with_gnss_is_within_3_sigma(tmp_path):
    """The issue's case: heading 117.97 deg with sigma 0.045 deg against a true 120.00 (45 sigma).
    Run by the installed console script from a temporary directory, without and with a description."""
    sins = shutil.which("sins", path=str(Path(sys.executable).parent) + os.pathsep + os.environ["PATH"])
    assert sins is not None
    cfg = tmp_path / "mems.yaml"
    cfg.write_text(yaml.safe_dump({"gnss": {"lever_arm": [0.8, 0.0, 1.5]}, "align": {"sensor": "mems"}}))
    for extra in ([], ["--config", str(cfg)]):
        out = tmp_path / "kf.yaml"
        p = subprocess.run([sins, "align", str(ROOT / "sample_data" / "imu.csv"), "--gnss",
                            str(ROOT / "sample_data" / "gnss.csv"), "--method", "kf", "-q", "-o", str(out)] + extra,
                           cwd=tmp_path, capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        d = yaml.safe_load(out.read_text())
        err, sig = _sample_kf_figures(d)
        assert np.all(np.abs(err) <= 3.0 * sig), (extra, err, sig)
        assert np.all(sig > 0.0)
        assert d["sigma_basis"] == ("config+data" if extra else "data"), d["sigma_basis"]
        out.unlink()


# --------------------------------------------------------------------------- motion checks

CAR = {"name": "car", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30},
       "imu": {"rate": 25, "sensor": "navigation"}, "gnss": {"rate": 1},
       "segments": [{"type": "rest", "duration": 5}, {"type": "accelerate", "speed": 10, "duration": 8},
                    {"type": "cruise", "duration": 10}, {"type": "turn", "angle": 90, "duration": 10, "bank": "none"},
                    {"type": "cruise", "duration": 10}]}
SWAY = {"roll": {"amplitude": 5, "freq": 0.15}, "pitch": {"amplitude": 5, "freq": 0.11, "phase": 60},
        "heave": {"amplitude": 0.5, "freq": 0.12}}


@pytest.mark.parametrize("sensor", ["navigation", "mems"])
def test_inertial_without_gnss_refuses_a_translating_base_and_accepts_a_swaying_one(sensor, tmp_path):
    from sinscli.sim.run import write_sim
    car = dict(copy.deepcopy(CAR), imu={"rate": 25, "sensor": sensor})
    r = sway.ScenarioRuns(sway.prepare_scenario(car, None, "car", None)).run(1)
    pos = (LAT, math.radians(114.0), 50.0)
    with pytest.raises(SinsError, match="the base translates: the velocity integral in the inertial frame"):
        align(r.imu, AlignOptions(method="inertial", position=pos, heading=math.radians(30.0)))
    rest = {"name": "s", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30},
            "imu": {"rate": 25, "sensor": sensor}, "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}]}
    rs = sway.ScenarioRuns(sway.prepare_scenario(rest, SWAY, "s", None)).run(1)
    res = align(rs.imu, AlignOptions(method="inertial", position=pos, heading=math.radians(30.0)))
    k = int(np.argmin(np.abs(rs.truth.time - res.state.time)))
    e = np.degrees(np.array(dcm_to_euler(res.state.Cbn, 0)) - np.array(dcm_to_euler(rs.truth.Cbn[k], 0)))
    assert np.all(np.abs(e[:2]) <= 3.0 * np.degrees(res.sigma[:2])), (e, np.degrees(res.sigma))
    # through the CLI: one line, exit 2, nothing written
    write_sim(r, tmp_path / "car")
    out = tmp_path / "init.yaml"
    res = CliRunner().invoke(main, ["align", str(tmp_path / "car" / "imu.csv"), "--method", "inertial",
                                    "--position", "30,114,50", "--heading", "30", "-o", str(out)])
    assert res.exit_code == 2 and not out.exists()
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sins: error:") and "translates" in lines[0]


def test_a_perfect_log_never_gets_a_sigma_of_zero():
    sc = copy.deepcopy(STATIC)
    r = sway.ScenarioRuns(sway.prepare_scenario(sc, None, "t", None)).run(0, perfect=True)
    for method in ("static", "inertial", "kf"):
        res = align(r.imu, AlignOptions(method=method, position=(LAT, math.radians(114.0), 50.0)))
        assert np.all(res.sigma > 0.0) and np.all(np.isfinite(res.sigma)), (method, res.sigma)
        assert np.all(res.sigma >= res.sigma_floor)


# --------------------------------------------------------------------------- outliers

def test_gnss_velocity_glitches_are_rejected_and_counted():
    p = sway.prepare_scenario(copy.deepcopy(MOVING), None, "t", None)
    r = sway.ScenarioRuns(p).run(4)
    v = r.gnss.vel_n.copy()
    for k, dv in ((12, [4.0, -3.0, 0.5]), (25, [-6.0, 2.0, 0.0]), (33, [0.0, 5.0, 1.0])):
        v[k] += dv
    bad = replace(r.gnss, vel_n=v)
    spec = build_options(merge_section({"sensor": "mems"}, "t"), "t").sensor
    arm = np.array(MOVING["gnss"]["lever_arm"])
    clean = align(r.imu, AlignOptions(method="gnss-inertial", sensor=spec, lever_arm=arm), r.gnss)
    res = align(r.imu, AlignOptions(method="gnss-inertial", sensor=spec, lever_arm=arm), bad)
    assert clean.dropped["gnss_velocity"] == 0 and res.dropped["gnss_velocity"] == 3
    assert any("dropped 3 GNSS velocity fix(es) as outliers" in n for n in res.notes)
    assert np.degrees(np.abs(dcm_to_euler(res.state.Cbn, 0)[2] - dcm_to_euler(clean.state.Cbn, 0)[2])) < \
        np.degrees(clean.sigma[2])
    kfr = align(r.imu, AlignOptions(method="kf", sensor=spec, lever_arm=arm), bad)
    assert kfr.dropped["kf_gnss_velocity"] == 3


def test_course_fit_rejects_glitches_and_estimates_the_drift():
    """The GNSS-course heading: course = heading + drift (a gyro bias about up) + noise; five glitches of
    40-120 deg and a reversing stretch are dropped; the correction at the end and its 1-sigma hold."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 60.0, 1.0)
    speed = np.full(t.size, 6.0)
    course = np.radians(50.0) + 0.3 * np.sin(t / 9.0)
    drift = math.radians(0.05)                     # rad/s: the estimate's heading drifts away
    h_est = course - math.radians(3.0) - drift * (t - t[-1]) + rng.normal(0, math.radians(0.5), t.size)
    vel = np.stack([speed * np.sin(course), speed * np.cos(course), np.zeros(t.size)], axis=-1)
    for k, d in ((7, 40.0), (19, -60.0), (33, 120.0), (41, 45.0), (52, -90.0)):
        vel[k, :2] = speed[k] * np.array([math.sin(course[k] + math.radians(d)), math.cos(course[k] + math.radians(d))])
    vel[45:48] *= -1.0                               # reversing
    co = observability.course_heading(t, vel, h_est, 0.5, 0.05, math.radians(1.0), math.radians(0.2))
    assert co.dropped == 8
    assert abs(co.delta_end - math.radians(3.0)) < 3.0 * co.sigma()
    assert abs(co.drift - drift) < math.radians(0.02)
    assert math.radians(1.0) <= co.sigma() < math.radians(1.5)


# --------------------------------------------------------------------------- one sensor description

def test_sensor_description_forms_give_one_budget(tmp_path):
    """A preset name, a sensor YAML path (relative to the config), the same inline, and the legacy
    four-number mapping all go through sinscli.sensors.load_sensor and map to the same budget terms."""
    preset = build_options(merge_section({"sensor": "tactical"}, "t"), "t").sensor
    text = (ROOT / "sinscli" / "data" / "sensors" / "tactical.yaml").read_text()
    (tmp_path / "my_imu.yaml").write_text(text)
    path = build_options(merge_section({"sensor": "my_imu.yaml"}, "t"), "t", base_dir=tmp_path).sensor
    inline = build_options(merge_section({"sensor": yaml.safe_load(text)}, "t"), "t").sensor
    assert preset == replace(path, name=preset.name) == replace(inline, name=preset.name)
    # turn-on and in-run bias together; misalignment and scale factor kept for the motion terms
    assert preset.gyro_bias == pytest.approx(math.hypot(1.0, 0.5) * math.pi / 180 / 3600)
    assert preset.accel_mis == pytest.approx(100.0 * math.pi / 180 / 3600)
    assert preset.gyro_bias_rw == pytest.approx(math.sqrt(2.0 * 0.5 ** 2 / 600) * math.pi / 180 / 3600)
    legacy = build_options(merge_section({"sensor": {"gyro_bias": 1.118, "accel_vrw": 50}}, "t"), "t").sensor
    assert legacy.gyro_bias == pytest.approx(1.118 * math.pi / 180 / 3600) and legacy.gyro_arw is None
    with pytest.raises(SinsError, match="align.sensor: no sensor preset or file 'phone'"):
        build_options(merge_section({"sensor": "phone"}, "t"), "t")
    with pytest.raises(SinsError, match="gyro.bais: unknown key"):
        build_options(merge_section({"sensor": {"gyro": {"bais": 1}}}, "t"), "t")


def test_output_says_where_the_sigma_came_from(tmp_path):
    r = sway.ScenarioRuns(sway.prepare_scenario(copy.deepcopy(STATIC), None, "t", None)).run(2)
    from sinscli.sim.run import write_sim
    write_sim(r, tmp_path / "d")
    out = tmp_path / "init.yaml"
    (tmp_path / "cfg").mkdir()
    cfg = tmp_path / "cfg" / "c.yaml"           # the sensor file is found next to the config
    cfg.write_text("align:\n  sensor: my_imu.yaml\n")
    (tmp_path / "cfg" / "my_imu.yaml").write_text((ROOT / "sinscli" / "data" / "sensors" / "navigation.yaml").read_text())
    res = CliRunner().invoke(main, ["align", str(tmp_path / "d" / "imu.csv"), "--method", "inertial",
                                    "--position", "30,114,50", "--config", str(cfg), "-o", str(out)])
    assert res.exit_code == 0, res.output
    d = yaml.safe_load(out.read_text())
    assert d["sigma_basis"].startswith("config")
    assert set(d["sensor_budget"]) >= {"gyro_bias", "gyro_arw", "accel_bias", "accel_vrw", "from"}
    assert len(d["sigma_floor"]) == 3 and all(0.0 < f <= s for f, s in zip(d["sigma_floor"], (
        d["sigma_roll"], d["sigma_pitch"], d["sigma_heading"])))
    assert d["residual"]["chi2_dof"] > 0.0 and "gyro_bias_sigma" in d
    res = CliRunner().invoke(main, ["align", str(tmp_path / "d" / "imu.csv"), "--method", "static",
                                    "--position", "30,114,50", "-o", str(out)])
    d = yaml.safe_load(out.read_text())
    assert d["sigma_basis"] == "data" and "no sensor description" in res.output
    assert d["sensor_budget"]["from"]["gyro_bias"].startswith("data (2 component(s) at rest")
