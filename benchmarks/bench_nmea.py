"""Read speed of NMEA logs: sinscli's numba reader against pynmea2, in the same process.

Writes a day of 10 Hz GGA + RMC + GST (864,000 epochs, 2,592,000 sentences, ~200 MB; the simulator's NMEA
writer, :func:`sinscli.io.nmea.format_sentences`, on a moving receiver) once, then measures

- ``read_log_s``: ``sinscli.io.receiver.read_receiver_log`` on the file: read, checksum and parse every sentence,
  date the epochs, velocity, accuracy, limits, the GnssLog (the issue's target: <= 5 s);
- ``sentences_per_s``: the same file's sentences through :class:`sinscli.io.nmea.Sentences` (scan + parse);
- ``pynmea2_sentences_per_s``: ``pynmea2.parse(line, check=True)`` and the attributes sinscli reads
  (timestamp, latitude, longitude, ... : pynmea2 parses lazily), over the first ``--pynmea2-count`` lines;

and prints the ratio.  The first call of the reader (the numba kernels load or compile) is made on a small file
before the timing.

    python benchmarks/bench_nmea.py [--hours 24] [--pynmea2-count 200000] [--dir DIR] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from sinscli.io.nmea import Sentences, format_sentences
from sinscli.io.receiver import read_receiver_log
from sinscli.types import GnssLog

T0 = 1715644800.0            # 2024-05-14 00:00:00 UTC


def write_day(path: Path, hours: float) -> int:
    """A moving receiver's GGA, RMC, GST at 10 Hz for ``hours`` (written in blocks of an hour); the sentence count."""
    n_total = 0
    with open(path, "w", newline="") as fh:
        for h in range(int(np.ceil(hours))):
            n = int(min(hours - h, 1.0) * 36000)
            t = T0 + h * 3600.0 + np.arange(n) / 10.0
            a = 2 * np.pi * (t - T0) / 600.0               # a 10-minute circle of ~950 m
            lat = 48.1 + 0.0086 * np.sin(a)
            lon = 11.5 + 0.0128 * np.cos(a)
            vel = np.column_stack([-10.0 * np.sin(a), 10.0 * np.cos(a), np.zeros(n)])
            g = GnssLog(t, lat, lon, 520.0 + np.sin(a), vel_n=vel, std_pos=np.tile([0.012, 0.015, 0.03], (n, 1)))
            lines = format_sentences(g, t, quality=4, geoid_separation=47.0, high_precision=True)
            fh.write("\r\n".join(lines) + "\r\n")
            n_total += len(lines)
    return n_total


def pynmea2_rate(path: Path, count: int) -> float:
    import pynmea2
    with open(path, "r", newline="") as fh:
        lines = [next(fh).rstrip("\r\n") for _ in range(count)]
    t0 = time.perf_counter()
    for line in lines:
        m = pynmea2.parse(line, check=True)
        if m.sentence_type == "GGA":
            (m.timestamp, m.latitude, m.longitude, m.gps_qual, m.num_sats, m.horizontal_dil, m.altitude, m.geo_sep)
        elif m.sentence_type == "RMC":
            (m.timestamp, m.status, m.latitude, m.longitude, m.spd_over_grnd, m.true_course, m.datestamp)
        else:
            (m.timestamp, m.std_dev_latitude, m.std_dev_longitude, m.std_dev_altitude)
    return len(lines) / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--pynmea2-count", type=int, default=200000)
    ap.add_argument("--dir", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=3, help="reads of the file (the best is printed)")
    a = ap.parse_args()
    d = a.dir or Path(tempfile.mkdtemp(prefix="sins-bench-nmea-"))
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"day_{a.hours:g}h.nmea"
    if not path.exists():
        t0 = time.perf_counter()
        n = write_day(path, a.hours)
        print(f"wrote {path}: {n:,} sentences, {path.stat().st_size / 1e6:.0f} MB in {time.perf_counter() - t0:.0f} s")
    small = d / "warm.nmea"
    small.write_bytes(path.open("rb").read(20000).rsplit(b"\n", 1)[0] + b"\n")
    read_receiver_log(small)                                   # the kernels load (or compile) here
    t_read = c_read = float("inf")
    for _ in range(a.repeat):                                  # the best of a few: a shared machine's load varies
        t0, c0 = time.perf_counter(), time.process_time()
        g = read_receiver_log(path)
        t_read, c_read = min(t_read, time.perf_counter() - t0), min(c_read, time.process_time() - c0)
    buf = np.frombuffer(path.read_bytes(), dtype=np.uint8)     # read-only, as the reader's (one numba signature)
    t0, c0 = time.perf_counter(), time.process_time()
    s = Sentences(buf)
    t_parse, c_parse = time.perf_counter() - t0, time.process_time() - c0
    n = sum(s.table[k].shape[0] for k in s.table)
    ours = n / t_parse
    lib = pynmea2_rate(path, min(a.pynmea2_count, n))
    print(f"read_log_s: {t_read:.2f} s wall, {c_read:.2f} s CPU for {len(g):,} epochs ({n:,} sentences, "
          f"{path.stat().st_size / 1e6:.0f} MB), target <= 5 s; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} CPUs")
    print(f"sentences_per_s: {ours:,.0f} (scan + parse {t_parse:.2f} s wall, {c_parse:.2f} s CPU)")
    print(f"pynmea2_sentences_per_s: {lib:,.0f} (first {min(a.pynmea2_count, n):,} lines; the whole file would take "
          f"{n / lib:.0f} s)")
    print(f"ratio: {ours / lib:.0f} x pynmea2")


if __name__ == "__main__":
    main()
