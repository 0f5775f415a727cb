"""Issue 19's simulator additions against closed forms and exact truth: the consumer preset, the mount's
engine vibration, rate output, stamp jitter and clock offsets, the sensor-to-body mounting, correlated
GNSS noise with a reported sigma, wheel odometry, the walker's gait and the run's record."""
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.config import mounting_matrix
from sinscli.io.body_vel_csv import read_body_velocity_csv
from sinscli.io.gnss_csv import read_gnss_csv
from sinscli.io.imu_csv import apply_mounting, read_imu_csv
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sensors import load_sensor
from sinscli.sim import simulate
from sinscli.sim.errors import gauss_markov_times
from sinscli.sim.run import prepare
from sinscli.sim.vibration import envelope, mount_motion

ROOT = Path(__file__).resolve().parents[1]
SCEN = ROOT / "configs" / "scenarios"
DEG = math.pi / 180.0

REST = {"name": "rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 20.0},
        "imu": {"rate": 100}, "segments": [{"type": "rest", "duration": 20}]}


def _sc(**extra):
    d = yaml.safe_load(yaml.safe_dump(REST))
    for k, v in extra.items():
        d[k] = dict(d.get(k, {}), **v) if isinstance(v, dict) and isinstance(d.get(k), dict) else v
    return d


def _car(**over):
    """consumer_car.yaml without its mount flex (a motion the truth leaves out, tests/test_sim_hard.py): these
    tests take the vibration as the only motion of the mount against the body."""
    d = yaml.safe_load((SCEN / "consumer_car.yaml").read_text())
    d.pop("mount_flex", None)
    for k, v in over.items():
        d[k] = v
    return d


def test_consumer_preset_is_phone_class():
    s = load_sensor("consumer", None, "<t>", ROOT)
    g, a = s["gyro"], s["accel"]
    assert np.all(g["arw"] >= 0.2 * DEG / 60)                                       # >= 0.2 deg/sqrt(h)
    assert np.all((g["bias_instability"] >= 10 * DEG / 3600) & (g["bias_instability"] <= 50 * DEG / 3600))
    assert np.all((g["bias_tau"] >= 100) & (g["bias_tau"] <= 300))
    assert np.all(a["vrw"] == pytest.approx(70e-6 * 9.80665))                       # 70 micro-g/sqrt(Hz)
    assert np.all((a["bias_instability"] >= 50e-6 * 9.80665) & (a["bias_instability"] <= 100e-6 * 9.80665))
    assert np.all(a["bias_sigma"] == pytest.approx(10e-3 * 9.80665))                # 10 mg turn-on
    for t in (g, a):
        assert np.all((t["scale_factor_sigma"] >= 3e-3) & (t["scale_factor_sigma"] <= 1e-2))
        assert np.all((t["misalignment_sigma"] >= 0.1 * DEG) & (t["misalignment_sigma"] <= 0.3 * DEG))


# ---- engine vibration of the mount -------------------------------------------------------------------

def _vib(gyro=0.0, accel=0.0, **kw):
    return dict({"gyro_rms": gyro, "accel_rms": accel, "band": [20, 40], "lines": 4, "seed": 3}, **kw)


def test_single_axis_vibration_increments_are_the_closed_form():
    """A rotation about x alone leaves the x rate ``w_x + theta_x'``: the x increment is the still one plus
    ``theta_x(t_k) - theta_x(t_k-1)``; a z translation alone adds ``d_z'(t_k) - d_z'(t_k-1)`` to dvel_z
    (its other terms, ``2 w x d'`` and ``w x (w x d)`` with the earth rate, are below 1e-13 m/s^2 in z)."""
    still = simulate(_sc(), perfect=True)
    for vib, pick in ((_vib(gyro=[2.0, 0.0, 0.0]), 0), (_vib(accel=[0.0, 0.0, 0.4]), 1)):
        sc = _sc(vibration=vib)
        r, p = simulate(sc, perfect=True), prepare(sc)
        tau = np.concatenate([[0.0], r.imu.time - r.imu.t0])
        motion = mount_motion(p.vibration, tau)
        ref = (motion[0][:, 0], motion[3][:, 2])[pick]                       # theta_x or d_z'
        got = (r.imu.dtheta_b[:, 0] - still.imu.dtheta_b[:, 0], r.imu.dvel_b[:, 2] - still.imu.dvel_b[:, 2])[pick]
        # exact but for the rounding of the phases w t (4 eps w t_max in angle, times the amplitude) and of
        # the still increment the difference is taken against (0.098 m/s: 1.4e-17)
        w = (p.vibration.rot_w, p.vibration.lin_w)[pick].max()
        tol = 4 * np.finfo(float).eps * w * tau[-1] * np.abs(ref).max() + (1e-19, 3e-17)[pick]
        assert np.abs(got - np.diff(ref)).max() < tol
        assert np.abs(np.diff(ref)).max() > (1e-4, 1e-3)[pick]                 # the vibration is there
    # the rate RMS of the samples after the smooth start is the one asked (lines of distinct frequencies;
    # the increments, interval means, see it attenuated by sinc(w dt / 2), 0.85 at 30 Hz and 100 Hz)
    sc = _sc(vibration=_vib(gyro=[2.0, 0.0, 0.0]), imu={"rate": 100, "output": "rates"})
    sc["segments"][0]["duration"] = 120
    rate = simulate(sc, perfect=True).imu_rates.gyro[100:, 0]
    assert np.sqrt(np.mean((rate - rate.mean()) ** 2)) == pytest.approx(2.0 * DEG, rel=0.05)


def test_vibrating_mount_rate_is_the_derivative_of_its_attitude():
    """``w_iv^v = R^T w_ib^b + J_r(theta) theta'`` against central differences of ``R(theta(t))``; three axes."""
    from sinscli.nav.rotation import rotvec_to_dcm
    from sinscli.sim.vibration import draw_vibration, vibrate
    v = draw_vibration({"gyro_rms": np.array([60.0, 40.0, 50.0]) * DEG, "accel_rms": np.zeros(3),
                        "band": (20.0, 40.0), "lines": 3, "seed": 5, "ramp": 0.5})
    t = np.linspace(0.1, 2.0, 57)
    w_in = np.tile([1e-4, -2e-4, 3e-4], (t.size, 1))
    w, _ = vibrate(v, t, w_in, np.zeros_like(w_in))
    h = 1e-6
    for k, tk in enumerate(t):
        rm, r0, rp = (rotvec_to_dcm(mount_motion(v, np.array([tk + s]))[0][0]) for s in (-h, 0.0, h))
        k_skew = r0.T @ (rp - rm) / (2 * h)
        w_fd = 0.5 * np.array([k_skew[2, 1] - k_skew[1, 2], k_skew[0, 2] - k_skew[2, 0], k_skew[1, 0] - k_skew[0, 1]])
        assert np.abs(w[k] - (r0.T @ w_in[k] + w_fd)).max() < 1e-7 * np.abs(w_fd).max()


def test_envelope_and_the_mount_at_rest_on_the_body_at_the_start():
    m, m1, m2 = envelope(np.array([0.0, 0.5, 1.0, 2.0]), 1.0)
    assert m.tolist() == [0.0, 0.5, 1.0, 1.0] and m1[0] == m1[2] == m1[3] == 0.0 and m2[0] == m2[2] == 0.0
    p = prepare(_car())
    th, dth, d, dd, _ = mount_motion(p.vibration, np.array([0.0]))
    assert not np.any(th) and not np.any(dth) and not np.any(d) and not np.any(dd)


def test_vibration_increments_converge_with_the_quadrature():
    sc = _sc(vibration=_vib(gyro=2.0, accel=[0.2, 0.2, 0.4]))
    sc["segments"] = [{"type": "rest", "duration": 3}, {"type": "accelerate", "speed": 10, "duration": 4},
                      {"type": "turn", "angle": 60, "duration": 3, "bank": "none"}]
    a, b = simulate(sc, perfect=True, nodes=8), simulate(sc, perfect=True, nodes=16)
    vib = prepare(sc).vibration
    # the nodes' time rounding moves each phase by up to 4 eps w t: that much of the lines' increment
    phase = 4 * np.finfo(float).eps * vib.max_frequency() * 10.0
    for x, y, amp in ((a.imu.dtheta_b, b.imu.dtheta_b, vib.rot_a), (a.imu.dvel_b, b.imu.dvel_b, vib.lin_b)):
        assert np.abs(x - y).max() < 2e-15 * np.abs(x).max() + phase * amp.sum(axis=1).max() * 0.01


def test_perfect_vibrating_car_navigates_to_the_excluded_oscillation():
    """Navigated at 1600 Hz the vibrating mount's increments give the body truth back to the mount's own
    oscillation (attitude, velocity) with no drift; at 100 Hz the navigator's coning/sculling of 20-40 Hz
    lines costs centimetres in 5 min (the figures of docs/simulate.md)."""
    sc = _car()
    sc["imu"] = {"rate": 1600, "output": "increments"}
    sc["segments"] = [{"type": "rest", "duration": 10}, {"type": "accelerate", "speed": 15, "duration": 8},
                      {"type": "turn", "angle": -90, "duration": 10, "bank": "none"}, {"type": "cruise", "duration": 12}]
    r = simulate(sc, perfect=True)
    e = compare_trajectories(r.truth, navigate(r.imu, r.init, NavOptions()))
    exc = r.record["vibration"]["excluded_from_truth"]
    ang = np.linalg.norm(exc["angle_rms_deg"])
    assert np.degrees(e.angle_rad).max() < 4 * ang and np.abs(e.vel_enu_mps).max() < 4 * np.linalg.norm(exc["velocity_rms_m_s"])
    assert np.abs(e.pos_enu_m).max() < 1e-4
    sc["imu"]["rate"] = 100
    r = simulate(sc, perfect=True)
    e = compare_trajectories(r.truth, navigate(r.imu, r.init, NavOptions()))
    assert 1e-5 < np.abs(e.pos_enu_m).max() < 0.02


# ---- rates, stamps, clocks ----------------------------------------------------------------------------

def test_rate_samples_are_the_instantaneous_outputs():
    """Error-free rates at the IMU instants: their trapezoid is the increment to the trapezoid rule's own
    error (``dt^3 w''/12``), and at rest they are the earth rate and gravity exactly."""
    sc = _car(imu={"rate": 100, "output": "rates"})
    sc.pop("vibration")
    r = simulate(sc, perfect=True, duration=200)
    g = r.imu_rates.gyro
    trap = 0.5 * (g[1:] + g[:-1]) * np.diff(r.imu_rates.time - r.imu.t0)[:, None]   # the written intervals
    # trapezoid error -dt^3 w''/12 per interval, w'' from second differences of the samples (an interval-mean
    # sample would be off by dt^2 w'/2 instead, 100 times more)
    d2 = np.abs(g[2:] - 2 * g[1:-1] + g[:-2])                 # dt^2 w'' at the inner samples
    bound = np.maximum(np.vstack([d2, d2[-1:]]), np.vstack([d2[:1], d2])) * 0.01 / 12
    assert np.all(np.abs(trap - r.imu.dtheta_b) <= 1.5 * bound + 1e-17)
    assert np.abs(trap - r.imu.dtheta_b).max() > 1e-9
    assert np.array_equal(r.imu_rates.time, np.concatenate([[r.imu.t0], r.imu.time]))
    still = simulate(_sc(imu={"rate": 100, "output": "rates"}), perfect=True)
    dt = np.diff(still.imu_rates.time)[:, None]
    assert np.abs(still.imu_rates.gyro[1:] * dt - still.imu.dtheta_b).max() < 1e-21
    assert np.abs(still.imu_rates.accel[1:] * dt - still.imu.dvel_b).max() < 1e-17


def test_rates_with_sensor_errors_keep_the_realized_constants():
    sc = _sc(imu={"rate": 100, "output": "rates", "sensor": "consumer"})
    r = simulate(sc, seed=4)
    ref = simulate(dict(sc, imu={"rate": 100, "sensor": "consumer"}), seed=4)
    for which in ("gyro", "accel"):
        for k in ("bias", "scale_factor", "misalignment"):
            assert np.array_equal(r.sensor[which][k], ref.sensor[which][k])
    # white noise of density arw: per-sample sigma arw / sqrt(dt); quantization q / dt with the remainder
    # carried (the increment model), a differenced uniform: sigma q / (dt sqrt 6); the turn-on bias is the mean
    # (the 200 s bias instability barely moves in 20 s)
    gyro = load_sensor("consumer", None, "<t>", ROOT)["gyro"]
    x = r.imu_rates.gyro[:, 0] - still_rate(r)[:, 0]
    expect = math.sqrt(gyro["arw"][0] ** 2 / 0.01 + (gyro["quantization"][0] / 0.01) ** 2 / 6)
    assert np.std(x) == pytest.approx(expect, rel=0.05)


def still_rate(r):
    p = simulate(dict(r.scenario.raw, imu={"rate": 100, "output": "rates"}), perfect=True)
    return p.imu_rates.gyro


def test_stamp_jitter_and_clock_offsets(tmp_path):
    sc = _car(imu={"rate": 100, "output": "rates", "stamp_jitter": 0.001, "time_offset": 0.02})
    sc["gnss"] = dict(sc["gnss"], time_offset=-0.3)
    r = simulate(sc, duration=120)
    true_t = r.imu_rates.time
    e = r.imu_stamps - true_t - 0.02
    assert np.abs(e).max() <= 0.001 + 1e-6 and np.std(e) == pytest.approx(0.001 / math.sqrt(3), rel=0.05)
    assert np.all(np.diff(r.imu_stamps) > 0)
    out = tmp_path / "run"
    res = CliRunner().invoke(main, ["simulate", str(_write(tmp_path, sc)), "-o", str(out), "--duration", "120", "-q"])
    assert res.exit_code == 0, res.output
    assert np.array_equal(np.loadtxt(out / "imu.csv", delimiter=",", skiprows=1, usecols=0), r.imu_stamps)
    rec = yaml.safe_load((out / "sim_truth.yaml").read_text())
    assert rec["imu"]["time_offset"] == 0.02 and rec["gnss"]["time_offset"] == -0.3
    assert rec["config"]["imu"]["time_offset"] == -0.02 and rec["config"]["gnss"]["time_offset"] == 0.3
    # the navigation config's gnss.time_offset (s added on reading) = minus the simulated offset undoes it
    gnss = read_gnss_csv(out / "gnss.csv")
    tau_g = prepare(sc, duration=120).tau_gnss
    assert np.abs(gnss.time + rec["config"]["gnss"]["time_offset"] - (r.scenario.t0 + tau_g)).max() < 5e-7
    # the samples of the jittered, offset log are those of the true instants (only the stamps move)
    plain = simulate(dict(sc, imu={k: v for k, v in sc["imu"].items() if k not in ("stamp_jitter", "time_offset")},
                          gnss=dict(sc["gnss"], time_offset=0.0)), duration=120)
    assert np.array_equal(r.imu_rates.gyro, plain.imu_rates.gyro) and np.array_equal(r.gnss.lat, plain.gnss.lat)
    assert plain.imu_stamps is None and simulate(sc, perfect=True, duration=10).imu_stamps is None


def _write(tmp_path, sc, name="scenario.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(sc, sort_keys=False))
    return p


# ---- mounting -------------------------------------------------------------------------------------------

def test_mounting_writes_sensor_axes_and_the_config_mounting_recovers_the_body(tmp_path):
    """A perfect run with the IMU rotated (roll 1.5, pitch -2.5, yaw 3.5 deg) navigated through the CLI with
    the same imu.mounting in the config is the truth to the perfect-run level; without it, degrees off."""
    sc = _car(imu={"rate": 100, "mounting": {"roll": 1.5, "pitch": -2.5, "yaw": 3.5}})
    sc.pop("vibration")
    sc["gnss"] = {"rate": 1}
    r = simulate(sc, perfect=True, duration=200)
    c = mounting_matrix(sc["imu"]["mounting"])
    base = simulate(dict(sc, imu={"rate": 100}), perfect=True, duration=200)
    # the same increments to rounding: within 8 ulps of the largest (the simulator's fixed-order product, sim/pinned.py)
    assert np.abs(r.imu.dtheta_b @ c.T - base.imu.dtheta_b).max() < 8 * np.spacing(np.abs(base.imu.dtheta_b).max())
    out = tmp_path / "run"
    assert CliRunner().invoke(main, ["simulate", str(_write(tmp_path, sc)), "-o", str(out), "--perfect",
                                     "--duration", "200", "-q"]).exit_code == 0
    rec = yaml.safe_load((out / "sim_truth.yaml").read_text())
    assert rec["imu"]["mounting"] == {"roll": 1.5, "pitch": -2.5, "yaw": 3.5}
    assert np.allclose(rec["imu"]["mounting_matrix"], c, atol=1e-15)
    cfg = tmp_path / "nav.yaml"
    cfg.write_text(yaml.safe_dump({"imu": {"mounting": rec["config"]["imu"]["mounting"]}}))
    errs = {}
    for name, extra in (("with", ["--config", str(cfg)]), ("without", [])):
        nav = tmp_path / f"{name}.csv"
        res = CliRunner().invoke(main, ["navigate", str(out / "imu.csv"), "--init", str(out / "init.yaml"),
                                        "-o", str(nav), "-q"] + extra)
        assert res.exit_code == 0, res.output
        from sinscli.io.trajectory import read_trajectory
        e = compare_trajectories(read_trajectory(out / "truth.csv"), read_trajectory(nav))
        errs[name] = (math.degrees(e.angle_rad.max()), np.abs(e.pos_enu_m).max())
    ref = compare_trajectories(base.truth, navigate(base.imu, base.init, NavOptions()))
    assert errs["with"][0] < 1e-9 and errs["with"][1] < 2 * np.abs(ref.pos_enu_m).max() + 1e-9
    assert errs["without"][0] > 2.0
    # the library form: the reader's mounting rotation gives the body increments back
    imu = apply_mounting(read_imu_csv(out / "imu.csv"), c)
    assert np.abs(imu.dtheta_b - base.imu.dtheta_b).max() < 1e-15


# ---- GNSS -----------------------------------------------------------------------------------------------

def test_gauss_markov_at_irregular_times_is_the_exact_discretization():
    rng = np.random.default_rng(0)
    n = 200000
    tau = np.cumsum(rng.uniform(0.2, 0.3, n))
    e = gauss_markov_times(tau, np.array([2.0, 1.0, 0.5]), np.array([30.0, 0.0, 5.0]), rng.standard_normal((n, 3)))
    assert np.std(e, axis=0) == pytest.approx([2.0, 1.0, 0.5], rel=0.05)
    # correlation at the lag of ~120 fixes (30 s): exp(-lag/tau)
    lag = 120
    dt = tau[lag:] - tau[:-lag]
    for i, tc in ((0, 30.0), (2, 5.0)):
        rho = np.mean(e[lag:, i] * e[:-lag, i]) / np.var(e[:, i])
        assert rho == pytest.approx(np.mean(np.exp(-dt / tc)), abs=0.05)
    assert abs(np.mean(e[1:, 1] * e[:-1, 1])) < 0.02                       # tau 0: white


def test_correlated_noise_reported_sigma_and_no_velocity(tmp_path):
    sc = _sc(gnss={"rate": 4, "pos_noise": [0.015, 0.015, 0.03], "pos_tau": 30, "vel_noise": 0.02,
                   "reported_pos_sigma": 0.05, "velocity": False})
    sc["segments"] = [{"type": "rest", "duration": 600}]
    r = simulate(sc, seed=2)
    assert r.gnss.vel_n is None and r.gnss.std_vel is None
    assert np.all(r.gnss.std_pos == 0.05)
    lat0, h0 = r.truth.lat[0], r.truth.height[0]
    from sinscli.nav.earth import radii_py
    rm, _ = radii_py(np.sin(lat0))
    north = (np.radians(r.gnss.lat) - lat0) * (rm + h0)
    up = r.gnss.height - h0
    assert 0.3 * 0.015 < np.std(north) < 2.0 * 0.015 and 0.3 * 0.03 < np.std(up) < 2.0 * 0.03
    lag1 = np.corrcoef(north[1:], north[:-1])[0, 1]
    assert lag1 == pytest.approx(math.exp(-0.25 / 30), abs=0.01)
    # white (tau 0) keeps the old realization bit for bit
    w = dict(sc["gnss"])
    w.pop("pos_tau")
    assert np.array_equal(simulate(dict(sc, gnss=w), seed=2).gnss.lat,
                          simulate(dict(sc, gnss=dict(w, pos_tau=0)), seed=2).gnss.lat)


# ---- odometry -------------------------------------------------------------------------------------------

def test_odometry_scale_noise_and_the_csv_reader(tmp_path):
    sc = yaml.safe_load((SCEN / "rover.yaml").read_text())
    exact = dict(sc, odometry={"rate": 10, "scale_factor": 0.03})
    r = simulate(exact, duration=200)
    p = simulate(exact, perfect=True, duration=200)
    assert np.array_equal(r.odometry.vel_b, 1.03 * p.odometry.vel_b) and r.odometry.std is None
    # the truth's body velocity: forward speed, no sideslip (skid-steer, IMU on the path point)
    assert np.abs(p.odometry.vel_b[:, 1]).max() < 1e-12
    k = np.searchsorted(p.truth.time, p.odometry.time)
    speed = np.linalg.norm(p.truth.vel_n[k], axis=1)
    assert np.abs(np.linalg.norm(p.odometry.vel_b, axis=1) - speed).max() < 1e-12
    noisy = simulate(sc, duration=200)
    d = noisy.odometry.vel_b - 1.03 * p.odometry.vel_b
    moving = speed > 0.01
    assert np.std(d[moving], axis=0) == pytest.approx([0.03, 0.01, 0.01], rel=0.15)
    assert not np.any(d[~moving])
    out = tmp_path / "rover"
    res = CliRunner().invoke(main, ["simulate", str(SCEN / "rover.yaml"), "-o", str(out), "--duration", "60", "-q"])
    assert res.exit_code == 0, res.output
    bv = read_body_velocity_csv(out / "odom.csv")
    ref = simulate(sc, duration=60).odometry
    assert np.array_equal(bv.vel_b, ref.vel_b) and np.all(bv.std == 0.032)


# ---- walker ---------------------------------------------------------------------------------------------

def test_walker_gait_amplitudes_standstill_and_turns():
    sc = yaml.safe_load((SCEN / "walker.yaml").read_text())
    sc["segments"] = [{"type": "rest", "duration": 10}, {"type": "accelerate", "speed": 1.3, "duration": 3},
                      {"type": "cruise", "duration": 30}]
    r = simulate(sc, perfect=True)
    t = r.truth.time - r.truth.time[0]
    still = t < 9.999
    assert not np.any(r.truth.vel_n[still]) and np.all(r.truth.Cbn[still] == r.truth.Cbn[0])
    walk = t >= 15.0
    h = r.truth.height[walk]
    assert (h.max() - h.min()) / 2 == pytest.approx(0.03, rel=0.01)          # bob amplitude
    spd = np.linalg.norm(r.truth.vel_n[walk][:, :2], axis=1)
    f = np.abs(np.fft.rfft(h - h.mean()))
    freq = np.fft.rfftfreq(h.size, 0.01)
    assert freq[np.argmax(f)] == pytest.approx(1.9, abs=0.05)                # at the step frequency
    assert spd.mean() == pytest.approx(1.3, abs=0.01) and (spd.max() - spd.min()) / 2 > 0.14
    from sinscli.nav.rotation import dcm_to_euler
    roll = np.array([dcm_to_euler(np.ascontiguousarray(c), 0)[0] for c in r.truth.Cbn[walk][::5]])
    assert np.degrees(np.abs(roll).max()) == pytest.approx(2.0, rel=0.05)     # hand wobble
    # the gait in the rate-doubling navigation check: tests/test_sim_navigation.py (walker.yaml)


# ---- validation -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["imu"].update(output="counts"), r"key imu\.output: expected one of increments, rates, got 'counts'"),
    (lambda d: d["imu"].update(stamp_jitter=0.006), r"imu\.stamp_jitter: must be below half the IMU interval"),
    (lambda d: d["imu"].update(time_offset="late"), r"key imu\.time_offset: expected a finite number"),
    (lambda d: d["imu"].update(mounting={"roll": 1, "yew": 2}), r"key imu\.mounting\.yew: unknown key"),
    (lambda d: d["imu"].update(mounting=[[1, 0], [0, 1]]), r"key imu\.mounting: expected \{roll, pitch, yaw\}"),
    (lambda d: d.update(vibration={"gyro_rms": 1, "band": [20, 60]}),
     r"vibration\.band: 60 Hz is above the IMU's Nyquist frequency 50 Hz"),
    (lambda d: d.update(vibration={"gyro_rms": -1}), r"key vibration\.gyro_rms: expected a number >= 0, got -1"),
    (lambda d: d.update(vibration={"lines": 0}), r"vibration\.lines: expected an integer 1\.\.64"),
    (lambda d: d.update(vibration={"rms": 1}), r"key vibration\.rms: unknown key"),
    (lambda d: d.update(gait={"surge": 2.0}), r"gait\.surge: must be below gait\.speed"),
    (lambda d: d.update(gait={"step_freq": 0}), r"key gait\.step_freq: expected a number > 0, got 0"),
    (lambda d: d.update(odometry={"rate": 30}), r"odometry\.rate: must divide the IMU rate 100 Hz"),
    (lambda d: d.update(odometry={"scale_factor": 2}), r"odometry\.scale_factor: expected a fraction"),
    (lambda d: d.update(odometry={"reported_sigma": 0}), r"odometry\.reported_sigma: must be > 0"),
    (lambda d: d.update(gnss={"pos_tau": -1}), r"key gnss\.pos_tau: expected a number >= 0, got -1"),
    (lambda d: d.update(gnss={"reported_pos_sigma": [1, 0, 1]}), r"gnss\.reported_pos_sigma: must be > 0"),
    (lambda d: d.update(gnss={"velocity": False, "reported_vel_sigma": 0.1}),
     r"gnss\.reported_vel_sigma: given with gnss\.velocity: false"),
    (lambda d: d.update(gnss={"time_offset": 1e5}), r"gnss\.time_offset: expected a clock offset within"),
])
def test_bad_new_keys_are_refused_with_the_key_named(tmp_path, mutate, message):
    d = yaml.safe_load(yaml.safe_dump(REST))
    mutate(d)
    p = _write(tmp_path, d)
    res = CliRunner().invoke(main, ["simulate", str(p), "-o", str(tmp_path / "out"), "-q"])
    assert res.exit_code == 2 and not (tmp_path / "out").exists()
    line = res.output.strip().splitlines()[-1]
    assert line.startswith("sins: error: ") and "scenario.yaml: " in line and "Traceback" not in res.output
    assert __import__("re").search(message, line), line


def test_shipped_realistic_scenarios_record_their_truth(tmp_path):
    for name in ("consumer_car", "walker", "rover"):
        out = tmp_path / name
        res = CliRunner().invoke(main, ["simulate", str(SCEN / f"{name}.yaml"), "-o", str(out), "--duration", "30", "-q"])
        assert res.exit_code == 0, res.output
        rec = yaml.safe_load((out / "sim_truth.yaml").read_text())
        sc = yaml.safe_load((SCEN / f"{name}.yaml").read_text())
        assert rec["gnss"]["lever_arm"] == [float(x) for x in sc["gnss"].get("lever_arm", [0, 0, 0])]
        assert rec["imu"]["mounting"] == {k: float(sc["imu"].get("mounting", {}).get(k, 0.0))
                                          for k in ("roll", "pitch", "yaw")}
        assert set(rec["imu"]["errors"]) == {"gyro", "accel"}
        real = simulate(SCEN / f"{name}.yaml", duration=30).sensor["gyro"]            # the realized bias, deg/h
        c = np.array(rec["imu"]["mounting_matrix"])
        assert np.allclose(rec["imu"]["errors"]["gyro"]["bias"], np.degrees(real["bias"]) * 3600, rtol=1e-15)
        assert np.allclose(rec["imu"]["errors"]["gyro"]["bias_body"], c @ np.degrees(real["bias"]) * 3600,
                           rtol=1e-12)
        header = (out / "imu.csv").read_text().split("\n", 1)[0]
        assert header == "time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"
        imu = read_imu_csv(out / "imu.csv")                                     # the reader's rate form
        assert len(imu) == 30 * 100 - rec["imu"].get("dropped", {}).get("rows", 0)    # consumer_car drops rows
    assert "vibration" in yaml.safe_load((tmp_path / "consumer_car" / "sim_truth.yaml").read_text())
