"""Rendering of the statistics of many runs (:mod:`sinscli.evaluate.stats`): CSV, Markdown, HTML, box plots.

Kept apart from the numbers so that another front end (an interactive HTML
report) can replace it; every writer goes through ``atomic_path``.
"""
from __future__ import annotations

import csv
import html
import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.atomic import atomic_path
from .figures import wrap_title
from ..evaluate.stats import PERCENTILES, STATISTICS

_LOW, _HIGH = PERCENTILES[0], PERCENTILES[-1]


def _cell(v) -> str:
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    return "" if not math.isfinite(v) else repr(v)


def write_stats_csv(path, stats) -> None:
    """The long table of :func:`sinscli.evaluate.stats.row_statistics`; floats in shortest round-trip form."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(list(stats.columns))
        for row in stats.itertuples(index=False):
            w.writerow([v if isinstance(v, str) else _cell(v) for v in row])


def _fmt(v) -> str:
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return "" if not math.isfinite(float(v)) else f"{float(v):.5E}"


def stats_markdown(stats, group: str, title: str = "", labels: dict | None = None) -> str:
    """One Markdown table per group value: a row per quantity, a column per statistic."""
    lines = [f"**{title}**", ""] if title else []
    for g in dict.fromkeys(stats[group]):
        sub = stats[stats[group] == g]
        lines += [f"### {g}", "", "| Quantity | Unit | " + " | ".join(STATISTICS) + " |",
                  "|---|---|" + "---:|" * len(STATISTICS)]
        for row in sub.itertuples(index=False):
            r = row._asdict()
            name = (labels or {}).get(r["quantity"], r["quantity"])
            lines.append(f"| {name} | {r['unit']} | " + " | ".join(_fmt(r[s]) for s in STATISTICS) + " |")
        lines.append("")
    return "\n".join(lines)


def write_stats_md(path, stats, group: str, title: str = "", labels: dict | None = None) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(stats_markdown(stats, group, title, labels), encoding="utf-8")


def stats_html(stats, group: str, labels: dict | None = None) -> str:
    """The same tables as HTML (numbers ``%.5E``)."""
    out = []
    for g in dict.fromkeys(stats[group]):
        sub = stats[stats[group] == g]
        out.append(f"<h3>{html.escape(str(g))}</h3>\n<table class=\"sortable\">\n<tr><th>Quantity</th><th>Unit</th>"
                   + "".join(f"<th>{s}</th>" for s in STATISTICS) + "</tr>")
        for row in sub.itertuples(index=False):
            r = row._asdict()
            name = html.escape(str((labels or {}).get(r["quantity"], r["quantity"])).replace("\\|", "|"))
            unit = "" if r["unit"] == "1" else r["unit"]
            out.append(f"<tr><td>{name}</td><td>{html.escape(unit)}</td>"
                       + "".join(f"<td class=\"num\">{_fmt(r[s])}</td>" for s in STATISTICS) + "</tr>")
        out.append("</table>")
    return "\n".join(out)


def plot_boxes(path, frame, group: str, quantities: list[str], units: dict, title: str,
               labels: dict | None = None) -> None:
    """Box plots, one panel per quantity and one box per group value: box from the 25th to the 75th
    percentile, median line, whiskers at the 5th and 95th, the runs beyond as points, mean as a
    triangle.  ``frame`` has one row per run."""
    groups = list(dict.fromkeys(frame[group]))
    ncols = min(3, len(quantities))
    nrows = int(math.ceil(len(quantities) / ncols))
    fig = Figure(figsize=(max(4.0, 0.9 * len(groups) + 2.0) * ncols, 3.3 * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).reshape(-1)
    for ax, q in zip(axes, quantities):
        data = []
        for g in groups:
            v = frame.loc[frame[group] == g, q].to_numpy(dtype=float)
            data.append(v[np.isfinite(v)])
        ax.boxplot(data, whis=(_LOW, _HIGH), showmeans=True, flierprops={"markersize": 2, "alpha": 0.4},
                   medianprops={"color": "C1"})
        ax.set_xticks(range(1, len(groups) + 1), groups, rotation=30, ha="right", fontsize=8)
        unit = units.get(q, "")
        ax.set_ylabel((labels or {}).get(q, q).replace("\\|", "|") + (f" ({unit})" if unit not in ("", "1") else ""),
                      fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    for ax in axes[len(quantities):]:
        ax.set_axis_off()
    n = max((int((frame[group] == g).sum()) for g in groups), default=0)
    fig.suptitle(f"{wrap_title(title)}\n{n} runs per {group}: box 25-75 %, whiskers {_LOW}-{_HIGH} %, "
                 "triangle = mean", fontsize=9)
    fig.tight_layout()
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
