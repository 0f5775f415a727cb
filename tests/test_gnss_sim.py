"""Single-point positioning on simulated raw observations with exact truth (sins simulate's raw GNSS):
accuracy against the theoretical DOP x sigma, velocity likewise, honest 1-sigma, FDE, canyons, round trip
through RINEX 3.04."""
from __future__ import annotations

import numpy as np
import pytest

from sinscli.gnss import spp as S
from sinscli.gnss.pipeline import run_spp
from sinscli.io.rinex import read_nav, read_obs, write_nav, write_obs
from sinscli.nav.earth import ecef_to_lla, enu_rotation
from sinscli.sim.raw_gnss import static_receiver

SIGMA = 0.5          # m, code a = b
DOP_SIGMA = 0.05     # m/s at the zenith


def _exact_opts(**kw):
    """The solver's weights equal to the simulated noise: no URA, iono or tropo residual terms."""
    base = dict(elev_mask_deg=5.0, code_a=SIGMA, code_b=SIGMA, doppler_sigma=DOP_SIGMA, use_ura=False, iono_var=0.0,
                tropo_sigma=0.0, iono="klobuchar", fde=False, variance_factor=False)
    base.update(kw)
    return S.spp_options(**base)


@pytest.fixture(scope="module")
def static_run():
    sim = static_receiver(37.4, -122.2, 30.0, 3600, {"systems": "G", "code_sigma": SIGMA,
                                                    "doppler_sigma": DOP_SIGMA}, seed=11)
    return sim, run_spp(sim.obs, sim.nav, systems=[0], options=_exact_opts())


def _theory_h(sim, res, what="pos"):
    """sqrt(mean over epochs of the horizontal variance) of weighted least squares computed here with numpy
    from the true geometry (true receiver and satellite positions) and the simulated noise model: the
    theoretical HDOP x sigma."""
    lat, lon, _ = ecef_to_lla(sim.pos[0])
    out = []
    opts = _exact_opts()
    for e in range(0, len(sim.obs), 7):
        r = np.arange(sim.obs.start[e], sim.obs.start[e + 1])
        el, az = res.el[r], res.az[r]
        cn0 = sim.obs.values[r, 3]
        g = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el), np.ones(r.size)])
        var = np.array([(S.code_variance if what == "pos" else S.doppler_variance)(opts, a, c)
                        for a, c in zip(el, cn0)])
        q = np.linalg.inv(g.T @ (g / var[:, None]))
        out.append(q[0, 0] + q[1, 1])
    return float(np.sqrt(np.mean(out)))


def test_spp_horizontal_rms_within_10pc_of_theory(static_run):
    """An hour at 1 Hz, GPS geometry of the shipped broadcast file: horizontal RMS against the truth within 10 %
    of the theoretical HDOP x sigma (measured 0.1 %), and the same for the Doppler velocity."""
    sim, res = static_run
    assert (res.status != S.TOO_FEW).all()
    lat, lon, _ = ecef_to_lla(sim.pos[0])
    rot = enu_rotation(lat, lon)
    d = (res.pos - sim.pos) @ rot.T
    rms_h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
    theory = _theory_h(sim, res)
    assert rms_h == pytest.approx(theory, rel=0.10), (rms_h, theory)
    dv = (res.vel - sim.vel) @ rot.T
    rms_v = np.sqrt(np.mean(dv[:, 0] ** 2 + dv[:, 1] ** 2))
    theory_v = _theory_h(sim, res, "vel")
    assert rms_v == pytest.approx(theory_v, rel=0.10), (rms_v, theory_v)
    # the receiver clock and drift against the simulated ones; the solution time against the true time
    c = 299792458.0
    assert np.sqrt(np.mean((res.clk[:, 0] - sim.clock_bias * c) ** 2)) < 3.0 * SIGMA * 3
    assert np.sqrt(np.mean((res.drift - sim.clock_drift * c) ** 2)) < 0.2
    assert np.abs(res.solution_time() - sim.t_true).max() < 1e-7 * 20


def test_spp_noise_free_is_exact():
    """Without noise the solver's models equal the simulator's exact geometry: < 2 cm, < 3 mm/s."""
    sim = static_receiver(-33.9, 151.2, 100.0, 120, {"systems": "G", "code_sigma": 1e-6, "doppler_sigma": 1e-7,
                                                     "clock_drift": 1e-7}, seed=1)
    res = run_spp(sim.obs, sim.nav, systems=[0], options=_exact_opts(code_a=1e-6, code_b=1e-6,
                                                                     doppler_sigma=1e-7))
    assert np.abs(res.pos - sim.pos).max() < 0.02
    assert np.abs(res.vel - sim.vel).max() < 0.003


@pytest.mark.parametrize("noise_factor", [1.0, 3.0])
def test_spp_sigma_is_honest(noise_factor):
    """3-sigma fraction of the position and velocity errors per axis: with the noise the solver assumes, and
    with noise three times larger than it assumes (the a-posteriori variance factor scales the covariance)."""
    sim = static_receiver(51.5, -0.1, 50.0, 1200, {"systems": "G", "code_sigma": SIGMA * noise_factor,
                                                  "doppler_sigma": DOP_SIGMA * noise_factor}, seed=5)
    res = run_spp(sim.obs, sim.nav, systems=[0], options=_exact_opts(variance_factor=True, fde=True))
    ok = res.fix
    assert ok.mean() > 0.98
    for est, cov, truth in ((res.pos, res.cov, sim.pos), (res.vel, res.cov_vel, sim.vel)):
        err = est[ok] - truth[ok]
        sig = np.sqrt(np.einsum("eii->ei", cov[ok]))
        frac = np.mean(np.abs(err) < 3.0 * sig)
        nees = np.mean(np.einsum("ei,eij,ej->e", err, np.linalg.inv(cov[ok]), err))
        assert frac > 0.97, frac
        if noise_factor == 1.0:
            assert 2.5 < nees < 3.6, nees          # chi-square(3) mean; the factor only ever inflates
        assert np.all(sig > 0)


def test_fde_excludes_a_faulty_satellite():
    """A 60 m ramp on one satellite for 100 epochs: the chi-square test excludes exactly it, and the fixes stay
    at the noise level."""
    sim = static_receiver(37.4, -122.2, 30.0, 300, {"systems": "G", "code_sigma": SIGMA}, seed=3)
    obs = sim.obs
    victim = int(obs.prn[obs.start[0]])
    ep = obs.epoch_of_record()
    hit = (obs.prn == victim) & (ep >= 100) & (ep < 200)
    obs.values[hit, 0] += 60.0
    res = run_spp(obs, sim.nav, systems=[0], options=_exact_opts(fde=True, variance_factor=True))
    excluded = res.rec_status == S.EXCLUDED
    assert excluded[hit].mean() > 0.98
    assert excluded[~hit].mean() < 0.005
    text = res.excluded_text()
    assert text[150] == f"G{victim:02d}"
    d = np.linalg.norm(res.pos - sim.pos, axis=1)
    assert np.sqrt(np.mean(d[100:200] ** 2)) < 6 * SIGMA * 3


def test_urban_canyon_leaves_too_few_satellites():
    """A 30 s canyon keeping 3 satellites and an azimuth mask: the epochs are written with 3 satellites and the
    solver reports them unsolved (TOO_FEW) instead of a fix."""
    cfg = {"systems": "G", "canyons": [{"start": 60, "duration": 30, "keep": 3}],
           "azimuth_mask": [[0, 90, 40]]}
    sim = static_receiver(37.4, -122.2, 30.0, 150, cfg, seed=2)
    assert (sim.visible[60:90] == 3).all() and (sim.visible[:60] > 4).all()
    res = run_spp(sim.obs, sim.nav, systems=[0], options=_exact_opts())
    assert (res.status[60:90] == S.TOO_FEW).all()
    assert (res.status[:60] != S.TOO_FEW).all()
    # no satellite inside the masked sector below 40 deg
    az, el = np.degrees(res.az), np.degrees(res.el)
    assert not np.any((az < 90) & (el < 39.9) & ~np.isnan(az))


def test_rinex_round_trip_of_simulated_data(tmp_path):
    """RINEX 3.04 writer -> reader: the same observations (to the format's 1 mm / 0.001) and ephemerides (to
    the 12 significant digits of the format), and the same solution."""
    sim = static_receiver(37.4, -122.2, 30.0, 60, {"systems": "G", "frequencies": 2}, seed=4)
    write_obs(tmp_path / "obs.rnx", sim.obs)
    write_nav(tmp_path / "nav.rnx", sim.nav)
    obs = read_obs(tmp_path / "obs.rnx")
    nav = read_nav(tmp_path / "nav.rnx")
    assert obs.types == sim.obs.types
    np.testing.assert_array_equal(obs.prn, sim.obs.prn)
    assert np.abs(obs.time - sim.obs.time).max() < 1e-7
    np.testing.assert_allclose(obs.values, sim.obs.values, atol=6e-4, rtol=0)
    np.testing.assert_allclose(nav.eph, sim.nav.eph, rtol=1e-11, atol=1e-20)
    a = run_spp(sim.obs, sim.nav, systems=[0], options=_exact_opts())
    b = run_spp(obs, nav, systems=[0], options=_exact_opts())
    assert np.abs(a.pos - b.pos).max() < 0.01


def test_two_systems_with_an_inter_system_bias():
    """GPS and a second Keplerian constellation (the GPS orbits turned by 60 deg in node and 1 rad in anomaly,
    labelled Galileo) with a 20 ns receiver inter-system bias: one clock per system takes it (their
    difference is 20 ns x c within its noise), the position stays at the noise level; a single clock could
    not (the position error would be metres)."""
    from sinscli.sim.raw_gnss import check_config, load_nav_for_sim, with_second_constellation
    both = with_second_constellation(load_nav_for_sim(check_config({})))
    cfg = {"systems": "GE", "code_sigma": SIGMA, "system_bias": {"E": 20e-9}}
    sim = static_receiver(37.4, -122.2, 30.0, 600, cfg, seed=9, nav=both)
    assert set(np.unique(sim.obs.sys)) == {0, 2}
    res = run_spp(sim.obs, sim.nav, systems=[0, 2], options=_exact_opts())
    assert res.fix.mean() > 0.98
    isb = (res.clk[:, 2] - res.clk[:, 0]) / 299792458.0
    assert np.mean(isb) == pytest.approx(20e-9, abs=0.3e-9)
    lat, lon, _ = ecef_to_lla(sim.pos[0])
    d = (res.pos - sim.pos) @ enu_rotation(lat, lon).T
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) < 1.5
    assert np.abs(np.mean(d, axis=0)).max() < 0.2                  # no bias from the ISB


def test_simulate_cli_moving_receiver(tmp_path):
    """`sins simulate SCENARIO --raw-gnss RAW.yaml` on the vehicle drive: `sins gnss spp` on its obs.rnx/nav.rnx
    against gnss_truth.csv (the antenna's exact track): horizontal error and Doppler velocity at the noise level,
    and the 30 s canyon of the config has no fix."""
    from pathlib import Path

    from click.testing import CliRunner

    from sinscli.cli import main
    from sinscli.io.gnss_csv import read_gnss_csv
    from sinscli.nav.earth import lla_to_ecef
    root = Path(__file__).resolve().parents[1]
    raw = tmp_path / "raw.yaml"
    raw.write_text("systems: G\ncode_sigma: 0.5\ndoppler_sigma: 0.05\nelevation_mask: 5\n"
                   "canyons: [{start: 20, duration: 10, keep: 3}]\n")
    out = tmp_path / "sim"
    r = CliRunner().invoke(main, ["simulate", str(root / "configs/scenarios/vehicle_drive.yaml"), "-o", str(out),
                                  "--duration", "60", "--raw-gnss", str(raw), "-q"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["gnss", "spp", str(out / "obs.rnx"), "--nav", str(out / "nav.rnx"), "-o",
                                  str(out / "spp.csv"), "--elev-mask", "5", "--code-sigma", "0.5", "-q"])
    assert r.exit_code == 0, r.output
    fix = read_gnss_csv(out / "spp.csv")
    truth = np.loadtxt(out / "gnss_truth.csv", delimiter=",", skiprows=1)
    k = np.searchsorted(truth[:, 0], fix.time - 1e-6)
    assert np.abs(truth[k, 0] - fix.time).max() < 1e-6            # the solution time is the true time
    a = lla_to_ecef(np.radians(fix.lat), np.radians(fix.lon), fix.height)
    b = lla_to_ecef(np.radians(truth[k, 1]), np.radians(truth[k, 2]), truth[k, 3])
    lat0, lon0 = np.radians(truth[0, 1]), np.radians(truth[0, 2])
    d = (a - b) @ enu_rotation(lat0, lon0).T
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) < 3.0
    assert np.sqrt(np.mean(np.sum((fix.vel_n[:, :2] - truth[k, 4:6]) ** 2, axis=1))) < 0.3
    t_rel = truth[k, 0] - truth[0, 0]
    assert not np.any((t_rel >= 20) & (t_rel < 30))
    assert len(fix) >= 45
    assert np.all(np.abs(d) < 3.5 * fix.std_pos)


def test_hatch_smoothing_and_cycle_slips():
    """Carrier smoothing over 100 s cuts the code noise (here ~4x in position RMS); a cycle slip of 1000 cycles
    that the receiver did not flag restarts the filter (no bias after it)."""
    sim = static_receiver(37.4, -122.2, 30.0, 900, {"systems": "G", "code_sigma": SIGMA}, seed=21)
    obs = sim.obs
    lcol = obs.types[0].index("L1C")
    ep = obs.epoch_of_record()
    victim = int(obs.prn[obs.start[300]])
    obs.values[(obs.prn == victim) & (ep >= 300), lcol] += 1000.0
    raw = run_spp(obs, sim.nav, systems=[0], options=_exact_opts())
    sm = run_spp(obs, sim.nav, systems=[0], options=_exact_opts(), smooth=100.0)
    err = lambda r: np.linalg.norm(r.pos[200:] - sim.pos[200:], axis=1)       # noqa: E731
    assert np.sqrt(np.mean(err(sm) ** 2)) < np.sqrt(np.mean(err(raw) ** 2)) / 3.0
    assert np.max(err(sm)[100:110]) < 4.0                                      # around the slip


def test_loosely_coupled_fusion_of_spp_fixes(tmp_path):
    """Simulated drive with raw GNSS -> `sins gnss spp` (time base shifted to the scenario's) -> `sins navigate
    --gnss` (the loosely coupled filter) against the exact truth: the fused trajectory is better than the SPP
    fixes it was given (horizontal RMS), and every fix was accepted."""
    import re
    from pathlib import Path

    from click.testing import CliRunner

    from sinscli.cli import main
    from sinscli.io.gnss_csv import read_gnss_csv
    from sinscli.io.trajectory import read_trajectory
    root = Path(__file__).resolve().parents[1]
    raw = tmp_path / "raw.yaml"
    raw.write_text("systems: G\ncode_sigma: 0.5\ndoppler_sigma: 0.05\nelevation_mask: 5\n")
    out = tmp_path / "sim"
    r = CliRunner().invoke(main, ["simulate", str(root / "configs/scenarios/vehicle_drive.yaml"), "-o", str(out),
                                  "--duration", "120", "--raw-gnss", str(raw)])
    assert r.exit_code == 0, r.output
    offset = re.search(r"--time-offset (-?\d+)", r.output).group(1)
    r = CliRunner().invoke(main, ["gnss", "spp", str(out / "obs.rnx"), "--nav", str(out / "nav.rnx"), "-o",
                                  str(out / "spp.csv"), "--elev-mask", "5", "--smooth-code", "0", "--time-offset",
                                  offset, "-q"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["navigate", str(out / "imu.csv"), "--init", str(out / "init.yaml"), "--gnss",
                                  str(out / "spp.csv"), "-o", str(out / "fused.csv"), "-q"])
    assert r.exit_code == 0, r.output
    truth = read_trajectory(out / "truth.csv")
    fused = read_trajectory(out / "fused.csv")
    fix = read_gnss_csv(out / "spp.csv")
    from sinscli.nav.earth import lla_to_local_enu
    lat0, lon0, h0 = truth.lat[0], truth.lon[0], truth.height[0]

    def herr(t, lat, lon, h):
        k = np.clip(np.searchsorted(truth.time, t), 0, len(truth) - 1)
        a = lla_to_local_enu(lat, lon, h, lat0, lon0, h0)
        b = lla_to_local_enu(truth.lat[k], truth.lon[k], truth.height[k], lat0, lon0, h0)
        return np.sqrt(np.mean(np.sum((a - b)[:, :2] ** 2, axis=1)))

    assert abs(fix.time[0] - truth.time[0]) < 1.0                   # the time bases agree
    e_fix = herr(fix.time, np.radians(fix.lat), np.radians(fix.lon), fix.height)
    sel = fused.time >= 20.0
    e_fused = herr(fused.time[sel], fused.lat[sel], fused.lon[sel], fused.height[sel])
    print(f"LC: SPP fixes {e_fix:.2f} m, fused {e_fused:.2f} m horizontal RMS")
    assert e_fused < e_fix, (e_fused, e_fix)
