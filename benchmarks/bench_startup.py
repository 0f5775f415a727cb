"""Start-up time of the command line: ``sins --help`` and ``sins CMD --help`` against ``python -c pass``.

hyperfine-like: each command runs 2 times to warm the file cache, then ``RUNS`` times; prints the
minimum and the median wall time (s) and the median's ratio to the baseline ``python -c pass``
measured in the same process (robust on a loaded machine).  The issue 14 target is
``sins --help`` <= 0.3 s.  Run: ``python benchmarks/bench_startup.py [RUNS]``.
"""
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

RUNS = 15


def _sins():
    exe = Path(sys.executable).parent / "sins"
    return str(exe) if exe.exists() else shutil.which("sins")


def measure(argv, runs):
    for _ in range(2):
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times)


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else RUNS
    sins = _sins()
    cases = [("python -c pass (baseline)", [sys.executable, "-c", "pass"]),
             ("sins --help", [sins, "--help"])]
    cases += [(f"sins {c} --help", [sins, c, "--help"])
              for c in ("navigate", "simulate", "compare", "align", "info", "convert")]
    base = None
    for label, argv in cases:
        tmin, tmed = measure(argv, runs)
        base = base or tmed
        print(f"{label:28s} min_s={tmin:.3f} median_s={tmed:.3f} ratio_to_python={tmed / base:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
