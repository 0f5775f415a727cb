"""The exact-truth engine: kinematic identities, closed-form motions, quadrature and position precision."""
import numpy as np
import pytest

from sinscli.nav.earth import A, E2, OMEGA_IE, earth_rate_n, gravity, gravity_py, lla_to_ecef, radii_py
from sinscli.nav.rotation import FLU, euler_to_dcm
from sinscli.sim import motions, simulate
from sinscli.sim.imu_synth import body_rate_nb, normal_gravity_n, sensor_outputs
from sinscli.sim.jets import Jet, axis_rotation, stack
from sinscli.sim.quadrature import gauss_legendre
from sinscli.sim.run import prepare
from sinscli.sim.segments import C_FLU_TO_RFU
from sinscli.sim.truth import evaluate

DEG = np.pi / 180.0


def test_at_rest_rates_and_specific_force_are_earth_rate_and_gravity():
    r = motions.static(duration=2.0, rate=100.0, lat=45.0, lon=10.0, h=300.0, heading=37.0)
    lat, h = np.radians(45.0), 300.0
    cbn = euler_to_dcm(0.0, 0.0, 37.0 * DEG, FLU)
    w_ib = cbn.T @ earth_rate_n(lat)
    f_b = -cbn.T @ np.array([0.0, 0.0, -gravity(np.sin(lat), h)])
    # increments are integrals over the intervals between the written (float) time stamps
    dt = np.diff(r.truth.time)[:, None]
    assert np.abs(dt - 0.01).max() > 0.0          # the float intervals are not all exactly 0.01
    assert np.abs(r.imu.dtheta_b - w_ib * dt).max() <= 1e-15 * np.abs(w_ib * 0.01).max()
    assert np.abs(r.imu.dvel_b - f_b * dt).max() <= 1e-15 * np.abs(f_b * 0.01).max()
    assert np.abs(r.truth.Cbn - cbn).max() < 1e-15
    assert np.all(r.truth.lat == lat) and np.all(r.truth.height == h) and np.all(r.truth.vel_n == 0.0)


def test_increments_cover_the_written_time_stamps_at_a_large_epoch():
    """With a GPS-like epoch the file's time stamps are rounded; the increments integrate exactly
    over the intervals between those written stamps (what a navigator's dt is)."""
    sc = {"start": {"time": 345678.9, "lat": 10.0, "lon": 20.0}, "imu": {"rate": 100},
          "segments": [{"type": "rest", "duration": 5.0}]}
    r = simulate(sc, perfect=True)
    assert r.imu.t0 == 345678.9 and r.truth.time[0] == 345678.9
    assert np.array_equal(r.imu.time, 345678.9 + np.arange(1, 501) / 100.0)
    dt = np.diff(r.truth.time)
    assert np.abs(dt - 0.01).max() > 1e-12                 # the stamps' rounding is visible
    w = r.truth.Cbn[0].T @ earth_rate_n(np.radians(10.0))
    assert np.abs(r.imu.dtheta_b - w * dt[:, None]).max() <= 1e-15 * np.abs(w).max() * 0.01


def _ecef_jets(lat, lon, h):
    """ECEF position jets from geodetic jets (lla_to_ecef written out for jets)."""
    _, rn = radii_py(np.sin(lat))
    return stack([(rn + h) * np.cos(lat) * np.cos(lon), (rn + h) * np.cos(lat) * np.sin(lon),
                  (rn * (1.0 - E2) + h) * np.sin(lat)], axis=-1)


def _c_en_jets(lat, lon):
    """``C_e^n`` rows E, N, U as jets (enu_rotation written out for jets)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    zero = 0.0 * sl
    e = stack([-so, co, zero], axis=-1)
    n = stack([-sl * co, -sl * so, cl], axis=-1)
    u = stack([cl * co, cl * so, sl], axis=-1)
    return stack([e, n, u], axis=-2)


def test_sensor_kernel_matches_an_independent_ecef_formulation():
    """f^b and w_ib^b from the ENU kernel equal the ECEF forms
    ``f^b = C_e^b (r'' + 2 W x r' - g^e)`` and ``w_ib^b = w_eb^b + C_e^b W`` on an analytic
    geodetic trajectory (fast: 300 m/s, climbing, turning)."""
    t = Jet.time(np.linspace(0.0, 50.0, 11), 2)
    lat = 0.6 + 4e-5 * t + 3e-7 * t * t
    lon = 1.9 + 2e-5 * t - 1e-7 * t * t
    h = 1000.0 + 50.0 * t + 0.4 * t * t
    r_e = _ecef_jets(lat, lon, h)
    c_en = _c_en_jets(lat, lon)
    v_e = r_e.deriv()                                    # order 1: velocity and acceleration
    vel_n = (c_en.truncate(1) @ v_e[..., None])[..., 0]  # ENU components of the ECEF velocity
    hdg, pit, rol = 0.3 + 0.05 * t, 0.2 * np.sin(0.1 * t), 0.5 * np.cos(0.2 * t)
    cbn = (axis_rotation(2, -hdg.truncate(1)) @ axis_rotation(0, pit.truncate(1))
           @ axis_rotation(1, rol.truncate(1)) @ C_FLU_TO_RFU)
    lat_v, h_v = lat.v, h.v
    g_n = normal_gravity_n(lat_v, h_v)
    w_ib, f_b = sensor_outputs(lat_v, h_v, vel_n.v, vel_n.d1, cbn.v, body_rate_nb(cbn.v, cbn.d1), g_n)
    W = np.array([0.0, 0.0, OMEGA_IE])
    cbe = np.swapaxes(c_en.v, -1, -2) @ cbn.v                          # C_b^e
    dcbe = np.swapaxes(c_en.d1, -1, -2) @ cbn.v + np.swapaxes(c_en.v, -1, -2) @ cbn.d1
    g_e = np.einsum("nij,ni->nj", c_en.v, g_n)
    a_e = v_e.d1 + 2.0 * np.cross(W, v_e.v) - g_e
    f_ref = np.einsum("nji,nj->ni", cbe, a_e)
    w_ref = body_rate_nb(cbe, dcbe) + np.einsum("nji,j->ni", cbe, W)
    assert np.abs(f_b - f_ref).max() < 1e-12 * np.abs(f_ref).max()
    assert np.abs(w_ib - w_ref).max() < 1e-12 * np.abs(w_ref).max()


def _coning_closed_form(t, beta, omega):
    """R(t) and w_nb^b(t) of pure coning (motions.coning docstring)."""
    c, s = np.cos(omega * t), np.sin(omega * t)
    q0, q2, q3 = np.cos(beta / 2), np.sin(beta / 2) * c, np.sin(beta / 2) * s
    R = np.zeros(t.shape + (3, 3))
    R[..., 0, 0] = q0 * q0 - q2 * q2 - q3 * q3
    R[..., 0, 1] = -2 * q0 * q3
    R[..., 0, 2] = 2 * q0 * q2
    R[..., 1, 0] = 2 * q0 * q3
    R[..., 1, 1] = q0 * q0 + q2 * q2 - q3 * q3
    R[..., 1, 2] = 2 * q2 * q3
    R[..., 2, 0] = -2 * q0 * q2
    R[..., 2, 1] = 2 * q2 * q3
    R[..., 2, 2] = q0 * q0 - q2 * q2 + q3 * q3
    w = np.stack([np.full_like(t, -2 * omega * np.sin(beta / 2) ** 2),
                  -omega * np.sin(beta) * s, omega * np.sin(beta) * c], axis=-1)
    return R, w


def test_pure_coning_truth_and_increments_match_closed_form():
    beta, f, rate, lat = 2.0 * DEG, 3.0, 100.0, 30.0 * DEG
    r = motions.coning(duration=4.0, rate=rate, half_angle_deg=2.0, freq_hz=f, lat=30.0)
    omega = 2 * np.pi * f
    t = r.truth.time
    R, _ = _coning_closed_form(t, beta, omega)
    c0 = euler_to_dcm(0.0, 0.0, 0.0, FLU)
    assert np.abs(r.truth.Cbn - c0 @ R).max() < 2e-15
    # the rate vector has constant magnitude 2 W sin(beta/2)
    _, w = _coning_closed_form(t, beta, omega)
    assert np.allclose(np.linalg.norm(w, axis=1), 2 * omega * np.sin(beta / 2), rtol=1e-15)
    # increments: closed-form integral of w_nb^b plus the earth-rate part C_n^b w_ie^n
    ta, tb = t[:-1], t[1:]
    wn = np.stack([-2 * omega * np.sin(beta / 2) ** 2 * (tb - ta),
                   np.sin(beta) * (np.cos(omega * tb) - np.cos(omega * ta)),
                   np.sin(beta) * (np.sin(omega * tb) - np.sin(omega * ta))], axis=-1)
    x, wq, _ = gauss_legendre(20)
    tn = 0.5 * (ta + tb)[:, None] + 0.5 * (tb - ta)[:, None] * x[None, :]
    Rn, _ = _coning_closed_form(tn, beta, omega)
    v = c0.T @ earth_rate_n(lat)
    earth = 0.5 * (tb - ta)[:, None] * np.einsum("nkji,j,k->ni", Rn, v, wq)
    ref = wn + earth
    # The closed form sin(beta) (cos W tb - cos W ta) evaluates the phase W t in float64: its
    # rounding (one ulp of W t_end per cosine) bounds the agreement, plus rounding of the sums.
    tol = 2.0 * np.sin(beta) * np.spacing(omega * t[-1]) + 1e-15 * np.abs(ref).max()
    assert np.abs(r.imu.dtheta_b - ref).max() < tol
    # at rest the specific force is -C_n^b g^n exactly
    g = np.array([0.0, 0.0, -gravity_py(np.sin(lat), 50.0)])
    fref = -0.5 * (tb - ta)[:, None] * np.einsum("nkji,j,k->ni", Rn, c0.T @ g, wq)
    assert np.abs(r.imu.dvel_b - fref).max() < 2e-15 * np.abs(fref).max()


MIXED = {"start": {"lat": 30.0, "lon": 114.0, "height": 500.0, "heading": 20.0, "speed": 60.0},
         "imu": {"rate": 100}, "gnss": {"rate": 10},
         "segments": [{"type": "roll", "angle": 720, "duration": 8},
                      {"type": "maneuver", "heading": 200, "pitch": 360, "roll": -360, "duration": 9},
                      {"type": "turn", "angle": 120, "duration": 6},
                      {"type": "coning", "half_angle": 1.5, "freq": 4.0, "ramp": 1.0, "duration": 4},
                      {"type": "sculling", "angle": 0.5, "accel": 3.0, "freq": 8.0, "ramp": 0.5,
                       "duration": 3},
                      {"type": "boost", "accel": 10, "spin": 90, "pitch": 30, "ramp": 1, "duration": 5}]}


def test_increments_converge_with_the_number_of_gauss_nodes():
    a = simulate(MIXED, perfect=True, nodes=8)
    b = simulate(MIXED, perfect=True, nodes=16)
    for k in ("dtheta_b", "dvel_b"):
        x, y = getattr(a.imu, k), getattr(b.imu, k)
        assert np.abs(x - y).max() < 1e-15 * np.abs(x).max(), k
    assert np.abs(a.truth.lat - b.truth.lat).max() < 3e-16
    assert np.abs(a.truth.height - b.truth.height).max() < 1e-11


def test_rate_doubling_gives_the_same_truth_and_summed_increments():
    a = simulate(MIXED, perfect=True)
    b = simulate(dict(MIXED, imu={"rate": 200}), perfect=True)
    assert np.array_equal(a.truth.time, b.truth.time[::2])
    assert np.abs(a.truth.Cbn - b.truth.Cbn[::2]).max() < 1e-15
    assert np.abs(a.truth.lat - b.truth.lat[::2]).max() < 3e-16
    assert np.abs(a.truth.height - b.truth.height[::2]).max() < 1e-11
    for k in ("dtheta_b", "dvel_b"):
        x, y = getattr(a.imu, k), getattr(b.imu, k).reshape(-1, 2, 3).sum(axis=1)
        assert np.abs(x - y).max() < 4e-15 * np.abs(x).max(), k


def test_motion_is_smooth_across_segment_joints():
    p = prepare(MIXED, perfect=True)
    starts = np.array([q.t_start for q in p.prims])
    for k in range(1, len(p.prims)):
        tj = np.array([starts[k]])
        left = evaluate(p.prims, starts, tj, side="left")
        right = evaluate(p.prims, starts, tj, side="right")
        for a, b in zip(left, right):
            assert np.abs(a - b).max() < 1e-12 * max(1.0, np.abs(a).max()), (k, p.prims[k].kind)
        # the angular rate is continuous too (C^1 attitude)
        assert np.abs(body_rate_nb(left[0], left[1]) - body_rate_nb(right[0], right[1])).max() < 1e-12
    # channel values continuous up to the third derivative (C^3: rates C^2), ramps and steps included
    P = np.polynomial.polynomial
    for q0, q1 in zip(p.prims[:-1], p.prims[1:]):
        c0, c1 = q0.channel_coeffs(), q1.channel_coeffs()
        for order in range(1, 4):
            d0 = P.polyval(1.0, P.polyder(c0, order, axis=1).T) * (2.0 / q0.duration) ** order
            d1 = P.polyval(-1.0, P.polyder(c1, order, axis=1).T) * (2.0 / q1.duration) ** order
            assert np.abs(d0 - d1).max() < 1e-9 * max(1.0, np.abs(d0).max()), order


def test_due_east_on_the_equator_has_analytic_longitude():
    sc = {"start": {"lat": 0.0, "lon": 10.0, "height": 100.0, "heading": 90.0, "speed": 5.0},
          "imu": {"rate": 50}, "gnss": {"rate": 1},
          "segments": [{"type": "accelerate", "speed": 250.0, "duration": 20.0},
                       {"type": "cruise", "duration": 100.0},
                       {"type": "decelerate", "speed": 40.0, "duration": 30.0}]}
    r = simulate(sc, perfect=True)
    t = r.truth.time
    # distance: 5 t + 245 T S1(u) in the first segment etc. (S1(1) = 1/2)
    S1 = lambda u: 7 * u ** 5 - 14 * u ** 6 + 10 * u ** 7 - 2.5 * u ** 8        # noqa: E731
    s = np.where(t <= 20, 5 * t + 245 * 20 * S1(np.clip(t / 20, 0, 1)),
                 np.where(t <= 120, 5 * 20 + 245 * 10 + 250 * (t - 20),
                          100 + 2450 + 25000 + 250 * (t - 120) - 210 * 30 * S1(np.clip((t - 120) / 30, 0, 1))))
    lon_ref = np.radians(10.0) + s / (A + 100.0)
    assert np.abs(r.truth.lat).max() < 1e-18
    assert np.abs(r.truth.height - 100.0).max() < 1e-9
    assert np.abs((r.truth.lon - lon_ref) * (A + 100.0)).max() < 2e-9       # metres


def _meridian_arc(lat0, lat1, n=40):
    """``int RM dL`` from lat0 to lat1 by Gauss-Legendre (the integrand is smooth: exact to rounding)."""
    x, w, _ = gauss_legendre(n)
    lat = 0.5 * (lat0 + lat1)[..., None] + 0.5 * (lat1 - lat0)[..., None] * x
    rm, _ = radii_py(np.sin(lat))
    return 0.5 * (lat1 - lat0) * (rm @ w)


def test_due_north_latitude_satisfies_the_meridian_arc_length():
    """For a run due north at constant height h, ``int_{L0}^{L} (RM + h) dL`` = distance travelled
    (an elliptic integral, evaluated independently); checks the latitude integration over 3 degrees."""
    h = 2000.0
    sc = {"start": {"lat": 20.0, "lon": 10.0, "height": h, "heading": 0.0, "speed": 300.0},
          "imu": {"rate": 20}, "gnss": {"rate": 1},
          "segments": [{"type": "accelerate", "speed": 900.0, "duration": 60.0},
                       {"type": "cruise", "duration": 300.0}]}
    r = simulate(sc, perfect=True)
    t = r.truth.time
    S1 = lambda u: 7 * u ** 5 - 14 * u ** 6 + 10 * u ** 7 - 2.5 * u ** 8        # noqa: E731
    s = np.where(t <= 60, 300 * t + 600 * 60 * S1(np.clip(t / 60, 0, 1)),
                 300 * 60 + 600 * 30 + 900 * (t - 60))
    lat0 = np.radians(20.0)
    arc = _meridian_arc(np.full(t.shape, lat0), r.truth.lat) + h * (r.truth.lat - lat0)
    assert np.degrees(r.truth.lat[-1] - lat0) > 2.5
    assert np.abs(arc - s).max() < 1e-8                                        # metres over 290 km
    assert np.abs(r.truth.lon - np.radians(10.0)).max() < 1e-15


def test_geodetic_truth_is_consistent_with_ecef_velocity():
    """Central differences of the ECEF positions of the truth equal ``C_n^e v^n`` (formula check
    of the latitude/longitude/height integration on a turning, climbing, accelerating run)."""
    r = simulate(MIXED | {"segments": MIXED["segments"][:3] + MIXED["segments"][5:]}, perfect=True)
    tr = r.truth
    xyz = lla_to_ecef(tr.lat, tr.lon, tr.height)
    dt = 0.01
    v_fd = (-xyz[4:] + 8 * xyz[3:-1] - 8 * xyz[1:-3] + xyz[:-4]) / (12 * dt)
    from sinscli.nav.earth import enu_rotation
    c_en = enu_rotation(tr.lat, tr.lon)
    v_e = np.einsum("nij,ni->nj", c_en, tr.vel_n)[2:-2]
    # m/s: the 4th-order difference has truncation h^4 x^(5) / 30 ~ 1e-8 x^(5) and rounding
    # 1.5 ulp(6.4e6 m) / 0.01 s ~ 1.4e-7; a wrong radius or sign would show as > 1e-3.
    assert np.abs(v_fd - v_e).max() < 1e-6


@pytest.mark.parametrize("conv", ["rfu", "frd"])
def test_body_convention_option_rotates_increments_and_attitude(conv):
    a = simulate(MIXED | {"duration": 3.0}, perfect=True)
    b = simulate(MIXED | {"duration": 3.0, "body": conv}, perfect=True)
    from sinscli.nav.rotation import BODY_CONVENTIONS, conv_to_flu
    m = conv_to_flu(BODY_CONVENTIONS[conv])             # C_conv^FLU
    assert np.abs(b.imu.dtheta_b @ m.T - a.imu.dtheta_b).max() < 1e-18
    assert np.abs(b.truth.Cbn - a.truth.Cbn @ m).max() < 1e-16
