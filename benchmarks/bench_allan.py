"""``sins allan`` speed: a 10-hour 200 Hz static log (7,200,000 samples per axis, six axes).

Prints, for the whole characterization in memory (rest check, overlapping Allan deviation of the six
axes at every cluster time, fit of each axis), ``allan samples_per_s=<float> seconds=<float>`` and the
ratio to a baseline run in the same process: allantools' ``oadev`` (the maintained library) on the same
cluster times, per axis, extrapolated to six axes from ``--baseline-axes`` axes (default 1).  The
target is <= 10 s for the characterization; reading the log comes on top (``docs/allan.md``).
Run: ``python benchmarks/bench_allan.py [--hours 10] [--rate 200]``.
"""
import argparse
import time

import numpy as np

from bench_navigate import best_of   # same folder: one timing helper for the benchmarks
from sinscli.allan.adev import cluster_sizes
from sinscli.allan.pipeline import characterize
from sinscli.types import ImuLog


def make_log(hours: float, rate: float, seed: int = 1) -> ImuLog:
    """Static increments: earth rate and gravity, white noise and a random-walk bias (MEMS-like)."""
    n = int(round(hours * 3600 * rate))
    dt = 1.0 / rate
    rng = np.random.default_rng(seed)
    arw, vrw = 0.3 * np.pi / 180 / 60, 100 * 9.80665e-6
    dth = np.array([5.5e-5, 3.2e-5, 3.6e-5]) * dt + arw * np.sqrt(dt) * rng.standard_normal((n, 3))
    dv = np.array([0.0, 0.0, 9.79]) * dt + vrw * np.sqrt(dt) * rng.standard_normal((n, 3))
    dth += np.cumsum(1e-9 * rng.standard_normal((n, 3)), axis=0) * dt
    return ImuLog(np.arange(1, n + 1) * dt, dth, dv, 0.0, "bench", "increments")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--baseline-axes", type=int, default=1)
    args = ap.parse_args()
    log = make_log(args.hours, args.rate)
    n = len(log)
    characterize(make_log(0.05, args.rate))                          # compile the kernels
    t = best_of(lambda: characterize(log), repeat=1)
    print(f"allan samples_per_s={6 * n / t:.4g} seconds={t:.3f} (n={n} per axis, six axes, "
          f"{len(cluster_sizes(n))} cluster times)")
    try:
        import allantools
    except ImportError:
        print("baseline: allantools not installed (pip install '.[test]'); no ratio")
        return
    taus = cluster_sizes(n) / args.rate
    y = log.dtheta_b[:, 0] * args.rate
    t0 = time.perf_counter()
    for _ in range(args.baseline_axes):
        allantools.oadev(y, rate=args.rate, data_type="freq", taus=taus)
    tb = (time.perf_counter() - t0) / args.baseline_axes * 6
    print(f"allantools.oadev samples_per_s={6 * n / tb:.4g} seconds={tb:.3f} (six axes, Allan deviation only)")
    print(f"ratio={tb / t:.3g} (sins allan whole characterization against allantools' deviations alone)")


if __name__ == "__main__":
    main()
