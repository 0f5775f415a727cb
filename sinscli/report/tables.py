"""Writers of the error tables (``errors.csv``, ``errors.md``) and the error time series (``timeseries.csv``).

Each writer writes one file through :func:`sinscli.io.atomic.atomic_path`.
CSV floats use the shortest round-trip form (``repr``), so they read back to
the identical float64; the Markdown table uses the paper's ``%.5E`` style.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..evaluate.errors import (
    CONSISTENCY_UNITS,
    METRIC_STATISTICS,
    ROW_UNITS,
    ConsistencyTable,
    ErrorSeries,
    ErrorTable,
)
from ..io.atomic import atomic_path, check_finite

#: How Tables 1-2 of seed 000 name each row (subscript g = truth, n = navigation).
ROW_LABELS = dict(
    {f"C{i}{j}": f"C{i}{j}g - C{i}{j}n" for i in range(1, 4) for j in range(1, 4)},
    pos_E="Eg - En", pos_N="Ng - Nn", pos_U="Ug - Un",
    vel_E="VEg - VEn", vel_N="VNg - VNn", vel_U="VUg - VUn",
    max_pos_E="max \\|Eg - En\\|", max_pos_N="max \\|Ng - Nn\\|", max_pos_U="max \\|Ug - Un\\|",
    max_vel_E="max \\|VEg - VEn\\|", max_vel_N="max \\|VNg - VNn\\|", max_vel_U="max \\|VUg - VUn\\|",
    max_att_deg="max attitude error angle",
)
ROW_LABELS.update({f"{g}_{s}": f"{label} {s.upper() if s == 'rmse' else s}"
                   for g, label in (("ate", "ATE"), ("rpe_trans", "RPE translation"), ("rpe_rot", "RPE rotation"))
                   for s in METRIC_STATISTICS}, align_scale="Sim(3) alignment scale")

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
#: The navigator's 1-sigma at the same epochs, for the runs that carry it (aided trajectories).
TIMESERIES_SIGMAS = [
    ("pos_e_std_m", "pos_std_m", 0, 1.0), ("pos_n_std_m", "pos_std_m", 1, 1.0), ("pos_u_std_m", "pos_std_m", 2, 1.0),
    ("vel_e_std_mps", "vel_std_mps", 0, 1.0), ("vel_n_std_mps", "vel_std_mps", 1, 1.0),
    ("vel_u_std_mps", "vel_std_mps", 2, 1.0),
    ("att_roll_std_deg", "att_std_rad", 0, _DEG), ("att_pitch_std_deg", "att_std_rad", 1, _DEG),
    ("att_heading_std_deg", "att_std_rad", 2, _DEG),
]

#: How the consistency rows are named in errors.md.
_GROUP_WORDS = {"pos": "position", "vel": "velocity", "att": "attitude"}
CONSISTENCY_LABELS = dict(
    {k: f"epochs inside 3 sigma, {_GROUP_WORDS[k.split('_')[1]]} {k.split('_')[2]}"
     for k in CONSISTENCY_UNITS if k.startswith("in3")},
    **{f"nees_{g}": f"average NEES, {w} (3 dof)" for g, w in _GROUP_WORDS.items()})


def _r(x: float) -> str:
    return repr(float(x))


def write_errors_csv(path, table: ErrorTable, consistency: ConsistencyTable | None = None) -> None:
    """``quantity,unit,<method>...``: one row per table row, full precision; then the consistency rows
    (``in3sigma_*``, ``nees_*``) when some method has sigma columns (empty cells for the others)."""
    check_finite(path, dict(zip(table.rows, table.values)))
    if consistency is not None:                  # NaN: the method has no such sigma (an empty cell)
        check_finite(path, {k: v[~np.isnan(v)] for k, v in zip(consistency.rows, consistency.values)})
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["quantity", "unit", *table.methods])
        for r, key in enumerate(table.rows):
            w.writerow([key, ROW_UNITS[key], *(_r(v) for v in table.values[r])])
        if consistency is not None:
            for r, key in enumerate(consistency.rows):
                w.writerow([key, CONSISTENCY_UNITS[key],
                            *("" if np.isnan(v) else _r(v) for v in consistency.values[r])])


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def table_caption(table: ErrorTable) -> str:
    """What the table's values are (the epoch of the seed-000 rows, or trajectory metrics alone)."""
    if table.epoch is None:
        return "Trajectory metrics: statistics over the matched epochs."
    text = f"Errors truth minus navigation at t = {float(table.epoch)!r} s; maxima over the time span compared."
    if any(k.startswith(("ate_", "rpe_")) for k in table.rows):
        text += " ATE and RPE rows: statistics over the matched epochs (pairs)."
    return text


def markdown_table(table: ErrorTable, title: str = "") -> str:
    """The table laid out like seed 000 Tables 1-2: No., quantity, one column per method."""
    lines = []
    if title:
        lines += [f"**{_md_cell(title)}**", ""]
    lines.append(table_caption(table))
    lines.append("")
    lines.append("| No. | Quantity | Unit | " + " | ".join(_md_cell(m) for m in table.methods) + " |")
    lines.append("|---:|---|---|" + "---:|" * len(table.methods))
    for r, key in enumerate(table.rows):
        cells = " | ".join(f"{v:.5E}" for v in table.values[r])
        lines.append(f"| {r + 1} | {ROW_LABELS[key]} | {ROW_UNITS[key]} | {cells} |")
    return "\n".join(lines) + "\n"


def markdown_consistency(cons: ConsistencyTable) -> str:
    """The consistency rows as a Markdown table (``-`` where a method has no such sigma)."""
    lines = ["Consistency of each navigator's own 1-sigma: the fraction of epochs inside +-3 sigma (0.9973 for "
             "an honest Gaussian claim) and the average NEES over the three axes (3 for an honest claim; "
             "diagonal, the files carry no cross-covariance).", "",
             "| Quantity | Unit | " + " | ".join(_md_cell(m) for m in cons.methods) + " |",
             "|---|---|" + "---:|" * len(cons.methods)]
    for r, key in enumerate(cons.rows):
        cells = " | ".join("-" if np.isnan(v) else (f"{v:.4f}" if key.startswith("in3") else f"{v:.3f}")
                           for v in cons.values[r])
        lines.append(f"| {CONSISTENCY_LABELS[key]} | {CONSISTENCY_UNITS[key]} | {cells} |")
    return "\n".join(lines) + "\n"


def write_errors_md(path, table: ErrorTable, title: str = "", summary: list[str] = (),
                    consistency: ConsistencyTable | None = None) -> None:
    """``errors.md``: :func:`markdown_table` with a title line, the summary lines under it, and
    :func:`markdown_consistency` when the navigators carry sigmas."""
    text = markdown_table(table, title)
    if summary:
        text += "\n" + "".join(f"- {_md_cell(s)}\n" for s in summary)
    if consistency is not None:
        text += "\n" + markdown_consistency(consistency)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def timeseries_columns(s: ErrorSeries, every: int = 1) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """One run's part of ``timeseries.csv``: every n-th epoch (plus the last) and each quantity of
    :data:`TIMESERIES_QUANTITIES`, then of :data:`TIMESERIES_SIGMAS` when the run carries them, in its
    unit.  A batch computes it on the worker."""
    keep = np.arange(0, len(s), max(int(every), 1))
    if keep[-1] != len(s) - 1:
        keep = np.append(keep, len(s) - 1)
    cols = {}
    for suffix, attr, col, scale in TIMESERIES_QUANTITIES + TIMESERIES_SIGMAS:
        arr = getattr(s, attr)
        if arr is None:                  # no sigma columns (a navigation that is not aided)
            continue
        v = arr[keep] if col is None else arr[keep, col]
        cols[suffix] = v * scale
    return s.time[keep], cols


def timeseries_frame(columns: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]):
    """Wide table on the union of epochs: ``time``, then ``<method>.<quantity>`` (empty where absent);
    ``columns``: method -> :func:`timeseries_columns`."""
    import pandas as pd   # 0.3 s, only for the wide timeseries table (tests/test_cli_startup.py)

    cols = {}
    for name, (time, values) in columns.items():
        idx = pd.Index(time, name="time")
        for suffix, v in values.items():
            cols[f"{name}.{suffix}"] = pd.Series(v, index=idx)
    return pd.DataFrame(cols).sort_index()


def write_timeseries_csv(path, columns: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]) -> None:
    """``timeseries.csv`` (see :func:`timeseries_frame`); floats in shortest round-trip form."""
    sigma_suffixes = {suffix for suffix, _, _, _ in TIMESERIES_SIGMAS}
    for name, (time, values) in columns.items():
        check_finite(path, {f"{name}.{k}": v for k, v in values.items()}, time,
                     sigmas=[f"{name}.{k}" for k in values if k in sigma_suffixes])
    frame = timeseries_frame(columns)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=True, na_rep="", lineterminator="\n")


def write_metric_series_csv(outdir, results) -> list[str]:
    """``ate.csv`` (method, time, ate_m) and ``rpe.csv`` (method, time_start, time_end, trans_m, rot_deg)."""
    outdir = Path(outdir)
    written = []
    for m, r in results.items():
        check_finite(outdir / "ate.csv", {f"{m}.ate_m": r.ate_m} if r.ate_m is not None else {}, r.time)
        if r.rpe_i is not None:
            check_finite(outdir / "rpe.csv", {f"{m}.trans_m": r.rpe_trans_m, f"{m}.rot_deg": r.rpe_rot_deg},
                         r.time[r.rpe_i])
    ate = {m: r for m, r in results.items() if r.ate_m is not None}
    if ate:
        with atomic_path(outdir / "ate.csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["method", "time", "ate_m"])
            for m, r in ate.items():
                w.writerows([m, _r(t), _r(e)] for t, e in zip(r.time, r.ate_m))
        written.append("ate.csv")
    rpe = {m: r for m, r in results.items() if r.rpe_i is not None}
    if rpe:
        with atomic_path(outdir / "rpe.csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(["method", "time_start", "time_end", "trans_m", "rot_deg"])
            for m, r in rpe.items():
                w.writerows([m, _r(r.time[i]), _r(r.time[j]), _r(a), _r(b)]
                            for i, j, a, b in zip(r.rpe_i, r.rpe_j, r.rpe_trans_m, r.rpe_rot_deg))
        written.append("rpe.csv")
    return written
