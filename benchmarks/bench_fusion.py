"""Fusion speed and memory: the tactical RTK drive (200 Hz IMU, 10 Hz GNSS) forward-filtered, and with
the RTS smoother, against plain navigation of the same increments in the same process.

Prints ``samples_per_s`` and the ratio to plain navigation; ``--hour`` fuses and smooths one continuous
hour at 200 Hz with 10 Hz GNSS (the drive's segments three times over: a continuous log, no position
jumps; simulated once and cached in the temp dir) in a child process and prints its peak RSS
(``resource.getrusage``: the process' whole footprint, interpreter and JIT included).
Run: ``python benchmarks/bench_fusion.py [--hour]``.
"""
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
import time

import yaml

import numpy as np

from sinscli.fusion.options import build_fusion_options
from sinscli.fusion.pipeline import run_fusion
from sinscli.nav.pipeline import NavOptions, navigate
from sinscli.sim.run import simulate
from sinscli.types import GnssLog, ImuLog

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_navigate import best_of  # noqa: E402


HOUR_CACHE = Path(tempfile.gettempdir()) / "sins_bench_fusion_hour.npz"


def hour_log():
    """One continuous hour: the tactical RTK drive's segments three times over (the vehicle drives on
    from where it stopped), 200 Hz IMU, 10 Hz GNSS; cached as npz in the temp dir."""
    if not HOUR_CACHE.exists():
        sc = yaml.safe_load(Path("configs/scenarios/tactical_rtk_drive.yaml").read_text())
        sc["segments"] = sc["segments"] * 3
        sc["gnss"]["outages"] = [[600, 660]]
        sim = simulate(sc, duration=3600.0)
        i, g, s = sim.imu, sim.gnss, sim.init
        np.savez(HOUR_CACHE, t=i.time, th=i.dtheta_b, dv=i.dvel_b, t0=i.t0, gt=g.time, lat=g.lat, lon=g.lon,
                 h=g.height, gv=g.vel_n, gsp=g.std_pos, gsv=g.std_vel, init_t=s.time, init_pos=[s.lat, s.lon, s.height],
                 init_v=s.vel_n, init_c=s.Cbn)
    return HOUR_CACHE


def hour_child(path):
    """Fuse and smooth the cached hour; print samples, time and the peak RSS."""
    from sinscli.types import NavState
    d = np.load(path)
    imu = ImuLog(d["t"], d["th"], d["dv"], t0=float(d["t0"]))
    gnss = GnssLog(d["gt"], d["lat"], d["lon"], d["h"], d["gv"], d["gsp"], d["gsv"])
    la, lo, h = d["init_pos"]
    init = NavState(float(d["init_t"]), float(la), float(lo), float(h), d["init_v"], d["init_c"])
    fo = build_fusion_options({"sensor": "tactical", "lever_arm": [0.8, 0.0, 1.5]}, "bench")
    t0 = time.perf_counter()
    traj = run_fusion(imu, init, gnss, fo, smooth=True)[0]
    el = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20          # kB -> GiB (Linux)
    print(f"one hour: samples={len(imu)} fixes={len(gnss)} rows={len(traj)} fused+smoothed in {el:.1f} s, "
          f"peak RSS {rss:.2f} GiB (target 2 GiB)")


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
        path = hour_log()
        subprocess.run([sys.executable, __file__, "--hour-child", str(path)], check=True)
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--hour-child":
        sys.exit(hour_child(sys.argv[2]))
    sys.exit(main())
