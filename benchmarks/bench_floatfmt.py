"""Float formatting speed (issue 21): the compiled Ryu formatter (``sinscli/io/floatfmt.py``) against pyarrow's
CSV writer (double-conversion, the writer before it) in the same process, on one thread, CPU time per float.

    python benchmarks/bench_floatfmt.py [--rows N]

Data: 26 trajectory-like columns (random walks near 30, near 1e-9, values rounded to 3 decimals) and 10^6
random bit patterns.  Prints ns/float for both, the ratio, and whether the bytes are identical.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from sinscli.io.floatfmt import format_rows, row_bytes


def _arrow(rows: np.ndarray) -> bytes:
    table = pa.Table.from_arrays([pa.Array.from_buffers(pa.float64(), rows.shape[0], [None, pa.py_buffer(
        np.ascontiguousarray(rows[:, k]))]) for k in range(rows.shape[1])], names=[str(k) for k in range(rows.shape[1])])
    sink = pa.BufferOutputStream()
    pacsv.write_csv(table, sink, write_options=pacsv.WriteOptions(include_header=False, quoting_style="none"))
    return sink.getvalue().to_pybytes()


def _ours(rows: np.ndarray) -> bytes:
    out = np.empty(rows.shape[0] * row_bytes(rows.shape[1]), np.uint8)
    return out[:format_rows(rows, np.empty(0, np.uint8), out)].tobytes()


def _best_cpu(f, rows, repeat):
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        text = f(rows)
        best = min(best, time.process_time() - t)
    return best / rows.size * 1e9, text


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    traj = np.cumsum(rng.normal(size=(a.rows, 26)), axis=0) * 1e-3 + 30.0
    traj[:, 3] *= 1e-9
    traj[:, 4] = np.round(traj[:, 4], 3)
    bits = rng.integers(0, 2 ** 64 - 1, size=1_000_000, dtype=np.uint64).view(np.float64)
    rand = bits[np.isfinite(bits)].reshape(-1, 1).copy()
    _ours(traj[:10])                                            # load (or compile) the kernel
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; CPU time per float, best of {a.repeat}")
    for name, rows in (("trajectory (26 columns)", traj), ("random bit patterns", rand)):
        ours, t1 = _best_cpu(_ours, rows, a.repeat)
        arrow, t2 = _best_cpu(_arrow, rows, a.repeat)
        print(f"{name:26s} Ryu {ours:6.1f} ns/float   pyarrow {arrow:6.1f} ns/float   ratio {arrow / ours:4.2f}x   "
              f"bytes identical: {t1 == t2}")


if __name__ == "__main__":
    main()
