"""Speed of the exact-truth simulator: IMU samples per second, against a static baseline.

Run: ``python benchmarks/bench_simulate.py [SECONDS]``.  Prints samples/s of a
drive (turns, climbs, speed changes) and of the full-attitude aircraft motion,
and their ratio to a static run of the same length in the same process (the
static run has the least motion per node, so the ratio isolates the cost of
the motion model).  Then the issue-19 scenarios of ``configs/scenarios/`` (consumer car with
engine vibration and rate output, walker with its gait, rover with odometry), whole, each with the
seconds that 30 min at 100 Hz (180,000 samples) take at that speed.
"""
import sys
import time
from pathlib import Path

from sinscli.sim import motions, simulate

SCEN = Path(__file__).resolve().parents[1] / "configs" / "scenarios"


def _rate(fn, duration):
    t = time.perf_counter()
    r = fn(duration=duration, rate=100.0)
    return len(r.imu) / (time.perf_counter() - t)


def main(duration: float = 600.0):
    motions.static(duration=2.0)                       # compile the numba kernels first
    base = _rate(motions.static, duration)
    print(f"static         {base:12.0f} samples/s (baseline)")
    for name in ("drive", "full_attitude", "coning"):
        r = _rate(getattr(motions, name), duration)
        print(f"{name:14s} {r:12.0f} samples/s  ratio to static {r / base:.2f}")
    for name in ("consumer_car", "walker", "rover"):
        path = SCEN / f"{name}.yaml"
        simulate(path, duration=2.0)                   # compile what the scenario adds
        t = time.perf_counter()
        n = len(simulate(path).imu)
        r = n / (time.perf_counter() - t)
        print(f"{name:14s} {r:12.0f} samples/s  ratio to static {r / base:.2f}  (30 min at 100 Hz: "
              f"{180000 / r:.1f} s)")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 600.0)
