"""End to end: ``sins navigate`` on an increment CSV against the kernel it runs, and the CSV writer.

Builds a 720,000-row increment CSV (``sample_data/imu.csv``, the vehicle drive, repeated on a uniform
100 Hz grid) and prints, all in one process (ratios are robust to the machine's load):

- ``kernel``: :func:`sinscli.nav.pipeline.navigate` on the same samples in memory (quat, 2-sample
  coning), samples/s: the speed of the kernels;
- ``writer``: the trajectory's 26 columns through :class:`sinscli.io.csvcore.CsvTableWriter` with one
  thread (the formatting alone, as before issue 14) and with the default threads overlapped;
- ``sins navigate`` (the installed console script, warm numba cache, best of ``--repeat``) to a full
  CSV and to Parquet, and on a 1,000-row log (the fixed cost: start-up, imports, kernel loading), with
  the wall time, the peak memory of the child, and the ratio of its time to the kernel's;
- the CSV it wrote read back and compared bit for bit with the in-memory trajectory.

``--baseline DIR`` runs ``sins navigate`` also from another source tree (e.g. ``git archive`` of main
unpacked in DIR; its own numba cache), interleaved with this one, and prints the ratio of the times.
``--big N`` adds the N-sample run (issue 14: 10,000,000 samples <= 30 s at <= 1 GB peak), to CSV.

    python benchmarks/bench_end_to_end.py [--rows 720000] [--repeat 3] [--baseline DIR] [--big 10000000] [--dir DIR]
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from sinscli.io import csvcore
from sinscli.io.atomic import atomic_path
from sinscli.io.imu_csv import read_imu_csv
from sinscli.io.init_state import read_init
from sinscli.io.trajectory import BASE_COLUMNS, DCM_COLUMNS, trajectory_columns
from sinscli.nav.pipeline import NavOptions, navigate

ROOT = Path(__file__).resolve().parent.parent
SINS = Path(sys.executable).with_name("sins")
INIT = ROOT / "sample_data" / "init.yaml"


def write_increment_csv(path: Path, n: int) -> None:
    """The vehicle drive of ``sample_data/imu.csv`` repeated to ``n`` rows on its own time grid."""
    drive = read_imu_csv(ROOT / "sample_data" / "imu.csv")
    dt = float(np.median(np.diff(drive.time)))
    names = ["dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z"]
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    step = 1_000_000
    with open(path, "wb") as fh:
        fh.write(("time," + ",".join(names) + "\n").encode())
        for a in range(0, n, step):
            k = np.arange(a, min(a + step, n))
            j = k % len(drive.time)
            cols = {"time": (k + 1) * dt}              # in the header's order (the columns were interleaved
            for i in range(3):                          # before issue 21: dvel under dtheta names)
                cols[names[i]] = drive.dtheta_b[j, i]
            for i in range(3):
                cols[names[3 + i]] = drive.dvel_b[j, i]
            pacsv.write_csv(pa.table(cols), fh, write_options=opts)


_WRAPPER = ("import resource, subprocess, sys, time\n"
            "t0 = time.perf_counter()\n"
            "r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)\n"
            "wall = time.perf_counter() - t0\n"
            "sys.stderr.write(r.stderr.decode())\n"
            "ru = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
            "print(r.returncode, wall, ru.ru_maxrss, ru.ru_utime + ru.ru_stime)\n")

LAST_CPU = [0.0]        # CPU seconds (user + system) of the last run_cli


def run_cli(args: list[str], cwd: Path, source: Path | None = None) -> tuple[float, float]:
    """(wall s, peak memory GB) of one ``sins`` run, started from a small wrapper process: a child forked
    from this (large) process would count this process's memory in its peak.  ``source``: run the
    ``sinscli`` of that source tree instead of the installed one (``python -S``, so that no editable
    install shadows it).  Its CPU time goes to ``LAST_CPU[0]``."""
    env = None
    cmd = [str(SINS)]
    if source is not None:
        import site
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(source), *site.getsitepackages()]))
        cmd = [sys.executable, "-S", "-c", "from sinscli.cli.base import main; main()"]
    r = subprocess.run([sys.executable, "-c", _WRAPPER, *cmd, *args], cwd=cwd, capture_output=True,
                       text=True, check=True, env=env)
    code, wall, rss_kb, cpu = r.stdout.split()
    if int(code):
        raise SystemExit(f"sins {' '.join(args)} failed ({code}): {r.stderr}")
    LAST_CPU[0] = float(cpu)
    return float(wall), int(rss_kb) / 1024 ** 2


def best(fn, repeat):
    out = [fn() for _ in range(repeat)]
    return min(out, key=lambda r: r[0] if isinstance(r, tuple) else r)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=720_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big", type=int, default=0, help="also the N-sample run to CSV (e.g. 10000000)")
    ap.add_argument("--dir", type=Path, default=None)
    ap.add_argument("--baseline", type=Path, default=None, help="source tree to compare with (its sinscli/)")
    ap.add_argument("--no-fusion", action="store_true", help="skip the whole-process fused figures")
    ap.add_argument("--only-fusion", action="store_true", help="only the whole-process fused figures")
    a = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="sins-e2e-", dir=a.dir))
    try:
        return _bench(a, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _bench(a, work: Path) -> int:
    if not a.no_fusion:
        _fusion(a, work)
    if a.only_fusion:
        return 0
    n = a.rows
    imu_path, small_path = work / "imu.csv", work / "imu_small.csv"
    write_increment_csv(imu_path, n)
    write_increment_csv(small_path, 1000)
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; "
          f"writer threads {csvcore.writer_threads()}")

    imu = read_imu_csv(imu_path)
    init = read_init(INIT, imu.t0, 0)
    navigate(read_imu_csv(small_path), init, NavOptions())            # JIT warm-up
    kern = best(lambda: _timed(lambda: navigate(imu, init, NavOptions())), a.repeat)
    traj = navigate(imu, init, NavOptions())
    print(f"kernel (navigate in memory, quat coning 2): {kern:.3f} s, samples_per_s={n / kern:.0f}")

    cols = trajectory_columns(traj, 0)
    names = BASE_COLUMNS + DCM_COLUMNS
    w1 = best(lambda: _timed(lambda: _write(work / "w1.csv", cols, names, 1)), a.repeat)
    wn = best(lambda: _timed(lambda: _write(work / "wn.csv", cols, names, None)), a.repeat)
    floats = len(traj) * len(names)
    print(f"writer: {floats / 1e6:.1f} M floats; 1 thread {w1:.3f} s ({floats / w1 / 1e6:.1f} M floats/s), "
          f"{csvcore.writer_threads()} threads {wn:.3f} s; speed-up {w1 / wn:.2f}")

    run_cli(["navigate", str(small_path), "--init", str(INIT), "-q", "-o", "warm.csv"], work)   # warm cache
    fixed_cpu = []

    def _fixed():
        r = run_cli(["navigate", str(small_path), "--init", str(INIT), "-q", "-o", "s.csv"], work)
        fixed_cpu.append(LAST_CPU[0])
        return r
    fixed = best(_fixed, a.repeat)
    print(f"sins navigate, 1,000 rows (fixed cost): {fixed[0]:.2f} s wall, {min(fixed_cpu):.2f} s CPU "
          f"(target <= 0.4 s), peak {fixed[1]:.2f} GB")
    for suffix, target in ((".csv", 1.5), (".parquet", 1.0)):
        cpus = []

        def _one():
            r = run_cli(["navigate", str(imu_path), "--init", str(INIT), "-q", "-o", f"out{suffix}"], work)
            cpus.append(LAST_CPU[0])
            return r
        wall, peak = best(_one, a.repeat)
        print(f"sins navigate {n:,} rows -> {suffix}: {wall:.2f} s wall, {min(cpus):.2f} s CPU (target <= {target} s "
              f"wall idle), "
              f"peak {peak:.2f} GB, samples_per_s={n / wall:.0f}, time / kernel = {wall / kern:.2f}, "
              f"(time - fixed cost) / kernel = {(wall - fixed[0]) / kern:.2f}")
    if a.baseline is not None:
        src = a.baseline.resolve()
        nav = ["navigate", str(imu_path), "--init", str(INIT), "-q", "-o"]
        run_cli(nav + ["b.csv"], work, src)                           # its numba cache warm
        for suffix in (".csv", ".parquet"):
            this, base = [], []
            for _ in range(a.repeat):                                  # interleaved: the load changes
                this.append(run_cli(nav + [f"n{suffix}"], work)[0])
                base.append(run_cli(nav + [f"b{suffix}"], work, src)[0])
            print(f"sins navigate {n:,} rows -> {suffix}: this tree {min(this):.2f} s, baseline {src} "
                  f"{min(base):.2f} s; baseline / this = {min(base) / min(this):.2f}")
    back = csvcore.read_numeric_columns(work / "out.csv", {c: c for c in names})
    same = all(np.array_equal(back[c].view(np.int64), np.asarray(cols[c], dtype=float).view(np.int64))
               for c in names)
    print(f"CSV read back bit for bit equal to the in-memory trajectory: {same}")
    if not same:
        return 1
    if a.big:
        big = work / "imu_big.csv"
        write_increment_csv(big, a.big)
        for f in work.glob("*.csv"):
            if f != big:
                f.unlink()
        wall, peak = run_cli(["navigate", str(big), "--init", str(INIT), "-q", "-o", "big.csv"], work)
        size = (work / "big.csv").stat().st_size / 1e9
        print(f"sins navigate {a.big:,} rows -> .csv ({size:.1f} GB): {wall:.1f} s (target <= 30 s), "
              f"peak {peak:.2f} GB (target <= 1 GB), samples_per_s={a.big / wall:.0f}, "
              f"time / kernel rate = {wall / (kern * a.big / n):.2f}")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    return 0


FUSION_CONFIG = "fusion:\n  sensor: tactical\n  lever_arm: [0.8, 0.0, 1.5]\n"


def _cpu_best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def _fusion(a, work: Path) -> None:
    """Issue 21: the whole process per IMU sample (CPU of ``sins navigate``, writing every IMU epoch with the
    1-sigma columns) for plain, fused and fused + smoothed navigation of the tactical RTK drive (200 Hz IMU,
    10 Hz GNSS, 240,000 samples), beside the kernels alone on the same log in this process, and the ratio."""
    from sinscli.fusion.options import build_fusion_options
    from sinscli.fusion.pipeline import run_fusion
    from sinscli.io.gnss_csv import read_gnss_csv
    d = work / "tactical"
    subprocess.run([str(SINS), "simulate", str(ROOT / "configs/scenarios/tactical_rtk_drive.yaml"), "-o", str(d), "-q"],
                   check=True)
    (work / "fusion.yaml").write_text(FUSION_CONFIG)
    imu = read_imu_csv(d / "imu.csv")
    gnss = read_gnss_csv(d / "gnss.csv")
    init = read_init(d / "init.yaml", imu.t0, 0)
    fo = build_fusion_options({"sensor": "tactical", "lever_arm": [0.8, 0.0, 1.5]}, "bench")
    n = len(imu)
    from sinscli.types import ImuLog
    small = ImuLog(imu.time[:4000], imu.dtheta_b[:4000], imu.dvel_b[:4000], t0=imu.t0)
    run_fusion(small, init, gnss, fo, smooth=True)                   # kernels loaded
    navigate(small, init, NavOptions())
    kernel = {"plain": _cpu_best(lambda: navigate(imu, init, NavOptions()), a.repeat),
              "fused": _cpu_best(lambda: run_fusion(imu, init, gnss, fo), a.repeat),
              "fused + smoothed": _cpu_best(lambda: run_fusion(imu, init, gnss, fo, smooth=True), a.repeat)}
    base = ["navigate", str(d / "imu.csv"), "--init", str(d / "init.yaml"), "-q"]
    fused = base + ["--gnss", str(d / "gnss.csv"), "--config", str(work / "fusion.yaml")]
    runs = {"plain": base + ["-o", "plain.csv"], "fused": fused + ["-o", "fused.csv"],
            "fused + smoothed": fused + ["--smooth", "-o", "smoothed.csv"]}
    print(f"whole process per IMU sample (tactical drive, {n:,} samples at 200 Hz, 10 Hz GNSS; every epoch written "
          f"with its 1-sigma columns; CPU time, best of {a.repeat}; load {os.getloadavg()[0]:.1f}):")
    for name, args in runs.items():
        run_cli(args, work)                                           # warm
        cpu = wall = float("inf")
        for _ in range(a.repeat):
            w, _ = run_cli(args, work)
            cpu, wall = min(cpu, LAST_CPU[0]), min(wall, w)
        k = kernel[name]
        print(f"  {name:17s} whole {cpu / n * 1e6:6.2f} us/sample CPU ({wall:.2f} s wall)   kernel alone "
              f"{k / n * 1e6:6.2f} us/sample   whole / kernel {cpu / k:5.2f}")
    print(f"  (targets: fused + smoothed whole process <= 4 us/sample CPU idle; load {os.getloadavg()[0]:.1f})")


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _write(path, cols, names, threads):
    with atomic_path(path) as tmp:
        with csvcore.CsvTableWriter(tmp, names, threads=threads) as w:
            step = 1 << 17
            n = len(cols["time"])
            for s in range(0, n, step):
                w.write({c: cols[c][s:s + step] for c in names})
            w.close()


if __name__ == "__main__":
    sys.exit(main())
