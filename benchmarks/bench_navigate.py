"""Navigation speed: 720,000 samples (1 h at 200 Hz) through each attitude method.

Prints ``METHOD samples_per_s=<float>`` and the ratio to a baseline run in the
same process: the same kernel with attitude ``quat`` and coning order 1 is
the reference of the methods; the plain-numpy cumulative sum of the
increments shows the memory-bound floor.  Run: ``python benchmarks/bench_navigate.py``.
"""
import math
import sys
import time

import numpy as np

from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.types import ImuLog, NavState

N = 720_000
RATE = 200.0


def make_log(n=N):
    rng = np.random.default_rng(0)
    t = np.arange(1, n + 1) / RATE
    dth = 1e-3 * np.column_stack([np.sin(0.3 * t), np.cos(0.2 * t), 0.1 * np.ones(n)]) / RATE * 50
    dv = np.column_stack([0.1 * rng.standard_normal(n), 0.1 * rng.standard_normal(n), 9.8 * np.ones(n)]) / RATE
    return ImuLog(t, dth, dv)


def best_of(fn, repeat=3):
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    imu = make_log()
    init = NavState(0.0, math.radians(30), math.radians(114), 10.0, np.zeros(3), np.eye(3))
    small = ImuLog(imu.time[:1000], imu.dtheta_b[:1000], imu.dvel_b[:1000])
    methods = [("quat", dict(attitude="quat")), ("dcm", dict(attitude="dcm")),
               ("dcm-seed000", dict(attitude="dcm", dcm_variant="seed000")),
               ("krylov", dict(attitude="krylov")), ("euler3-rk4", dict(attitude="euler"))]
    for _, kw in methods:                      # JIT warm-up
        navigate(small, init, NavOptions(**kw))
    navigate(small, init, NavOptions(attitude="quat", coning=1))
    base_np = best_of(lambda: (np.cumsum(imu.dtheta_b, axis=0), np.cumsum(imu.dvel_b, axis=0)))
    base = best_of(lambda: navigate(imu, init, NavOptions(attitude="quat", coning=1)))
    print(f"baseline numpy-cumsum samples_per_s={N / base_np:.0f}")
    print(f"baseline quat-coning1 samples_per_s={N / base:.0f}")
    for name, kw in methods:
        el = best_of(lambda: navigate(imu, init, NavOptions(**kw)))
        print(f"{name} samples_per_s={N / el:.0f} ratio_to_quat_coning1={base / el:.3f}")
        if name == "quat":
            quat_el = el
        if name == "krylov":
            print(f"krylov per-step cost / quat = {el / quat_el:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
