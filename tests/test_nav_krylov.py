"""`--attitude krylov|euler` through the navigation loop (seed 003), against exact truth.

The 1000 s manoeuvre uses the analytic attitude truth of ``test_krylov.py``
(docs/krylov.md, "Measured accuracy"); the navigation-level cases use the simulator's full-attitude
flight, with position and velocity.
"""
import logging
import math

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.trajectory import read_trajectory
from sinscli.nav import krylov as K
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.nav.rotation import conv_to_flu, dcm_to_quat, quat_to_dcm_many
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sim import motions, write_sim
from sinscli.types import ImuLog, NavState
from test_krylov import Motion, err_deg, quat_run, run_case

# docs/krylov.md, "Measured accuracy" over 1000 s: background motion, barrel rolls (peak ~86 deg/s), loops within 0.2 deg of
# pitch +-90 deg, tumbling about all axes, repeated through the run.
M1000 = Motion([
    ([(0.3, 0.05, 0.0), (0.1, 0.31, 1.0)], [(250.0, 8.0, 2), (600.0, 8.0, -2), (900.0, 8.0, 1)]),
    ([(0.05, 0.13, 0.3), (0.02, 0.7, 0.0)], [(110.0, 15.0, 3), (255.0, 6.43, -2), (520.0, 15.0, 2),
                                            (820.0, 6.43, -2)]),
    ([(0.1, 0.11, 2.0), (0.05, 0.9, 0.5)], [(40.0, 6.43, 3), (235.0, 8.0, 3), (400.0, 6.43, -3),
                                           (700.0, 8.0, 3), (950.0, 6.43, 2)]),
    ([(0.012, 0.17, 0.0), (0.006, 1.3, 1.0)], [(270.0, 8.0, -2), (650.0, 8.0, 2)]),
])


def test_1000s_manoeuvre_krylov_vs_quat_and_three_angles():
    t, ct, dth, dt = run_case(M1000, 1000.0, 100, np.zeros(3))
    assert 80 < np.degrees(np.linalg.norm(dth, axis=1).max() / dt) < 90
    cbn, angs, sets, transfers = K.krylov_propagate(ct[0], dth, dt, np.zeros(3))
    e_k = err_deg(ct, cbn).max()
    e_q = err_deg(ct, quat_to_dcm_many(quat_run(dcm_to_quat(ct[0]), dth, dt, np.zeros(3)))).max()
    e_3 = err_deg(ct, K.euler3_propagate(ct[0], dth, dt, np.zeros(3), K.EULER3_RK4)[0]).max()
    e_e = err_deg(ct, K.euler3_propagate(ct[0], dth, dt, np.zeros(3), K.EULER3_FORWARD_EULER)[0]).max()
    assert e_k < 1e-5                 # measured 5.34e-6 deg
    assert e_k < 1.1 * e_q            # measured ratio 1.0005
    assert e_3 > 50 * e_k             # measured ~7e4 x
    assert 0.3 < e_e < 30.0           # degrees
    assert transfers >= 8


@pytest.fixture(scope="module")
def flight():
    return motions.full_attitude(duration=300.0, rate=100.0)


def _att(res, **kw):
    nav = navigate(res.imu, res.init, NavOptions(**kw))
    s = compare_trajectories(res.truth, nav)
    return math.degrees(s.angle_rad.max()), float(np.abs(s.pos_enu_m).max()), nav


def test_navigation_loop_krylov_matches_quat(flight):
    e_k, p_k, _ = _att(flight, attitude="krylov")
    e_q, p_q, _ = _att(flight, attitude="quat")
    e_3, _, _ = _att(flight, attitude="euler", euler_integrator="rk4")
    e_e, _, _ = _att(flight, attitude="euler", euler_integrator="euler")
    assert e_k < 1e-5 and e_k < 1.1 * e_q
    assert p_k < 2 * p_q
    assert e_3 > 50 * e_k and 0.1 < e_e < 30.0


def test_krylov_error_is_third_order():
    errs = [_att(motions.full_attitude(duration=100.0, rate=r), attitude="krylov")[0] for r in (50.0, 100.0, 200.0)]
    assert 6.0 < errs[0] / errs[1] < 10.5 and 6.0 < errs[1] / errs[2] < 10.5, errs


@pytest.mark.parametrize("conv", [1, 2])
def test_other_body_conventions_go_through_flu(flight, conv):
    """The same motion given in RFU or FRD axes navigates to the same attitude."""
    c = conv_to_flu(conv)             # C_conv^flu
    imu = flight.imu
    imu_c = ImuLog(imu.time, imu.dtheta_b @ c, imu.dvel_b @ c, t0=imu.t0)   # x_conv = C^T x_flu
    i0 = flight.init
    init_c = NavState(i0.time, i0.lat, i0.lon, i0.height, i0.vel_n, i0.Cbn @ c)
    a = navigate(imu, i0, NavOptions(attitude="krylov"))
    b = navigate(imu_c, init_c, NavOptions(attitude="krylov", conv=conv))
    assert np.abs(b.Cbn @ c.T - a.Cbn).max() < 1e-12


def test_cli_angles_columns_and_transfer_log(tmp_path, caplog):
    d = tmp_path / "sim"
    write_sim(motions.full_attitude(duration=60.0, rate=100.0), d)
    out = tmp_path / "k.csv"
    with caplog.at_level(logging.DEBUG, logger="sins"):
        r = CliRunner().invoke(main, ["--debug", "navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"),
                                      "--attitude", "krylov", "--angles", "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    header = out.read_text().splitlines()[0].split(",")
    assert header[-5:] == ["k_phi", "k_psi", "k_gamma", "k_xi", "k_set"]
    nav = read_trajectory(out)
    sets = nav.extra["k_set"]
    assert set(np.unique(sets)) <= {0.0, 1.0}
    # the angles rebuild the written DCM
    for k in range(0, len(nav), 997):
        ang = np.radians([nav.extra[c][k] for c in ("k_phi", "k_psi", "k_gamma", "k_xi")])
        c = K.krylov_dcm(ang, int(sets[k]), ang[0] if sets[k] == 1 else 0.0)
        assert np.abs(c - nav.Cbn[k]).max() < 1e-12
    if (np.diff(sets) != 0).any():
        assert "krylov transfer at t=" in caplog.text


def test_euler_singularity_reported_or_stopped(tmp_path, caplog, flight):
    d = tmp_path / "sim"
    write_sim(motions.full_attitude(duration=120.0, rate=100.0), d)
    out = tmp_path / "e.csv"
    r = CliRunner().invoke(main, ["navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"),
                                  "--attitude", "euler", "--on-singularity", "stop", "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    assert "stopped there" in caplog.text
    nav = read_trajectory(out)
    assert nav.time[-1] < 120.0 - 1.0          # stopped early, at the reported epoch
    caplog.clear()
    r = CliRunner().invoke(main, ["navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"),
                                  "--attitude", "euler", "-o", str(out), "-q"])
    assert r.exit_code == 0 and "carrying on" in caplog.text
    assert abs(read_trajectory(out).time[-1] - 120.0) < 1e-9


def test_non_orthonormal_initial_dcm_and_angles_misuse_refused(tmp_path):
    d = tmp_path / "sim"
    write_sim(motions.full_attitude(duration=2.0, rate=100.0), d)
    truth = (d / "truth.csv").read_text().splitlines()
    header = truth[0].split(",")
    row = truth[1].split(",")
    i = header.index("c11")
    row[i] = repr(float(row[i]) * (1 + 1e-4))
    bad = tmp_path / "bad_init.csv"
    bad.write_text("\n".join([truth[0], ",".join(row)]) + "\n")
    out = tmp_path / "o.csv"
    r = CliRunner().invoke(main, ["navigate", str(d / "imu.csv"), "--init", str(bad), "--attitude", "krylov",
                                  "-o", str(out), "-q"])
    assert r.exit_code == 2 and "not orthonormal" in r.output and not out.exists()
    r = CliRunner().invoke(main, ["navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"),
                                  "--attitude", "quat", "--angles", "-o", str(out), "-q"])
    assert r.exit_code == 2 and "--angles" in r.output and not out.exists()
