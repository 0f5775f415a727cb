"""Sensor error models and GNSS synthesis: exact deterministic terms, statistics, reproducibility."""
import numpy as np
import pytest

from sinscli.errors import SinsError
from sinscli.nav.earth import enu_rotation, lla_to_ecef
from sinscli.sim import simulate
from sinscli.sim.run import prepare
from sinscli.sensors import ACCEL_UNITS, GYRO_UNITS, load_sensor
from sinscli.sim.errors import corrupt, gauss_markov, quantize

DEG = np.pi / 180.0

DRIVE = {"start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 10.0},
         "imu": {"rate": 100}, "gnss": {"rate": 5},
         "segments": [{"type": "rest", "duration": 2}, {"type": "accelerate", "speed": 15, "duration": 4},
                      {"type": "turn", "angle": 90, "duration": 4, "bank": "none"},
                      {"type": "climb", "pitch": 4, "duration": 6, "transition": 2},
                      {"type": "roll", "angle": 30, "duration": 2}, {"type": "cruise", "duration": 2}]}


def _spec(**gyro):
    return load_sensor({"gyro": gyro}, None, "<t>", None)["gyro"]


def test_deterministic_terms_are_exact():
    rng = np.random.default_rng(5)
    inc = rng.standard_normal((1000, 3)) * 1e-3
    dt = np.full(1000, 0.01)
    spec = _spec(bias=[1.0, -2.0, 3.0], scale_factor=[100.0, 200.0, -300.0],
                 misalignment=[10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    out, real = corrupt(inc, dt, spec, np.random.SeedSequence(0), "arw")
    b = np.array([1.0, -2.0, 3.0]) * DEG / 3600.0
    a = 4.84813681109536e-06        # one arcsecond in rad
    M = np.array([[1 + 100e-6, 10 * a, 20 * a], [30 * a, 1 + 200e-6, 40 * a], [50 * a, 60 * a, 1 - 300e-6]])
    ref = inc @ M.T + b * 0.01
    assert np.abs(out - ref).max() < 1e-18
    assert np.allclose(real["bias"], b, rtol=1e-15)


def test_random_walk_and_turn_on_bias_statistics():
    n = 200_000
    inc = np.zeros((n, 3))
    dt = np.full(n, 0.01)
    arw = 0.3                                     # deg/sqrt(h)
    out, _ = corrupt(inc, dt, _spec(arw=arw), np.random.SeedSequence(1), "arw")
    sigma = arw * DEG / 60.0 * np.sqrt(0.01)      # rad per sample
    assert np.allclose(out.std(axis=0), sigma, rtol=0.01)        # 5 sigma of the estimate: 0.8 %
    assert np.abs(out.mean(axis=0)).max() < 5 * sigma / np.sqrt(n)
    # turn-on biases over many seeds: N(0, sigma)
    draws = np.array([corrupt(inc[:1], dt[:1], _spec(bias_sigma=2.0), np.random.SeedSequence(s), "arw")[1]["bias"]
                      for s in range(2000)])
    assert np.allclose(draws.std(axis=0), 2.0 * DEG / 3600.0, rtol=0.08)


def test_gauss_markov_steady_state_and_correlation():
    n, dt, tau, sig = 400_000, 0.01, 1.0, 2e-5
    phi = np.exp(-dt / tau)
    w = np.random.default_rng(3).standard_normal((n, 3))
    b = gauss_markov(np.full(3, phi), np.full(3, sig * np.sqrt(1 - phi * phi)), np.zeros(3), w)
    assert np.allclose(b[1000:].std(axis=0), sig, rtol=0.05)
    lag = int(tau / dt)
    x = b[1000:, 0]
    rho = np.mean(x[:-lag] * x[lag:]) / np.mean(x * x)
    assert abs(rho - np.exp(-1.0)) < 0.05
    # recursion by hand for the first samples
    assert b[0, 1] == pytest.approx(sig * np.sqrt(1 - phi * phi) * w[0, 1], rel=1e-15)
    assert b[1, 1] == pytest.approx(phi * b[0, 1] + sig * np.sqrt(1 - phi * phi) * w[1, 1], rel=1e-15)


def test_quantization_keeps_the_remainder():
    rng = np.random.default_rng(0)
    inc = rng.uniform(-3e-6, 5e-6, (5000, 3))
    q = np.array([1e-6, 2e-6, 0.0])
    out = quantize(inc, q)
    assert np.allclose(out[:, :2] / q[:2], np.round(out[:, :2] / q[:2]), atol=1e-9)
    assert np.array_equal(out[:, 2], inc[:, 2])
    # cumulative angle lost is below half a count at every sample
    err = np.abs(np.cumsum(inc[:, :2], axis=0) - np.cumsum(out[:, :2], axis=0))
    assert np.all(err <= 0.5 * q[:2] + 1e-18)


def test_presets_load_and_unknown_keys_are_refused(tmp_path):
    for name in ("navigation", "tactical", "mems", "consumer"):
        s = load_sensor(name, None, "<t>", tmp_path)
        assert set(s["gyro"]) <= set(GYRO_UNITS) and set(s["accel"]) <= set(ACCEL_UNITS)
        assert s["gyro"]["arw"][0] > 0 and s["accel"]["vrw"][0] > 0
    nav, mems = load_sensor("navigation", None, "<t>", tmp_path), load_sensor("mems", None, "<t>", tmp_path)
    assert nav["gyro"]["bias_sigma"][0] < mems["gyro"]["bias_sigma"][0] / 1000
    with pytest.raises(SinsError, match=r"gyro\.bais: unknown key"):
        load_sensor({"gyro": {"bais": 1.0}}, None, "s.yaml", tmp_path)
    with pytest.raises(SinsError, match="no sensor preset or file 'phone'"):
        load_sensor("phone", None, "s.yaml", tmp_path)
    with pytest.raises(SinsError, match="bias_tau: required with bias_instability"):
        load_sensor({"accel": {"bias_instability": 10}}, None, "s.yaml", tmp_path)


def test_seeded_runs_are_bit_reproducible_and_seeds_differ():
    sc = DRIVE | {"imu": {"rate": 100, "sensor": "tactical"},
                  "gnss": {"rate": 5, "pos_noise": [1, 1, 2], "vel_noise": 0.05}}
    a, b, c = simulate(sc, seed=11), simulate(sc, seed=11), simulate(sc, seed=12)
    for x, y in ((a.imu.dtheta_b, b.imu.dtheta_b), (a.imu.dvel_b, b.imu.dvel_b), (a.gnss.lat, b.gnss.lat),
                 (a.gnss.vel_n, b.gnss.vel_n)):
        assert np.array_equal(x, y)
    assert not np.array_equal(a.imu.dtheta_b, c.imu.dtheta_b)
    assert not np.array_equal(a.gnss.height, c.gnss.height)
    # the truth does not depend on the seed; perfect drops every error
    assert np.array_equal(a.truth.Cbn, c.truth.Cbn)
    p = simulate(sc, seed=11, perfect=True)
    assert np.array_equal(p.imu.dtheta_b, simulate(DRIVE, perfect=True).imu.dtheta_b)
    # the tactical errors are of the expected size: bias ~1 deg/h against 0.1 deg/sqrt(h) noise
    d = (a.imu.dtheta_b - p.imu.dtheta_b).mean(axis=0) / 0.01
    assert 0.001 * DEG / 3600 < np.abs(d).max() < 100 * DEG / 3600


def test_scenario_seed_and_gnss_stream_independence():
    sc = DRIVE | {"seed": 4, "imu": {"rate": 100, "sensor": "mems"}, "gnss": {"rate": 5, "pos_noise": 2.0}}
    assert np.array_equal(simulate(sc).imu.dvel_b, simulate(sc, seed=4).imu.dvel_b)
    # changing the GNSS settings leaves the IMU errors as they were (separate streams)
    other = simulate(sc | {"gnss": {"rate": 2, "pos_noise": 5.0}}, seed=4)
    assert np.array_equal(simulate(sc, seed=4).imu.dvel_b, other.imu.dvel_b)


def test_gnss_antenna_with_lever_arm_is_the_truth_at_the_antenna():
    lever = np.array([1.2, -0.4, 1.8])          # FLU
    r = simulate(DRIVE | {"gnss": {"rate": 5, "lever_arm": lever.tolist()}}, perfect=True)
    tr, g = r.truth, r.gnss
    k = np.searchsorted(tr.time, g.time)
    assert np.array_equal(tr.time[k], g.time)
    x_imu = lla_to_ecef(tr.lat[k], tr.lon[k], tr.height[k])
    x_ant = lla_to_ecef(np.radians(g.lat), np.radians(g.lon), g.height)
    c_en = enu_rotation(tr.lat[k], tr.lon[k])
    d_n = np.einsum("nij,nj->ni", c_en, x_ant - x_imu)              # ENU offset antenna - IMU
    assert np.abs(d_n - tr.Cbn[k] @ lever).max() < 1e-8               # metres
    # antenna velocity: central differences of the antenna positions (5 Hz fixes are too sparse;
    # use a 100 Hz GNSS on the same motion)
    r2 = simulate(DRIVE | {"gnss": {"rate": 100, "lever_arm": lever.tolist()}}, perfect=True)
    g2 = r2.gnss
    x = lla_to_ecef(np.radians(g2.lat), np.radians(g2.lon), g2.height)
    v_fd = (-x[4:] + 8 * x[3:-1] - 8 * x[1:-3] + x[:-4]) / (12 * 0.01)
    v_e = np.einsum("nij,ni->nj", enu_rotation(np.radians(g2.lat), np.radians(g2.lon)), g2.vel_n)[2:-2]
    # stencils across a segment joint see the jump of the 4th derivative (values are C^3): skip them
    joints = np.array([p.t_start for p in prepare(DRIVE, perfect=True).prims[1:]])
    tc = g2.time[2:-2]
    smooth = np.abs(tc[:, None] - joints[None, :]).min(axis=1) > 0.025
    assert smooth.sum() > 0.9 * tc.size
    # rounding: ~1e-9 m (ECEF of the fixes) amplified 150x by the stencil; the lever-arm term itself
    # (w x l) is ~0.5 m/s here, so a wrong sign or frame would show at once
    assert np.abs(v_fd - v_e)[smooth].max() < 1e-6
    # without a lever arm the fixes are the truth itself
    r0 = simulate(DRIVE, perfect=True)
    k0 = np.searchsorted(r0.truth.time, r0.gnss.time)
    assert np.array_equal(np.radians(r0.gnss.lat), np.radians(np.degrees(r0.truth.lat[k0])))
    assert np.array_equal(r0.gnss.vel_n, r0.truth.vel_n[k0])


def test_gnss_noise_outages_and_std_columns():
    sc = DRIVE | {"gnss": {"rate": 10, "pos_noise": [2.0, 3.0, 5.0], "vel_noise": 0.1,
                           "outages": [[3.0, 7.5], [15.0, 30.0]]}}
    r = simulate(sc, seed=2)
    t = r.gnss.time
    assert not np.any((t >= 3.0) & (t < 7.5)) and not np.any(t >= 15.0)
    assert np.isclose(t[t < 3.0][-1], 2.9) and np.isclose(t[t >= 7.5][0], 7.5)
    assert np.allclose(r.gnss.std_pos, [2.0, 3.0, 5.0]) and np.allclose(r.gnss.std_vel, 0.1)
    p = simulate(sc, seed=2, perfect=True)
    assert p.gnss.std_pos is None and np.array_equal(p.gnss.time, t)     # perfect keeps the outages
    dh = r.gnss.height - p.gnss.height
    assert 2.0 < dh.std() < 8.0
