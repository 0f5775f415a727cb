"""Navigation speed: 720,000 samples (1 h at 200 Hz) through each attitude method.

Prints ``METHOD samples_per_s=<float>`` and the ratio to a baseline run in the
same process: the same kernel with attitude ``quat`` and coning order 1 is
the reference of the methods; the plain-numpy cumulative sum of the
increments shows the memory-bound floor.  Then the per-sample cost of
``krylov`` against ``quat`` on real motions: the vehicle drive
(``sample_data/imu.csv`` repeated to 720,000 samples; no RK4 sub-steps, issue 14
target <= 1.5) and the 2 rev/s spin boost (``configs/scenarios/spin_boost.yaml``,
its first 32 s simulated error-free, repeated), with the sub-steps the Krylov update took.
Run: ``python benchmarks/bench_navigate.py``.
"""
import math
import sys
import time

from pathlib import Path

import numpy as np

from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.types import ImuLog, NavState

N = 720_000
RATE = 200.0
ROOT = Path(__file__).resolve().parent.parent


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
    krylov_on_motions()
    return 0


def _repeat(imu, n=N):
    """``imu`` repeated to ``n`` samples on a uniform time grid (a cost test, not a trajectory)."""
    reps = -(-n // len(imu))
    dt = float(np.median(np.diff(imu.time)))
    t0 = imu.t0 if imu.t0 is not None else float(imu.time[0]) - dt
    return ImuLog(t0 + dt * np.arange(1, n + 1), np.tile(imu.dtheta_b, (reps, 1))[:n],
                  np.tile(imu.dvel_b, (reps, 1))[:n], t0=t0)


def krylov_on_motions():
    """krylov / quat per-sample cost on the vehicle drive and on the 2 rev/s spin boost (same process)."""
    from sinscli.io.imu_csv import read_imu_csv
    from sinscli.io.init_state import read_init
    from sinscli.nav.krylov import SUBSTEP_ANGLE, substep_counts
    from sinscli.sim import simulate

    drive = read_imu_csv(ROOT / "sample_data" / "imu.csv")
    init_drive = read_init(ROOT / "sample_data" / "init.yaml", drive.t0, 0)
    spin = simulate(ROOT / "configs" / "scenarios" / "spin_boost.yaml", perfect=True, duration=32.0)
    for label, imu, init in (("vehicle drive (sample_data, repeated)", drive, init_drive),
                             ("spin boost 2 rev/s (repeated)", spin.imu, spin.init)):
        log = _repeat(imu)
        m = substep_counts(log.dtheta_b, SUBSTEP_ANGLE)
        for att in ("quat", "krylov"):
            navigate(ImuLog(log.time[:1000], log.dtheta_b[:1000], log.dvel_b[:1000], t0=log.t0), init,
                     NavOptions(attitude=att))
        el = {}
        for _ in range(2):                      # interleaved, best of 2 x 2: load changes between runs
            for att in ("quat", "krylov"):
                el[att] = min(el.get(att, math.inf), best_of(lambda: navigate(log, init, NavOptions(attitude=att)),
                                                             repeat=2))
        print(f"{label}: quat samples_per_s={N / el['quat']:.0f} krylov samples_per_s={N / el['krylov']:.0f} "
              f"krylov per-sample cost / quat = {el['krylov'] / el['quat']:.2f} "
              f"(RK4 sub-steps per interval: max {m.max()}, mean {m.mean():.3f})")


if __name__ == "__main__":
    sys.exit(main())
