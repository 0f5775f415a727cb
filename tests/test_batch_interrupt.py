"""Interrupting a batch, and resuming it (issues 11 and 12).

The contract: SIGINT (the terminal's Ctrl-C, sent to the whole process group), SIGTERM and SIGHUP
stop a batch within 2 s, with the local pool and with a Dask LocalCluster; the command says how many
jobs finished, that their results are kept under DIR/jobs/ and that ``--resume`` runs the rest; and it
leaves exactly that: the finished jobs' result files (each complete), no simulated data, no
``.part``, no partial report, no worker process.  ``--resume`` then runs only the missing jobs and
gives the same report as an uninterrupted run.
"""
import os
import signal
import time
from pathlib import Path

import numpy as np
import pandas as pd
import psutil
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.batch.jobs import FINGERPRINT

from batchutil import assert_same_report, start_sins, stop, write_batch

STOP_WITHIN_S = 2.0


def finished_jobs(out: Path) -> list[Path]:
    return sorted((out / "jobs").rglob("*.npz")) if (out / "jobs").exists() else []


def assert_only_finished_jobs(out: Path) -> int:
    """``out`` holds nothing but ``jobs/``: the fingerprint and complete job files."""
    if not out.exists():
        return 0
    assert [p.name for p in out.iterdir()] == ["jobs"], sorted(p.name for p in out.iterdir())
    files = sorted(p for p in (out / "jobs").rglob("*") if p.is_file())
    jobs = finished_jobs(out)
    assert files == sorted(jobs + [out / "jobs" / FINGERPRINT]), [str(f) for f in files]
    for p in jobs:                                       # each one complete
        with np.load(p, allow_pickle=False) as z:
            assert "meta" in z.files and len(z.files) > 1
            for k in z.files[1:]:
                assert np.isfinite(z[k]).all(), (p, k)
    return len(jobs)


def _running(proc: psutil.Process) -> bool:
    """Alive and not a zombie (a dead process whose new parent has not reaped it yet)."""
    try:
        return proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def _signal_cases():
    """Every signal on every back end; the quick run keeps SIGINT to the group on the pool and SIGTERM to the
    process on a local Dask cluster, the rest are marked slow."""
    quick = {("SIGINT-group", "pool"), ("SIGTERM", "local2")}
    for sig, group, sid in ((signal.SIGINT, True, "SIGINT-group"), (signal.SIGTERM, False, "SIGTERM"),
                            (signal.SIGHUP, True, "SIGHUP-group")):
        for backend, bid in ((["--jobs", "2"], "pool"), (["--scheduler", "local:2"], "local2")):
            marks = () if (sid, bid) in quick else (pytest.mark.slow,)
            yield pytest.param(backend, sig, group, id=f"{sid}-{bid}", marks=marks)


@pytest.mark.parametrize("backend, sig, group", list(_signal_cases()))
def test_signal_stops_the_batch_and_leaves_only_finished_jobs(tmp_path, backend, sig, group):
    batch = write_batch(tmp_path / "b", seeds=60, duration=20.0)      # 120 jobs of ~0.1 s
    out = tmp_path / "out"
    p = start_sins(["compare", batch, "-o", out, *backend], tmp_path)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(finished_jobs(out)) < 2:
            assert p.poll() is None, p.communicate()
            time.sleep(0.02)
        workers = psutil.Process(p.pid).children(recursive=True)
        t0 = time.monotonic()
        if group:
            os.killpg(p.pid, sig)                # as the terminal does
        else:
            p.send_signal(sig)                   # kill PID
        _, err = p.communicate(timeout=30)
        took = time.monotonic() - t0
    finally:
        stop(p)
    assert p.returncode == 128 + sig, err
    assert took < STOP_WITHIN_S, f"stopped after {took:.2f} s"
    _, alive = psutil.wait_procs(workers, timeout=1.0)
    assert not [w for w in alive if _running(w)], f"worker processes left: {alive}"
    n = assert_only_finished_jobs(out)
    assert 2 <= n < 120
    last = err.strip().splitlines()[-1]
    assert last == (f"sins: interrupted ({signal.Signals(sig).name}): {n} of 120 jobs had finished; their results "
                    f"are kept in {out / 'jobs'}/ and nothing else was written; rerun the same command with "
                    f"--resume to run the other {120 - n} and write the report"), err
    assert "Traceback" not in err


@pytest.mark.slow
def test_monte_carlo_interrupted_and_resumed(tmp_path):
    """``sins align --monte-carlo`` keeps the same contract: SIGTERM, then --resume, then the same report."""
    scen = {"name": "mc_rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 0.0},
            "imu": {"rate": 50, "sensor": {"gyro": {"bias_sigma": 0.01, "arw": 0.001},
                                           "accel": {"bias_sigma": 50, "vrw": 10}}},
            "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}],
            "align": {"method": "inertial"}, "monte_carlo": {"roll_window": 5}}
    path = tmp_path / "mc.yaml"
    path.write_text(yaml.safe_dump(scen))
    args = ["align", "--monte-carlo", "300", "--scenario", path, "-q"]
    p = start_sins(args + ["-o", tmp_path / "out", "--jobs", "2"], tmp_path)
    try:
        while len(finished_jobs(tmp_path / "out")) < 5:
            assert p.poll() is None, p.communicate()
            time.sleep(0.02)
        t0 = time.monotonic()
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=30)
        took = time.monotonic() - t0
    finally:
        stop(p)
    assert p.returncode == 128 + signal.SIGTERM and took < STOP_WITHIN_S, (took, err)
    n = assert_only_finished_jobs(tmp_path / "out")
    assert f"{n} of 300 jobs had finished" in err and "--resume" in err
    r = CliRunner().invoke(main, [*map(str, args), "-o", str(tmp_path / "out"), "--resume", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, [*map(str, args), "-o", str(tmp_path / "ref"), "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert_same_report(tmp_path / "ref", tmp_path / "out")
    assert len(pd.read_parquet(tmp_path / "out" / "results.parquet")) == 300 * 2


@pytest.mark.slow
def test_interrupted_1000_job_batch_resumes_to_the_same_report(tmp_path):
    """1,000 tiny jobs (1,000 seeds x 1 method, in this process); interrupted after 400 finished,
    the folder holds exactly those; ``--resume`` runs the other 600 and writes the report of an
    uninterrupted run, byte for byte."""
    from sinscli.batch.compare import load_batch, run_batch
    from sinscli.batch.jobs import StudyInterrupted

    batch = write_batch(tmp_path / "b", seeds=1000, duration=0.5,
                        methods=[{"name": "quat2", "attitude": "quat", "coning": 2}])
    spec = load_batch(batch)
    out = tmp_path / "out"
    done = [0]

    def tick(n):
        done[0] += n
        if done[0] >= 400:
            raise KeyboardInterrupt               # as SIGINT would, between two jobs

    with pytest.raises(StudyInterrupted) as info:
        run_batch(spec, out, jobs=1, on_progress=tick)
    assert info.value.finished == 400 and info.value.total == 1000
    assert assert_only_finished_jobs(out) == 400
    before = {p: p.stat().st_mtime_ns for p in finished_jobs(out)}

    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "--resume", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert "1000 jobs (400 resumed from" in r.output and "600 run)" in r.output, r.output
    assert all(p.stat().st_mtime_ns == t for p, t in before.items())      # the 400 were not run again
    assert len(finished_jobs(out)) == 1000

    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(tmp_path / "ref"), "--jobs", "1", "-q"])
    assert r.exit_code == 0, r.output
    assert_same_report(tmp_path / "ref", out)
    # 1000 seeds: the statistical report, never a figure per run
    names = {p.name for p in (out / "tiny").iterdir()}
    assert {"errors_stats.csv", "errors_stats.md", "errors_mc.csv", "stats_position.png", "index.html"} <= names
    assert not names & {"errors.csv", "timeseries.csv", "att_roll.png"}
    assert len(pd.read_parquet(out / "results.parquet")) == 1000


def test_resume_checks_the_jobs_belong_to_the_batch(tmp_path):
    batch = write_batch(tmp_path / "b", seeds=2, methods=[{"name": "quat2", "attitude": "quat", "coning": 2}])
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "--resume", "-q"])
    assert r.exit_code == 2 and "--resume: no finished jobs of an earlier run here" in r.output
    assert not out.exists()
    assert CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "-q", "--jobs", "1"]).exit_code == 0
    (tmp_path / "b" / "tiny.yaml").write_text((tmp_path / "b" / "tiny.yaml").read_text().replace("20.0", "21.0"))
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "--resume", "-q"])
    assert r.exit_code == 2 and "these jobs were run with other inputs or options (differing: scenarios)" in r.output
    # without --resume the earlier jobs are replaced, and the command says so
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "--jobs", "1"])
    assert r.exit_code == 0 and "replaced 2 job results of an earlier run (--resume keeps them)" in r.output


def test_a_killed_run_is_cleaned_by_the_next(tmp_path):
    """SIGKILL cannot be handled: what it leaves (a temporary job file, a staged report) is removed by
    the next run to the same folder, and --resume keeps the finished jobs."""
    batch = write_batch(tmp_path / "b", seeds=2, methods=[{"name": "quat2", "attitude": "quat", "coning": 2}])
    out = tmp_path / "out"
    assert CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "-q", "--jobs", "1"]).exit_code == 0
    (out / "jobs" / "tiny" / "quat2" / "seed1.npz").unlink()
    (out / "jobs" / "tiny" / "quat2" / ".seed1.npz.abc123.part").write_bytes(b"half")
    (out / ".report.xyz.part").mkdir()
    (out / ".report.xyz.part" / "summary.csv").write_text("half")
    r = CliRunner().invoke(main, ["compare", str(batch), "-o", str(out), "-q", "--jobs", "1", "--resume"])
    assert r.exit_code == 0, r.output
    assert not list(out.rglob("*.part")) and len(finished_jobs(out)) == 2
