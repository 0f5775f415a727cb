"""Read speed of RINEX 3 observations: our reader (numba kernel over the file's bytes) against georinex.

Builds a day at 1 Hz of multi-constellation observations (86,400 epochs) from the epochs of the shipped SLAC
file (GPS, GLONASS, Galileo; ~22 satellites, 4-6 observation types each), then measures

- ``sins``: ``sinscli.io.rinex.read_obs`` on the whole day (epochs/s and seconds; a first call compiles);
- ``georinex``: ``georinex.load`` on the first ``--georinex-epochs`` epochs (default 1 hour: georinex on a
  whole day takes many minutes), and ``sins`` on the same slice: the ratio is per epoch;

and checks that both give the same pseudoranges on that slice.

    python benchmarks/bench_rinex.py [--obs slac1350.20o] [--georinex-epochs 3600] [--dir DIR]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from sinscli.gnss.timesys import calendar
from sinscli.io.rinex import read_obs

DEFAULT_OBS = next((p for p in (Path(__file__).resolve().parents[1] / "tests/data/rinex_static/slac1350.20o",) if p.is_file()),
                   Path("slac1350.20o"))


def build_day(src: Path, out: Path, epochs: int) -> None:
    """``epochs`` epochs at 1 s, cycling through the source file's epochs (their satellites and values)."""
    text = src.read_text()
    head, body = text.split("END OF HEADER", 1)
    head = head + "END OF HEADER" + body[:body.index("\n") + 1]
    body = body[body.index("\n") + 1:]
    blocks = [">" + b for b in body.split("\n>")]
    blocks[0] = blocks[0][1:]
    blocks = [b.split("\n", 1)[1].rstrip("\n") + "\n" for b in blocks]
    counts = [b.count("\n") for b in blocks]
    t0 = 1273528800.0
    with open(out, "w") as f:
        f.write(head)
        for e in range(epochs):
            y, mo, d, h, mi, s = calendar(t0 + e)
            k = e % len(blocks)
            f.write(f"> {y:4d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{counts[k]:3d}\n")
            f.write(blocks[k])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--obs", type=Path, default=DEFAULT_OBS)
    ap.add_argument("--epochs", type=int, default=86400)
    ap.add_argument("--georinex-epochs", type=int, default=3600)
    ap.add_argument("--dir", type=Path, default=None)
    a = ap.parse_args()
    d = a.dir or Path(tempfile.mkdtemp(prefix="bench_rinex_"))
    day, part = d / "day.rnx", d / "part.rnx"
    build_day(a.obs, day, a.epochs)
    build_day(a.obs, part, a.georinex_epochs)
    print(f"file: {day} ({day.stat().st_size / 1e6:.0f} MB, {a.epochs} epochs)")
    read_obs(part)                                        # compile / load the kernels
    t = time.perf_counter()
    obs = read_obs(day)
    dt_day = time.perf_counter() - t
    print(f"sins read_obs, whole day: {dt_day:.2f} s, {len(obs) / dt_day:,.0f} epochs/s, "
          f"{obs.n_records:,} satellite records")
    t = time.perf_counter()
    ours = read_obs(part)
    dt_ours = time.perf_counter() - t
    try:
        import georinex
    except ImportError:
        print("georinex not installed (pip install georinex): no comparison")
        return
    t = time.perf_counter()
    ds = georinex.load(part, use="G")
    dt_geo = time.perf_counter() - t
    print(f"{a.georinex_epochs} epochs (GPS only for georinex): sins {dt_ours:.3f} s (all systems), georinex "
          f"{dt_geo:.2f} s: ratio {dt_geo / dt_ours:.0f}x; a day with georinex ~{dt_geo * a.epochs / a.georinex_epochs:.0f} s")
    # the same C1C of GPS on the slice
    g = ours.sys == 0
    ep = ours.epoch_of_record()[g]
    c1c = ours.values[g, ours.types[0].index("C1C")]
    geo = ds["C1C"].values
    sats = [str(s) for s in ds.sv.values]
    col = np.array([sats.index(f"G{p:02d}") for p in ours.prn[g]])
    assert np.allclose(geo[ep, col], c1c, equal_nan=True), "georinex and sins disagree"
    print("values: identical C1C pseudoranges on the slice")


if __name__ == "__main__":
    main()
