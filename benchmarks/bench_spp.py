"""Single-point positioning speed: epochs/s of ``solve_epochs`` (position, Doppler velocity, chi-square test)
with ~20 satellites per epoch, against the kernel's own cost without the velocity (Doppler removed) as the
ratio baseline in the same process.

Simulated GPS geometry of the shipped broadcast file with a low elevation mask (so that ~20 satellites are
used; the solver's mask the same), 1 Hz.

    python benchmarks/bench_spp.py [--epochs 20000]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from sinscli.gnss import spp as S
from sinscli.gnss.pipeline import run_spp
from sinscli.sim.raw_gnss import static_receiver


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--epochs", type=int, default=20000)
    a = ap.parse_args()
    sim = static_receiver(10.0, 20.0, 0.0, a.epochs, {"systems": "G", "elevation_mask": -25.0}, seed=1)
    obs = sim.obs
    n_sat = np.diff(obs.start).mean()
    opts = S.spp_options(elev_mask_deg=-25.0, iono="klobuchar")
    run_spp(obs, sim.nav, [0], opts)                 # compile
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        res = run_spp(obs, sim.nav, [0], opts)
        best = min(best, time.perf_counter() - t)
    dop_col = obs.types[0].index("D1C")
    saved = obs.values[:, dop_col].copy()
    obs.values[:, dop_col] = np.nan
    base = np.inf
    for _ in range(3):
        t = time.perf_counter()
        run_spp(obs, sim.nav, [0], opts)
        base = min(base, time.perf_counter() - t)
    obs.values[:, dop_col] = saved
    print(f"{len(obs)} epochs, {n_sat:.1f} satellites per epoch, {res.nsat.mean():.1f} used, "
          f"{(res.status == S.FIX).mean() * 100:.1f} % fixes")
    print(f"spp with Doppler velocity: {len(obs) / best:,.0f} epochs/s (target 2,000); position only: "
          f"{len(obs) / base:,.0f} epochs/s; ratio {base / best:.2f}")


if __name__ == "__main__":
    main()
