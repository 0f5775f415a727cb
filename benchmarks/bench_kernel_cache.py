"""The navigation kernel loaded from the cache a wheel ships (issue 21) against the same kernel compiled now, in
one process, interleaved (the ratio does not depend on the load).

    python benchmarks/bench_kernel_cache.py        # with the python of an installed (non-editable) package

720,000 samples of the sample drive (quat, coning 2); prints the CPU time of each, best of 5, and their ratio
(issue 21: the shipped kernels no more than 5 % slower), and whether the first came from the cache.
"""
import os
import time
from pathlib import Path

import numpy as np
from numba import njit

from sinscli.io.imu_csv import read_imu_csv
from sinscli.io.init_state import read_init
from sinscli.nav import strapdown as sd
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.types import ImuLog

ROOT = Path(__file__).resolve().parent.parent


def main():
    d = read_imu_csv(ROOT / "sample_data" / "imu.csv")
    k = np.arange(720_000) % len(d.time)
    imu = ImuLog((np.arange(720_000) + 1) * 0.01, d.dtheta_b[k], d.dvel_b[k], t0=0.0)
    init = read_init(ROOT / "sample_data" / "init.yaml", 0.0, 0)
    shipped = sd.RUN[sd.ATT_QUAT]
    opts = {k: v for k, v in shipped.targetoptions.items() if k not in ("cache", "nopython")}
    now = njit(**opts)(shipped.py_func)            # the same source and options, compiled in this process

    def cpu(run):
        sd.RUN[sd.ATT_QUAT] = run
        c = time.process_time()
        navigate(imu, init, NavOptions())
        return time.process_time() - c

    cpu(shipped)
    cpu(now)
    a, b = [], []
    for _ in range(5):
        a.append(cpu(shipped))
        b.append(cpu(now))
    hits = sum(shipped.stats.cache_hits.values())
    print(f"cached kernel {min(a):.3f} s CPU ({'loaded from the cache' if hits else 'NOT from the cache'}), "
          f"compiled now {min(b):.3f} s CPU, ratio cached / now {min(a) / min(b):.3f} "
          f"(load {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")


if __name__ == "__main__":
    main()
