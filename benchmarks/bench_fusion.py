"""Fusion speed and memory: the tactical RTK drive (200 Hz IMU, 10 Hz GNSS) forward-filtered, and with
the RTS smoother, against plain navigation of the same increments in the same process.

Prints ``samples_per_s`` and the ratio to plain navigation; ``--hour`` runs one hour (720,000 samples,
36,000 fixes, the drive repeated with its time shifted) with the smoother under tracemalloc and
prints the peak Python-allocated memory.  Run: ``python benchmarks/bench_fusion.py [--hour]``.
"""
import sys
from pathlib import Path
import time
import tracemalloc

import numpy as np

from sinscli.fusion.options import build_fusion_options
from sinscli.fusion.pipeline import run_fusion
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.sim.run import simulate
from sinscli.types import GnssLog, ImuLog

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_navigate import best_of  # noqa: E402


def repeat_log(sim, times):
    """The drive's IMU and GNSS repeated ``times`` times back to back (time shifted)."""
    imu, g = sim.imu, sim.gnss
    T = float(imu.time[-1] - imu.t0)
    t = np.concatenate([imu.time + k * T for k in range(times)])
    gi = g.time[1:]
    sl = slice(1, None)
    gt = np.concatenate([gi + k * T for k in range(times)])
    cat = lambda a: np.concatenate([a[sl]] * times)  # noqa: E731
    return (ImuLog(t, np.tile(imu.dtheta_b, (times, 1)), np.tile(imu.dvel_b, (times, 1)), t0=imu.t0),
            GnssLog(gt, cat(g.lat), cat(g.lon), cat(g.height), cat(g.vel_n), cat(g.std_pos), cat(g.std_vel)))


def main():
    sim = simulate("configs/scenarios/tactical_rtk_drive.yaml")
    fo = build_fusion_options({"sensor": "tactical", "lever_arm": [0.8, 0.0, 1.5]}, "bench")
    imu, gnss, init = sim.imu, sim.gnss, sim.init
    n = len(imu)
    small = ImuLog(imu.time[:4000], imu.dtheta_b[:4000], imu.dvel_b[:4000], t0=imu.t0)
    run_fusion(small, init, gnss, fo)                       # JIT warm-up
    run_fusion(small, init, gnss, fo, smooth=True)
    navigate(small, init, NavOptions())
    base = best_of(lambda: navigate(imu, init, NavOptions()))
    fwd = best_of(lambda: run_fusion(imu, init, gnss, fo))
    smo = best_of(lambda: run_fusion(imu, init, gnss, fo, smooth=True), repeat=2)
    print(f"samples={n} gnss_fixes={len(gnss)} (200 Hz IMU, 10 Hz GNSS)")
    print(f"plain navigation samples_per_s={n / base:.0f}")
    print(f"fused samples_per_s={n / fwd:.0f} ratio_to_navigation={base / fwd:.3f}")
    print(f"fused+smoothed samples_per_s={n / smo:.0f} ratio_to_navigation={base / smo:.3f}")
    if "--hour" in sys.argv:
        imu_h, gnss_h = repeat_log(sim, 3)
        del sim
        tracemalloc.start()
        t0 = time.perf_counter()
        run_fusion(imu_h, init, gnss_h, fo, smooth=True)
        el = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        print(f"one hour: samples={len(imu_h)} fixes={len(gnss_h)} smoothed in {el:.1f} s, "
              f"peak traced memory {peak / 2**30:.2f} GiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
