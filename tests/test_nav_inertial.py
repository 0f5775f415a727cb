"""Launch-centred inertial navigation (``--frame launch-inertial``) against independent truth.

Truth sources: a spherical-harmonic evaluation of the WGS-84 normal field written here
(Legendre polynomials in spherical coordinates) and Somigliana's closed-form normal
gravity; closed-form increments at rest on the rotating earth; the simulator's exact
long-range flight (``configs/scenarios/long_range_flight.yaml``, ``gravity: j2``).
"""
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from numpy.polynomial import legendre

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.io.trajectory import read_trajectory
from sinscli.nav import earth
from sinscli.nav.inertial import COLUMNS, LaunchFrame, earth_state, inertial_state
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.nav.rotation import euler_to_dcm
from sinscli.evaluate.errors import compare_trajectories
from sinscli.sim import simulate, write_sim
from sinscli.sim.imu_synth import j2_gravity_n
from sinscli.types import ImuLog, NavState

ROOT = Path(__file__).resolve().parents[1]
FLIGHT = ROOT / "configs" / "scenarios" / "long_range_flight.yaml"

# WGS-84 normal field (NIMA TR8350.2 table 3.7, ellipsoidal C_n,0 unnormalized: J_n = -C_n,0)
J_NORMAL = {2: earth.J2, 4: -2.37091222e-6, 6: 6.08347e-9, 8: -1.42681e-11}
GAMMA_E, GAMMA_P = 9.7803253359, 9.8321849379      # Somigliana: normal gravity at equator, pole


def zonal_gravitation(x, y, z, jn):
    """Gradient of ``U = GM/r (1 - sum_n J_n (a/r)^n P_n(sin phi))`` in ECEF, by spherical components."""
    r = np.sqrt(x * x + y * y + z * z)
    p = np.hypot(x, y)
    s, c = z / r, p / r
    lam = np.arctan2(y, x)
    gr = np.ones_like(r)
    gphi = np.zeros_like(r)
    for n, j in jn.items():
        pn = legendre.Legendre.basis(n)
        gr = gr - (n + 1) * j * (earth.A / r) ** n * pn(s)
        gphi = gphi - j * (earth.A / r) ** n * c * pn.deriv()(s)
    k = -earth.GM / r ** 2
    gr, gphi = k * gr, -k * gphi      # g_r = dU/dr, g_phi = (1/r) dU/dphi
    e_r = np.stack([c * np.cos(lam), c * np.sin(lam), s])
    e_phi = np.stack([-s * np.cos(lam), -s * np.sin(lam), c])
    return gr * e_r + gphi * e_phi


def test_j2_gravitation_matches_a_spherical_harmonic_evaluation():
    rng = np.random.default_rng(1)
    n = 200
    lat = rng.uniform(-np.pi / 2, np.pi / 2, n)
    lon = rng.uniform(-np.pi, np.pi, n)
    h = rng.uniform(-1e4, 2e6, n)
    xyz = earth.lla_to_ecef(lat, lon, h)
    ref = zonal_gravitation(xyz[:, 0], xyz[:, 1], xyz[:, 2], {2: earth.J2})
    got = np.stack(earth.gravitation_py(xyz[:, 0], xyz[:, 1], xyz[:, 2]))
    assert np.abs(got - ref).max() < 1e-14 * 10.0
    one = earth.gravitation(*xyz[7])           # the numba kernel is the same formula
    assert np.abs(np.array(one) - got[:, 7]).max() < 1e-15 * 10.0
    # J2 matters: without it the field is off by up to 1.6e-2 m/s^2
    assert np.abs(zonal_gravitation(xyz[:, 0], xyz[:, 1], xyz[:, 2], {}) - ref).max() > 1e-2


def test_normal_field_series_reproduces_somigliana_at_equator_and_pole():
    """GM, a, b, J2 and the centrifugal term together with the WGS-84 J4..J8 give the normal gravity."""
    rest = {k: v for k, v in J_NORMAL.items() if k > 2}
    eq = np.array(earth.plumb_gravity_py(earth.A, 0.0, 0.0)) + zonal_gravitation(
        np.array(earth.A), np.array(0.0), np.array(0.0), rest) - zonal_gravitation(
        np.array(earth.A), np.array(0.0), np.array(0.0), {})
    pole = np.array(earth.plumb_gravity_py(0.0, 0.0, earth.B)) + zonal_gravitation(
        np.array(0.0), np.array(0.0), np.array(earth.B), rest) - zonal_gravitation(
        np.array(0.0), np.array(0.0), np.array(earth.B), {})
    assert abs(-eq[0] - GAMMA_E) < 1e-9 and abs(eq[1]) + abs(eq[2]) < 1e-15     # measured 2e-11
    assert abs(-pole[2] - GAMMA_P) < 1e-9
    # the J2 field alone differs from the normal one by the J4 term, about 4e-5 m/s^2 at the equator
    assert 3e-5 < abs(-earth.plumb_gravity_py(earth.A, 0.0, 0.0)[0] - GAMMA_E) < 6e-5


def test_simulator_j2_model_is_the_plumb_gravity_in_enu():
    rng = np.random.default_rng(2)
    lat = rng.uniform(-1.5, 1.5, 50)
    lon = rng.uniform(-3.0, 3.0, 50)
    h = rng.uniform(0.0, 6e5, 50)
    xyz = earth.lla_to_ecef(lat, lon, h)
    g_e = zonal_gravitation(xyz[:, 0], xyz[:, 1], xyz[:, 2], {2: earth.J2}).T
    g_e[:, :2] += earth.OMEGA_IE ** 2 * xyz[:, :2]          # centrifugal: outward from the axis
    ref = np.einsum("nij,nj->ni", earth.enu_rotation(lat, lon), g_e)
    got = j2_gravity_n(lat, h)
    assert np.abs(got - ref).max() < 1e-13
    assert np.abs(got[:, 0]).max() < 1e-15 and np.abs(got[:, 1]).max() > 1e-3   # north component


def test_launch_frame_axes_and_earth_round_trip():
    fr = LaunchFrame(time=100.0, lat=math.radians(40.0), lon=math.radians(100.0), height=1000.0,
                     azimuth=math.radians(30.0))
    c = fr.c_ei
    c_ne = earth.enu_rotation(fr.lat, fr.lon).T
    a = fr.azimuth
    assert np.allclose(c @ c_ne @ [math.sin(a), math.cos(a), 0.0], [1, 0, 0], atol=1e-15)   # x downrange
    assert np.allclose(c @ c_ne @ [0.0, 0.0, 1.0], [0, 1, 0], atol=1e-15)                     # y up
    assert np.allclose(c @ c_ne @ [math.cos(a), -math.sin(a), 0.0], [0, 0, 1], atol=1e-15)   # z right
    # the launch point at the launch time is the origin, with the earth's velocity W x R
    at_launch = NavState(100.0, fr.lat, fr.lon, 1000.0, np.zeros(3), np.eye(3))
    r_i, v_i, cbi = inertial_state(fr, at_launch)
    assert np.array_equal(r_i, np.zeros(3))
    r0 = fr.r0_e
    assert abs(np.linalg.norm(v_i) - earth.OMEGA_IE * math.hypot(r0[0], r0[1])) < 1e-12
    assert np.allclose(cbi, c @ c_ne, atol=1e-15)
    # a state 3 h after launch elsewhere goes to the inertial frame and back
    s = NavState(100.0 + 3 * 3600, 0.3, -2.0, 5e5, np.array([100.0, -2000.0, 30.0]),
                 euler_to_dcm(0.3, -1.2, 4.0, 0))
    r_i, v_i, cbi = inertial_state(fr, s)
    lat, lon, h, vel, cbn = earth_state(fr, np.array([s.time]), r_i[None], v_i[None], cbi[None])
    assert abs(lat[0] - s.lat) < 1e-15 and abs(lon[0] - s.lon) < 1e-15 and abs(h[0] - s.height) < 1e-8
    assert np.abs(vel[0] - s.vel_n).max() < 1e-11 and np.abs(cbn[0] - s.Cbn).max() < 1e-15


def static_log(minutes=10.0, rate=100.0, lat_deg=35.0, lon_deg=11.5, h=300.0, att=(0.1, -0.05, 1.0)):
    """Exact increments at rest in the J2 field: ``w_ib^b = C_n^b w_ie^n``, ``f^b = -C_n^b g^n``."""
    lat = math.radians(lat_deg)
    cbn = euler_to_dcm(*att, 0)
    w_n = np.array([0.0, earth.OMEGA_IE * math.cos(lat), earth.OMEGA_IE * math.sin(lat)])
    g_n = j2_gravity_n(np.array([lat]), np.array([h]))[0]
    n = int(round(minutes * 60 * rate))
    t = 50.0 + np.arange(1, n + 1) / rate
    imu = ImuLog(t, np.tile(cbn.T @ w_n / rate, (n, 1)), np.tile(-cbn.T @ g_n / rate, (n, 1)), t0=50.0)
    return imu, NavState(50.0, lat, math.radians(lon_deg), h, np.zeros(3), cbn)


@pytest.mark.parametrize("attitude,variant", [("quat", "exact"), ("dcm", "exact"), ("dcm", "seed000")])
def test_static_ten_minutes_stays_put(attitude, variant):
    """At rest on the rotating earth (launch elsewhere, 20 s earlier): the inertial navigation stays put."""
    imu, init = static_log()
    launch = {"lat": 30.0, "lon": 10.0, "height": 0.0, "azimuth": 75.0, "time": 30.0}
    nav = navigate(imu, init, NavOptions(attitude=attitude, dcm_variant=variant, coning=2,
                                         frame="launch-inertial", launch=launch))
    assert len(nav) == len(imu) + 1 and list(nav.extra) == list(COLUMNS)
    rm, rn = earth.radii(math.sin(init.lat))
    dn = (nav.lat - init.lat) * (rm + init.height)
    de = (nav.lon - init.lon) * (rn + init.height) * math.cos(init.lat)
    assert np.hypot(dn, de).max() < 1e-6          # measured 2e-8 m
    assert np.abs(nav.height - init.height).max() < 1e-6
    assert np.abs(nav.vel_n).max() < 3e-9         # measured 1e-10 m/s
    att = np.array([np.linalg.norm(c @ init.Cbn.T - np.eye(3)) for c in nav.Cbn[::600]])
    assert att.max() < 1e-13
    # the inertial columns: the fixed point turns with the earth, r^i(t) = C_e(t)^i R^e - R_0^i
    fr = LaunchFrame(30.0, math.radians(30.0), math.radians(10.0), 0.0, math.radians(75.0))
    k = len(nav) - 1
    at_end = NavState(float(nav.time[k]), init.lat, init.lon, init.height, np.zeros(3), init.Cbn)
    r_i, v_i, _ = inertial_state(fr, at_end)
    got_r = np.array([nav.extra[c][k] for c in COLUMNS[:3]])
    got_v = np.array([nav.extra[c][k] for c in COLUMNS[3:]])
    assert np.abs(got_r - r_i).max() < 1e-6 and np.abs(got_v - v_i).max() < 3e-9
    assert np.linalg.norm(r_i) > 1e5               # it did move by hundreds of km in inertial space


def _flight(rate=100.0, gravity="j2"):
    sc = yaml.safe_load(FLIGHT.read_text())
    assert sc["gravity"] == "j2"
    sc["imu"]["rate"] = rate
    sc["gravity"] = gravity
    return simulate(sc, perfect=True)


@pytest.fixture(scope="module")
def flights():
    return {"j2-100": _flight(100.0), "j2-50": _flight(50.0), "normal-100": _flight(100.0, "normal")}


def _errs(res, **opts):
    nav = navigate(res.imu, res.init, NavOptions(launch=res.launch, **opts))
    s = compare_trajectories(res.truth, nav)
    return dict(att=math.degrees(s.angle_rad.max()), pos=np.abs(s.pos_enu_m).max(axis=0),
                vel=np.abs(s.vel_enu_mps).max(axis=0), nav=nav)


def test_long_range_flight_errors_are_the_algorithms(flights):
    """Seed 000's flight (boost with 180 deg/s spin, pitch-over, 1130 s, ~2000 km) at 10 ms."""
    res = flights["j2-100"]
    li = dict(frame="launch-inertial")
    c2 = _errs(res, attitude="quat", coning=2, **li)
    assert c2["att"] < 1e-4 and c2["pos"].max() < 10.0 and c2["vel"].max() < 1e-2
    # the same algorithm error as the ENU frame shows on the same flight in its own gravity model
    enu = _errs(flights["normal-100"], attitude="quat", coning=2)
    assert abs(c2["att"] / enu["att"] - 1.0) < 0.03
    assert np.abs(c2["pos"] - enu["pos"]).max() < 0.1 * enu["pos"].max()
    # quaternion and seed 000's DCM recursion agree far below the algorithm error
    d2 = _errs(res, attitude="dcm", dcm_variant="seed000", coning=2, **li)
    ang = [np.linalg.norm(a @ b.T - np.eye(3)) for a, b in zip(c2["nav"].Cbn[::500], d2["nav"].Cbn[::500])]
    assert max(ang) < 1e-9 and np.abs(c2["pos"] - d2["pos"]).max() < 1e-3
    # model mismatch is shown, not hidden: j2 flight in ENU, normal-gravity flight in launch-inertial
    assert _errs(res, attitude="quat", coning=2)["pos"].max() > 1e3
    assert _errs(flights["normal-100"], attitude="quat", coning=2, **li)["pos"].max() > 1e3


def test_long_range_flight_errors_fall_with_the_rate_as_the_order_predicts(flights):
    """Fixed-axis (1-sample) update: second order; 2-sample coning: third order (general motion)."""
    li = dict(frame="launch-inertial", attitude="quat")
    one = [_errs(flights[k], coning=1, **li) for k in ("j2-50", "j2-100")]
    two = [_errs(flights[k], coning=2, **li) for k in ("j2-50", "j2-100")]
    assert 3.6 < one[0]["att"] / one[1]["att"] < 4.4
    assert 3.6 < one[0]["vel"].max() / one[1]["vel"].max() < 4.4
    assert 7.0 < two[0]["att"] / two[1]["att"] < 9.0
    assert 7.0 < two[0]["vel"].max() / two[1]["vel"].max() < 9.0
    assert two[1]["att"] < one[1]["att"] / 30


def test_chunked_and_two_speed_runs(flights):
    """Block-wise navigation is bit-identical; N = 2 sub-samples per update writes every other epoch."""
    from sinscli.nav.pipeline import concat, navigate_blocks
    res = flights["j2-100"]
    imu = res.imu
    n = 30000
    opts = NavOptions(frame="launch-inertial", launch=res.launch)
    whole = navigate(ImuLog(imu.time[:n], imu.dtheta_b[:n], imu.dvel_b[:n], t0=imu.t0), res.init, opts)
    blocks = [ImuLog(imu.time[a:min(a + 7777, n)], imu.dtheta_b[a:min(a + 7777, n)],
                     imu.dvel_b[a:min(a + 7777, n)], t0=imu.t0) for a in range(0, n, 7777)]
    parts = concat(list(navigate_blocks(blocks, res.init, opts)))
    assert np.array_equal(whole.Cbn, parts.Cbn) and np.array_equal(whole.extra["x_i"], parts.extra["x_i"])
    two = navigate(ImuLog(imu.time[:n], imu.dtheta_b[:n], imu.dvel_b[:n], t0=imu.t0), res.init,
                   NavOptions(frame="launch-inertial", launch=res.launch, subsamples=2))
    assert len(two) == n // 2 + 1 and np.array_equal(two.time[1:], whole.time[2::2])
    s = compare_trajectories(res.truth, two)
    assert math.degrees(s.angle_rad.max()) < 1e-3 and np.abs(s.pos_enu_m).max() < 1.0


# ------------------------------------------------------------------------------------------ CLI

def run(args):
    return CliRunner().invoke(main, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def simdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("lrf")
    write_sim(simulate(FLIGHT, perfect=True, duration=30.0), d)
    return d


def test_cli_navigates_in_the_launch_frame_and_compare_reads_it(simdir, tmp_path):
    out = tmp_path / "nav.csv"
    r = run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "--frame",
             "launch-inertial", "-o", str(out), "-q"])
    assert r.exit_code == 0, r.output
    header = out.read_text().splitlines()[0].split(",")
    assert header[:14] == ["time", "lat", "lon", "height", "vel_e", "vel_n", "vel_u", "roll", "pitch",
                           "heading", "qw", "qx", "qy", "qz"] and "c33" in header
    assert header[-6:] == list(COLUMNS)
    nav = read_trajectory(out)
    truth = read_trajectory(simdir / "truth.csv")
    s = compare_trajectories(truth, nav)
    assert len(nav) == len(truth) and math.degrees(s.angle_rad.max()) < 1e-4
    assert np.abs(s.pos_enu_m).max() < 0.05
    # on the pad for 10 s: the origin at launch, then the earth's rotation only
    assert nav.extra["x_i"][0] == 0.0 and nav.extra["y_i"][0] == 0.0 and nav.extra["z_i"][0] == 0.0
    assert abs(math.hypot(nav.extra["vx_i"][0], nav.extra["vz_i"][0]) - 355.9) < 1.0
    # sins compare takes it as any trajectory
    r = run(["compare", "--truth", str(simdir / "truth.csv"), str(out), "-o", str(tmp_path / "cmp"), "-q"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "cmp" / "errors.csv").exists()
    # another launch frame (config) gives the same earth-referenced trajectory, other inertial columns
    cfg = tmp_path / "nav.yaml"
    cfg.write_text(yaml.safe_dump({"navigation": {"frame": "launch-inertial", "launch": {
        "lat": 10.0, "lon": 90.0, "height": 0.0, "azimuth": 200.0}}}))
    out2 = tmp_path / "nav2.parquet"
    r = run(["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "--config", str(cfg),
             "-o", str(out2), "-q", "--every", "10"])
    assert r.exit_code == 0, r.output
    nav2 = read_trajectory(out2)
    assert len(nav2) == 301 and np.array_equal(nav2.time, nav.time[::10])
    s2 = compare_trajectories(nav, nav2)
    assert np.abs(s2.pos_enu_m).max() < 1e-6 and np.abs(s2.vel_enu_mps).max() < 1e-9
    assert math.degrees(s2.angle_rad.max()) < 1e-10
    assert abs(nav2.extra["x_i"][0]) > 1e6


@pytest.mark.parametrize("case, message", [
    ("no_launch", r"frame launch-inertial needs the launch point"),
    ("missing_key", r"navigation\.launch\.azimuth: missing"),
    ("krylov", r"--frame launch-inertial: the attitude is dcm or quat, not krylov"),
    ("bad_init_launch", r"init\.yaml: launch\.height: expected a finite number, got 'high'"),
])
def test_cli_bad_launch_input(simdir, tmp_path, case, message):
    import re
    out = tmp_path / "nav.csv"
    args = ["navigate", str(simdir / "imu.csv"), "--init", str(simdir / "init.yaml"), "--frame",
            "launch-inertial", "-o", str(out), "-q"]
    if case == "no_launch":       # a trajectory CSV as init carries no launch point
        args[3] = str(simdir / "truth.csv")
    elif case == "missing_key":
        cfg = tmp_path / "nav.yaml"
        cfg.write_text(yaml.safe_dump({"navigation": {"launch": {"lat": 1.0, "lon": 2.0, "height": 0.0}}}))
        args += ["--config", str(cfg)]
    elif case == "krylov":
        args += ["--attitude", "krylov"]
    else:
        init = yaml.safe_load((simdir / "init.yaml").read_text())
        init["launch"]["height"] = "high"
        p = tmp_path / "init.yaml"
        p.write_text(yaml.safe_dump(init))
        args[3] = str(p)
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    assert re.search(message, r.output), r.output
    assert not out.exists() and not list(tmp_path.glob(".nav.csv*"))


def test_launch_frame_refuses_a_bad_latitude():
    from sinscli.nav.inertial import launch_frame
    with pytest.raises(SinsError, match=r"navigation\.launch\.lat: 91\.0 deg is outside"):
        launch_frame({"lat": 91.0, "lon": 0.0, "height": 0.0, "azimuth": 0.0}, 0.0)
