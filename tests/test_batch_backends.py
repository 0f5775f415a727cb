"""Execution back ends of batches: the local pool, a Dask LocalCluster (``--scheduler local:2``) and an
external Dask scheduler with two workers started here on 127.0.0.1 give the same report byte for byte
(timings apart); a worker killed mid-batch costs no job; a job that fails, or a worker that cannot see
an input file, is reported with the path and the host while the other jobs finish; the command-line
errors of ``--scheduler``."""
import builtins
import os
import signal
import time

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError

from batchutil import assert_same_report, start_sins, stop, write_batch
from daskutil import dask_cluster

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::ResourceWarning")


def compare(*args):
    return CliRunner().invoke(main, ["compare", *map(str, args)])


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    with dask_cluster(tmp_path_factory.mktemp("dask")) as (address, workers):
        yield address, workers


@pytest.mark.slow
def test_same_report_on_every_back_end(tmp_path, cluster):
    address, _ = cluster
    batch = write_batch(tmp_path / "b", seeds=3, files=True)
    runs = {"pool": ["--jobs", "2"], "inline": ["--jobs", "1"], "local2": ["--scheduler", "local:2"],
            "tcp": ["--scheduler", address]}
    for name, opts in runs.items():
        r = compare(batch, "-o", tmp_path / name, "-q", *opts)
        assert r.exit_code == 0, (name, r.output)
    for name in runs:
        assert_same_report(tmp_path / "pool", tmp_path / name)
    out = tmp_path / "pool"
    # 3 seeds x 2 methods of the scenario, 1 x 2 of the files dataset
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 8 and (summary["status"] == "ok").all()
    hosts = pd.read_parquet(tmp_path / "tcp" / "results.parquet")["host"]
    assert hosts.str.contains("Dask worker tcp://127.0.0.1:").all()
    assert len(list((out / "jobs").rglob("*.npz"))) == 8
    assert (out / "tiny" / "errors_stats.csv").exists() and (out / "tiny" / "att_roll.png").exists()


def test_monte_carlo_same_on_pool_and_external_scheduler(tmp_path, cluster):
    address, _ = cluster
    scen = {"name": "mc_rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 0.0},
            "imu": {"rate": 50, "sensor": {"gyro": {"bias_sigma": 0.01, "arw": 0.001},
                                           "accel": {"bias_sigma": 50, "vrw": 10}}},
            "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 30}],
            "align": {"method": "inertial"}, "monte_carlo": {"roll_window": 5, "methods": ["static"]}}
    path = tmp_path / "mc.yaml"
    path.write_text(yaml.safe_dump(scen))
    for name, opts in (("pool", ["--jobs", "2"]), ("tcp", ["--scheduler", address])):
        r = CliRunner().invoke(main, ["align", "--monte-carlo", "6", "--scenario", str(path), "-o",
                                      str(tmp_path / name), "-q", *opts])
        assert r.exit_code == 0, r.output
    assert_same_report(tmp_path / "pool", tmp_path / "tcp")
    runs = pd.read_parquet(tmp_path / "tcp" / "results.parquet")
    assert len(runs) == 6 * 3 and set(runs["method"].astype(str)) == {"inertial", "inertial+roll-window", "static"}


def test_a_worker_that_cannot_see_a_file_and_a_failing_job_are_reported(tmp_path, cluster):
    """The batch file is checked at the client; the file then vanishes before the workers read it
    (as on a worker without the shared filesystem): that job's error names the path and the host,
    the scenario jobs still finish and are reported."""
    from sinscli.batch.compare import load_batch, run_batch
    address, _ = cluster
    batch = write_batch(tmp_path / "b", seeds=2, files=True)
    spec = load_batch(batch)
    (tmp_path / "b" / "files" / "imu.csv").unlink()
    errors = []
    res = run_batch(spec, tmp_path / "out", scheduler=address, on_error=errors.append)
    failed = {(j.dataset, j.method): j.error for j in res.failed}
    assert set(failed) == {("files", "quat2"), ("files", "dcm000")}
    msg = failed[("files", "quat2")]
    assert f"{tmp_path / 'b' / 'files' / 'imu.csv'}: not found on host " in msg and "Dask worker tcp://127.0.0.1:" in msg
    assert "shared" not in msg or "filesystem that every worker sees" in msg
    assert any("job files/quat2 failed" in e for e in errors)
    assert set(res.reports) == {"tiny"} and (tmp_path / "out" / "tiny" / "errors.csv").exists()
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert (summary[summary["dataset"] == "tiny"]["status"] == "ok").all()
    assert (summary[summary["dataset"] == "files"]["status"] == "failed").all()
    assert not (tmp_path / "out" / "jobs" / "files").exists()          # --resume would run them again


def _hosts(out) -> dict:
    """Job file -> the worker that ran it."""
    import json
    got = {}
    for f in out.rglob("*.npz"):
        with np.load(f, allow_pickle=False) as z:
            got[f] = json.loads(str(z["meta"]))["host"]
    return got


@pytest.mark.slow
def test_a_worker_killed_mid_batch_costs_no_job(tmp_path):
    """Two ``dask worker`` processes; once both have finished jobs, one is killed (SIGKILL) while the
    batch runs: the scheduler reschedules its tasks and the batch completes with every job, the same
    report as the local pool."""
    batch = write_batch(tmp_path / "b", seeds=40, duration=10.0, methods=METHODS_ONE)
    ref = compare(batch, "-o", tmp_path / "ref", "-q", "--jobs", "2")
    assert ref.exit_code == 0, ref.output
    out = tmp_path / "out"
    with dask_cluster(tmp_path / "dask") as (address, workers):
        p = start_sins(["compare", batch, "-o", out, "-q", "--scheduler", address], tmp_path)
        try:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and len(set(_hosts(out).values())) < 2:
                assert p.poll() is None, p.communicate()
                time.sleep(0.05)
            os.kill(workers[0].pid, signal.SIGKILL)
            before = _hosts(out)
            _, err = p.communicate(timeout=240)
        finally:
            stop(p)
        assert workers[0].wait(10) == -signal.SIGKILL
    assert p.returncode == 0, err
    assert len(set(before.values())) == 2 and len(before) < 40, before
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 40 and (summary["status"] == "ok").all()
    after = {f: h for f, h in _hosts(out).items() if f not in before}
    assert len(before) + len(after) == 40
    assert_same_report(tmp_path / "ref", out)


METHODS_ONE = [{"name": "quat2", "attitude": "quat", "coning": 2}]


def test_scheduler_option_errors(tmp_path, monkeypatch):
    batch = write_batch(tmp_path / "b", seeds=1, methods=METHODS_ONE)
    for args, text in ((["--scheduler", "dask.example"], "expected tcp://HOST:PORT"),
                       (["--scheduler", "local:0"], "local:N with N >= 1"),
                       (["--scheduler", "local:2", "--jobs", "2"], "--jobs and --scheduler: give one")):
        r = compare(batch, "-o", tmp_path / "o", *args)
        assert r.exit_code == 2 and f"sins: error: " in r.output and text in r.output, r.output
        assert not (tmp_path / "o").exists()
    import sinscli.batch.exec as ex
    monkeypatch.setattr(ex, "CONNECT_TIMEOUT_S", 2.0)
    t = time.monotonic()
    r = compare(batch, "-o", tmp_path / "o", "--scheduler", "tcp://127.0.0.1:9")       # nothing listens there
    assert r.exit_code == 2 and "cannot connect to a Dask scheduler there within 2 s" in r.output, r.output
    assert time.monotonic() - t < 30 and not (tmp_path / "o").exists()
    r = CliRunner().invoke(main, ["compare", "--truth", str(batch), str(batch), "-o", str(tmp_path / "o"),
                                  "--scheduler", "local:2"])
    assert r.exit_code == 2 and "--scheduler: only used with a batch file" in r.output


def test_without_dask_the_scheduler_option_says_what_to_install(tmp_path, monkeypatch):
    real_import = builtins.__import__

    def no_dask(name, *args, **kw):
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError(f"No module named '{name}'")
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    batch = write_batch(tmp_path / "b", seeds=1, methods=METHODS_ONE)
    r = compare(batch, "-o", tmp_path / "o", "--scheduler", "local:2")
    assert r.exit_code == 2, r.output
    assert r.output.strip().splitlines()[-1] == ("sins: error: --scheduler needs Dask distributed, which is not "
                                                "installed: install the Dask extra: pip install "
                                                "'sinscli[distributed]' (pip install '.[distributed]' in a checkout)")
    assert not (tmp_path / "o").exists()
    with pytest.raises(SinsError, match="--scheduler needs Dask"):
        from sinscli.batch.exec import open_backend
        open_backend(scheduler="local:1")
    # the local pool needs nothing of Dask
    r = compare(batch, "-o", tmp_path / "o", "-q", "--jobs", "1")
    assert r.exit_code == 0, r.output
    assert np.isfinite(pd.read_csv(tmp_path / "o" / "tiny" / "errors.csv")["quat2"]).all()
