"""``sins compare --truth TRUTH NAV... -o DIR`` through the CLI: outputs and bad input."""
import csv
import re

import numpy as np
import pandas as pd
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io.trajectory import write_trajectory
from sinscli.evaluate.errors import ROWS
from sinscli.types import Trajectory

from test_report_errors import displaced, make_truth

D_QUAT = np.array([-7.09673e-02, -4.00094e-01, 4.62018e-01])
D_DCM = np.array([1.47416e-01, 6.70270e-02, 4.61033e-01])
DV = np.array([6.0e-03, 7.6e-03, 2.9e-02])
PHI = np.array([2e-6, -4e-6, 7e-6])


def write_case(tmp_path, t0=100.0, nav_t0=None):
    truth = make_truth(n=120, t0=t0)
    write_trajectory(tmp_path / "truth.csv", truth)
    quat = displaced(truth, D_QUAT, DV, phi_n=PHI)
    dcm = displaced(truth, D_DCM, -DV, phi_n=-2 * PHI)
    if nav_t0 is not None:
        quat.time = quat.time - t0 + nav_t0
    write_trajectory(tmp_path / "quat.csv", quat)
    write_trajectory(tmp_path / "dcm.parquet", dcm)
    return truth


def run(args):
    return CliRunner().invoke(main, ["compare", *map(str, args)])


def test_compare_writes_tables_timeseries_figures_and_html(tmp_path):
    truth = write_case(tmp_path)
    out = tmp_path / "rep"
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv", tmp_path / "dcm.parquet", "-o", out, "-q"])
    assert r.exit_code == 0, r.output
    with open(out / "errors.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["quantity", "unit", "quat", "dcm"]
    assert [r_[0] for r_ in rows[1:]] == ROWS
    val = {r_[0]: (float(r_[2]), float(r_[3])) for r_ in rows[1:]}
    for k, axis in enumerate("ENU"):
        np.testing.assert_allclose(val[f"pos_{axis}"], (D_QUAT[k], D_DCM[k]), atol=2e-7)
        np.testing.assert_allclose(val[f"max_pos_{axis}"], (abs(D_QUAT[k]), abs(D_DCM[k])), atol=2e-7)
        np.testing.assert_allclose(val[f"vel_{axis}"], (DV[k], -DV[k]), atol=1e-12)
    np.testing.assert_allclose(val["max_att_deg"], np.degrees([np.linalg.norm(PHI), 2 * np.linalg.norm(PHI)]),
                               rtol=1e-8)
    # C rows: first order [phi x] Cbn_true at the last epoch (second order ~ |phi|^2).
    c = truth.Cbn[-1]
    skew = np.array([[0, -PHI[2], PHI[1]], [PHI[2], 0, -PHI[0]], [-PHI[1], PHI[0], 0]])
    expect = (skew @ c).reshape(9)
    got = np.array([val[f"C{i}{j}"][0] for i in (1, 2, 3) for j in (1, 2, 3)])
    np.testing.assert_allclose(got, expect, atol=1e-10)

    md = (out / "errors.md").read_text()
    assert "| 10 | Eg - En | m | " in md
    assert re.search(r"\| 10 \| Eg - En \| m \| -7\.0967[0-9]E-02 \| 1\.4741[0-9]E-01 \|", md)
    assert f"t = {float(truth.time[-1])!r} s" in md

    ts = pd.read_csv(out / "timeseries.csv")
    assert len(ts) == len(truth)
    np.testing.assert_allclose(ts["quat.pos_n_m"], D_QUAT[1], atol=2e-7)
    np.testing.assert_allclose(ts["dcm.vel_u_mps"], -DV[2], atol=1e-12)
    np.testing.assert_allclose(ts["quat.att_angle_deg"], np.degrees(np.linalg.norm(PHI)), rtol=1e-8)

    html = (out / "index.html").read_text()
    links = re.findall(r'(?:src|href)="([^"]+)"', html)
    for fig in ("att_pitch.png", "att_heading.png", "att_roll.png", "att_angle.png", "pos_error.png",
                "vel_error.png"):
        assert fig in links
        assert (out / fig).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for link in links:
        assert not link.startswith(("/", "http", "file:")), link
        assert (out / link).exists(), link
    assert "7.09673E-02" in html or "-7.09673E-02" in html
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_labels_epoch_and_interpolation(tmp_path):
    truth = write_case(tmp_path)
    out = tmp_path / "rep"
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv", "--label", "Method 1", "--epoch",
             repr(float(truth.time[40])), "-o", out, "-q"])
    assert r.exit_code == 0, r.output
    assert (out / "errors.csv").read_text().splitlines()[0] == "quantity,unit,Method 1"
    assert f"t = {float(truth.time[40])!r} s" in (out / "errors.md").read_text()
    # Navigation at mid-epochs: refused without --interpolate, accepted with it.
    nav = displaced(truth, [0.5, 0.0, 0.0], [0, 0, 0])
    mid = Trajectory(truth.time[:-1] + 0.005, nav.lat[:-1], nav.lon[:-1], nav.height[:-1], nav.vel_n[:-1],
                     nav.Cbn[:-1])
    write_trajectory(tmp_path / "mid.csv", mid)
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "mid.csv", "-o", tmp_path / "r2", "-q"])
    assert r.exit_code == 2 and "--interpolate" in r.output and "mid.csv" in r.output
    r = run(["--truth", tmp_path / "truth.csv", tmp_path / "mid.csv", "--interpolate", "-o", tmp_path / "r2", "-q"])
    assert r.exit_code == 0, r.output


def _bad(tmp_path, args, *patterns):
    out = tmp_path / "bad_out"
    r = run([*args, "-o", out, "-q"])
    assert r.exit_code == 2, r.output
    for p in patterns:
        assert re.search(p, r.output), (p, r.output)
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".bad_out")]


def test_no_common_epochs(tmp_path):
    write_case(tmp_path)
    late = make_truth(n=20, t0=500.0)
    write_trajectory(tmp_path / "late.csv", late)
    _bad(tmp_path, ["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv", tmp_path / "late.csv"],
         r"sins: error: .*late\.csv: no common epochs", "do not overlap")


def test_different_time_bases(tmp_path):
    write_case(tmp_path, t0=1.7e9, nav_t0=0.0)
    _bad(tmp_path, ["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv"],
         r"quat\.csv: no common epochs", "different time bases", "absolute seconds")


def test_nav_missing_columns(tmp_path):
    write_case(tmp_path)
    df = pd.read_csv(tmp_path / "quat.csv").drop(columns=["vel_n"])
    df.to_csv(tmp_path / "short.csv", index=False)
    _bad(tmp_path, ["--truth", tmp_path / "truth.csv", tmp_path / "short.csv"],
         r"short\.csv: missing trajectory column\(s\) vel_n")


def test_usage_errors(tmp_path):
    write_case(tmp_path)
    _bad(tmp_path, [tmp_path / "quat.csv"], "--truth TRUTH")
    _bad(tmp_path, ["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv", "--label", "a", "--label", "b"],
         "--label given 2")
    _bad(tmp_path, ["--truth", tmp_path / "truth.csv", tmp_path / "quat.csv", "--epoch", "1e6"],
         "--epoch.*not an epoch of method 'quat'")
