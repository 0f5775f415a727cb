"""Tightly coupled fusion speed against the loosely coupled filter on the same data, in the same process.

The tactical drive (``configs/scenarios/tactical_rtk_drive.yaml``: 20 min, 200 Hz IMU, 240,000 samples) with
simulated raw GNSS of its antenna (GPS, and GPS + a second constellation, at 1 Hz and 10 Hz,
:mod:`sinscli.sim.raw_gnss`): the loosely coupled filter fuses the single-point fixes of the raw data
(``sins gnss spp``'s solution, position and Doppler velocity), the tightly coupled one every satellite's
pseudorange and range rate.  Prints ``samples_per_s`` of each and the ratio of their costs per IMU sample
(TC / LC; the target is 2 at most): of the filters alone, and from the raw data (both need the single-point
solution: LC fuses its fixes, TC takes its approximate positions for the corrections; TC also prepares its rows,
the satellite states and corrections of :func:`sinscli.fusion.raw.raw_measurements`).  Then TC with TDCP
(``fusion.raw.tdcp``: the carrier rows, the 4 clone states, the epoch's slip test) against TC without, the filter
alone, per IMU sample, in the same process.
Run: ``python benchmarks/bench_tc.py``.
"""
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sinscli.fusion.options import build_fusion_options
from sinscli.fusion.pipeline import run_fusion
from sinscli.fusion.raw import raw_measurements, raw_spp, spp_log
from sinscli.sim.raw_gnss import simulate_from_result
from sinscli.sim.run import simulate
from sinscli.types import ImuLog

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_navigate import best_of  # noqa: E402


def two_constellation_nav(path):
    """The shipped GPS file plus a synthetic second constellation (:func:`with_second_constellation`)."""
    from sinscli.io.rinex import write_nav
    from sinscli.sim.raw_gnss import check_config, load_nav_for_sim, with_second_constellation
    write_nav(path, with_second_constellation(load_nav_for_sim(check_config({}))))
    return path


def main():
    sim = simulate("configs/scenarios/tactical_rtk_drive.yaml")
    fo = build_fusion_options({"sensor": "tactical", "lever_arm": [0.8, 0.0, 1.5]}, "bench")
    imu, init = sim.imu, sim.init
    n = len(imu)
    small = ImuLog(imu.time[:4000], imu.dtheta_b[:4000], imu.dvel_b[:4000], t0=imu.t0)
    two = two_constellation_nav(Path(tempfile.mkdtemp()) / "two.rnx")
    print(f"samples={n} (200 Hz IMU, tactical drive, 20 min)")
    for label, cfg in (("GPS 1 Hz", {"systems": "G", "rate": 1.0}), ("GPS+E 1 Hz", {"nav": str(two), "systems": "GE"}),
                       ("GPS 10 Hz", {"systems": "G", "rate": 10.0})):
        raw = simulate_from_result(sim, cfg, seed=1)
        off = -raw.gps_offset
        spp = raw_spp(raw.obs, raw.nav, fo)
        rm = raw_measurements(raw.obs, raw.nav, fo, off, init, spp=spp)
        fixes = spp_log(spp, off, "bench")
        run_fusion(small, init, fixes, fo)                     # JIT warm-up
        run_fusion(small, init, fixes, fo, raw=rm)
        t_spp = best_of(lambda: raw_spp(raw.obs, raw.nav, fo))
        t_rows = best_of(lambda: raw_measurements(raw.obs, raw.nav, fo, off, init, spp=spp))
        t_lc = best_of(lambda: run_fusion(imu, init, fixes, fo))
        t_tc = best_of(lambda: run_fusion(imu, init, fixes, fo, raw=rm))
        sats = rm.epoch_nsat[rm.epoch_nsat > 0].mean()
        print(f"{label}: {len(raw.obs)} epochs, {sats:.1f} satellites per epoch ({len(rm.rows)} raw rows)")
        print(f"  filter alone: LC on the {len(fixes)} SPP fixes samples_per_s={n / t_lc:.0f}, TC "
              f"samples_per_s={n / t_tc:.0f}, ratio_tc_to_lc={t_tc / t_lc:.3f}")
        print(f"  from the raw data (SPP {t_spp:.2f} s for both, TC rows {t_rows:.2f} s): LC "
              f"samples_per_s={n / (t_spp + t_lc):.0f}, TC samples_per_s={n / (t_spp + t_rows + t_tc):.0f}, "
              f"ratio_tc_to_lc={(t_spp + t_rows + t_tc) / (t_spp + t_lc):.3f}")
        fo_td = build_fusion_options({"sensor": "tactical", "lever_arm": [0.8, 0.0, 1.5], "raw": {"tdcp": True}},
                                     "bench")
        rm_td = raw_measurements(raw.obs, raw.nav, fo_td, off, init, spp=spp)
        run_fusion(small, init, fixes, fo_td, raw=rm_td)         # JIT warm-up
        t_td = best_of(lambda: run_fusion(imu, init, fixes, fo_td, raw=rm_td))
        print(f"  TC + TDCP ({rm_td.tdcp_info['pairs']} carrier rows, {len(rm_td.rows)} raw rows): "
              f"samples_per_s={n / t_td:.0f}, ratio_tdcp_to_tc={t_td / t_tc:.3f}")
    return 0


if __name__ == "__main__":
    t0 = time.time()
    rc = main()
    print(f"(bench_tc: {time.time() - t0:.0f} s)")
    sys.exit(rc)
