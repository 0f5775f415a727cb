"""The interactive ``index.html`` of a comparison: summary in words, plan view, linked error plots, tables.

It draws what the report's other files hold (:class:`~.digest.SeriesDigest` lines, the
:class:`~.errors.ErrorTable`), so the single ``sins compare`` and a batch's per-run pages are the
same page.  Rendering only: every number comes from :mod:`sinscli.evaluate.errors`,
:mod:`sinscli.evaluate.stats` and :mod:`sinscli.evaluate.metrics`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..evaluate.errors import (
    CONSISTENCY_UNITS,
    HEADLINE,
    ROW_UNITS,
    ConsistencyTable,
    ErrorTable,
)
from ..nav.earth import lla_to_local_enu
from .figures import ATTITUDE_FIGURES, _angle_unit, envelope
from .tables import CONSISTENCY_LABELS, ROW_LABELS
from .webpage import Page, esc, table

DASHES = ["", "6 3", "2 2", "8 3 2 3"]
LINE_BINS = 1000          # min/max bins per line on the page (the PNGs keep 4000); a plot is 860 px wide
SIGMA_BINS = 300          # the claimed sigma varies slowly
TRACK_POINTS = 2000       # plan-view points per trajectory
_AXES = {"e": "east", "n": "north", "u": "up"}


def display_unit(unit: str) -> str:
    """A table's unit cell: nothing for a dimensionless quantity (never "1")."""
    return "" if unit in ("1", "") else unit


def row_meaning(key: str) -> str:
    """The error-table row ``key`` in words."""
    if key[0] == "C" and len(key) == 3:
        return (f"truth minus navigation element (row {key[1]}, column {key[2]}) of the direction-cosine matrix "
                "Cbn from body to navigation axes")
    kind, _, axis = key.rpartition("_")
    words = {"E": "east", "N": "north", "U": "up"}
    if kind in ("pos", "vel"):
        return f"{words[axis]} {'position' if kind == 'pos' else 'velocity'} error, truth minus navigation, at the epoch"
    if kind in ("max_pos", "max_vel"):
        return f"largest |{words[axis]} {'position' if kind == 'max_pos' else 'velocity'} error| over the run"
    if key == "max_att_deg":
        return "largest attitude error angle |phi| over the run (phi: the rotation from navigation to truth attitude)"
    if key == "align_scale":
        return "scale of the Sim(3) alignment of the trajectory to the truth"
    for g, what in (("rpe_trans", "relative pose error, translation part"), ("rpe_rot", "relative pose error, "
                     "rotation angle"), ("ate", "absolute trajectory error |p_nav - p_truth|")):
        if key.startswith(g + "_"):
            stat = key[len(g) + 1:]
            return f"{what}: {'RMS' if stat == 'rmse' else stat} over the epochs" + (" (pairs)" if g != "ate" else "")
    return key


def error_table(table_: ErrorTable, legend: dict[str, str]) -> str:
    """The seed-000 table with each row's notation explained in words; columns named by ``legend``."""
    header = ["No.", "Notation", "Meaning", "Unit"] + [legend.get(m, m) for m in table_.methods]
    rows = [[r + 1, ROW_LABELS[k].replace("\\|", "|"), row_meaning(k), display_unit(ROW_UNITS[k])]
            + [float(v) for v in table_.values[r]] for r, k in enumerate(table_.rows)]
    return table(header, rows, sortable=True)


def consistency_table(cons: ConsistencyTable, legend: dict[str, str]) -> str:
    header = ["Quantity", "Unit"] + [legend.get(m, m) for m in cons.methods]
    rows = [[CONSISTENCY_LABELS[k], display_unit(CONSISTENCY_UNITS[k])] + [float(v) for v in cons.values[r]]
            for r, k in enumerate(cons.rows)]
    return table(header, rows, num_format="{:.4f}")


@dataclass
class GnssOverlay:
    """GNSS fixes in the plan view's frame and its outages (gaps over 3 nominal intervals)."""
    name: str
    time: np.ndarray          # (N,) s
    east: np.ndarray          # (N,) m, local ENU at the truth's first point
    north: np.ndarray
    outages: list             # (start, length) s


def gnss_overlay(gnss, truth, name: str) -> GnssOverlay:
    """:class:`GnssOverlay` of a :class:`~sinscli.types.GnssLog` (degrees) about the truth's first point."""
    # the fusion stage (scipy.stats, its kernels' modules) loads only for a report with GNSS fixes
    from ..fusion.options import FusionOptions
    from ..fusion.pipeline import outages
    enu = lla_to_local_enu(np.radians(gnss.lat), np.radians(gnss.lon), gnss.height,
                           float(truth.lat[0]), float(truth.lon[0]), float(truth.height[0]))
    return GnssOverlay(name, gnss.time, enu[:, 0], enu[:, 1], outages(gnss.time, FusionOptions().outage))


def overlay_from_arrays(arrays, name: str) -> GnssOverlay | None:
    """The :class:`GnssOverlay` a batch job stored (``gnss.*`` arrays), or None."""
    if "gnss.time" not in arrays:
        return None
    # the fusion stage loads only for a report with GNSS fixes (tests/test_cli_startup.py)
    from ..fusion.options import FusionOptions
    from ..fusion.pipeline import outages
    t = np.asarray(arrays["gnss.time"])
    return GnssOverlay(name, t, np.asarray(arrays["gnss.east"]), np.asarray(arrays["gnss.north"]),
                       outages(t, FusionOptions().outage))


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def summary_lines(digests: dict, legend: dict[str, str], truth_name: str | None, table_: ErrorTable | None,
                  gnss: GnssOverlay | None = None) -> list[str]:
    """The summary in words: what was compared, the time span, headline max/RMS and the best method of each."""
    names = [legend.get(m, m) for m in digests]
    out = []
    if truth_name:
        out.append(f"Compared {len(names)} trajectory file(s) with the truth {truth_name}: {', '.join(names)}.")
    spans = {m: (float(d.timeseries[0][0]), float(d.timeseries[0][-1])) for m, d in digests.items()
             if len(d.timeseries[0])}
    if spans:
        t0, t1 = min(s[0] for s in spans.values()), max(s[1] for s in spans.values())
        out.append(f"Time span compared: {t0!r} to {t1!r} s ({t1 - t0:.6g} s)"
                   + ("" if table_ is None or table_.epoch is None else
                      f"; the table's epoch errors are at t = {float(table_.epoch)!r} s") + ".")
    if gnss is not None:
        out.append(f"GNSS {gnss.name}: {len(gnss.time)} fixes, {len(gnss.outages)} outage(s)"
                   + (": " + ", ".join(f"{len_:.3g} s from {t!r} s" for t, len_ in gnss.outages[:5])
                      if gnss.outages else "") + ".")
    heads = {m: d.headline for m, d in digests.items() if d.headline is not None and np.all(np.isfinite(d.headline))}
    for k, (key, (what, unit)) in enumerate(HEADLINE.items()):
        if not heads:
            break
        parts = [f"{legend.get(m, m)} max {_fmt(h[2 * k])} {unit}, RMS {_fmt(h[2 * k + 1])} {unit}"
                 for m, h in heads.items()]
        line = f"{what[0].upper()}{what[1:]}: " + "; ".join(parts)
        if len(heads) > 1:
            rms = {m: h[2 * k + 1] for m, h in heads.items()}
            best = min(rms, key=rms.get)
            ties = [m for m in rms if m != best and rms[m] <= rms[best] * (1 + 1e-3) + 1e-300]
            line += (f". Lowest RMS: {legend.get(best, best)}" if not ties else
                     f". Equal RMS (within 0.1 %): {', '.join(legend.get(m, m) for m in [best] + ties)}")
        out.append(line + ".")
    return out


def _time_axis(digests: dict) -> tuple[float, str]:
    t0s = [float(d.timeseries[0][0]) for d in digests.values() if len(d.timeseries[0])]
    x0 = min(t0s) if t0s else 0.0
    return x0, ("time (s)" if x0 == 0.0 else f"time since t0 = {x0!r} s (s)")


def _line_plot(pid, title, ylabel, lines, legend, quantity, scale, x0, xlabel, spans, logy=False) -> dict:
    series = []
    for k, (m, ln) in enumerate(lines.items()):
        sd = ln.get(f"{quantity}_std")
        if sd is not None:
            t, s = envelope(np.asarray(sd[0]), np.asarray(sd[1]), SIGMA_BINS)
            series.append({"name": f"{legend.get(m, m)} +-1 and +-3 sigma (own claim)", "style": "sigma",
                           "x": t - x0, "s": s * scale, "mult": [3, 1], "opacity": [0.08, 0.2], "ci": k})
    for k, (m, ln) in enumerate(lines.items()):
        if quantity not in ln:
            continue
        t, y = envelope(np.asarray(ln[quantity][0]), np.asarray(ln[quantity][1]), LINE_BINS)
        series.append({"name": legend.get(m, m), "x": t - x0, "y": np.asarray(y) * scale, "ci": k,
                       "dash": DASHES[k % len(DASHES)]})
    return {"id": pid, "kind": "line", "title": title, "xlabel": xlabel, "ylabel": ylabel, "group": "time",
            "logy": logy, "series": series, "spans": spans, "spanlabel": "GNSS outage"}


def add_error_plots(page: Page, lines: dict, legend: dict[str, str], x0: float, xlabel: str,
                    gnss: GnssOverlay | None = None) -> None:
    """Attitude (roll, pitch, heading, angle), position and velocity E, N, U against time, x-axes linked."""
    if not lines:
        return
    spans = [] if gnss is None else [[t - x0, t + d - x0] for t, d in gnss.outages]
    unit, scale = _angle_unit(lines)
    page.h("Errors against time (truth minus navigation)")
    for _, q, label in ATTITUDE_FIGURES:
        page.plot(_line_plot(f"plot-{q}", label, f"truth - navigation ({unit})", lines, legend, q, scale, x0,
                             xlabel, spans))
    logy = any(np.max(ln["att_angle"][1]) > 0 for ln in lines.values() if len(ln["att_angle"][1]))
    page.plot(_line_plot("plot-att_angle", "Attitude error angle |phi|" + (" (log scale)" if logy else ""),
                         f"angle ({unit})", lines, legend, "att_angle", scale, x0, xlabel, spans, logy))
    for prefix, what, u in (("pos", "position", "m"), ("vel", "velocity", "m/s")):
        for ax in "enu":
            page.plot(_line_plot(f"plot-{prefix}_{ax}", f"{_AXES[ax].capitalize()} {what} error", f"{_AXES[ax]} ({u})",
                                 lines, legend, f"{prefix}_{ax}", 1.0, x0, xlabel, spans))


def plan_view(page: Page, lines: dict, legend: dict[str, str], gnss: GnssOverlay | None = None,
              metrics: dict | None = None) -> None:
    """East/north of the truth, every trajectory and the GNSS fixes (from the digests' tracks, or from the
    trajectory metrics' positions when there are no digests)."""
    series = []
    tracks = {m: ln for m, ln in lines.items() if "track_e" in ln}
    if tracks:
        first = next(iter(tracks.values()))
        st = max(1, -(-len(first["track_e"][1]) // TRACK_POINTS))
        series.append({"name": "truth", "truth": True, "width": 2.5, "x": first["track_e"][1][::st],
                       "y": first["track_n"][1][::st]})
        for k, (m, ln) in enumerate(tracks.items()):
            st = max(1, -(-len(ln["track_e"][1]) // TRACK_POINTS))
            series.append({"name": legend.get(m, m), "x": ln["track_nav_e"][1][::st], "y": ln["track_nav_n"][1][::st],
                           "ci": k, "dash": DASHES[k % len(DASHES)]})
        xlabel, ylabel = "east (m)", "north (m)"
    elif metrics:
        first = next(iter(metrics.values()))
        step = max(1, len(first.time) // TRACK_POINTS)
        series.append({"name": "truth", "truth": True, "width": 2.5, "x": first.ref_pos[::step, 0],
                       "y": first.ref_pos[::step, 1]})
        for k, (m, r) in enumerate(metrics.items()):
            step = max(1, len(r.time) // TRACK_POINTS)
            series.append({"name": legend.get(m, m) + ("" if r.alignment.mode == "none" else
                                                      f" ({r.alignment.mode}-aligned)"),
                           "x": r.est_pos[::step, 0], "y": r.est_pos[::step, 1], "ci": k,
                           "dash": DASHES[k % len(DASHES)]})
        xlabel, ylabel = "x / east (m)", "y / north (m)"
    else:
        return
    if gnss is not None:
        series.append({"name": f"GNSS fixes ({gnss.name})", "style": "points", "x": gnss.east, "y": gnss.north,
                       "color": "#888"})
    page.h("Plan view")
    page.plot({"id": "plot-plan", "kind": "plan", "title": "Track seen from above: truth and every trajectory"
               + (" with the GNSS fixes" if gnss is not None else ""), "xlabel": xlabel, "ylabel": ylabel,
               "series": series})


def add_box_plots(page: Page, stats, group: str, quantities: list[str], labels: dict, units: dict,
                  prefix: str) -> None:
    """One box plot per quantity, a box per ``group`` value (method, variant): p25-p75 box, median line,
    p5-p95 whiskers, min and max as points (from :func:`sinscli.evaluate.stats.row_statistics`)."""
    for q in quantities:
        sub = stats[stats["quantity"] == q]
        if sub.empty:
            continue
        boxes = [{"name": str(r[group]), **{k: float(r[k]) for k in ("p5", "p25", "p50", "p75", "p95", "min", "max")}}
                 for _, r in sub.iterrows()]
        u = display_unit(units.get(q, ""))
        page.plot({"id": f"{prefix}-{q}", "kind": "box", "title": labels.get(q, q) + (f" ({u})" if u else ""),
                   "ylabel": u, "series": [], "boxes": boxes, "height": 220})


def files_section(page: Page, files: list[str], figures: list[str]) -> None:
    page.h("Files")
    page.links("Data:", list(files))
    page.links("Figures for papers (PNG):", list(figures))


def compare_page(title: str, digests: dict, table_: ErrorTable | None, legend: dict[str, str] | None = None,
                 files: list[str] = (), figures: list[str] = (), notes: list[str] = (), truth_name: str | None = None,
                 extra_summary: list[str] = (), consistency: ConsistencyTable | None = None, metrics: dict | None = None,
                 gnss: GnssOverlay | None = None, extra_html: str = "") -> Page:
    """The whole page of one comparison (see the module docstring)."""
    legend = dict(legend or {})
    page = Page(title)
    page.h("Summary")
    page.items(summary_lines(digests, legend, truth_name, table_, gnss) + list(extra_summary))
    for n in notes:
        page.p(n, "note")
    lines = {m: d.lines for m, d in digests.items()}
    plan_view(page, lines, legend, gnss, metrics)
    x0, xlabel = _time_axis(digests)
    add_error_plots(page, lines, legend, x0, xlabel, gnss)
    if metrics:
        ate = {m: r for m, r in metrics.items() if r.ate_m is not None}
        if ate:
            series = []
            for k, (m, r) in enumerate(ate.items()):
                t, y = envelope(r.time, r.ate_m, LINE_BINS)
                series.append({"name": legend.get(m, m), "x": t - x0, "y": y, "ci": k, "dash": DASHES[k % 4]})
            page.plot({"id": "plot-ate", "kind": "line", "title": "Absolute trajectory error", "xlabel": xlabel,
                       "ylabel": "ATE (m)", "group": "time", "series": series})
    if table_ is not None:
        page.h("Trajectory metrics" if table_.epoch is None else
               f"Error table (seed 000 Tables 1-2) at t = {float(table_.epoch)!r} s")
        page.p("Notation of seed 000: subscript g is the truth, n the navigation; every error is truth minus "
               "navigation. Click a column header to sort.", "note")
        page.raw(error_table(table_, legend))
    if consistency is not None:
        page.h("Consistency of the navigators' own 1-sigma")
        page.p("Fraction of epochs whose error lies inside +-3 sigma (0.9973 for an honest Gaussian claim) and the "
               "average NEES over the three axes (3 for an honest claim).", "note")
        page.raw(consistency_table(consistency, legend))
    if extra_html:
        page.raw(extra_html)
    if files or figures:
        files_section(page, files, figures)
    return page


__all__ = ["compare_page", "GnssOverlay", "gnss_overlay", "summary_lines", "display_unit", "row_meaning",
           "add_box_plots", "esc"]
