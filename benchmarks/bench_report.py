"""``index.html`` of ``sins compare``: time to write it and its size, against the PNG figures of the same report.

Three methods with the navigator's 1-sigma over ``--epochs`` matched epochs (default 100,000: a 1000 s run at
100 Hz).  Prints ``html seconds=<float> kB=<float> samples_per_s=<float>`` (epochs of all methods per second)
and the ratio to the baseline run in the same process: the matplotlib PNG figures of the same report
(``plot_all``), which the report writes anyway.  Run: ``python benchmarks/bench_report.py [--epochs N]``.
"""
import argparse
import tempfile
from pathlib import Path

import numpy as np

from bench_navigate import best_of   # same folder: one timing helper for the benchmarks
from sinscli.report.compare_page import compare_page
from sinscli.report.digest import digest
from sinscli.evaluate.errors import ErrorSeries, build_table
from sinscli.report.figures import plot_all


def series(n: int, seed: int) -> ErrorSeries:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    walk = lambda s: np.cumsum(s * rng.standard_normal((n, 3)), axis=0)       # noqa: E731
    ang = walk(1e-6)
    track = np.column_stack([300 * np.sin(t / 200), 300 * (1 - np.cos(t / 200)), np.zeros(n)])
    return ErrorSeries(time=t, dC=np.zeros((n, 3, 3)), pos_enu_m=walk(0.01), vel_enu_mps=walk(1e-3), att_n_rad=ang,
                       att_rph_rad=ang, angle_rad=np.linalg.norm(ang, axis=1), pos_std_m=np.full((n, 3), 0.5),
                       vel_std_mps=np.full((n, 3), 0.05), att_std_rad=np.full((n, 3), 1e-4), track_enu_m=track)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--epochs", type=int, default=100_000)
    args = ap.parse_args()
    runs = {f"method{k}.csv": series(args.epochs, k) for k in range(3)}
    digests = {m: digest(s, 10) for m, s in runs.items()}
    table = build_table(runs)
    out = Path(tempfile.mkdtemp())

    def html():
        compare_page("bench", digests, table, {}, files=["errors.csv"], figures=["att_roll.png"]).write(out / "index.html")

    def png():
        plot_all(out, {m: d.lines for m, d in digests.items()}, "bench")

    t_html, t_png = best_of(html, 3), best_of(png, 1)
    kb = (out / "index.html").stat().st_size / 1024
    n = args.epochs * len(runs)
    print(f"html seconds={t_html:.3f} kB={kb:.0f} samples_per_s={n / t_html:.4g}")
    print(f"png figures (baseline) seconds={t_png:.3f}  ratio png/html={t_png / t_html:.2f}")


if __name__ == "__main__":
    main()
