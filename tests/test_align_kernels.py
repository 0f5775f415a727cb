"""Alignment kernels against closed forms: Wahba (SVD vs q-method), the navigation-frame integral of
seed 001 eqs 20-21, and exact alignment on error-free data (static and swaying base)."""
import math

import numpy as np
import pytest

from sinscli.align import coarse, inertial, sway, wahba
from sinscli.align.options import AlignOptions, SensorSpec
from sinscli.align.pipeline import align
from sinscli.nav.earth import OMEGA_IE, gravity
from sinscli.nav.rotation import attitude_error_many, rotvec_to_dcm
from sinscli.nav import imu_stats


def dcm_to_rotvec_many(c):
    from sinscli.nav.rotation import dcm_to_rotvec
    return np.array([dcm_to_rotvec(np.ascontiguousarray(x)) for x in c])

LAT = math.radians(30.0)
POS = (LAT, math.radians(114.0), 50.0)
SPEC = SensorSpec(1e-9, 1e-9, 1e-7, 1e-7)


def _err_deg(c_true, c_est):
    return np.degrees(np.abs(attitude_error_many(np.asarray(c_true)[None], np.asarray(c_est)[None])[0]))


def test_wahba_svd_and_q_method_agree_with_the_rotation():
    rng = np.random.default_rng(3)
    c = rotvec_to_dcm(rng.normal(size=3))
    a = rng.normal(size=(7, 3)) * np.array([1.0, 10.0, 100.0])
    b = a @ c.T
    assert np.abs(wahba.solve(a, b) - c).max() < 1e-12
    assert np.abs(wahba.q_method(a, b) - c).max() < 1e-12
    # with noise both methods solve the same problem: the same optimum
    bn = b + 0.05 * rng.normal(size=b.shape)
    w = rng.uniform(0.5, 2.0, size=7)
    assert np.abs(wahba.solve(a, bn, w) - wahba.q_method(a, bn, w)).max() < 1e-12
    assert 1e-4 < np.abs(wahba.solve(a, bn) - c).max() < 0.05
    # cumulative: the last row is the whole solution, the centered fit ignores a common offset
    assert np.abs(wahba.solve_cumulative(a, bn)[-1] - wahba.solve(a, bn)).max() < 1e-12
    off = b + np.array([3.0, -2.0, 1.0])
    assert np.abs(wahba.solve_cumulative(a, off, centered=True)[-1] - c).max() < 1e-12
    assert np.abs(wahba.solve_cumulative(a, off)[-1] - c).max() > 1e-3


def test_nav_side_gravity_integral_is_the_closed_form():
    """At rest beta_v(t) = -int_0^t exp([w_ie s x]) g^n ds, with
    int exp = t I + (1 - cos wt)/w [u x] + (t - sin(wt)/w) [u x]^2."""
    M, T = 3000, 0.1
    dt = np.full(M, T)
    lat = np.full(M + 1, LAT)
    h = np.full(M + 1, 50.0)
    cnn0 = np.empty((M + 1, 3, 3))
    beta = np.empty((M + 1, 3))
    inertial.nav_side(dt, lat, h, np.zeros((M + 1, 3)), cnn0, beta)
    w = np.array([0.0, OMEGA_IE * math.cos(LAT), OMEGA_IE * math.sin(LAT)])
    wn = np.linalg.norm(w)
    u = w / wn
    ux = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    g = np.array([0.0, 0.0, -gravity(math.sin(LAT), 50.0)])
    for k in (1, 100, M):
        t = k * T
        integral = t * np.eye(3) + (1 - math.cos(wn * t)) / wn * ux + (t - math.sin(wn * t) / wn) * ux @ ux
        assert np.abs(beta[k] - (-integral @ g)).max() < 1e-9 * t * 10.0
        assert np.abs(cnn0[k] - rotvec_to_dcm(w * t)).max() < 1e-13


@pytest.fixture(scope="module")
def perfect_static():
    sc = {"name": "s", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 123.0, "pitch": 2.0, "roll": -3.0},
          "imu": {"rate": 50}, "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 120}]}
    return sway.ScenarioRuns(sway.prepare_scenario(sc, None, "t", None)).run(0, perfect=True)


def test_error_free_static_base_is_aligned_exactly(perfect_static):
    r = perfect_static
    for method in ("static", "inertial"):
        res = align(r.imu, AlignOptions(method=method, position=POS, sensor=SPEC))
        assert _err_deg(r.truth.Cbn[-1], res.state.Cbn).max() < 1e-8, method
    w_mean, f_mean = imu_stats.mean_rates(r.imu.time, r.imu.dtheta_b, r.imu.dvel_b, r.imu.t0)
    assert _err_deg(r.truth.Cbn[0], coarse.triad(f_mean, w_mean, LAT)).max() < 1e-8


def test_error_free_swaying_base_is_aligned_exactly():
    sw = {"roll": {"amplitude": 5, "freq": 0.15}, "pitch": {"amplitude": 5, "freq": 0.11, "phase": 60},
          "heading": {"amplitude": 1, "freq": 0.07}, "heave": {"amplitude": 0.5, "freq": 0.12}}
    sc = {"name": "s", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30},
          "imu": {"rate": 50}, "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 120}]}
    r = sway.ScenarioRuns(sway.prepare_scenario(sc, sw, "t", None)).run(0, perfect=True)
    # the sway is there: +-5 deg roll and pitch, +-0.5 m heave
    from sinscli.nav.rotation import dcm_to_euler_many
    eul = np.degrees(dcm_to_euler_many(r.truth.Cbn, 0))
    assert 9.5 < np.ptp(eul[:, 0]) < 10.01 and 9.5 < np.ptp(eul[:, 1]) < 10.01
    assert 0.99 < np.ptp(r.truth.height) < 1.01
    # the kernels: the Wahba solution of the interval vectors is exact but for the heave velocity,
    # which the method takes as zero (a moored base): ~1e-6 deg in 120 s
    dt = np.diff(np.concatenate([[r.imu.t0], r.imu.time]))
    M = len(dt)
    cbb0, alpha, cnn0, beta = inertial.integrate(r.imu.dtheta_b, r.imu.dvel_b, dt, np.full(M + 1, LAT),
                                                 np.full(M + 1, 50.0), np.zeros((M + 1, 3)), 2)
    rows = np.arange(50, M + 1, 50)
    c0 = wahba.solve(np.diff(alpha[np.r_[0, rows]], axis=0), np.diff(beta[np.r_[0, rows]], axis=0))
    assert _err_deg(r.truth.Cbn[0], c0).max() < 1e-5
    assert _err_deg(r.truth.Cbn[-1], inertial.attitude_at(c0, cbb0[-1:], cnn0[-1:])[0]).max() < 1e-5
    # the pipeline's fit takes the 0.38 m/s heave velocity as unmodelled white noise (it finds ~0.27 m/s)
    # and weighs the epochs accordingly: within 1e-4 deg, and its 1-sigma says so
    res = align(r.imu, AlignOptions(method="inertial", position=POS, sensor=SPEC))
    err = _err_deg(r.truth.Cbn[-1], res.state.Cbn)
    assert err.max() < 1e-4 and 0.1 < res.residual["unmodelled_velocity_noise"] < 0.4
    assert np.all(err[:2] < 3.0 * np.degrees(res.sigma[:2]))
    start = align(r.imu, AlignOptions(method="inertial", position=POS, sensor=SPEC, epoch="start"))
    assert _err_deg(r.truth.Cbn[0], start.state.Cbn).max() < 1e-4
    assert start.state.time == r.imu.t0


def test_sway_scenario_keys_are_checked():
    from sinscli.errors import SinsError
    with pytest.raises(SinsError, match="sway.yaw: unknown key"):
        sway.sway_waves({"yaw": {"amplitude": 1}}, "f.yaml")
    with pytest.raises(SinsError, match="sway.roll.freq: must be >= 0"):
        sway.sway_waves({"roll": {"amplitude": 1, "freq": -1}}, "f.yaml")


def test_bias_sensitivities_are_the_first_order_change_of_alpha():
    """B, G and the gyro-matrix terms of the fit (sinscli.align.fit) against finite differences: the
    observation vector alpha integrated from increments with a small accelerometer bias, gyro bias or
    gyro scale-factor/misalignment matrix added moves by B nabla, G eps, G^E e."""
    from sinscli.align import fit
    sc = {"name": "d", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30, "speed": 5},
          "imu": {"rate": 50}, "gnss": {"rate": 1},
          "segments": [{"type": "turn", "angle": 90, "duration": 10, "bank": "none"},
                       {"type": "accelerate", "speed": 10, "duration": 5}, {"type": "roll", "angle": 20, "duration": 5}]}
    r = sway.ScenarioRuns(sway.prepare_scenario(sc, None, "t", None)).run(0, perfect=True)
    dt = np.diff(np.concatenate([[r.imu.t0], r.imu.time]))
    dth, dv = r.imu.dtheta_b, r.imu.dvel_b
    cbb0, alpha = fit._integrate(dth, dv, dt, 2)
    rows = np.array([100, 500, 1000])
    n = rows.size
    B, G, PE, GE = np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 9)), np.empty((n, 3, 9))
    fit.bias_sensitivities(cbb0, alpha, np.ascontiguousarray(dth), dt, rows, B, G, PE, GE)
    nab = np.array([2e-3, -1e-3, 3e-3])
    eps = np.radians([0.001, -0.002, 0.0015])
    E = np.array([[1e-4, 2e-4, -1e-4], [-3e-4, 2e-4, 1e-4], [1e-4, -2e-4, 3e-4]])
    for kind, d_th, d_v, pred in (
            ("accel", dth, dv + nab * dt[:, None], np.einsum("nij,j->ni", B, nab)),
            ("gyro", dth + eps * dt[:, None], dv, np.einsum("nij,j->ni", G, eps)),
            ("matrix", dth + dth @ E.T, dv, np.einsum("nij,j->ni", GE, E.ravel()))):
        _, a2 = fit._integrate(d_th, d_v, dt, 2)
        got = a2[rows] - alpha[rows]
        assert np.abs(got - pred).max() < 1e-3 * np.abs(pred).max(), (kind, got, pred)
    # B and P^E are the integrals of C_b^b(0) dt and C_b^b(0) e_i dtheta_j: the turn's frame rotation
    c, _ = fit._integrate(dth + eps * dt[:, None], dv, dt, 2)
    psi = dcm_to_rotvec_many(np.matmul(c[rows], np.swapaxes(cbb0[rows], 1, 2)))
    assert np.abs(psi - np.einsum("nij,j->ni", B, eps)).max() < 2e-3 * np.abs(psi).max()


def test_fit_covariance_at_rest_matches_the_closed_form_budget():
    """At rest the fit's attitude covariance (its priors: the description) and the closed-form static
    budget of observability.py, two derivations of one thing, agree within 10 %."""
    sc = {"name": "s", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 123.0, "pitch": 2.0, "roll": -3.0},
          "imu": {"rate": 20, "sensor": {"gyro": {"bias": 0.01, "arw": 0.001}, "accel": {"bias": 50, "vrw": 10}}},
          "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 300}]}
    r = sway.ScenarioRuns(sway.prepare_scenario(sc, None, "t", None)).run(1)
    spec = SensorSpec(0.01 * math.pi / 180 / 3600, 0.001 * math.pi / 180 / 60, 50 * 9.80665e-6, 10 * 9.80665e-6)
    res = align(r.imu, AlignOptions(method="inertial", position=POS, sensor=spec))
    g = gravity(math.sin(LAT), 50.0)
    from sinscli.align import observability
    tilt = observability.tilt_sigma(300.0, 50 * 9.80665e-6, 10 * 9.80665e-6, g)
    head = observability.earth_rate_heading_sigma(LAT, 300.0, spec.gyro_bias, spec.gyro_arw, spec.accel_bias, g,
                                                  spec.accel_vrw)
    assert res.sigma[0] == pytest.approx(tilt, rel=0.1) and res.sigma[1] == pytest.approx(tilt, rel=0.1)
    assert res.sigma[2] == pytest.approx(head, rel=0.1)
