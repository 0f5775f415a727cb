"""Statistics of many runs as data: per group (method, variant) and quantity, over the runs.

Pure pandas/numpy, no rendering (``stats_render.py`` draws and writes them;
an interactive report can take the same frames).  Every function takes the
runs in a fixed order (the caller sorts them by dataset, seed, method), so the
floating-point sums, and with them the report, do not depend on the order in
which the jobs finished.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

#: The statistics of each quantity, in column order.  Percentiles by numpy's default (linear) rule.
PERCENTILES = (5, 25, 50, 75, 95)
STATISTICS = ("n", "mean", "std", "rms", "min", *(f"p{p}" for p in PERCENTILES), "max")


def describe(values) -> dict:
    """The :data:`STATISTICS` of one sample (finite values only; ``std`` with ddof = 1)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    n = int(v.shape[0])
    out = {"n": n}
    if n == 0:
        return out | {k: np.nan for k in STATISTICS[1:]}
    out["mean"] = float(np.mean(v))
    out["std"] = float(np.std(v, ddof=1)) if n > 1 else 0.0
    out["rms"] = float(np.sqrt(np.mean(v * v)))
    out["min"] = float(np.min(v))
    for p, q in zip(PERCENTILES, np.percentile(v, PERCENTILES)):
        out[f"p{p}"] = float(q)
    out["max"] = float(np.max(v))
    return out


def row_statistics(frame: pd.DataFrame, group: str, quantities: list[str], units: dict | None = None) -> pd.DataFrame:
    """Long table: one row per (group value, quantity) with the :data:`STATISTICS` over the runs.

    ``frame`` holds one row per run: the ``group`` column (e.g. ``method``) and one column per
    quantity.  Groups keep their order of first appearance; quantities the given order.
    """
    rows = []
    for g in pd.unique(frame[group]):
        sub = frame[frame[group] == g]
        for q in quantities:
            rows.append({group: g, "quantity": q, "unit": (units or {}).get(q, ""), **describe(sub[q].to_numpy())})
    return pd.DataFrame(rows, columns=[group, "quantity", "unit", *STATISTICS])


def pivot(stats: pd.DataFrame, group: str, statistic: str) -> pd.DataFrame:
    """One statistic as a quantity x group table (e.g. the RMS of every row for every method)."""
    out = stats.pivot(index="quantity", columns=group, values=statistic)
    return out.loc[list(dict.fromkeys(stats["quantity"])), list(dict.fromkeys(stats[group]))]
