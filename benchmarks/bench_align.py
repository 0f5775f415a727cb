"""Alignment speed: 1 h at 200 Hz (720,000 samples) at rest through each method.

Prints ``METHOD samples_per_s=<float> ratio=<float>``: the ratio is to a baseline run in the same
process, the navigation of the same log (``quat``, coning 2), which does per sample what the
inertial-frame alignment's body side does plus velocity and position.  The kf restarts the navigator
at each 1 s update and runs a 12-state filter, so it is the slowest.  Run:
``python benchmarks/bench_align.py``.
"""
import math

import numpy as np

from bench_navigate import best_of   # same folder: one timing helper for the benchmarks
from sinscli.align.options import AlignOptions, SensorSpec
from sinscli.align.pipeline import align
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.nav.rotation import dcm_to_euler, euler_to_dcm
from sinscli.sim.run import simulate
from sinscli.types import ImuLog, NavState

RATE = 200.0
SECONDS = 3600.0


def make_log():
    sc = {"name": "rest", "start": {"lat": 30, "lon": 114, "height": 50, "heading": 30},
          "imu": {"rate": RATE, "sensor": {"gyro": {"bias": 0.01, "arw": 0.001}, "accel": {"bias": 50, "vrw": 10}}},
          "segments": [{"type": "rest", "duration": SECONDS}]}
    return simulate(sc, seed=1)


def main():
    r = make_log()
    imu = r.imu
    n = len(imu)
    pos = (math.radians(30), math.radians(114), 50.0)
    init = NavState(imu.t0, pos[0], pos[1], pos[2], np.zeros(3), euler_to_dcm(0.0, 0.0, math.radians(30), 0))
    log = ImuLog(imu.time, imu.dtheta_b, imu.dvel_b, t0=imu.t0)
    navigate(ImuLog(log.time[:1000], log.dtheta_b[:1000], log.dvel_b[:1000], t0=log.t0), init)   # compile
    base = best_of(lambda: navigate(log, init, NavOptions(attitude="quat", coning=2)))
    print(f"baseline navigate samples_per_s={n / base:.4g}")
    spec = SensorSpec(1e-9, 1e-9, 1e-7, 1e-7)
    for method in ("static", "inertial", "kf"):
        opts = AlignOptions(method=method, position=pos, sensor=spec)
        align(ImuLog(log.time[:20000], log.dtheta_b[:20000], log.dvel_b[:20000], t0=log.t0), opts)  # compile
        res = None

        def run():
            nonlocal res
            res = align(log, opts)
        t = best_of(run)
        h = math.degrees(dcm_to_euler(res.state.Cbn, 0)[2])
        print(f"{method} samples_per_s={n / t:.4g} ratio={base / t:.3g} (heading {h:.4f} deg)")


if __name__ == "__main__":
    main()
