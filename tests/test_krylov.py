"""Extended Krylov angles (seed 003, docs/krylov.md) and the classic 3-angle baseline.

Independent truth: closed-form attitude histories ``Cbn(t) = Rz(a) Ry(b) Rx(c) Rz(e)``
(FLU body, ENU nav) whose angles are sinusoids plus tanh ramps of whole turns, with the
analytic body rate; gyro increments are 8-point Gauss-Legendre integrals of the analytic
``w_ib^b = w_nb^b + Cbn^T w_in^n``.  The second method is the quaternion update with the
two-sample coning rotation vector ``phi = dth + (1/12) dth_prev x dth``.
"""
import math

import numpy as np
import pytest
from numba import njit

from sinscli.nav import krylov as K
from sinscli.nav.rotation import (attitude_error_many, dcm_to_quat, quat_mul_t, quat_normalize_t,
                                  quat_to_dcm_many, rotvec_to_quat_t, v_cross)

D2R = math.pi / 180.0
NAV_RATE = np.array([2e-3, 3e-3, 4e-3])          # rad/s, |w_in^n| = 0.31 deg/s


# ----------------------------------------------------------------- independent truth

def _rot(axis, ang):
    """Active elementary rotations (docs/krylov.md 1.2) for an array of angles -> (..., 3, 3)."""
    c, s = np.cos(ang), np.sin(ang)
    m = np.zeros(np.shape(ang) + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[..., axis, axis] = 1.0
    m[..., i, i] = c
    m[..., j, j] = c
    m[..., i, j] = -s
    m[..., j, i] = s
    return m


_AXES = (2, 1, 0, 2)        # Cbn = Rz(a) Ry(b) Rx(c) Rz(e)


class Motion:
    """Analytic attitude: each of the 4 angles = sum A sin(w t + p) + sum of tanh ramps.

    ``spec`` = 4 x (sines [(A, w, p)], ramps [(t0, tau, turns)]); ``speed`` scales time.
    """

    def __init__(self, spec, speed=1.0):
        self.spec = spec
        self.speed = speed

    def angles(self, t):
        out = []
        ts = t * self.speed
        for sines, ramps in self.spec:
            v = np.zeros_like(ts)
            d = np.zeros_like(ts)
            for amp, w, p in sines:
                v = v + amp * np.sin(w * ts + p)
                d = d + amp * w * np.cos(w * ts + p)
            for t0, tau, turns in ramps:
                x = (ts - t0) / tau
                v = v + turns * math.pi * (1.0 + np.tanh(x))
                d = d + turns * math.pi / tau / np.cosh(x) ** 2
            out.append((v, d * self.speed))
        return out

    def dcm(self, t):
        c = None
        for ax, (v, _) in zip(_AXES, self.angles(t)):
            r = _rot(ax, v)
            c = r if c is None else c @ r
        return c

    def w_nb_b(self, t):
        """Body rate w.r.t. the nav frame: sum of angle rates times the axes seen in body."""
        ang = self.angles(t)
        w = np.zeros(np.shape(t) + (3,))
        tail = np.broadcast_to(np.eye(3), np.shape(t) + (3, 3))    # R_{i+1} ... R_4
        for i in range(3, -1, -1):
            w = w + ang[i][1][..., None] * tail[..., _AXES[i], :]   # (tail^T e_axis)
            tail = _rot(_AXES[i], ang[i][0]) @ tail
        return w

    def increments(self, t_end, dt, w_in_n):
        """Gyro increments over (t_end - dt, t_end] by 8-point Gauss-Legendre quadrature."""
        x, wts = np.polynomial.legendre.leggauss(8)
        tn = (t_end[:, None] - dt) + 0.5 * dt * (x[None, :] + 1.0)
        w = self.w_nb_b(tn)
        if np.any(w_in_n):
            w = w + np.einsum("...ji,j->...i", self.dcm(tn), w_in_n)
        return 0.5 * dt * np.einsum("k,nkj->nj", wts, w)


def run_case(motion, duration, rate_hz, w_in_n):
    """Truth DCMs at t = 0, dt, ..., and the increments of each interval."""
    dt = 1.0 / rate_hz
    n = int(round(duration * rate_hz))
    t = np.arange(n + 1) * dt
    return t, motion.dcm(t), motion.increments(t[1:], dt, w_in_n), dt


def err_deg(c_true, c_est):
    """Rotation angle of Cest Ctrue^T per epoch, degrees."""
    e = attitude_error_many(c_true, c_est)
    return np.degrees(np.sqrt((e * e).sum(axis=1)))


@njit(cache=True)
def quat_run(q0, dth, dt, w_in_n):
    """Quaternion reference: 2-sample coning rotation vector, nav-frame rotation by -zeta."""
    n = dth.shape[0]
    out = np.empty((n + 1, 4))
    q = (q0[0], q0[1], q0[2], q0[3])
    out[0] = q0
    qn = rotvec_to_quat_t((-w_in_n[0] * dt, -w_in_n[1] * dt, -w_in_n[2] * dt))
    prev = (dth[0, 0], dth[0, 1], dth[0, 2])
    for k in range(n):
        cur = (dth[k, 0], dth[k, 1], dth[k, 2])
        cr = v_cross(prev, cur)
        phi = (cur[0] + cr[0] / 12.0, cur[1] + cr[1] / 12.0, cur[2] + cr[2] / 12.0)
        q = quat_normalize_t(quat_mul_t(qn, quat_mul_t(q, rotvec_to_quat_t(phi))))
        for j in range(4):
            out[k + 1, j] = q[j]
        prev = cur
    return out


def margins_deg(angs, sets):
    return np.where(sets == K.SET_A, 90.0 - np.degrees(np.abs(angs[:, 2])),
                    90.0 - np.degrees(np.abs(angs[:, 2] - math.pi / 2)))


# The deterministic manoeuvre (docs/krylov.md, "Measured accuracy" in short): a background motion throughout,
# 3 barrel rolls around t = 40 s (peak 84 deg/s), 3 loops around t = 110 s passing within
# 0.15 deg of pitch +-90 deg, then tumbling about all axes from t = 220 s.
MANOEUVRE = Motion([
    ([(0.3, 0.05, 0.0), (0.1, 0.31, 1.0)], [(250.0, 8.0, 2)]),
    ([(0.05, 0.13, 0.3), (0.02, 0.7, 0.0)], [(110.0, 15.0, 3), (255.0, 6.43, -2)]),
    ([(0.1, 0.11, 2.0), (0.05, 0.9, 0.5)], [(40.0, 6.43, 3), (235.0, 8.0, 3)]),
    ([(0.012, 0.17, 0.0), (0.006, 1.3, 1.0)], [(270.0, 8.0, -2)]),
])


def random_tumbling(seed, duration):
    """Random tumbling about all axes, time-scaled to a peak rate of 305-360 deg/s."""
    rng = np.random.default_rng(seed)
    spec = []
    for _ in range(4):
        sines = [(rng.uniform(0.3, 1.5), rng.uniform(0.1, 1.5), rng.uniform(0.0, 6.3)) for _ in range(3)]
        ramps = [(rng.uniform(0.0, duration), rng.uniform(3.0, 10.0), int(rng.integers(-3, 4)))]
        spec.append((sines, ramps))
    tt = np.linspace(0.0, duration, 20001)
    peak = np.degrees(np.linalg.norm(Motion(spec).w_nb_b(tt), axis=1).max())
    return Motion(spec, speed=rng.uniform(305.0, 360.0) / peak)


def random_dcms(n, seed):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    return quat_to_dcm_many(q)


# ----------------------------------------------------------------- DCM, transfers, init

def test_dcm_is_the_four_rotation_product():
    rng = np.random.default_rng(3)
    for phi, psi, gam, xi in rng.uniform(-math.pi, math.pi, size=(2000, 4)):
        ref = _rot(2, phi) @ _rot(1, psi) @ _rot(0, gam) @ _rot(1, xi)
        assert np.abs(K.krylov4_dcm(phi, psi, gam, xi) - ref).max() < 2e-15
        # set A ignores psi (frozen at 0), set B uses phiB for phi
        assert np.abs(K.krylov_dcm(np.array([phi, 9.0, gam, xi]), K.SET_A, 7.0)
                      - _rot(2, phi) @ _rot(0, gam) @ _rot(1, xi)).max() < 2e-15
        assert np.abs(K.krylov_dcm(np.array([phi, psi, gam, xi]), K.SET_B, phi) - ref).max() < 2e-15
    a3 = np.array([0.3, -1.2, 2.5])
    assert np.abs(K.euler3_dcm(a3) - _rot(2, 0.3) @ _rot(1, -1.2) @ _rot(0, 2.5)).max() < 2e-15


def test_patent_example_transfer():
    """(-90, 0, -45, -13.15) deg transfers to (0, 135, 90, -103.15) deg, same DCM."""
    before = np.array([-90.0, 0.0, -45.0, -13.15]) * D2R
    phib, psi, gam, xi = K.transfer_a_to_b(before[0], before[2], before[3])
    after = np.array([phib, psi, gam, xi])
    assert np.abs(np.degrees(after) - [0.0, 135.0, 90.0, -103.15]).max() < 1e-12
    assert np.abs(K.krylov_dcm(before, K.SET_A, 0.0) - K.krylov_dcm(after, K.SET_B, phib)).max() < 1e-12
    # Through the step: past the 45 deg threshold (as in the replay of docs/krylov.md, "The patent's example", gamma
    # = -45.015 deg) with zero increments the step only transfers.
    before[2] = -45.015 * D2R
    zero = np.zeros(3)
    ang, kset, phib, tr = K.krylov_step(before, K.SET_A, 0.0, zero, zero, 0.01, zero)
    assert tr and kset == K.SET_B
    assert np.abs(np.degrees(ang) - [0.0, 135.015, 90.0, -103.15]).max() < 1e-12
    assert np.abs(K.krylov_dcm(before, K.SET_A, 0.0) - K.krylov_dcm(ang, kset, phib)).max() < 1e-12
    # no transfer inside the 45 deg band
    before[2] = -44.9 * D2R
    ang, kset, phib, tr = K.krylov_step(before, K.SET_A, 0.0, zero, zero, 0.01, zero)
    assert not tr and kset == K.SET_A and np.array_equal(ang, before)


def test_transfer_mappings_are_exact_and_land_with_margin():
    rng = np.random.default_rng(5)
    worst = 0.0
    for phi, gam, xi, phib in rng.uniform(-math.pi, math.pi, size=(5000, 4)):
        # A -> B (M1): exact identity for every angle, lands at gamma = 90 deg
        a = np.array([phi, 0.0, gam, xi])
        pb, psi, g, x = K.transfer_a_to_b(phi, gam, xi)
        worst = max(worst, np.abs(K.krylov_dcm(a, K.SET_A, 0.0)
                                  - K.krylov_dcm(np.array([pb, psi, g, x]), K.SET_B, pb)).max())
        # B -> A on the states that leave set B (sin gamma < cos 45 deg): margin > 45 deg
        gb = rng.uniform(-40.0, 40.0) * D2R + (0.0 if rng.random() < 0.5 else math.pi)
        b = np.array([phib, phi, gb, xi])
        fa, ga, xa = K.transfer_b_to_a(phi, gb, xi, phib)
        worst = max(worst, np.abs(K.krylov_dcm(b, K.SET_B, phib)
                                  - K.krylov_dcm(np.array([fa, 0.0, ga, xa]), K.SET_A, 0.0)).max())
        assert 90.0 - abs(math.degrees(ga)) > 45.0
        assert -math.pi < fa <= math.pi and -math.pi < xa <= math.pi
    assert worst < 1e-14


def test_init_from_random_dcms_has_margin_and_rebuilds():
    cs = random_dcms(20000, seed=11)
    # special attitudes: level, Y' vertical (bank +-90), X' vertical (pitch +-90), upside down
    special = [np.eye(3), _rot(0, math.pi / 2), _rot(0, -math.pi / 2), _rot(1, math.pi / 2),
               _rot(1, -math.pi / 2), _rot(0, math.pi), _rot(0, math.pi / 4), _rot(0, -math.pi / 4)]
    cs = np.concatenate([cs, np.array(special)])
    rebuild = 0.0
    mins = 90.0
    n_b = 0
    for c in cs:
        ang, kset, phib = K.krylov_init(c)
        rebuild = max(rebuild, np.abs(K.krylov_dcm(ang, kset, phib) - c).max())
        m = math.degrees(K.krylov_margin(ang, kset))
        mins = min(mins, m)
        if kset == K.SET_B:
            n_b += 1
            assert ang[0] == phib and abs(ang[2] - math.pi / 2) < 1e-12   # margin 90 deg
        else:
            assert ang[1] == 0.0
    assert rebuild < 1e-12
    assert mins >= 45.0
    assert 0.2 * len(cs) < n_b < 0.4 * len(cs)     # P(|elevation of Y'| > 45 deg) = 0.29


def test_euler3_init_rebuilds():
    worst = 0.0
    for c in random_dcms(5000, seed=12):
        a = K.euler3_init(c)
        assert -math.pi / 2 <= a[1] <= math.pi / 2
        worst = max(worst, np.abs(K.euler3_dcm(a) - c).max())
    assert worst < 1e-12
    # X' exactly vertical: gamma := 0, still rebuilds
    c = _rot(2, 0.4) @ _rot(1, math.pi / 2) @ _rot(0, 0.9)
    a = K.euler3_init(c)
    assert a[2] == 0.0 and np.abs(K.euler3_dcm(a) - c).max() < 1e-12


def test_wrap_pi():
    vals = np.array([0.0, math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 7.0, -7.0, 1e3, -0.5])
    for v in vals:
        w = K.wrap_pi(v)
        assert -math.pi < w <= math.pi
        assert abs(math.remainder(w - v, 2 * math.pi)) < 1e-12
    assert K.wrap_pi(-math.pi) == math.pi and K.wrap_pi(1.25) == 1.25


# ----------------------------------------------------------------- propagation

def test_step_dcm_matches_the_angles_and_array_forms():
    t, ct, dth, dt = run_case(MANOEUVRE, 60.0, 100, NAV_RATE)
    ang, kset, phib = K.krylov_init(ct[0])
    prev = dth[0]
    worst = 0.0
    for k in range(dth.shape[0]):
        a_t, ks_t, pb_t, tr_t, c_t = K.krylov_step_dcm_t((ang[0], ang[1], ang[2], ang[3]), kset, phib,
                                                         prev, dth[k], dt, NAV_RATE)
        ang, kset, phib, tr = K.krylov_step(ang, kset, phib, prev, dth[k], dt, NAV_RATE)
        assert np.array_equal(np.array(a_t), ang) and ks_t == kset and pb_t == phib and tr_t == tr
        worst = max(worst, np.abs(np.array(c_t) - K.krylov_dcm(ang, kset, phib)).max())
        prev = dth[k]
    assert worst < 1e-14


def test_patent_replay_roll_about_the_south_axis():
    """docs/krylov.md, "The patent's example": one transfer near gamma = -45 deg, then 3 full rolls purely in psi."""
    xi0 = -13.15 * D2R
    rate = -30.0 * D2R                                  # rad/s about Q (horizontal, South)
    dt, n = 0.01, 3800                                   # 38 s: 5 deg + 3 turns + a bit
    t = np.arange(n + 1) * dt
    gam_true = -40.0 * D2R + rate * t
    ct = _rot(2, -math.pi / 2) @ _rot(0, gam_true) @ _rot(1, xi0)
    w_b = rate * np.array([math.cos(xi0), 0.0, math.sin(xi0)])   # Ry(-xi0) e_x
    dth = np.tile(w_b * dt, (n, 1))
    cbn, angs, sets, transfers = K.krylov_propagate(ct[0], dth, dt, np.zeros(3))
    assert np.abs(np.degrees(angs[0]) - [-90.0, 0.0, -40.0, -13.15]).max() < 1e-12
    assert transfers == 1
    k = int(np.argmax(sets == K.SET_B))                  # first state in set B (after step k-1)
    gam_tr = gam_true[k - 1]                             # the transfer fired at t_{k-1}
    assert gam_tr < -45.0 * D2R < gam_true[k - 2]
    assert np.all(sets[k:] == K.SET_B)
    assert np.abs(angs[k:, 0]).max() < 1e-12             # phiB = 0
    assert np.abs(angs[k:, 2] - math.pi / 2).max() < 1e-12
    assert np.abs(angs[k:, 3] - (xi0 - math.pi / 2)).max() < 1e-12
    # psi: 90 - gamma at the transfer, then turning with -rate (3 full turns)
    psi_unwrapped = np.unwrap(angs[k:, 1])
    assert abs(psi_unwrapped[0] - (math.pi / 2 - gam_tr + (-rate) * dt)) < 1e-12
    assert psi_unwrapped[-1] - psi_unwrapped[0] > 3 * 2 * math.pi
    assert err_deg(ct, cbn).max() < 1e-9


@pytest.mark.parametrize("w_in", [np.zeros(3), NAV_RATE], ids=["fixed-nav", "rotating-nav"])
def test_manoeuvre_accuracy_against_quaternion_and_3_angle_baseline(w_in):
    """300 s at 100 Hz: barrel rolls, loops through pitch +-90 deg, tumbling (<= ~86 deg/s)."""
    t, ct, dth, dt = run_case(MANOEUVRE, 300.0, 100, w_in)
    peak = np.degrees(np.linalg.norm(dth, axis=1).max() / dt)
    assert 80.0 < peak < 90.0
    # the loops pass close to the 3-angle singularity (X' vertical)
    assert np.degrees(np.arccos(np.abs(ct[:, 2, 0]).max())) < 0.2

    cbn, angs, sets, transfers = K.krylov_propagate(ct[0], dth, dt, w_in)
    e_k = err_deg(ct, cbn).max()
    e_q = err_deg(ct, quat_to_dcm_many(quat_run(dcm_to_quat(ct[0]), dth, dt, w_in))).max()
    e_3rk4 = err_deg(ct, K.euler3_propagate(ct[0], dth, dt, w_in, K.EULER3_RK4)[0]).max()
    e_3eul = err_deg(ct, K.euler3_propagate(ct[0], dth, dt, w_in, K.EULER3_FORWARD_EULER)[0]).max()
    print(f"\nkrylov {e_k:.3g} deg, quat {e_q:.3g} deg, ratio {e_k / e_q:.4f}; "
          f"3-angle RK4 {e_3rk4:.3g} deg ({e_3rk4 / e_k:.0f}x), forward Euler {e_3eul:.3g} deg; "
          f"{transfers} transfers, {100 * np.mean(sets == K.SET_B):.0f}% in set B, "
          f"min margin {margins_deg(angs, sets).min():.2f} deg")
    assert e_k < 1e-5
    assert e_k < 1.1 * e_q
    assert e_3rk4 > 50.0 * e_k
    assert 0.3 < e_3eul < 30.0
    assert transfers >= 4 and margins_deg(angs, sets).min() > 40.0
    assert 0.05 < np.mean(sets == K.SET_B) < 0.95          # both sets used


def test_error_is_third_order_in_the_step():
    errs = []
    for hz in (50, 100, 200):
        t, ct, dth, dt = run_case(MANOEUVRE, 80.0, hz, NAV_RATE)      # barrel rolls + loop start
        errs.append(err_deg(ct, K.krylov_propagate(ct[0], dth, dt, NAV_RATE)[0]).max())
    ratios = [errs[0] / errs[1], errs[1] / errs[2]]
    print(f"\nmax error 50/100/200 Hz: {errs}, ratios {ratios}")
    for r in ratios:
        assert 6.5 < r < 9.5


def test_random_tumbling_keeps_margin_and_matches_quaternion():
    for seed in range(4):
        motion = random_tumbling(seed, 60.0)
        t, ct, dth, dt = run_case(motion, 60.0, 100, np.zeros(3))
        peak = np.degrees(np.linalg.norm(dth, axis=1).max() / dt)
        assert peak > 300.0
        cbn, angs, sets, transfers = K.krylov_propagate(ct[0], dth, dt, np.zeros(3))
        e_k = err_deg(ct, cbn).max()
        e_q = err_deg(ct, quat_to_dcm_many(quat_run(dcm_to_quat(ct[0]), dth, dt, np.zeros(3)))).max()
        m = margins_deg(angs, sets).min()
        print(f"\nseed {seed}: peak {peak:.0f} deg/s, {transfers} transfers, min margin {m:.2f} deg, "
              f"krylov {e_k:.3g} deg, quat {e_q:.3g} deg, ratio {e_k / e_q:.3f}")
        assert m > 40.0
        assert transfers > 10
        assert e_k < 1.1 * e_q and e_k < 5e-3


def test_euler3_reports_the_singularity_and_does_not_crash():
    """A loop passing 0.05 deg from X' vertical: |cos psi| dips there; angles stay finite."""
    w = np.array([0.0, 40.0 * D2R, 0.0])               # Cbn = Ry(40 deg/s t) Rz(0.05 deg)
    dt, n = 0.01, 1000
    t = np.arange(n + 1) * dt
    ct = _rot(1, w[1] * t) @ _rot(2, np.full_like(t, 0.05 * D2R))
    dth = np.tile(_rot(2, -0.05 * D2R) @ w * dt, (n, 1))   # body rate Rz(-e0) (0, w, 0)
    thr = math.sin(1.0 * D2R)
    for integ in (K.EULER3_FORWARD_EULER, K.EULER3_RK4):
        cbn, ang3, cmin = K.euler3_propagate(ct[0], dth, dt, np.zeros(3), integ)
        assert np.all(np.isfinite(ang3)) and np.all(np.isfinite(cbn))
        first = int(np.argmax(cmin < thr))
        assert cmin[first] < thr
        # X' reaches 1 deg from the vertical at b = 89 deg, t = 89/40 s
        assert abs(t[first + 1] - 89.0 / 40.0) < 0.03
    # the four angles go through the same loop in set A without a transfer (docs/krylov.md, "The four angles")
    cbn, angs, sets, transfers = K.krylov_propagate(ct[0], dth, dt, np.zeros(3))
    assert transfers == 0 and np.all(sets == K.SET_A) and err_deg(ct, cbn).max() < 1e-9
    # exactly at the singularity with a rate that drives phi: finite result
    a, c = K.euler3_step(np.array([0.3, math.pi / 2, 0.4]), np.array([0.0, 0.0, 1e-3]),
                         np.array([0.0, 0.0, 1e-3]), 0.01, np.zeros(3), K.EULER3_RK4)
    assert np.all(np.isfinite(a)) and c < 1e-15


def test_cs_shift_angle_addition():
    """cos/sin of the RK4 stage angles by angle addition (series below 0.1 rad, libm above)."""
    for x in (-2.9, -0.7, 0.0, 0.4, 1.5707963267948966, 3.0):
        for d in np.concatenate([np.linspace(-0.5, 0.5, 201), [1e-9, -1e-12, 0.0999999, 0.1]]):
            c, s = K._cs_shift(math.cos(x), math.sin(x), d)
            assert abs(c - math.cos(x + d)) < 5e-16 and abs(s - math.sin(x + d)) < 5e-16


def test_rate_model_is_exact_for_a_linear_rate():
    """docs/krylov.md 4.4: for w(t) = a + b t the model gives w T at t_k, t_k + T/2, t_k + T."""
    a, b, T, tk = np.array([0.3, -1.1, 0.7]), np.array([2.0, 0.5, -4.0]), 0.01, 3.0
    inc = lambda t0: a * T + b * (t0 * T + 0.5 * T * T)          # integral over [t0, t0 + T]
    w0, wh, w1 = (np.array(v) for v in K.rate_model(inc(tk - T), inc(tk)))
    assert np.abs(w0 - (a + b * tk) * T).max() < 1e-15
    assert np.abs(wh - (a + b * (tk + T / 2)) * T).max() < 1e-15
    assert np.abs(w1 - (a + b * (tk + T)) * T).max() < 1e-15
    assert np.abs((w0 + 4 * wh + w1) / 6 - inc(tk)).max() < 1e-16          # a few ulp of 0.1
