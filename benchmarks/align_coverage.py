"""Coverage of the alignment 1-sigma, the larger variant of tests/test_align_honest.py.

Runs N seeds (default 200) of simulated logs through every method with the sensor description right,
absent and ten times too optimistic, and prints per method and case the fraction of runs whose error
lies within 3 (and 1) reported 1-sigma, the rms error, the median 1-sigma, the refusals and the wall
time.  Cases: a static base (navigation grade, 120 s; and MEMS with a user heading), a moving MEMS
rover without rest and the issue's low-grade IMU (0.2 deg/s, 0.1 m/s^2) with GNSS.  Run:
``python benchmarks/align_coverage.py [--runs N] [--case NAME]``.
"""
import argparse
import copy
import math
import time

import numpy as np

from sinscli.align.montecarlo import coverage_runs

DRIVE = [{"type": "accelerate", "speed": 12, "duration": 8},
         {"type": "turn", "angle": 90, "duration": 10, "bank": "none"},
         {"type": "cruise", "duration": 5}, {"type": "decelerate", "speed": 8, "duration": 5},
         {"type": "turn", "angle": -60, "duration": 8, "bank": "none"},
         {"type": "accelerate", "speed": 12, "duration": 9}]
GNSS = {"rate": 1, "vel_noise": 0.05, "pos_noise": 1.5, "lever_arm": [0.8, 0.2, 1.5]}
START = {"lat": 30, "lon": 114, "height": 50, "heading": 40, "pitch": 1.0, "roll": -2.0}
CASES = {
    "static-navigation": ({"name": "static", "start": START, "imu": {"rate": 20, "sensor": "navigation"},
                           "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 120}]},
                          ("static", "inertial", "kf"), {"with_gnss": False}),
    "static-mems-user-heading": ({"name": "static", "start": START, "imu": {"rate": 20, "sensor": "mems"},
                                 "gnss": {"rate": 1}, "segments": [{"type": "rest", "duration": 60}]},
                                ("static", "inertial", "kf"), {"with_gnss": False, "heading": math.radians(40.0)}),
    "moving-mems": ({"name": "moving", "start": dict(START, heading=30, speed=5, pitch=0, roll=0),
                     "imu": {"rate": 50, "sensor": "mems"}, "gnss": GNSS, "segments": DRIVE},
                    ("gnss-inertial", "kf"), {}),
    "moving-low-grade": ({"name": "low", "start": dict(START, heading=30, pitch=0, roll=0),
                          "imu": {"rate": 50, "sensor": {"gyro": {"bias": 720.0, "bias_sigma": 100.0, "arw": 0.5},
                                                         "accel": {"bias": 10197.0, "bias_sigma": 1000.0,
                                                                   "vrw": 200}}},
                          "gnss": GNSS, "segments": [{"type": "rest", "duration": 5}] + DRIVE},
                         ("static", "inertial", "gnss-inertial", "kf"), {}),
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--case", choices=sorted(CASES), action="append")
    a = ap.parse_args()
    for name in a.case or CASES:
        sc, methods, kw = CASES[name]
        t = time.perf_counter()
        cov = coverage_runs(copy.deepcopy(sc), methods, range(a.runs), **kw)
        wall = time.perf_counter() - t
        print(f"{name}: {a.runs} runs x {len(methods)} methods x 3 descriptions, {wall:.1f} s")
        print("  method         description  in 3 sigma (r, p, h)   in 1 sigma (r, p, h)   rms error (deg)            "
              "median 1-sigma (deg)       refused")
        for (m, c), v in cov.items():
            rms = np.sqrt((v.err ** 2).mean(axis=0)) if len(v.seeds) else np.full(3, np.nan)
            med = np.array([np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan for c in v.sigma.T])
            print(f"  {m:14s} {c:11s}  {np.array2string(v.inside(3.0), precision=3):20s}  "
                  f"{np.array2string(v.inside(1.0), precision=3):20s}  {np.array2string(rms, precision=4):25s}  "
                  f"{np.array2string(med, precision=4):25s}  {len(v.refused)}")


if __name__ == "__main__":
    main()
