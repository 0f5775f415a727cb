"""Issue 30 in the filter: receiver logs (NMEA, NAV-PVT) fuse as the CSV of the same fixes, and a horizontal-only
GNSS velocity is applied as its east and north components."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sinscli.evaluate.fusion import errors
from sinscli.fusion.options import build_fusion_options
from sinscli.fusion.pipeline import run_fusion
from sinscli.io.innovations import read_innovations, write_innovations
from sinscli.io.receiver import read_receiver_log
from sinscli.sim.run import SIM_GEOID_SEPARATION, simulate, write_receiver_logs

LEVER = [0.8, 0.0, 1.5]
INIT_SIGMA = {"position": [0.1] * 3, "velocity": [0.01] * 3, "attitude": np.radians([0.1, 0.1, 1.0])}
KNOT = 1852.0 / 3600.0
# a moving start (no standstill: an NMEA speed below 0.2 m/s has no course), turns, a climb; UTC start time
SCENARIO = {
    "name": "receivers", "seed": 3,
    "start": {"time": 1715680800.0, "lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 30.0, "speed": 10.0},
    "imu": {"rate": 100, "sensor": "mems"},
    "gnss": {"rate": 1, "pos_noise": [1.5, 1.5, 3.0], "vel_noise": 0.05, "lever_arm": LEVER},
    "segments": [{"type": "cruise", "duration": 20}, {"type": "turn", "angle": 90, "duration": 10, "bank": "none"},
                 {"type": "accelerate", "speed": 15, "duration": 5}, {"type": "cruise", "duration": 30},
                 {"type": "turn", "angle": -60, "duration": 10, "bank": "none"},
                 {"type": "climb", "pitch": 3, "duration": 20, "transition": 5}, {"type": "cruise", "duration": 25},
                 {"type": "decelerate", "speed": 8, "duration": 5},
                 {"type": "turn", "angle": 45, "duration": 10, "bank": "none"}, {"type": "cruise", "duration": 15}]}


@pytest.fixture(scope="module")
def sim():
    return simulate(SCENARIO)


def _fuse(sim, gnss, **kw):
    fo = build_fusion_options({"lever_arm": LEVER, "gnss_vel_sigma": [0.05, 0.05, 0.05], **kw}, "test")
    return run_fusion(sim.imu, sim.init, gnss, fo, init_sigma=INIT_SIGMA)


def _dm_round(x, decimals):
    """Degrees rounded as NMEA writes them: whole degrees and minutes of arc to ``decimals``."""
    a = np.abs(x)
    d = np.floor(a)
    m = np.round((a - d) * 60.0, decimals)
    d, m = np.where(m >= 60.0, d + 1, d), np.where(m >= 60.0, 0.0, m)
    return np.sign(x) * (d + m / 60.0)


def _diff(a, b):
    dr, dv, phi = errors(a, b)
    return np.hypot(dr[:, 0], dr[:, 1]).max(), np.abs(dr[:, 2]).max(), np.abs(dv).max(), np.degrees(np.abs(phi)).max()


def test_receiver_logs_fuse_as_the_csv_of_the_same_fixes(sim, tmp_path):
    """``sins simulate --gnss-format nmea,ubx`` logs, read and fused, against the same fixes in memory: exactly
    the fused result of the fixes rounded (by numpy here) to each format's resolution; against the exact fixes
    within that resolution (measured: NAV-PVT 3.7 mm horizontal, 4.0 mm vertical, 0.9 mm/s, 0.011 deg; NMEA
    9.2 mm, 23 mm, 3.2 mm/s, 0.006 deg)."""
    write_receiver_logs(sim.gnss, tmp_path, ["nmea", "ubx"])
    ubx, nmea = read_receiver_log(tmp_path / "gnss.ubx"), read_receiver_log(tmp_path / "gnss.nmea")
    g = sim.gnss
    assert len(ubx) == len(nmea) == len(g) and np.array_equal(ubx.time, g.time) and np.array_equal(nmea.time, g.time)
    # NAV-PVT with NAV-HPPOSLLH: 1e-9 deg, 0.1 mm, 1 mm/s; hAcc/vAcc/sAcc are the sigmas (1.5, 3 m; 0.05 m/s)
    ubx_ref = replace(g, lat=np.round(g.lat * 1e9) / 1e9, lon=np.round(g.lon * 1e9) / 1e9,
                      height=np.round(g.height * 1e4) / 1e4, vel_n=np.round(g.vel_n * 1e3) / 1e3)
    # NMEA: minutes of arc to 1e-5, altitude to 0.1 m (the separation exact), speed to 0.001 kn, course to
    # 0.01 deg, horizontal only; no velocity sigma (the configured one); GST 1.500, 1.500, 3.000
    sp = np.round(np.hypot(g.vel_n[:, 0], g.vel_n[:, 1]) / KNOT, 3) * KNOT
    co = np.radians(np.round(np.degrees(np.arctan2(g.vel_n[:, 0], g.vel_n[:, 1])) % 360.0, 2))
    nmea_exact = replace(g, vel_n=np.column_stack([g.vel_n[:, :2], np.full(len(g), np.nan)]), std_vel=None)
    nmea_ref = replace(nmea_exact, lat=_dm_round(g.lat, 5), lon=_dm_round(g.lon, 5),
                       height=np.round(g.height - SIM_GEOID_SEPARATION, 1) + SIM_GEOID_SEPARATION,
                       vel_n=np.column_stack([sp * np.sin(co), sp * np.cos(co), np.full(len(g), np.nan)]))
    out = {k: _fuse(sim, v)[0] for k, v in (("ubx", ubx), ("ubx_ref", ubx_ref), ("csv", g), ("nmea", nmea),
                                            ("nmea_ref", nmea_ref), ("nmea_exact", nmea_exact))}
    assert _diff(out["ubx"], out["ubx_ref"]) == (0.0, 0.0, 0.0, 0.0)
    assert _diff(out["nmea"], out["nmea_ref"]) == (0.0, 0.0, 0.0, 0.0)
    h, u, v, a = _diff(out["ubx"], out["csv"])
    assert h <= 0.011 and u <= 0.011 and v <= 0.002 and a <= 0.02      # NAV-PVT's 1e-7 deg (1.1 cm), 1 mm/s
    h, u, v, a = _diff(out["nmea"], out["nmea_exact"])
    assert h <= 0.0185 and u <= 0.1 and v <= 0.01 and a <= 0.02        # NMEA's 1e-5 minute (1.85 cm), 0.1 m


def test_horizontal_velocity_is_the_update_of_an_unknown_vertical(sim):
    """A horizontal-only velocity (m = 2) against the same velocity with its vertical sigma 1e4 m/s (m = 3, the
    vertical carrying no information): the same trajectory (the robust weighting off, whose chi-square bounds
    depend on m; with it on, the results differ by the weights: 9.6 cm, 0.056 deg here)."""
    g = sim.gnss
    h = replace(g, vel_n=np.column_stack([g.vel_n[:, :2], np.full(len(g), np.nan)]),
                std_vel=np.column_stack([g.std_vel[:, :2], np.full(len(g), np.nan)]))
    big = replace(g, std_vel=np.column_stack([g.std_vel[:, :2], np.full(len(g), 1e4)]))
    a = _fuse(sim, h, robust_probability=None)
    b = _fuse(sim, big, robust_probability=None)
    hd, ud, vd, ad = _diff(a[0], b[0])
    assert hd < 1e-6 and ud < 1e-6 and vd < 1e-6 and ad < 1e-6
    inn = a[1]
    vel = inn[inn["type"] == "gnss_vel"]
    assert set(vel["axis"].tolist()) == {"e", "n"} and vel.size > 200
    assert (vel["axis"] == "e").sum() == (vel["axis"] == "n").sum()
    assert set(b[1][b[1]["type"] == "gnss_vel"]["axis"].tolist()) == {"e", "n", "u"}


def test_horizontal_velocity_innovations_file(sim, tmp_path):
    g = sim.gnss
    h = replace(g, vel_n=np.column_stack([g.vel_n[:, :2], np.full(len(g), np.nan)]), std_vel=None)
    _, inn, summ, _ = _fuse(sim, h)
    write_innovations(tmp_path / "inn.csv", inn)
    back = read_innovations(tmp_path / "inn.csv")
    vel = back[back["type"] == "gnss_vel"]
    assert set(vel["axis"].tolist()) == {"e", "n"} and np.isfinite(vel["innovation"]).all()
    assert np.array_equal(back["innovation"], inn["innovation"])


def test_comma2k19_horizontal_velocity_real_log(tmp_path):
    """A real highway log whose u-blox fixes give speed and bearing only (comma2k19 example; no vertical
    velocity, no accuracy): fused with the horizontal-only velocity against the same fixes without it.  The
    heading against comma.ai's reference (the camera's, whose mounting is not given: its scatter about the mean
    offset after the first 5 s) 0.087 deg with the velocity, 0.096 deg without; the residual against the fixes
    0.215 m against 0.414 m; the heading from the course 0.1 s after the start against 1.3 s."""
    import pyarrow.csv as pc
    from click.testing import CliRunner
    from realdata import comma2k19_dir, comma2k19_gnss_hv, comma2k19_hv_reference_heading
    from sinscli.cli import main
    if comma2k19_dir() is None:
        pytest.skip("comma2k19_ex1 not shipped here (set SINS_REALDATA)")
    f = comma2k19_gnss_hv(tmp_path)
    (tmp_path / "nav.yaml").write_text(f["config"].read_text() + "align:\n  duration: 20\n")
    t_ref, h_ref = comma2k19_hv_reference_heading(f["utc_offset"])
    scatter = {}
    for k in ("gnss_hv", "gnss_pos"):
        r = CliRunner().invoke(main, ["navigate", str(f["imu"]), "--gnss", str(f[k]), "--align", "gnss-inertial",
                                      "--start", "+0.2", "--config", str(tmp_path / "nav.yaml"), "--innovations",
                                      str(tmp_path / f"inn_{k}.csv"), "-o", str(tmp_path / f"fused_{k}.csv")])
        assert r.exit_code == 0, r.output
        out = pc.read_csv(tmp_path / f"fused_{k}.csv").to_pydict()
        t, h = np.array(out["time"]), np.array(out["heading"])
        d = (h - np.interp(t, t_ref, np.degrees(np.unwrap(np.radians(h_ref)))) + 180.0) % 360.0 - 180.0
        d = d[t > t[0] + 5.0]
        scatter[k] = float(d.std())
        assert abs(d.mean() - 0.93) < 0.1                 # the camera's yaw against the IMU: the same in both
        inn = pc.read_csv(tmp_path / f"inn_{k}.csv").to_pydict()
        axes = {a for ty, a in zip(inn["type"], inn["axis"]) if ty == "gnss_vel"}
        assert axes == ({"e", "n"} if k == "gnss_hv" else set())
    # the velocity sharpens the heading: 0.087 deg against 0.096 deg without it (0.117 before the filter took the
    # phone gyro's biases and the fixes' correlated error from the log itself)
    assert scatter["gnss_hv"] <= 0.09 and scatter["gnss_hv"] < 0.95 * scatter["gnss_pos"], scatter
