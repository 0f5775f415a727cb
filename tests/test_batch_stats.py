"""What a batch reports from its workers' small results, checked against independent computations:

- the statistics of a sample against their textbook values;
- the error table built from each run's tail columns equals the one built from the whole series
  (``build_table``), for methods with different output rates and an explicit epoch;
- a 25-seed batch gives the statistical report (no per-run figure), and its statistics equal those
  pandas computes from ``results.parquet``, which holds every run; ``--figures all`` draws them;
- a per-run batch's ``results.parquet`` equals its ``errors.csv``; a run is reproduced by
  ``sins simulate --seed`` + the trajectory the batch kept + ``sins compare --truth``;
- a 200-run alignment Monte Carlo with the client's peak memory under 1 GB, ``results.parquet``
  holding every run and the summary agreeing with ``runs.csv``.
"""
import os
import subprocess

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.report.digest import TAIL_EPOCHS, table_from_tails, tail_table
from sinscli.evaluate.errors import ROWS, build_table, compare_trajectories
from sinscli.evaluate.stats import describe, row_statistics

from batchutil import SINS, write_batch
from test_report_errors import displaced, make_truth


def test_describe_against_textbook_values():
    x = np.arange(1.0, 101.0)                      # 1 .. 100
    d = describe(np.append(x, [np.nan, np.inf]))   # non-finite values are left out
    assert d["n"] == 100
    assert d["mean"] == 50.5
    assert d["std"] == pytest.approx(np.sqrt(100 * 101 / 12), rel=1e-14)    # sample std of 1..n: sqrt(n(n+1)/12)
    assert d["rms"] == pytest.approx(np.sqrt(101 * 201 / 6), rel=1e-14)     # sqrt(sum k^2 / n)
    # linear-interpolation percentiles of 1..100: 1 + p/100 * 99
    for p in (5, 25, 50, 75, 95):
        assert d[f"p{p}"] == pytest.approx(1 + p / 100 * 99, rel=1e-14)
    assert (d["min"], d["max"]) == (1.0, 100.0)
    frame = pd.DataFrame({"method": ["b", "a", "b"], "q": [1.0, 5.0, 3.0]})
    st = row_statistics(frame, "method", ["q"], {"q": "m"})
    assert list(st["method"]) == ["b", "a"] and list(st["mean"]) == [2.0, 5.0] and list(st["std"]) == [np.sqrt(2), 0.0]


def _series(sub: int, shift: float, n: int = 400):
    truth = make_truth(n=n)
    nav = displaced(truth, [0.1 * shift, 0.2, -0.3 * shift], [0.01 * shift, 0.0, 0.02], phi_n=[1e-6, -2e-6 * shift, 3e-6])
    keep = np.arange(0, n, sub)
    from sinscli.evaluate.errors import _subset
    return compare_trajectories(truth, _subset(nav, keep))


def test_table_from_tails_equals_the_table_of_whole_series():
    series = {"s1": _series(1, 1.0), "s3": _series(3, 2.0), "s4": _series(4, 3.0)}     # output every 1, 3, 4 epochs
    for epoch in (None, float(series["s1"].time[240])):          # epoch 240 is on all three grids
        full = build_table(series, epoch)
        tails = table_from_tails({k: tail_table(s, epoch) for k, s in series.items()}, epoch)
        assert tails.epoch == full.epoch and tails.methods == full.methods
        np.testing.assert_array_equal(tails.values, full.values)
    assert build_table(series).epoch == series["s1"].time[396]      # the last multiple of 12 epochs
    # no common epoch within the last TAIL_EPOCHS epochs of each run: the batch asks for one
    far = {"a": _series(1, 1.0, n=400), "b": _series(1, 1.0, n=400)}
    tails = {k: tail_table(s) for k, s in far.items()}
    tails["b"].time = tails["b"].time + 1e-3 * np.r_[0, np.ones(len(tails["b"].time) - 1)]   # shifted off-grid
    with pytest.raises(SinsError, match=f"among the last {TAIL_EPOCHS} epochs of each run; set epoch:"):
        table_from_tails(tails)


@pytest.fixture(scope="module")
def stats_batch(tmp_path_factory):
    d = tmp_path_factory.mktemp("stats")
    batch = write_batch(d / "b", seeds=25, duration=2.0)
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(d / "out"), "-q", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    return d, batch


def test_statistical_report_equals_pandas_on_the_parquet(stats_batch):
    d, _ = stats_batch
    out = d / "out"
    runs = pd.read_parquet(out / "results.parquet")
    assert sorted(p.name for p in (out / "results.parquet").iterdir()) == ["method=dcm000", "method=quat2"]
    assert len(runs) == 50 and (runs["status"] == "ok").all() and sorted(runs["seed"].unique()) == list(range(25))
    stats = pd.read_csv(out / "tiny" / "errors_stats.csv")
    assert len(stats) == 2 * len(ROWS)
    for (method, q), row in stats.set_index(["method", "quantity"]).iterrows():
        v = runs.loc[runs["method"] == method, q].astype(float)
        assert row["n"] == 25
        assert row["mean"] == pytest.approx(v.mean(), rel=1e-12, abs=1e-300)
        assert row["std"] == pytest.approx(v.std(ddof=1), rel=1e-9, abs=1e-300)
        assert row["p95"] == pytest.approx(v.quantile(0.95), rel=1e-12, abs=1e-300)
        assert row["max"] == v.max() and row["min"] == v.min()
    mc = pd.read_csv(out / "tiny" / "errors_mc.csv").set_index("quantity")
    q2 = runs[runs["method"] == "quat2"]
    assert mc.loc["pos_E", "quat2"] == pytest.approx(np.sqrt((q2["pos_E"] ** 2).mean()), rel=1e-12)
    assert mc.loc["max_att_deg", "quat2"] == q2["max_att_deg"].max()
    # the statistical report: box plots, no figure per run
    names = {p.name for p in (out / "tiny").iterdir()}
    assert {"stats_position.png", "stats_velocity.png", "stats_attitude.png", "errors_stats.md", "index.html"} <= names
    assert not names & {"att_roll.png", "timeseries.csv", "errors.csv"}
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 50 and np.allclose(summary["max_att_deg"].to_numpy(),
                                              runs.sort_values(["seed", "method"], key=lambda c: c if c.name == "seed"
                                                               else c.map({"quat2": 0, "dcm000": 1}))["max_att_deg"])


def test_figures_all_draws_every_run(stats_batch):
    d, batch = stats_batch
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(d / "all"), "-q", "--jobs", "1", "--figures", "all"])
    assert r.exit_code == 0, r.output
    errors = pd.read_csv(d / "all" / "tiny" / "errors.csv")
    assert len(errors.columns) == 2 + 50 and (d / "all" / "tiny" / "att_roll.png").exists()
    ts = pd.read_csv(d / "all" / "tiny" / "timeseries.csv")
    assert "quat2#s24.att_angle_deg" in ts.columns
    # the statistics do not depend on the figures
    a = pd.read_csv(d / "all" / "tiny" / "errors_stats.csv")
    b = pd.read_csv(d / "out" / "tiny" / "errors_stats.csv")
    pd.testing.assert_frame_equal(a, b)


def test_per_run_batch_parquet_errors_csv_and_reproduction(tmp_path):
    batch = write_batch(tmp_path / "b", seeds=[1, 4], write_trajectories=True)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "-q", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    errors = pd.read_csv(out / "tiny" / "errors.csv").set_index("quantity")
    runs = pd.read_parquet(out / "results.parquet")
    for _, row in runs.iterrows():
        col = errors[row["label"]]
        for q in ROWS:
            assert row[q] == col[q], (row["label"], q)           # exact: both are the same float
    # seed 4 again, outside the batch: the simulator's data and the kept trajectory give the same column
    subprocess.run([SINS, "simulate", str(tmp_path / "b" / "tiny.yaml"), "--seed", "4", "-o", str(tmp_path / "s4"),
                    "-q"], check=True, timeout=300)
    nav = out / "jobs" / "tiny" / "dcm000" / "seed4.nav.csv"
    assert nav.exists()
    subprocess.run([SINS, "compare", "--truth", str(tmp_path / "s4" / "truth.csv"), str(nav), "--label", "x",
                    "-o", str(tmp_path / "single"), "-q"], check=True, timeout=300, cwd=tmp_path)
    single = pd.read_csv(tmp_path / "single" / "errors.csv").set_index("quantity")
    np.testing.assert_allclose(single["x"].to_numpy(), errors["dcm000#s4"].to_numpy(), rtol=1e-12, atol=1e-15)


@pytest.mark.slow
def test_monte_carlo_of_200_runs_in_bounded_memory(tmp_path):
    """The small version of the 10,000-run benchmark (benchmarks/bench_batch.py memory)."""
    scen = {"name": "mc_rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 0.0},
            "imu": {"rate": 50, "sensor": {"gyro": {"bias_sigma": 0.01, "arw": 0.001},
                                           "accel": {"bias_sigma": 50, "vrw": 10}}},
            "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 30}],
            "align": {"method": "inertial"}, "monte_carlo": {"roll_window": 5, "methods": ["static"]}}
    (tmp_path / "mc.yaml").write_text(yaml.safe_dump(scen))
    # the issue's bound is on the client (the process that gathers the results); the workers' peaks are
    # printed (on a cold numba cache each compiles the kernels once, whatever the number of runs)
    with open(tmp_path / "stderr.txt", "w") as fh:
        client, workers = _peak_rss(p := subprocess.Popen(
            [SINS, "align", "--monte-carlo", "200", "--scenario", "mc.yaml", "-o", "out", "-q", "--jobs", "2"],
            cwd=tmp_path, stderr=fh, text=True))
    assert p.wait() == 0, (tmp_path / "stderr.txt").read_text()
    print(f"200-run Monte Carlo: client peak {client / 2**20:.0f} MiB, workers {[round(w / 2**20) for w in workers]} MiB")
    assert 0 < client < 1 << 30, (client, workers)
    out = tmp_path / "out"
    runs = pd.read_parquet(out / "results.parquet")
    assert len(runs) == 200 * 3 and (runs["status"] == "ok").all()
    per_seed = pd.read_csv(out / "runs.csv")
    assert len(per_seed) == 200
    summary = pd.read_csv(out / "summary.csv").set_index(["variant", "attitude", "angle"])
    for v in ("inertial", "static"):
        x = per_seed[f"{v}:heading"]
        assert summary.loc[(v, "current", "heading"), "std_deg"] == pytest.approx(x.std(ddof=1), rel=1e-12)
        y = runs[runs["method"] == v]["current_heading"]
        assert np.array_equal(np.sort(y.to_numpy()), np.sort(x.to_numpy()))
    assert (out / "mc_heading.png").exists() and (out / "mc_stats.png").exists()
    assert len(list((out / "jobs").rglob("*.npz"))) == 200


def _peak_rss(p) -> tuple[int, list[int]]:
    """Peak resident memory (bytes, /proc VmHWM) of process ``p`` and of each of its descendants, polled
    until ``p`` ends."""
    import time

    import psutil

    def hwm(pid):
        try:
            with open(f"/proc/{pid}/status") as fh:
                return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmHWM:"))
        except (OSError, StopIteration):
            return 0

    top, peaks = psutil.Process(p.pid), {}
    while p.poll() is None:
        try:
            kids = top.children(recursive=True)
        except psutil.NoSuchProcess:
            kids = []
        peaks[p.pid] = max(peaks.get(p.pid, 0), hwm(p.pid))
        for k in kids:
            peaks[k.pid] = max(peaks.get(k.pid, 0), hwm(k.pid))
        time.sleep(0.05)
    client = peaks.pop(p.pid, 0)
    return client, sorted(peaks.values(), reverse=True)
