"""RK4 sub-steps of the four Krylov angles under fast rotation (issue 14, docs/krylov.md).

Independent truths: a rotation about a fixed body axis has the closed form
``Cbn(t) = Cbn(0) exp([u x] int w dt)`` (Rodrigues), whatever the rate profile;
the simulated spin boost (``configs/scenarios/spin_boost.yaml``) has the exact
truth of ``sins simulate``; the second method is the quaternion update.
"""
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from sinscli import config as config_mod
from sinscli.nav import krylov as K
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.nav.rotation import rotvec_to_dcm
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sim import simulate, write_sim
from test_krylov import err_deg, margins_deg, random_dcms

ROOT = Path(__file__).resolve().parent.parent
SPIN_BOOST = ROOT / "configs" / "scenarios" / "spin_boost.yaml"
SPIN_SECONDS = 32.0                     # the boost with its spin; the rest of the scenario is a slow arc
TWO_REV = 4.0 * math.pi                 # 2 rev/s in rad/s


def test_substep_angle_and_count_rule():
    """m = ceil(|w|T / theta_s), theta_s = (tol / kappa)^(1/4); 1 below theta_s, capped at MAX_SUBSTEPS."""
    th_s = K.substep_angle(K.SUBSTEP_TOL)
    assert th_s == K.SUBSTEP_ANGLE
    assert abs(K.RK4_KAPPA * th_s ** 4 - K.SUBSTEP_TOL) < 1e-15 * K.SUBSTEP_TOL * 1e3
    assert 0.0125 < th_s < 0.0126                        # 0.72 deg per sub-step by default
    assert config_mod.DEFAULTS["navigation"]["krylov_substep_tol"] == K.SUBSTEP_TOL == NavOptions().krylov_substep_tol
    u = np.array([0.48, -0.6, 0.64])                     # unit axis
    for theta, m in ((0.5 * th_s, 1), (0.999 * th_s, 1), (1.001 * th_s, 2), (2.5 * th_s, 3),
                     (TWO_REV / 100, 10), (TWO_REV / 400, 3), (100.0, K.MAX_SUBSTEPS)):
        assert K.substep_counts(np.tile(theta * u, (3, 1)), th_s).tolist() == [m] * 3, theta
    # the largest rate of the linear model over the interval counts (its end: 1.5 dth - 0.5 dth_prev)
    d = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0 * th_s]])
    assert K.substep_counts(d, th_s).tolist() == [1, 3]
    assert K.substep_counts(d, math.inf).tolist() == [1, 1]


def _fixed_axis_run(c0, u, total_angle, dt, max_angle):
    """Krylov over increments ``u (phi(t_k) - phi(t_{k-1}))``; returns (errors deg, angles, sets, transfers)."""
    phi = total_angle
    dth = np.diff(phi)[:, None] * u[None, :]
    truth = np.array([c0 @ rotvec_to_dcm(p * u) for p in phi])
    cbn, angs, sets, transfers = K.krylov_propagate(c0, dth, dt, np.zeros(3), max_angle)
    return err_deg(truth, cbn), angs, sets, transfers


@pytest.mark.parametrize("pitch_deg", [20.0, 40.0, 60.0])
def test_fast_spin_about_a_fixed_axis_meets_the_tolerance(pitch_deg):
    """2 rev/s about the forward axis, nose pitched up, at 100 Hz (7.2 deg per interval) for 2 s.

    Y' sweeps up to 90 - pitch deg of elevation each turn, past the 45 deg transfer threshold at
    20 and 40 deg of pitch (a transfer inside a sub-stepped interval, then set B: M1 puts N_B
    where the spin does not bring Y').  Without
    sub-steps the RK4 truncation is (|w|T)^5-sized per interval; 2 sub-steps cut it 16x (fourth
    order in the sub-step); the default keeps it under tol x the rotation per interval, the
    promise of the sub-step rule; the active set stays off its singularity.
    """
    c0 = K.krylov4_dcm(math.radians(30.0), 0.0, 0.0, -math.radians(pitch_deg))    # FLU x pitched up
    u = np.array([1.0, 0.0, 0.0])
    dt = 0.01
    t = np.arange(201) * dt
    theta = TWO_REV * dt
    e1, _, _, _ = _fixed_axis_run(c0, u, TWO_REV * t, dt, math.inf)
    e2, _, _, _ = _fixed_axis_run(c0, u, TWO_REV * t, dt, 0.51 * theta)       # m = 2
    ed, angs, sets, transfers = _fixed_axis_run(c0, u, TWO_REV * t, dt, K.SUBSTEP_ANGLE)
    bound = 200 * K.SUBSTEP_TOL * theta                  # rad: tol x rotation, summed over intervals
    print(f"\npitch {pitch_deg}: no sub-steps {e1.max():.3g} deg, m=2 {e2.max():.3g} deg "
          f"(x{e1.max() / e2.max():.1f}), default (m=10) {ed.max():.3g} deg, bound {math.degrees(bound):.3g} deg, "
          f"{transfers} transfers, min margin {margins_deg(angs, sets).min():.3f} deg")
    assert e1.max() > 100.0 * math.degrees(bound)        # the shortfall
    assert 12.0 < e1.max() / e2.max() < 20.0
    assert ed.max() < math.degrees(bound)
    # one sub-step of overshoot at most past the 45 deg transfer threshold (|dgamma/dt| <= |w|)
    assert margins_deg(angs, sets).min() > 45.0 - math.degrees(K.SUBSTEP_ANGLE) - 1e-9
    assert transfers >= (1 if pitch_deg < 45.0 else 0)


def test_rising_spin_uses_the_linear_rate_model_inside_the_interval():
    """A fixed-axis spin rising linearly from 0 to 3 rev/s in 1.5 s at 100 Hz.

    For a fixed axis the attitude depends only on the integrated angle; a sub-step that took the
    wrong share of the rate model would be off by ~|dw/dt| T^2 (1e-2 rad here).  With the
    default tolerance the error stays under tol x the rotation per interval.
    """
    c0 = random_dcms(1, 11)[0]
    u = np.array([2.0, -1.0, 2.0]) / 3.0
    dt = 0.01
    t = np.arange(151) * dt
    b = 6.0 * math.pi / 1.5                               # rad/s^2
    e1, _, _, _ = _fixed_axis_run(c0, u, 0.5 * b * t * t, dt, math.inf)
    ed, _, _, transfers = _fixed_axis_run(c0, u, 0.5 * b * t * t, dt, K.SUBSTEP_ANGLE)
    bound = K.SUBSTEP_TOL * 0.5 * b * t[-1] ** 2
    print(f"\nrising spin: no sub-steps {e1.max():.3g} deg, default {ed.max():.3g} deg, "
          f"bound {math.degrees(bound):.3g} deg")
    assert ed.max() < math.degrees(bound)
    assert ed.max() < 1e-3 * e1.max()


def test_slow_motion_takes_the_single_step_bit_for_bit():
    """Below the sub-step angle (here ~86 deg/s at 200 Hz) the update is the one RK4 step of docs/krylov.md 4.6."""
    from test_krylov import MANOEUVRE, run_case
    t, ct, dth, dt = run_case(MANOEUVRE, 60.0, 200, np.zeros(3))
    assert K.substep_counts(dth, K.SUBSTEP_ANGLE).max() == 1
    a = K.krylov_propagate(ct[0], dth, dt, np.zeros(3))
    b = K.krylov_propagate(ct[0], dth, dt, np.zeros(3), math.inf)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


@pytest.fixture(scope="module")
def spin_boost_runs():
    """The spin boost at 100, 200, 400 Hz: max attitude error (deg) and position error (m) per method."""
    sc = yaml.safe_load(SPIN_BOOST.read_text())
    out = {}
    for rate in (100.0, 200.0, 400.0):
        sc["imu"]["rate"] = rate
        r = simulate(sc, perfect=True, duration=SPIN_SECONDS)
        row = {}
        for name, kw in (("quat", dict(attitude="quat")), ("krylov", dict(attitude="krylov")),
                         ("krylov-1", dict(attitude="krylov", krylov_substep_tol=0.5))):
            s = compare_trajectories(r.truth, navigate(r.imu, r.init, NavOptions(**kw)))
            row[name] = (math.degrees(s.angle_rad.max()), float(np.abs(s.pos_enu_m).max()))
        m = K.substep_counts(r.imu.dtheta_b, K.SUBSTEP_ANGLE)
        row["substeps"] = (int(m.max()), float(m.mean()))
        row["peak"] = math.degrees(np.linalg.norm(r.imu.dtheta_b, axis=1).max() * rate)
        out[rate] = row
        print(f"\n{rate:.0f} Hz: peak {row['peak']:.1f} deg/s; quat {row['quat'][0]:.4g} deg; "
              f"krylov {row['krylov'][0]:.4g} deg (x{row['krylov'][0] / row['quat'][0]:.4f}), "
              f"without sub-steps {row['krylov-1'][0]:.4g} deg (x{row['krylov-1'][0] / row['quat'][0]:.2f}); "
              f"position quat {row['quat'][1]:.3g} m, krylov {row['krylov'][1]:.3g} m; "
              f"sub-steps max {row['substeps'][0]}, mean {row['substeps'][1]:.3f}")
    return out


def test_spin_boost_krylov_matches_quat(spin_boost_runs):
    """Issue 14: krylov within 1.1x of quat on the 2 rev/s spin (100 Hz; 200 and 400 Hz as well)."""
    for rate, row in spin_boost_runs.items():
        assert 715.0 < row["peak"] < 725.0
        e_q, e_k, e_1 = row["quat"][0], row["krylov"][0], row["krylov-1"][0]
        assert e_k < 1.1 * e_q, rate
        assert row["krylov"][1] < 1.1 * row["quat"][1], rate
        assert e_1 > 2.0 * e_q, rate                      # the shortfall without sub-steps
    r100 = spin_boost_runs[100.0]
    assert r100["krylov-1"][0] > 8.0 * r100["quat"][0]    # measured 12.8x
    assert r100["krylov"][0] < 1.01 * r100["quat"][0]     # measured 1.001x
    assert [spin_boost_runs[r]["substeps"][0] for r in (100.0, 200.0, 400.0)] == [10, 5, 3]


def _sins():
    exe = Path(sys.executable).parent / "sins"
    return str(exe) if exe.exists() else shutil.which("sins")


def test_installed_sins_reports_substeps_and_takes_the_config_key(tmp_path):
    """`sins --debug navigate --attitude krylov` logs the sub-steps per block; the config key sets them."""
    d = tmp_path / "sim"
    res = simulate(SPIN_BOOST, perfect=True, duration=12.0)
    write_sim(res, d)
    # expected counts, from the rate model's end values in numpy
    dth = res.imu.dtheta_b
    prev = np.vstack([dth[:1], dth[:-1]])
    th = np.maximum(np.linalg.norm((prev + dth) / 2, axis=1), np.linalg.norm((3 * dth - prev) / 2, axis=1))
    m = np.where(th > K.SUBSTEP_ANGLE, np.ceil(th / K.SUBSTEP_ANGLE), 1.0)
    env = dict(os.environ)
    def run(*extra, out="k.csv"):
        return subprocess.run([_sins(), "--debug", "navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"),
                               "--attitude", "krylov", "-q", "-o", out, *extra], cwd=tmp_path, env=env,
                              capture_output=True, text=True)
    r = run()
    assert r.returncode == 0, r.stderr
    # 12 s: the spin has reached 605 deg/s (10.6 rad/s x 10 ms / 0.0126 rad -> 9 sub-steps)
    assert m.max() == 9
    assert (f"krylov: RK4 sub-steps per attitude interval in this block: max 9, mean {m.mean():.4f} "
            f"over 1200 intervals") in r.stderr
    assert "bytecode dump" not in r.stderr                # --debug is the sins logger's, not numba's
    cfg = tmp_path / "nav.yaml"
    cfg.write_text("navigation:\n  krylov_substep_tol: 0.5\n")
    r = run("--config", str(cfg))
    assert r.returncode == 0 and "in this block: max 1, mean 1.0000" in r.stderr
    cfg.write_text("navigation:\n  krylov_substep_tol: 0\n")
    r = run("--config", str(cfg), out="bad.csv")
    assert r.returncode == 2 and not (tmp_path / "bad.csv").exists()
    assert r.stderr.strip() == (f"sins: error: {cfg}: navigation.krylov_substep_tol: expected a number in "
                                "(0, 1), got 0")
