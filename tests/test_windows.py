"""Time windows and clock offsets (issue 10): ``navigate --start/--end/--duration`` (plain and fused),
``compare --start/--end``, ``--time-offset`` for GNSS (navigate) and truth (compare), and their refusals."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from sinscli.io.trajectory import read_trajectory
from test_contract import refused, sins

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    d = tmp_path_factory.mktemp("windows")
    for name in ("imu.csv", "truth.csv", "init.yaml"):
        (d / name).write_bytes((SAMPLE / name).read_bytes())
    (d / "i31.csv").write_text("\n".join((SAMPLE / "imu.csv").read_text().splitlines()[:3102]) + "\n")
    (d / "g30.csv").write_text("\n".join((SAMPLE / "gnss.csv").read_text().splitlines()[:31]) + "\n")
    (d / "init5.yaml").write_text((SAMPLE / "init.yaml").read_text().replace("time: 0.0", "time: 5.0"))
    rc, lines = sins(["navigate", "imu.csv", "--init", "init.yaml", "-q", "-o", "full.csv"], cwd=d)
    assert rc == 0, lines
    return d


def _close(a, b, tol=1e-9):
    assert len(a) == len(b)
    np.testing.assert_allclose(a.time, b.time, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.degrees(a.lat), np.degrees(b.lat), rtol=0, atol=tol)
    np.testing.assert_allclose(a.vel_n, b.vel_n, rtol=0, atol=tol * 1e5)
    np.testing.assert_allclose(a.Cbn, b.Cbn, rtol=0, atol=tol)


def test_navigate_window_is_the_full_run_cut(d):
    full = read_trajectory(d / "full.csv")
    for n, args in enumerate((["--start", "60", "--end", "90"], ["--start", "+60", "--duration", "30"])):
        rc, lines = sins(["navigate", "imu.csv", "--init", "init.yaml", "-q", "-o", f"w{n}.csv", *args], cwd=d)
        assert rc == 0, lines
        w = read_trajectory(d / f"w{n}.csv")
        assert w.time[0] == 60.0 and w.time[-1] == 90.0
        k = (full.time >= 60.0) & (full.time <= 90.0)
        _close(w, read_trajectory(d / "full.csv").__class__(full.time[k], full.lat[k], full.lon[k], full.height[k],
                                                           full.vel_n[k], full.Cbn[k]))


def test_trajectory_init_gives_its_row_at_the_start(d):
    truth = read_trajectory(d / "truth.csv")
    rc, lines = sins(["navigate", "imu.csv", "--init", "truth.csv", "-q", "-o", "wt.csv", "--start", "60",
                      "--end", "70"], cwd=d)
    assert rc == 0, lines
    w = read_trajectory(d / "wt.csv")
    k = int(np.flatnonzero(truth.time == 60.0)[0])
    assert w.time[0] == 60.0 and w.time[-1] == 70.0
    np.testing.assert_array_equal(w.Cbn[0], truth.Cbn[k])
    assert w.lat[0] == truth.lat[k] and np.array_equal(w.vel_n[0], truth.vel_n[k])


def test_fused_window_and_gnss_time_offset(d):
    rc, lines = sins(["navigate", "i31.csv", "--gnss", "g30.csv", "--init", "truth.csv", "-q", "-o", "fw.csv",
                      "--start", "10", "--end", "25"], cwd=d)
    assert rc == 0, lines
    fw = read_trajectory(d / "fw.csv")
    assert fw.time[0] == 10.0 and fw.time[-1] == 25.0
    # a GNSS file whose clock runs 7.5 s behind, with --time-offset 7.5 (or gnss.time_offset): the same run
    rows = list(csv.reader((d / "g30.csv").open()))
    with (d / "g_late.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for r in rows[1:]:
            w.writerow([repr(float(r[0]) - 7.5), *r[1:]])
    (d / "off.yaml").write_text("gnss:\n  time_offset: 7.5\n")
    outs = []
    for n, extra in enumerate(([], ["--time-offset", "7.5"], ["--config", "off.yaml"])):
        gnss = "g30.csv" if n == 0 else "g_late.csv"
        rc, lines = sins(["navigate", "i31.csv", "--gnss", gnss, "--init", "init.yaml", "-q", "-o", f"f{n}.csv",
                          *extra], cwd=d)
        assert rc == 0, lines
        outs.append((d / f"f{n}.csv").read_bytes())
    assert outs[0] == outs[1] == outs[2]


@pytest.mark.parametrize("args, fragments", [
    (["navigate", "imu.csv", "--init", "init.yaml", "--start", "500"], ["starts after the log ends"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--end", "-1"], ["ends before the log starts"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--start", "50", "--end", "40"], ["--end 40 is not after"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--end", "50", "--duration", "3"], ["--end or --duration"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--duration", "-3"], ["--duration", "positive"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--start", "abc"], ["--start", "expected a time"]),
    (["navigate", "imu.csv", "--init", "init5.yaml", "--start", "2"], ["init5.yaml", "after the window start"]),
    (["navigate", "i31.csv", "--gnss", "g30.csv", "--init", "init5.yaml", "--start", "2"],
     ["init5.yaml", "after the window start"]),
    (["navigate", "i31.csv", "--gnss", "g30.csv", "--init", "init.yaml", "--start", "40"],
     ["starts after the log ends"]),
    (["navigate", "i31.csv", "--gnss", "g30.csv", "--init", "init.yaml", "--time-offset", "1e6"],
     ["does not overlap", "time offset of 1e+06 s"]),
    (["navigate", "imu.csv", "--init", "init.yaml", "--time-offset", "3"], ["--time-offset needs --gnss"]),
    (["compare", "--truth", "truth.csv", "full.csv", "--time-offset", "1000"], ["no epoch in common",
                                                                            "time offset of 1000.0 s"]),
    (["compare", "--truth", "truth.csv", "full.csv", "--start", "500"], ["starts after"]),
])
def test_window_refusals(d, args, fragments):
    out = "rep_bad" if args[0] == "compare" else "bad.csv"
    refused([*args, "-o", out], *fragments, cwd=d)
    assert not (d / out).exists() and not list(d.glob("*.part*"))


def _errors(path):
    return {r[0]: float(r[2]) for r in csv.reader(path.open()) if r[0] not in ("quantity",)}


def test_compare_window_and_truth_offset(d):
    rc, lines = sins(["compare", "--truth", "truth.csv", "full.csv", "-o", "rep_full", "-q"], cwd=d)
    assert rc == 0, lines
    rc, lines = sins(["compare", "--truth", "truth.csv", "full.csv", "-o", "rep_w", "-q", "--start", "60",
                      "--end", "90"], cwd=d)
    assert rc == 0, lines
    ts = np.genfromtxt(d / "rep_full" / "timeseries.csv", delimiter=",", names=True)
    tw = np.genfromtxt(d / "rep_w" / "timeseries.csv", delimiter=",", names=True)
    assert tw["time"][0] == 60.0 and tw["time"][-1] == 90.0
    k = (ts["time"] >= 60.0) & (ts["time"] <= 90.0)
    e = _errors(d / "rep_w" / "errors.csv")
    assert e["max_pos_N"] == pytest.approx(np.abs(ts["fullpos_n_m"][k]).max(), rel=1e-12)
    assert e["max_pos_N"] < _errors(d / "rep_full" / "errors.csv")["max_pos_N"]     # the window is not the run
    assert "window from 60.0 s to 90.0 s" in (d / "rep_w" / "errors.md").read_text()
    t_first = float(np.genfromtxt(d / "truth.csv", delimiter=",", names=True)["time"][0])
    rc, lines = sins(["compare", "--truth", "truth.csv", "full.csv", "-o", "rep_rel", "-q", "--start",
                      f"+{60.0 - t_first!r}", "--end", f"+{90.0 - t_first!r}"], cwd=d)
    assert rc == 0, lines                  # a window relative to the truth's first epoch: the same, said the same
    assert "window from 60.0 s to 90.0 s" in (d / "rep_rel" / "errors.md").read_text()
    assert _errors(d / "rep_rel" / "errors.csv") == e
    # a truth on a clock 100 s ahead, with --time-offset -100: the same report
    rows = list(csv.reader((d / "truth.csv").open()))
    with (d / "truth_late.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for r in rows[1:]:
            w.writerow([repr(float(r[0]) + 100.0), *r[1:]])
    rc, lines = sins(["compare", "--truth", "truth_late.csv", "full.csv", "-o", "rep_off", "-q",
                      "--time-offset", "-100"], cwd=d)
    assert rc == 0, lines
    assert _errors(d / "rep_off" / "errors.csv") == _errors(d / "rep_full" / "errors.csv")
