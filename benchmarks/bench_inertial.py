"""Launch-inertial navigation speed: 720,000 samples (1 h at 200 Hz), ENU kernel as the baseline.

Prints ``NAME samples_per_s=<float>`` and the ratio to the ENU navigation of the
same log in the same process (same attitude method and coning order); the
launch-inertial figure includes the per-block conversion of the output to
latitude/longitude/height, ENU velocity and Cbn (every sample is output).
Run: ``python benchmarks/bench_inertial.py``.
"""
import math
import sys

import numpy as np

from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.types import ImuLog, NavState

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_navigate import N, best_of, make_log  # noqa: E402

LAUNCH = {"lat": 30.0, "lon": 114.0, "height": 10.0, "azimuth": 45.0}


def main():
    imu = make_log()
    init = NavState(0.0, math.radians(30), math.radians(114), 10.0, np.zeros(3), np.eye(3))
    small = ImuLog(imu.time[:1000], imu.dtheta_b[:1000], imu.dvel_b[:1000])
    for att in ("quat", "dcm"):
        enu = NavOptions(attitude=att)
        li = NavOptions(attitude=att, frame="launch-inertial", launch=LAUNCH)
        navigate(small, init, enu)             # JIT warm-up
        navigate(small, init, li)
        base = best_of(lambda: navigate(imu, init, enu))
        el = best_of(lambda: navigate(imu, init, li))
        print(f"baseline enu-{att} samples_per_s={N / base:.0f}")
        print(f"launch-inertial-{att} samples_per_s={N / el:.0f} ratio_to_enu={base / el:.3f}")
        every = NavOptions(attitude=att, frame="launch-inertial", launch=LAUNCH, every=100)
        navigate(small, init, every)
        el = best_of(lambda: navigate(imu, init, every))
        print(f"launch-inertial-{att}-every100 samples_per_s={N / el:.0f} ratio_to_enu={base / el:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
