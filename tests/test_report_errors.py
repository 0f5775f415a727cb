"""Error computations of ``sins compare`` against closed-form synthetic cases.

The navigation trajectories are built from the truth by a known rotation, a
known displacement in metres (applied exactly, through ECEF) and a known
velocity offset; the errors must come back as those numbers.
"""
import numpy as np
import pytest

from sinscli.errors import SinsError
from sinscli.nav.earth import ecef_to_lla, enu_rotation, lla_to_ecef
from sinscli.nav.rotation import FLU, FRD, RFU, dcm_to_euler_many, euler_to_dcm_many, rotvec_to_dcm, skew
from sinscli.evaluate.errors import (ROWS, build_table, common_epoch, compare_trajectories, interpolate_truth,
                                   match_epochs)
from sinscli.types import Trajectory

D2R = np.pi / 180.0


def make_truth(n=200, t0=100.0, dt=0.01, conv=FLU, pitch_deg=5.0):
    t = t0 + dt * np.arange(n)
    s = np.linspace(0.0, 1.0, n)
    roll = D2R * (10.0 * np.sin(3 * s))
    pitch = D2R * (pitch_deg + 2.0 * s)
    heading = D2R * (30.0 + 200.0 * s)
    cbn = euler_to_dcm_many(roll, pitch, heading, conv)
    return Trajectory(time=t, lat=D2R * (34.0 + 0.01 * s), lon=D2R * (108.0 + 0.02 * s),
                      height=400.0 + 50.0 * s, vel_n=np.column_stack([100 + s, 50 - s, 3 * s]), Cbn=cbn,
                      source="truth.csv")


def displaced(truth, d_enu, dv_enu, phi_n=None, phi_body=None):
    """A navigation copy with truth - nav = d_enu (m, exact through ECEF), dv_enu, and a rotation.

    ``phi_n``: Cbn_true = exp([phi_n x]) Cbn_nav; ``phi_body``: Cbn_true = Cbn_nav exp([phi_body x]).
    """
    ecef_t = lla_to_ecef(truth.lat, truth.lon, truth.height)
    c_en = np.swapaxes(enu_rotation(truth.lat, truth.lon), -1, -2)          # ENU -> ECEF
    ecef_n = ecef_t - np.einsum("nij,j->ni", c_en, np.asarray(d_enu))
    lat, lon, h = ecef_to_lla(ecef_n)
    cbn = truth.Cbn.copy()
    if phi_n is not None:
        r = rotvec_to_dcm(-np.asarray(phi_n, float))
        cbn = np.einsum("ij,njk->nik", r, cbn)
    if phi_body is not None:
        r = rotvec_to_dcm(-np.asarray(phi_body, float))
        cbn = np.einsum("nij,jk->nik", cbn, r)
    return Trajectory(time=truth.time.copy(), lat=lat, lon=lon, height=h, vel_n=truth.vel_n - np.asarray(dv_enu),
                      Cbn=cbn, source="nav.csv")


def test_known_displacement_rotation_and_velocity_come_back():
    truth = make_truth()
    d = np.array([-7.09673e-02, -4.00094e-01, 4.62018e-01])     # seed 000 Table 1 magnitudes
    dv = np.array([5.99965e-03, 7.61443e-03, 2.92191e-02])
    phi = np.array([3e-6, -5e-6, 8e-6])
    nav = displaced(truth, d, dv, phi_n=phi)
    s = compare_trajectories(truth, nav)
    assert len(s) == len(truth)
    # ECEF displacement vs ellipsoid-radii conversion differ by |d|^2 / R ~ 1e-8 m.
    np.testing.assert_allclose(s.pos_enu_m, np.tile(d, (len(truth), 1)), atol=2e-7)
    np.testing.assert_allclose(s.vel_enu_mps, np.tile(dv, (len(truth), 1)), atol=1e-13)
    np.testing.assert_allclose(s.att_n_rad, np.tile(phi, (len(truth), 1)), atol=1e-15)
    np.testing.assert_allclose(s.angle_rad, np.linalg.norm(phi), rtol=1e-9)
    # dC = Cbn_true - Cbn_nav = (I - exp(-[phi x])) Cbn_true = [phi x] Cbn_true + O(phi^2)
    first_order = np.einsum("ij,njk->nik", skew(phi), truth.Cbn)
    np.testing.assert_allclose(s.dC, first_order, atol=np.dot(phi, phi))
    table = build_table({"m": s})
    col = dict(zip(ROWS, table.values[:, 0]))
    assert table.epoch == truth.time[-1]
    np.testing.assert_allclose([col["pos_E"], col["pos_N"], col["pos_U"]], d, atol=2e-7)
    np.testing.assert_allclose([col["max_pos_E"], col["max_pos_N"], col["max_pos_U"]], np.abs(d), atol=2e-7)
    np.testing.assert_allclose([col["vel_E"], col["vel_N"], col["vel_U"]], dv, atol=1e-13)
    np.testing.assert_allclose(col["max_att_deg"], np.degrees(np.linalg.norm(phi)), rtol=1e-9)
    np.testing.assert_allclose([col[f"C{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3)],
                               s.dC[-1].reshape(9), rtol=0, atol=0)


def test_large_displacement_uses_radii_at_truth_point():
    """10 km north at 60 deg latitude: the conversion is (lat_t - lat_n)(RM + h_t), checked by hand."""
    truth = make_truth(n=5)
    truth.lat[:] = D2R * 60.0
    nav = Trajectory(truth.time, truth.lat - 10000.0 / 6.3e6, truth.lon.copy(), truth.height - 2.0,
                     truth.vel_n.copy(), truth.Cbn.copy())
    s = compare_trajectories(truth, nav)
    a, e2 = 6378137.0, 0.0066943799901413165
    w = 1 - e2 * np.sin(D2R * 60) ** 2
    rm = a * (1 - e2) / w ** 1.5
    np.testing.assert_allclose(s.pos_enu_m[:, 1], 10000.0 / 6.3e6 * (rm + truth.height), rtol=1e-12)
    np.testing.assert_allclose(s.pos_enu_m[:, 2], 2.0, rtol=1e-12)
    np.testing.assert_allclose(s.pos_enu_m[:, 0], 0.0, atol=0)


@pytest.mark.parametrize("conv", [FLU, RFU, FRD])
def test_level_components_are_euler_differences(conv):
    """Euler perturbations (dR, dP, dH) at any attitude give exactly (dR cos P, dP, dH - dR sin P)."""
    n = 50
    truth = make_truth(n=n, conv=conv)
    roll, pitch = np.full(n, 30 * D2R), np.linspace(-60, 60, n) * D2R
    truth.Cbn = euler_to_dcm_many(roll, pitch, np.linspace(0.3, 6.0, n), conv)
    eul_t = dcm_to_euler_many(truth.Cbn, conv)
    dr, dp, dh = 2e-5, -3e-5, 4e-5                       # truth minus navigation, rad
    cbn_nav = euler_to_dcm_many(eul_t[:, 0] - dr, eul_t[:, 1] - dp, eul_t[:, 2] - dh, conv)
    nav = Trajectory(truth.time, truth.lat, truth.lon, truth.height, truth.vel_n, cbn_nav)
    s = compare_trajectories(truth, nav, conv=conv)
    p = eul_t[:, 1]
    expect = np.column_stack([dr * np.cos(p), np.full(n, dp), dh - dr * np.sin(p)])
    # First order in the perturbation: second-order terms ~ (5e-5)^2.
    np.testing.assert_allclose(s.att_rph_rad, expect, atol=5e-9)
    # Level attitude: exactly the Euler differences (to second order).
    flat = euler_to_dcm_many(np.zeros(n), np.zeros(n), np.linspace(0.3, 6.0, n), conv)
    e_f = dcm_to_euler_many(flat, conv)
    nav_f = euler_to_dcm_many(e_f[:, 0] - dr, e_f[:, 1] - dp, e_f[:, 2] - dh, conv)
    s = compare_trajectories(Trajectory(truth.time, truth.lat, truth.lon, truth.height, truth.vel_n, flat),
                             Trajectory(truth.time, truth.lat, truth.lon, truth.height, truth.vel_n, nav_f), conv=conv)
    np.testing.assert_allclose(s.att_rph_rad, np.tile([dr, dp, dh], (n, 1)), atol=5e-9)


@pytest.mark.parametrize("conv", [FLU, RFU, FRD])
def test_level_components_do_not_spin_with_a_rolling_vehicle_near_vertical(conv):
    """Pitch 89.99 deg, rolling through 360 deg: a constant ENU error gives constant, bounded components."""
    n = 37
    truth = make_truth(n=n, conv=conv)
    heading = 30 * D2R
    truth.Cbn = euler_to_dcm_many(np.linspace(-np.pi, np.pi, n), np.full(n, 89.99 * D2R), np.full(n, heading),
                                  conv)
    phi = np.array([1e-5, -2e-5, 3e-5])
    nav = displaced(truth, [0, 0, 0], [0, 0, 0], phi_n=phi)
    s = compare_trajectories(truth, nav, conv=conv)
    f_h = np.array([np.sin(heading), np.cos(heading), 0.0])
    r_h = np.array([np.cos(heading), -np.sin(heading), 0.0])
    np.testing.assert_allclose(s.att_rph_rad, np.tile([phi @ f_h, phi @ r_h, -phi[2]], (n, 1)), atol=1e-13)


def test_matching_with_float_noise_and_decimation():
    truth = make_truth(n=300, t0=1.7e9, dt=0.01)          # UNIX seconds: ulp ~ 2.4e-7 s
    nav = displaced(truth, [1.0, 0, 0], [0, 0, 0])
    keep = np.arange(0, 300, 7)
    nav = Trajectory(nav.time[keep] + 4.8e-7, nav.lat[keep], nav.lon[keep], nav.height[keep], nav.vel_n[keep],
                     nav.Cbn[keep])
    it, inav = match_epochs(truth.time, nav.time)
    np.testing.assert_array_equal(it, keep)
    np.testing.assert_array_equal(inav, np.arange(keep.size))


def test_no_common_epochs_messages():
    truth = make_truth(n=50, t0=1.7e9)
    nav0 = make_truth(n=50, t0=0.0)
    with pytest.raises(SinsError, match=r"nav\.csv: no common epochs.*different time bases"):
        match_epochs(truth.time, nav0.time, "truth.csv", "nav.csv")
    week = make_truth(n=50, t0=345600.0)                  # GPS seconds of week against seconds from start
    with pytest.raises(SinsError, match="different time bases.*GPS week.*from the start"):
        match_epochs(week.time, nav0.time, "truth.csv", "nav.csv")
    later = make_truth(n=50, t0=100.6)
    with pytest.raises(SinsError, match="do not overlap"):
        match_epochs(make_truth(n=50).time, later.time, "truth.csv", "nav.csv")
    interleaved = make_truth(n=50, t0=100.005)
    with pytest.raises(SinsError, match="--interpolate"):
        match_epochs(make_truth(n=50).time, interleaved.time, "truth.csv", "nav.csv")


def test_interpolated_truth_is_exact_for_linear_motion_and_constant_rate_rotation():
    t = np.arange(0.0, 10.0, 1.0)
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    rate = 0.3                                            # rad/s about a fixed axis
    c0 = euler_to_dcm_many(np.array([0.1]), np.array([0.2]), np.array([0.3]), FLU)[0]
    cbn = np.stack([c0 @ rotvec_to_dcm(axis * rate * tk) for tk in t])
    truth = Trajectory(t, 0.5 + 1e-6 * t, 1.0 - 2e-6 * t, 100 + 3 * t, np.column_stack([t, 2 * t, -t]), cbn)
    tq = np.array([0.25, 3.5, 8.75, 9.0, 12.0])
    it, inside = interpolate_truth(truth, tq)
    np.testing.assert_array_equal(inside, [0, 1, 2, 3])
    tin = tq[:4]
    np.testing.assert_allclose(it.lat, 0.5 + 1e-6 * tin, rtol=1e-15)
    np.testing.assert_allclose(it.height, 100 + 3 * tin, rtol=1e-15)
    np.testing.assert_allclose(it.vel_n[:, 1], 2 * tin, rtol=1e-15)
    exact = np.stack([c0 @ rotvec_to_dcm(axis * rate * tk) for tk in tin])
    np.testing.assert_allclose(it.Cbn, exact, atol=1e-15)


def test_table_epoch_selection():
    truth = make_truth(n=100)
    a = compare_trajectories(truth, displaced(truth, [0.1, 0, 0], [0, 0, 0]))
    short = Trajectory(truth.time[:60], truth.lat[:60], truth.lon[:60], truth.height[:60], truth.vel_n[:60],
                       truth.Cbn[:60])
    b = compare_trajectories(truth, short)
    assert common_epoch({"a": a, "b": b}) == truth.time[59]
    tbl = build_table({"a": a, "b": b}, epoch=float(truth.time[10]))
    assert tbl.epoch == truth.time[10]
    assert tbl.values.shape == (len(ROWS), 2)
    with pytest.raises(SinsError, match="--epoch.*method 'b'"):
        build_table({"a": a, "b": b}, epoch=float(truth.time[80]))
