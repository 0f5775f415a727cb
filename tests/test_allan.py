"""``sins allan``: the Allan deviation kernel against allantools and closed forms, the confidence it prints
(Monte Carlo), recovery of the simulator's noise terms from 3 h static logs, the CLI and its sensor.yaml."""
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG
import yaml
from click.testing import CliRunner

from sinscli.allan.adev import adev_relative_sigma, cluster_sizes, overlapping_avar
from sinscli.allan.fit import GM_PEAK_RATIO, GM_PEAK_X, fit_axis, gm_avar
from sinscli.allan.pipeline import characterize
from sinscli.cli import main
from sinscli.io.imu_csv import rates_to_increments, write_imu_csv
from sinscli.sensors import load_sensor
from sinscli.sim.errors import apply_imu_errors
from sinscli.sim.run import simulate
from sinscli.types import ImuLog

HUSKY = HUSKY_BAG
DEG_H = np.pi / 180 / 3600
UG = 9.80665e-6
SENSOR = {"gyro": {"arw": 0.3, "bias_instability": 10.0, "bias_tau": 20.0},
          "accel": {"vrw": 100.0, "bias_instability": 50.0, "bias_tau": 20.0}}


def static_scenario(duration, sensor=SENSOR, segments=None):
    return {"name": "allan_static", "seed": 7, "start": {"time": 0.0, "lat": 30.0, "lon": 114.0, "height": 50.0,
                                                        "heading": 30.0},
            "imu": {"rate": 100, "sensor": sensor}, "gnss": {"rate": 1},
            "segments": segments or [{"type": "rest", "duration": duration}]}


def static_log(hours, seed, rate=100.0, spec=SENSOR):
    """What ``sins simulate`` writes for ``hours`` at rest: the exact rest increments (constant at rest) with
    the simulator's error model applied (:func:`test_simulator_errors_are_apply_imu_errors` checks that)."""
    exact = simulate(static_scenario(1.0), seed=seed, perfect=True)
    n = int(round(hours * 3600 * rate))
    dt = np.full(n, 1.0 / rate)
    sensor = load_sensor(spec, None, "test", Path("."))
    dth, dv, _ = apply_imu_errors(np.tile(exact.imu.dtheta_b[0], (n, 1)), np.tile(exact.imu.dvel_b[0], (n, 1)),
                                  dt, sensor, seed)
    return ImuLog(np.arange(1, n + 1) / rate, dth, dv, 0.0, "static", "increments")


def test_simulator_errors_are_apply_imu_errors():
    """sins simulate's measured increments are the exact ones through apply_imu_errors, bit for bit."""
    sc = static_scenario(20.0)
    exact = simulate(sc, seed=5, perfect=True)
    meas = simulate(sc, seed=5)
    sensor = load_sensor(SENSOR, None, "test", Path("."))
    dth, dv, _ = apply_imu_errors(exact.imu.dtheta_b, exact.imu.dvel_b,
                                  np.diff(np.concatenate([[exact.imu.t0], exact.imu.time])), sensor, 5)
    np.testing.assert_array_equal(dth, meas.imu.dtheta_b)
    np.testing.assert_array_equal(dv, meas.imu.dvel_b)
    # and at rest the exact increments are constant (so tiling them is the simulator's 3 h truth)
    for inc in (exact.imu.dtheta_b, exact.imu.dvel_b):
        assert np.ptp(inc, axis=0).max() < 1e-12 * np.abs(inc).max()


def test_kernel_equals_allantools():
    allantools = pytest.importorskip("allantools", reason="allantools is in the test extra")
    rng = np.random.default_rng(1)
    n, tau0 = 20000, 0.005
    y = rng.standard_normal((n, 2)) * [1.0, 0.01] + np.cumsum(rng.standard_normal((n, 2)), axis=0) * 1e-3 + 9.8
    ms = cluster_sizes(n)
    ours = np.sqrt(overlapping_avar(y * tau0, tau0, ms))
    for c in range(2):
        taus, ad, _, _ = allantools.oadev(y[:, c], rate=1.0 / tau0, data_type="freq", taus=ms * tau0)
        np.testing.assert_allclose(taus, ms * tau0, rtol=1e-12)
        np.testing.assert_allclose(ours[:, c], ad, rtol=1e-9)


def test_gauss_markov_allan_variance_closed_form():
    """G(tau/T) against the exact Allan variance of the sampled AR(1) sequence (double sum of its
    autocovariance), and the peak constants."""
    T, dt = 50.0, 0.05
    phi = np.exp(-dt / T)
    for m in (40, 400, 1890, 4000):        # the sampled sequence is piecewise constant: ~1/m^2 from continuous
        k = np.arange(-2 * m + 1, 2 * m)
        # y2 - y1 with y the m-sample means: weights -1/m (first m), +1/m (next m); var = w' R w
        w = np.r_[-np.ones(m), np.ones(m)] / m
        lag_weight = np.correlate(w, w, "full")
        exact = 0.5 * float(np.sum(lag_weight * phi ** np.abs(k)))
        assert gm_avar(np.array([m * dt]), T)[0] == pytest.approx(exact, rel=1.0 / m ** 2 + 1e-6), m
    x = np.linspace(1.5, 2.3, 200001)
    g = gm_avar(x, 1.0)
    assert x[np.argmax(g)] == pytest.approx(GM_PEAK_X, abs=1e-5)
    assert np.sqrt(g.max()) == pytest.approx(GM_PEAK_RATIO, rel=1e-9)
    # series branch meets the closed form, and both limits
    assert gm_avar(np.array([0.0099999999]), 1.0)[0] == pytest.approx(gm_avar(np.array([0.0100000001]), 1.0)[0],
                                                                      rel=1e-7)
    assert gm_avar(np.array([1e-4]), 1.0)[0] == pytest.approx(2e-4 / 3, rel=1e-3)        # K^2 tau / 3, K^2 = 2/T
    assert gm_avar(np.array([1e4]), 1.0)[0] == pytest.approx(2e-4, rel=1e-3)            # 2 T / tau


def test_printed_one_sigma_is_honest_monte_carlo():
    """The 1-sigma band 1/sqrt(2(N/m - 1)) holds the white-noise deviations at least at its stated rate."""
    n, runs = 4000, 300
    ms = np.array([2, 10, 50, 200, 800])
    rel = adev_relative_sigma(n, ms)
    rng = np.random.default_rng(11)
    dev = np.array([np.sqrt(overlapping_avar(rng.standard_normal((n, 1)), 1.0, ms))[:, 0] for _ in range(runs)])
    truth = 1.0 / np.sqrt(ms)                       # white rate noise, unit sigma per sample
    z = (dev / truth - 1.0) / rel
    inside1, inside3 = np.mean(np.abs(z) <= 1, axis=0), np.mean(np.abs(z) <= 3, axis=0)
    spread = dev.std(axis=0) / truth / rel
    print("fraction within 1 sigma", inside1, "within 3", inside3, "spread / claimed", spread)
    assert np.all(inside1 >= 0.68) and np.all(inside3 >= 0.99)
    assert np.all((spread > 0.6) & (spread <= 1.0))   # conservative, not absurdly (0.82 expected)


@pytest.mark.parametrize("seed", [3, 4])
def test_fit_recovers_simulated_noise_within_10_percent(seed):
    """3 h at 100 Hz at rest, ARW 0.3 deg/sqrt(h), VRW 100 ug/sqrt(Hz), Gauss-Markov 10 deg/h and 50 ug with
    T = 20 s: every axis within 10 % (the Monte Carlo spread of the bias sigma is 4 % rms, docs/allan.md)."""
    res = characterize(static_log(3.0, seed))
    for c, f in enumerate(res.fits):
        gyro = c < 3
        n_true = 0.3 * np.pi / 180 / 60 if gyro else 100 * UG
        b_true = 10 * DEG_H if gyro else 50 * UG
        assert f.white == pytest.approx(n_true, rel=0.10), c
        assert f.identified["white"] and f.identified["gauss_markov"], (c, f.identified)
        assert f.gm_sigma == pytest.approx(b_true, rel=0.10), c
        assert f.gm_tau == pytest.approx(20.0, rel=0.35), c       # the correlation time is the least certain
        assert not f.identified["rate_random_walk"] and not f.identified["quantization"]
        print(f"axis {c}: white {f.white / n_true - 1:+.4f}, sigma {f.gm_sigma / b_true - 1:+.4f}, "
              f"T {f.gm_tau / 20 - 1:+.4f}")


@pytest.mark.parametrize("q", [0.0, 3e-5])
def test_rate_random_walk_and_quantization_are_fitted_when_present(q):
    """White rate noise plus a rate random walk, counted by an integrating sensor with count size q (rad):
    quantization is seen only when a count exceeds ~3 sample noises (q = 3e-5 against 1e-5 here)."""
    rng = np.random.default_rng(2)
    n, tau0 = 400_000, 0.01
    N, K = 1e-4, 2e-6                                # rad/sqrt(s), rad/s/sqrt(s)
    rate = N / np.sqrt(tau0) * rng.standard_normal(n) + np.cumsum(K * np.sqrt(tau0) * rng.standard_normal(n))
    x = np.cumsum(rate * tau0)
    xq = np.round(x / q) * q if q else x
    inc = np.diff(np.r_[0.0, xq])[:, None]
    ms = cluster_sizes(n)
    f = fit_axis(ms * tau0, ms, overlapping_avar(inc, tau0, ms)[:, 0], adev_relative_sigma(n, ms), n)
    assert f.identified["rate_random_walk"] and f.identified["white"]
    assert f.identified["quantization"] == (q > 0)
    assert f.white == pytest.approx(N, rel=0.05)
    assert f.rrw == pytest.approx(K, rel=0.15)
    if q:
        assert np.sqrt(12) * f.quantization == pytest.approx(q, rel=0.15)


def test_rate_logs_trapezoid_increments_are_modelled():
    """Rate samples (ROS Imu) become increments by the trapezoidal rule, which halves the m = 1 Allan
    variance of white noise; the white term's (1 - 3/(4m)) factor recovers the noise density."""
    rng = np.random.default_rng(5)
    n, rate = 360_000, 100.0                          # 1 h
    t = np.arange(n + 1) / rate
    arw, vrw = 0.3 * np.pi / 180 / 60, 100 * UG
    gyro = arw * np.sqrt(rate) * rng.standard_normal((n + 1, 3))
    accel = np.array([0.0, 0.0, 9.8]) + vrw * np.sqrt(rate) * rng.standard_normal((n + 1, 3))
    tt, dth, dv, t0 = rates_to_increments(t, gyro, accel)
    res = characterize(ImuLog(tt, dth, dv, t0, "rates", "rates"))
    assert res.trapezoid
    assert res.adev[0, 0] / (arw / np.sqrt(1 / rate)) == pytest.approx(0.5, rel=0.02)   # sqrt(1 - 3/4)
    for c, f in enumerate(res.fits):
        assert f.white == pytest.approx(arw if c < 3 else vrw, rel=0.02), c
    plain = characterize(ImuLog(tt, dth, dv, t0, "same, called increments", "increments"))
    assert max(abs(f.white / (arw if c < 3 else vrw) - 1) for c, f in enumerate(plain.fits)) > 0.02


# --------------------------------------------------------------------------- CLI

def run(args):
    return CliRunner().invoke(main, ["allan", *map(str, args)])


def test_cli_writes_a_sensor_yaml_that_simulate_takes(tmp_path):
    log = static_log(0.5, 9)
    write_imu_csv(tmp_path / "imu.csv", log)
    r = run([tmp_path / "imu.csv", "-o", tmp_path / "out", "-q", "--name", "bench_imu"])
    assert r.exit_code == 0, r.output
    for f in ("sensor.yaml", "allan.csv", "fit.csv", "allan.png"):
        assert (tmp_path / "out" / f).stat().st_size > 0
    text = (tmp_path / "out" / "sensor.yaml").read_text()
    doc = yaml.safe_load(text)
    assert doc["name"] == "bench_imu" and doc["gyro"]["bias_sigma"] == 0 and "cannot observe" in text
    sensor = load_sensor(str(tmp_path / "out" / "sensor.yaml"), None, "test", tmp_path)
    np.testing.assert_allclose(sensor["gyro"]["arw"], 0.3 * np.pi / 180 / 60, rtol=0.1)
    np.testing.assert_allclose(sensor["accel"]["vrw"], 100 * UG, rtol=0.1)
    sim = simulate(static_scenario(10.0, sensor=str(tmp_path / "out" / "sensor.yaml")), seed=1)
    assert len(sim.imu) == 1000 and np.all(np.isfinite(sim.imu.dtheta_b))
    for which, white in (("gyro", "arw"), ("accel", "vrw")):       # what the fusion filter requires
        assert {white, "bias_sigma", "bias_instability", "bias_tau"} <= set(doc[which])
    csv_text = (tmp_path / "out" / "allan.csv").read_text().splitlines()
    assert csv_text[0].startswith("tau_s,m,clusters,gyro_x_adev_rad_s,gyro_x_sigma_rad_s,gyro_x_fit_rad_s")
    assert "nan" not in "".join(csv_text).lower()


def test_white_noise_log_gets_a_bias_bound_not_a_fit(tmp_path):
    """No bias term in the log: bias_instability/bias_tau are still written (the fusion filter needs them),
    as the Gauss-Markov curve whose peak touches the deviation's minimum, an upper bound."""
    write_imu_csv(tmp_path / "imu.csv", static_log(0.25, 4, spec={"gyro": {"arw": 0.3}, "accel": {"vrw": 100}}))
    r = run([tmp_path / "imu.csv", "-o", tmp_path / "out", "-q"])
    assert r.exit_code == 0, r.output
    text = (tmp_path / "out" / "sensor.yaml").read_text()
    assert "not identifiable on axis x, y, z" in text and "upper bound" in text
    sensor = load_sensor(str(tmp_path / "out" / "sensor.yaml"), None, "test", tmp_path)
    fit = {row.split(",")[0]: row.split(",") for row in (tmp_path / "out" / "fit.csv").read_text().splitlines()}
    for c, axis in enumerate(("x", "y", "z")):
        tau_min, b = float(fit[f"gyro_{axis}"][9]), float(fit[f"gyro_{axis}"][8])
        assert sensor["gyro"]["bias_tau"][c] == pytest.approx(tau_min / GM_PEAK_X, rel=1e-5)
        # its peak equals the deviation's minimum: 0.6174 sigma = 0.664 B
        assert GM_PEAK_RATIO * sensor["gyro"]["bias_instability"][c] == pytest.approx(0.664 * b * DEG_H, rel=1e-3)
        # and it stays under the white noise at the longest cluster times, as an upper bound should
        assert sensor["gyro"]["bias_instability"][c] < 0.3 * np.pi / 180 / 60 / np.sqrt(tau_min) / GM_PEAK_RATIO * 1.5


def test_installed_script_from_any_directory(tmp_path):
    write_imu_csv(tmp_path / "imu.csv", static_log(0.05, 2))
    exe = Path(sys.executable).with_name("sins")
    p = subprocess.run([str(exe), "allan", "imu.csv", "-o", "noise"], cwd=tmp_path, capture_output=True,
                       text=True, env=dict(os.environ, PYTHONPATH=""))
    assert p.returncode == 0, p.stderr
    assert "ARW" in p.stderr and (tmp_path / "noise" / "sensor.yaml").exists()


def test_moving_short_and_out_of_range_logs_are_refused(tmp_path):
    moving = simulate(static_scenario(0, segments=[{"type": "rest", "duration": 60},
                                                   {"type": "turn", "duration": 20, "rate": 5.0}]), seed=1)
    write_imu_csv(tmp_path / "moving.csv", moving.imu)
    r = run([tmp_path / "moving.csv", "-o", tmp_path / "out"])
    assert r.exit_code == 2 and "not a static log" in r.output
    # a turn of up to 5 deg/s (with its ramps) in the last 20 s of 80: 1 s means depart from the mean by most of it
    assert 3.0 < float(re.search(r"means off the interval's mean by up to ([0-9.]+) deg/s", r.output)[1]) <= 5
    assert "--start/--end" in r.output and not (tmp_path / "out").exists()
    # the rest before the turn is static, but too short for the bias terms: still accepted above 60 s
    r = run([tmp_path / "moving.csv", "--end", 60.0, "-o", tmp_path / "out", "-q"])
    assert r.exit_code == 0, r.output
    r = run([tmp_path / "moving.csv", "--end", 30.0, "-o", tmp_path / "out2"])
    assert r.exit_code == 2 and "needs at least" in r.output and not (tmp_path / "out2").exists()
    r = run([tmp_path / "moving.csv", "--start", 1e6, "-o", tmp_path / "out2"])
    assert r.exit_code == 2 and "--start 1000000.0 is outside the log" in r.output
    perfect = simulate(static_scenario(70.0), perfect=True)
    write_imu_csv(tmp_path / "perfect.csv", perfect.imu)
    r = run([tmp_path / "perfect.csv", "-o", tmp_path / "out2"])
    assert r.exit_code == 2 and "no noise to characterize" in r.output and not (tmp_path / "out2").exists()


@pytest.mark.skipif(not HUSKY.exists(), reason="the Husky bag is not in tests/data")
def test_husky_bag_is_refused_it_drives_throughout(tmp_path):
    """The rover moves from its first second (rates up to 29 deg/s); its quietest stretches last < 25 s."""
    r = run([HUSKY, "-o", tmp_path / "out"])
    assert r.exit_code == 2, r.output
    assert "not a static log" in r.output and "deg/s" in r.output and "Traceback" not in r.output
    r = run([HUSKY, "--start", 1432235658.0, "--end", 1432235678.0, "-o", tmp_path / "out"])
    assert r.exit_code == 2 and "needs at least 1000 samples and 60 s" in r.output
    assert not (tmp_path / "out").exists()


def test_serial_and_threaded_second_difference_sums_are_the_same_bits():
    """Issue 21: short stretches (the fusion's and alignment's rest windows) take the one-thread kernel, long
    logs numba's threads; the same chunks summed in the same order give the same bits, and both equal a
    direct numpy evaluation of the sums to rounding."""
    from sinscli.allan.adev import integrate_into, second_difference_sums, second_difference_sums_serial
    rng = np.random.default_rng(21)
    for n in (37, 5000):
        inc = rng.normal(size=(n, 6)) * 1e-3 + 9.8e-2
        x = np.empty((n + 1, 6))
        integrate_into(x, 0, inc, inc.mean(axis=0))
        ms = np.array([1, 2, 7, n // 4])
        a, b = second_difference_sums(x, ms), second_difference_sums_serial(x, ms)
        assert np.array_equal(a, b)
        direct = np.array([((x[2 * m:] - 2 * x[m:-m] + x[:-2 * m]) ** 2).sum(axis=0) for m in ms])
        np.testing.assert_allclose(a, direct, rtol=1e-12, atol=0)
