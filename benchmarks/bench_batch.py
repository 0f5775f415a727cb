"""Batches on the execution back ends (issue 12): scaling, scheduling overhead, client memory.

    python benchmarks/bench_batch.py              # all three (about 5 minutes on 2 idle cores)
    python benchmarks/bench_batch.py scaling [dask-local|pool]   # 40 CPU-bound jobs on 1 and 2 workers
    python benchmarks/bench_batch.py overhead     # 1,000 tiny jobs
    python benchmarks/bench_batch.py memory [N]   # an N-run (default 10,000) alignment Monte Carlo

Prints one line per measurement, ``name key=value ...``; ratios are between runs in the same process.

- **scaling**: 40 jobs (seeds) of a 240 s simulated drive, each simulated and navigated on its worker
  (about 1 s of CPU), on 1 then 2 workers, for the Dask LocalCluster and the local pool.  ``ratio`` is
  the 2-worker throughput over the 1-worker one, ``ratio_total`` with the start of the workers and
  the report included, ``ratio_steady`` from each worker's first result to the last (start-up apart).
- **overhead**: 1,000 jobs of a 0.5 s drive (a few ms each) on 2 workers.  ``per_job_ms`` =
  (workers x wall - sum of the jobs' own time on their workers) / jobs: the time a job costs a worker
  beyond its own work (scheduling, transfer, the client writing its result), from the first result to
  the last; ``per_job_total_ms`` the same with start-up and report.
- **memory**: ``sins align --monte-carlo N`` (30 s at rest, 50 Hz, one variant) on a LocalCluster of
  2 workers, in a child process whose own peak RSS (the client's; the workers are other processes) is
  printed with the rows of ``results.parquet``.
"""
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

DRIVE = {"name": "drive", "start": {"lat": 34.0, "lon": 108.0, "height": 500.0, "heading": 30.0, "speed": 20.0},
         "imu": {"rate": 100, "sensor": "mems"}, "gnss": {"rate": 1},
         "segments": [{"type": "turn", "duration": 240.0, "rate": 2.0}]}
REST = {"name": "mc_rest", "start": {"lat": 30.0, "lon": 114.0, "height": 50.0, "heading": 0.0},
        "imu": {"rate": 50, "sensor": {"gyro": {"bias_sigma": 0.01, "arw": 0.001},
                                       "accel": {"bias_sigma": 50, "vrw": 10}}},
        "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 30}],
        "align": {"method": "inertial"}, "monte_carlo": {"roll_window": None, "methods": []}}


def load() -> str:
    return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def _spin(n: int) -> float:
    t = time.perf_counter()
    s = 0
    for i in range(n):
        s += i
    return time.perf_counter() - t


def machine_parallelism(n: int = 10_000_000) -> float:
    """What the machine gives right now: the throughput of 2 processes running a pure-Python loop over
    that of 1 (2.0 on 2 idle cores; other jobs on a shared machine lower it).  The batch ratios are
    to be read against it."""
    import multiprocessing as mp
    one = _spin(n)
    with mp.get_context("spawn").Pool(2) as pool:
        pool.map(_spin, [1000, 1000])
        t = time.perf_counter()
        pool.map(_spin, [n, n])
        two = time.perf_counter() - t
    return 2.0 * one / two


def batch_file(d: Path, seeds: int, duration: float) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "drive.yaml").write_text(yaml.safe_dump(dict(DRIVE, segments=[dict(DRIVE["segments"][0],
                                                                             duration=duration)])))
    (d / "batch.yaml").write_text(yaml.safe_dump({"datasets": [{"scenario": "drive.yaml"}], "seeds": seeds,
                                                  "methods": [{"name": "quat2", "attitude": "quat", "coning": 2}]}))
    return d / "batch.yaml"


def timed_batch(batch: Path, out: Path, **backend):
    """Run a batch; returns (total wall, times of each job result, the jobs' own worker seconds)."""
    import pandas as pd

    from sinscli.batch.compare import load_batch, run_batch
    stamps = []
    t0 = time.perf_counter()
    res = run_batch(load_batch(batch), out, on_progress=lambda n: stamps.append(time.perf_counter()), **backend)
    total = time.perf_counter() - t0
    assert not res.failed, res.failed[:1]
    n = len(res.jobs)
    job_stamps = stamps[:n]                      # then one per report and the summary
    own = pd.read_csv(out / "timing.csv")["worker_seconds"].to_numpy()
    return total, [t - t0 for t in job_stamps], own


def scaling(tmp: Path, only: str | None = None) -> None:
    batch = batch_file(tmp / "scaling", seeds=40, duration=240.0)
    print(f"scaling machine_parallelism={machine_parallelism():.2f} (2 spinning processes / 1; {load()})",
          flush=True)
    from sinscli.batch.exec import PoolBackend
    # (--jobs 1 runs in this process: a pool of one process is the fair baseline of a pool of two)
    for kind, one, two in (("dask-local", {"scheduler": "local:1"}, {"scheduler": "local:2"}),
                           ("pool", {"backend": lambda: PoolBackend(1)}, {"backend": lambda: PoolBackend(2)})):
        if only and kind != only:
            continue
        res = {}
        for w, opts in ((1, one), (2, two)):
            total, stamps, own = timed_batch(batch, tmp / f"scaling-{kind}-{w}", **opts)
            steady = (len(stamps) - w) / (stamps[-1] - stamps[w - 1])
            res[w] = (len(stamps) / total, steady, own.mean())
            print(f"scaling {kind} workers={w} jobs={len(stamps)} wall_s={total:.2f} jobs_per_s={res[w][0]:.3f} "
                  f"steady_jobs_per_s={steady:.3f} job_cpu_s={own.mean():.3f}", flush=True)
        print(f"scaling {kind} ratio_total={res[2][0] / res[1][0]:.3f} ratio_steady={res[2][1] / res[1][1]:.3f} "
              f"(target >= 1.7; machine_parallelism={machine_parallelism():.2f}; {load()})", flush=True)


def overhead(tmp: Path) -> None:
    batch = batch_file(tmp / "overhead", seeds=1000, duration=0.5)
    for kind, opts, w in (("dask-local", {"scheduler": "local:2"}, 2), ("pool", {"jobs": 2}, 2)):
        total, stamps, own = timed_batch(batch, tmp / f"overhead-{kind}", **opts)
        n = len(stamps)
        span = stamps[-1] - stamps[w - 1]
        steady = (w * span - own[w:].sum()) / (n - w)
        whole = (w * total - own.sum()) / n
        print(f"overhead {kind} workers={w} jobs={n} wall_s={total:.2f} job_own_ms={1e3 * own.mean():.2f} "
              f"per_job_ms={1e3 * steady:.2f} per_job_total_ms={1e3 * whole:.2f} (target <= 50 ms; {load()})",
              flush=True)


def memory(tmp: Path, runs: int) -> None:
    (tmp / "mc.yaml").write_text(yaml.safe_dump(REST))
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, __file__, "memory-child", str(tmp / "mc.yaml"), str(tmp / "mc"), str(runs)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    print(out.stdout.strip(), f"wall_s={time.perf_counter() - t0:.1f} ({load()})", flush=True)


def memory_child(scenario: str, outdir: str, runs: int) -> None:
    import pandas as pd

    from sinscli.batch.mc_study import run_mc_study
    study = run_mc_study(scenario, outdir, runs, scheduler="local:2")
    rows = len(pd.read_parquet(Path(outdir) / "results.parquet"))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0          # KiB on Linux
    print(f"memory runs={study.mc.runs} failed={len(study.failed)} parquet_rows={rows} client_peak_MiB={peak:.0f} "
          f"(target <= 1024)")


def main(argv):
    what = argv[0] if argv else "all"
    if what == "memory-child":
        memory_child(argv[1], argv[2], int(argv[3]))
        return
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print(f"# {os.cpu_count()} cores, {load()}", flush=True)
        if what in ("scaling", "all"):
            scaling(tmp, argv[1] if what == "scaling" and len(argv) > 1 else None)
        if what in ("overhead", "all"):
            overhead(tmp)
        if what in ("memory", "all"):
            memory(tmp, int(argv[1]) if len(argv) > 1 else 10000)


if __name__ == "__main__":
    main(sys.argv[1:])
