"""Writers of the error tables (``errors.csv``, ``errors.md``) and the error time series (``timeseries.csv``).

Each writer writes one file through :func:`sinscli.io.atomic.atomic_path`.
CSV floats use the shortest round-trip form (``repr``), so they read back to
the identical float64; the Markdown table uses the paper's ``%.5E`` style.
"""
from __future__ import annotations

import csv

import numpy as np

from ..io.atomic import atomic_path
from .errors import ROW_UNITS, ErrorSeries, ErrorTable

#: How Tables 1-2 of seed 000 name each row (subscript g = truth, n = navigation).
ROW_LABELS = dict(
    {f"C{i}{j}": f"C{i}{j}g - C{i}{j}n" for i in range(1, 4) for j in range(1, 4)},
    pos_E="Eg - En", pos_N="Ng - Nn", pos_U="Ug - Un",
    vel_E="VEg - VEn", vel_N="VNg - VNn", vel_U="VUg - VUn",
    max_pos_E="max \\|Eg - En\\|", max_pos_N="max \\|Ng - Nn\\|", max_pos_U="max \\|Ug - Un\\|",
    max_vel_E="max \\|VEg - VEn\\|", max_vel_N="max \\|VNg - VNn\\|", max_vel_U="max \\|VUg - VUn\\|",
    max_att_deg="max attitude error angle",
)

#: timeseries.csv quantities per method: (suffix, ErrorSeries attribute, column, scale).
_DEG = float(np.degrees(1.0))
TIMESERIES_QUANTITIES = [
    ("att_roll_deg", "att_rph_rad", 0, _DEG), ("att_pitch_deg", "att_rph_rad", 1, _DEG),
    ("att_heading_deg", "att_rph_rad", 2, _DEG),
    ("att_e_deg", "att_n_rad", 0, _DEG), ("att_n_deg", "att_n_rad", 1, _DEG), ("att_u_deg", "att_n_rad", 2, _DEG),
    ("att_angle_deg", "angle_rad", None, _DEG),
    ("pos_e_m", "pos_enu_m", 0, 1.0), ("pos_n_m", "pos_enu_m", 1, 1.0), ("pos_u_m", "pos_enu_m", 2, 1.0),
    ("vel_e_mps", "vel_enu_mps", 0, 1.0), ("vel_n_mps", "vel_enu_mps", 1, 1.0), ("vel_u_mps", "vel_enu_mps", 2, 1.0),
]


def _r(x: float) -> str:
    return repr(float(x))


def write_errors_csv(path, table: ErrorTable) -> None:
    """``quantity,unit,<method>...``: one row per table row, full precision."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["quantity", "unit", *table.methods])
        for r, key in enumerate(table.rows):
            w.writerow([key, ROW_UNITS[key], *(_r(v) for v in table.values[r])])


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def markdown_table(table: ErrorTable, title: str = "") -> str:
    """The table laid out like seed 000 Tables 1-2: No., quantity, one column per method."""
    lines = []
    if title:
        lines += [f"**{_md_cell(title)}**", ""]
    lines.append(f"Errors truth minus navigation at t = {float(table.epoch)!r} s; maxima over the whole run.")
    lines.append("")
    lines.append("| No. | Quantity | Unit | " + " | ".join(_md_cell(m) for m in table.methods) + " |")
    lines.append("|---:|---|---|" + "---:|" * len(table.methods))
    for r, key in enumerate(table.rows):
        cells = " | ".join(f"{v:.5E}" for v in table.values[r])
        lines.append(f"| {r + 1} | {ROW_LABELS[key]} | {ROW_UNITS[key]} | {cells} |")
    return "\n".join(lines) + "\n"


def write_errors_md(path, table: ErrorTable, title: str = "") -> None:
    """``errors.md``: :func:`markdown_table` with a title line."""
    text = markdown_table(table, title)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def timeseries_columns(s: ErrorSeries, every: int = 1) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """One run's part of ``timeseries.csv``: every n-th epoch (plus the last) and each quantity of
    :data:`TIMESERIES_QUANTITIES` in its unit.  A batch computes it on the worker."""
    keep = np.arange(0, len(s), max(int(every), 1))
    if keep[-1] != len(s) - 1:
        keep = np.append(keep, len(s) - 1)
    cols = {}
    for suffix, attr, col, scale in TIMESERIES_QUANTITIES:
        arr = getattr(s, attr)
        v = arr[keep] if col is None else arr[keep, col]
        cols[suffix] = v * scale
    return s.time[keep], cols


def timeseries_frame(columns: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]):
    """Wide table on the union of epochs: ``time``, then ``<method>.<quantity>`` (empty where absent);
    ``columns``: method -> :func:`timeseries_columns`."""
    import pandas as pd

    cols = {}
    for name, (time, values) in columns.items():
        idx = pd.Index(time, name="time")
        for suffix, v in values.items():
            cols[f"{name}.{suffix}"] = pd.Series(v, index=idx)
    return pd.DataFrame(cols).sort_index()


def write_timeseries_csv(path, columns: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]) -> None:
    """``timeseries.csv`` (see :func:`timeseries_frame`); floats in shortest round-trip form."""
    frame = timeseries_frame(columns)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=True, na_rep="", lineterminator="\n")
