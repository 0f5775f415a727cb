"""`sins compare` with the navigator's 1-sigma columns: the fraction of epochs inside 3 sigma and the average
NEES against their analytic values for seeded Gaussian errors (honest, over- and under-stated sigma), the
series in timeseries.csv, the tables, and the sigma bands drawn in the figures."""
from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from sinscli.io.trajectory import write_trajectory
from sinscli.nav.earth import ecef_to_lla, enu_rotation, lla_to_ecef
from sinscli.nav.rotation import dcm_to_euler_many, euler_to_dcm_many, level_heading_frame, rotvec_to_dcm
from sinscli.evaluate.errors import CONSISTENCY_ROWS, build_consistency, compare_trajectories
from sinscli.report.figures import _line_plot, series_lines
from sinscli.types import Trajectory

SINS = Path(sys.executable).with_name("sins")
N = 20000
SIG_POS = np.array([0.5, 0.8, 1.5])          # m
SIG_VEL = np.array([0.02, 0.03, 0.05])       # m/s
SIG_ATT = np.array([0.05, 0.04, 0.3])        # deg: roll, pitch, heading


def _truth(n=N):
    s = np.linspace(0.0, 1.0, n)
    t = 1000.0 + 0.1 * np.arange(n)
    cbn = euler_to_dcm_many(np.radians(3 * np.sin(20 * s)), np.radians(2 * np.cos(15 * s)), np.radians(360 * s), 0)
    return Trajectory(t, np.radians(42.3 + 0.01 * s), np.radians(-71.1 + 0.01 * s), 20 + 5 * s,
                      np.column_stack([np.sin(30 * s), np.cos(30 * s), 0.1 * s]), cbn, source="truth.csv")


def _nav(truth, scale=1.0, seed=1):
    """A navigation with truth - nav = e, e ~ N(0, sigma^2) per axis (position exactly through ECEF, attitude as
    level-frame small angles), and sigma columns that claim ``scale`` times the real sigma."""
    rng = np.random.default_rng(seed)
    n = len(truth)
    e_pos, e_vel = rng.normal(0, 1, (n, 3)) * SIG_POS, rng.normal(0, 1, (n, 3)) * SIG_VEL
    e_att = rng.normal(0, 1, (n, 3)) * np.radians(SIG_ATT)
    c_en = np.swapaxes(enu_rotation(truth.lat, truth.lon), -1, -2)
    lat, lon, h = ecef_to_lla(lla_to_ecef(truth.lat, truth.lon, truth.height) - np.einsum("nij,nj->ni", c_en, e_pos))
    heading = dcm_to_euler_many(truth.Cbn, 0)[:, 2]
    phi_n = np.einsum("nij,nj->ni", level_heading_frame(heading), e_att)      # M is its own inverse
    cbn = np.stack([rotvec_to_dcm(-p) @ c for p, c in zip(phi_n, truth.Cbn)])
    extra = {}
    for names, sig in ((("pos_e_std", "pos_n_std", "pos_u_std"), SIG_POS),
                       (("vel_e_std", "vel_n_std", "vel_u_std"), SIG_VEL),
                       (("roll_std", "pitch_std", "heading_std"), SIG_ATT)):
        for c, sg in zip(names, sig):
            extra[c] = np.full(n, scale * sg)
    extra["gyro_bias_x"] = np.full(n, 3.0)
    return Trajectory(truth.time, lat, lon, h, truth.vel_n - e_vel, cbn, extra, source="nav.csv")


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("env")
    truth = _truth()
    write_trajectory(d / "truth.csv", truth)
    write_trajectory(d / "honest.csv", _nav(truth, 1.0, seed=1))
    write_trajectory(d / "optimistic.parquet", _nav(truth, 0.5, seed=2))
    write_trajectory(d / "pessimistic.csv", _nav(truth, 2.0, seed=3))
    plain = _nav(truth, 1.0, seed=4)
    plain.extra = {}
    write_trajectory(d / "plain.csv", plain)
    res = subprocess.run([str(SINS), "compare", "--truth", "truth.csv", "honest.csv", "optimistic.parquet",
                          "pessimistic.csv", "plain.csv", "-o", "rep", "-q"], cwd=d, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return d / "rep"


def _p_inside(k):
    """P(|z| <= k) for a standard normal."""
    return math.erf(k / math.sqrt(2.0))


def test_consistency_rows_against_analytic_values(report):
    with open(report / "errors.csv", newline="") as fh:
        rows = {r[0]: r for r in csv.reader(fh)}
    assert rows["quantity"] == ["quantity", "unit", "honest", "optimistic", "pessimistic", "plain"]
    for key in CONSISTENCY_ROWS:
        assert key in rows, key
        assert rows[key][5] == ""                        # no sigma columns: empty cell, never NaN
    # N = 20000 epochs: the fraction's standard error is 4e-4 at 0.9973, 2.4e-3 at 0.866; NEES's mean 0.017 * scale^-2
    for col, scale in ((2, 1.0), (3, 0.5), (4, 2.0)):
        p = _p_inside(3.0 * scale)
        se = math.sqrt(p * (1 - p) / N)
        for key in CONSISTENCY_ROWS[:9]:
            assert abs(float(rows[key][col]) - p) <= 5 * se + 1e-9, (key, scale, rows[key][col], p)
        for key in ("nees_pos", "nees_vel", "nees_att"):
            expect = 3.0 / scale ** 2
            assert abs(float(rows[key][col]) - expect) <= 5 * math.sqrt(6.0 / N) / scale ** 2, (key, rows[key][col])
    md = (report / "errors.md").read_text()
    assert "average NEES, position (3 dof)" in md and "epochs inside 3 sigma, attitude heading" in md
    html = (report / "index.html").read_text()
    assert "Consistency of the navigators' own 1-sigma" in html


def test_timeseries_carries_the_sigma_series(report):
    ts = pd.read_csv(report / "timeseries.csv")
    np.testing.assert_allclose(ts["honest.pos_u_std_m"], SIG_POS[2], rtol=1e-15)
    np.testing.assert_allclose(ts["optimistic.att_heading_std_deg"], 0.5 * SIG_ATT[2], rtol=1e-12)
    np.testing.assert_allclose(ts["pessimistic.vel_n_std_mps"], 2.0 * SIG_VEL[1], rtol=1e-15)
    assert "plain.pos_e_std_m" not in ts.columns and "plain.pos_e_m" in ts.columns
    # the errors themselves: truth - nav with the drawn sigma
    assert abs(np.std(ts["honest.pos_n_m"]) / SIG_POS[1] - 1) < 0.03
    assert abs(np.std(ts["honest.att_heading_deg"]) / SIG_ATT[2] - 1) < 0.03
    for f in ("pos_error.png", "vel_error.png", "att_roll.png", "att_pitch.png", "att_heading.png"):
        assert (report / f).stat().st_size > 10_000


def test_bands_are_drawn_only_for_runs_with_sigma():
    truth = _truth(500)
    series = {"honest": compare_trajectories(truth, _nav(truth, 1.0)),
              "plain": compare_trajectories(truth, Trajectory(truth.time, truth.lat, truth.lon, truth.height,
                                                              truth.vel_n, truth.Cbn))}
    assert series["honest"].has_sigma and not series["plain"].has_sigma
    ax = Figure().add_subplot()
    _line_plot(ax, {name: series_lines(s) for name, s in series.items()}, "pos_e")
    bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(bands) == 1                                # one +-3 sigma band, for the run with sigmas
    ylo, yhi = bands[0].get_paths()[0].vertices[:, 1].min(), bands[0].get_paths()[0].vertices[:, 1].max()
    assert ylo == pytest.approx(-3 * SIG_POS[0]) and yhi == pytest.approx(3 * SIG_POS[0])
    labels = [ln.get_label() for ln in ax.get_lines()]
    assert labels.count("honest +-1 sigma") == 1 and "plain" in labels
    assert build_consistency({"plain": series["plain"]}) is None


def test_a_batch_job_file_carries_the_sigma_report(tmp_path):
    """What a batch job sends back and stores under DIR/jobs/ (the run's digest as flat arrays in a .npz)
    gives the same report, byte for byte, as the single compare: consistency rows, sigma columns and bands."""
    import filecmp

    from sinscli.report.digest import SeriesDigest, digest
    from sinscli.evaluate.errors import build_table
    from sinscli.report.report import write_report, write_report_files

    truth = _truth(3000)
    series = {"honest": compare_trajectories(truth, _nav(truth, 1.0, seed=5)),
              "plain": compare_trajectories(truth, Trajectory(truth.time, truth.lat, truth.lon, truth.height,
                                                              truth.vel_n, truth.Cbn))}
    write_report(tmp_path / "single", series, "t", timeseries_every=7)
    digests = {}
    for name, s in series.items():
        np.savez(tmp_path / f"{name}.npz", **digest(s, 7).arrays())
        with np.load(tmp_path / f"{name}.npz", allow_pickle=False) as z:
            digests[name] = SeriesDigest.from_arrays({k: z[k] for k in z.files})
    assert digests["plain"].consistency is None and "pos_e_std" not in digests["plain"].lines
    assert [n for n in digests["honest"].lines if n.endswith("_std")][-1] == "vel_u_std"
    assert list(digests["honest"].lines)[-4:] == ["track_e", "track_n", "track_nav_e", "track_nav_n"]
    (tmp_path / "batch").mkdir()
    files = write_report_files(tmp_path / "batch", digests, build_table(series), "t")
    assert "att_roll.png" in files
    _, mismatch, errors = filecmp.cmpfiles(tmp_path / "single", tmp_path / "batch", files, shallow=False)
    assert not mismatch and not errors, (mismatch, errors)
    rows = {r[0]: r for r in csv.reader(open(tmp_path / "batch" / "errors.csv", newline=""))}
    assert rows["nees_pos"][3] == "" and abs(float(rows["nees_pos"][2]) - 3.0) <= 5 * math.sqrt(6.0 / 3000)
