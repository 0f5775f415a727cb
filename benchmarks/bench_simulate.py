"""Speed of the exact-truth simulator: IMU samples per second, against a static baseline.

Run: ``python benchmarks/bench_simulate.py [SECONDS]``.  Prints samples/s of a
drive (turns, climbs, speed changes) and of the full-attitude aircraft motion,
and their ratio to a static run of the same length in the same process (the
static run has the least motion per node, so the ratio isolates the cost of
the motion model).
"""
import sys
import time

from sinscli.sim import motions


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


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 600.0)
