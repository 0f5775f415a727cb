"""Navigation accuracy against exact truth (issue: navigation core, numbers to reach).

Truth comes from two independent sources: closed-form increments written here
(rest on the rotating earth), and the simulator's analytic motions (Taylor
jets + Gauss-Legendre quadrature, :mod:`sinscli.sim`).  Errors are computed by
:mod:`sinscli.report.errors` (DCM difference, metres E/N/U).
"""
import math

import numpy as np
import pytest

from sinscli.nav import earth
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.nav.rotation import euler_to_dcm
from sinscli.report.errors import compare_trajectories
from sinscli.sim import motions
from sinscli.types import ImuLog, NavState


def _errors(res, **opts):
    nav = navigate(res.imu, res.init, NavOptions(**opts))
    s = compare_trajectories(res.truth, nav)
    return dict(att_deg=math.degrees(s.angle_rad.max()),
                hor=float(np.hypot(s.pos_enu_m[:, 0], s.pos_enu_m[:, 1]).max()),
                ver=float(np.abs(s.pos_enu_m[:, 2]).max()),
                vel=float(np.abs(s.vel_enu_mps).max()), nav=nav)


@pytest.fixture(scope="module")
def drive():
    return motions.drive(duration=1200.0, rate=100.0)


def static_log(hours=1.0, rate=100.0, lat_deg=30.0, h=100.0, att=(0.1, -0.05, 1.0)):
    """Exact increments at rest: w_ib^b = C_n^b w_ie^n, f^b = -C_n^b g^n, constant in the body."""
    lat = math.radians(lat_deg)
    cbn = euler_to_dcm(*att, 0)
    w_n = np.array([0.0, earth.OMEGA_IE * math.cos(lat), earth.OMEGA_IE * math.sin(lat)])
    g = earth.gravity(math.sin(lat), h)
    dt = 1.0 / rate
    n = int(round(hours * 3600 * rate))
    t = np.arange(1, n + 1) * dt
    imu = ImuLog(t, np.tile(cbn.T @ w_n * dt, (n, 1)), np.tile(cbn.T @ np.array([0, 0, g]) * dt, (n, 1)))
    return imu, NavState(0.0, lat, 0.2, h, np.zeros(3), cbn)


@pytest.mark.parametrize("attitude,variant", [("quat", "exact"), ("dcm", "exact"), ("dcm", "seed000")])
def test_static_hour_stays_put(attitude, variant):
    imu, init = static_log()
    nav = navigate(imu, init, NavOptions(attitude=attitude, dcm_variant=variant, coning=2))
    rm, rn = earth.radii(math.sin(init.lat))
    dn = (nav.lat - init.lat) * (rm + init.height)
    de = (nav.lon - init.lon) * (rn + init.height) * math.cos(init.lat)
    assert len(nav) == len(imu) + 1
    assert np.hypot(dn, de).max() < 1e-6
    assert np.abs(nav.height - init.height).max() < 1e-4
    assert np.abs(nav.vel_n).max() < 1e-8
    att = np.array([np.linalg.norm(c @ init.Cbn.T - np.eye(3)) for c in nav.Cbn[::3600]])
    assert att.max() < 1e-12


def test_drive_20min(drive):
    e = _errors(drive, attitude="quat", coning=2)
    assert e["att_deg"] < 1e-7
    assert e["ver"] < 1e-3
    assert e["vel"] < 1e-6
    # measured 1.38e-4 m; guards against regressions (the 1e-4 m target is checked below)
    assert e["hor"] < 1.6e-4


@pytest.mark.xfail(strict=True, reason="measured 1.38e-4 m after 20 min, above the 1e-4 m target: a third-order "
                   "floor independent of the coning/sculling order and of the position rule (see the README)")
def test_drive_20min_horizontal_target(drive):
    assert _errors(drive, attitude="quat", coning=2)["hor"] < 1e-4


def test_dcm_and_quat_agree_on_drive(drive):
    q = _errors(drive, attitude="quat")["nav"]
    d = _errors(drive, attitude="dcm")["nav"]
    ang = [np.linalg.norm(a @ b.T - np.eye(3)) / math.sqrt(2) for a, b in zip(q.Cbn[::100], d.Cbn[::100])]
    assert max(ang) < 1e-9


def test_general_motion_error_is_third_order():
    errs = []
    for rate in (50.0, 100.0, 200.0):
        errs.append(_errors(motions.drive(duration=300.0, rate=rate), attitude="quat")["vel"])
    r1, r2 = errs[0] / errs[1], errs[1] / errs[2]
    assert 6.0 < r1 < 10.5 and 6.0 < r2 < 10.5, errs


def test_full_attitude_manoeuvre():
    e = _errors(motions.full_attitude(duration=300.0, rate=100.0), attitude="quat", coning=2)
    assert e["att_deg"] < 1e-5


def test_coning_10min():
    e = _errors(motions.coning(duration=600.0, rate=100.0), attitude="quat", coning=2)
    assert e["att_deg"] < 1e-4


def test_coning_drift_is_fourth_order_with_two_samples():
    a50 = _errors(motions.coning(duration=60.0, rate=50.0), attitude="quat", coning=2)["att_deg"]
    a100 = _errors(motions.coning(duration=60.0, rate=100.0), attitude="quat", coning=2)["att_deg"]
    assert 11.0 < a50 / a100 < 20.0
    one = _errors(motions.coning(duration=60.0, rate=100.0), attitude="quat", coning=1)["att_deg"]
    assert one > 100 * a100   # the fixed-axis (seed 000) assumption rectifies the cone


@pytest.mark.parametrize("order", [3, 4])
def test_multisample_coning_beats_two_sample(order):
    two = _errors(motions.coning(duration=60.0, rate=100.0), attitude="quat", coning=2)["att_deg"]
    more = _errors(motions.coning(duration=60.0, rate=100.0), attitude="quat", coning=order)["att_deg"]
    assert more < two / 4


def test_two_speed_matches_one_speed_order(drive):
    """N = 2 fast samples per attitude update navigates the same drive at the attitude rate's accuracy."""
    res = motions.drive(duration=120.0, rate=200.0)
    one = _errors(res, attitude="quat", coning=2, subsamples=1)
    two = _errors(res, attitude="quat", coning=2, subsamples=2)
    assert len(two["nav"]) == len(res.imu) // 2 + 1
    assert two["att_deg"] < 1e-7 and two["vel"] < 1e-5
    assert one["att_deg"] < two["att_deg"]


def test_chunked_run_is_identical(drive):
    """Block-wise navigation (as for long logs) gives bit-identical states."""
    from sinscli.nav.pipeline import concat, navigate_blocks
    imu = drive.imu
    n = 40000
    blocks = [ImuLog(imu.time[a:min(a + 7777, n)], imu.dtheta_b[a:min(a + 7777, n)],
                     imu.dvel_b[a:min(a + 7777, n)]) for a in range(0, n, 7777)]
    whole = navigate(ImuLog(imu.time[:n], imu.dtheta_b[:n], imu.dvel_b[:n]), drive.init)
    parts = concat(list(navigate_blocks(blocks, drive.init, NavOptions())))
    assert np.array_equal(whole.Cbn, parts.Cbn) and np.array_equal(whole.lat, parts.lat)
