"""Figures of the alignment: the attitude against alignment time, and the Monte Carlo errors (seed 001
Figs. 1-3).  Matplotlib's object API on the Agg canvas (no pyplot state); files written atomically."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.atomic import atomic_path
from .figures import wrap_title

ANGLES = ("roll", "pitch", "heading")


def _save(fig: Figure, path) -> None:
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)


STARTUP_FRACTION = 0.1     # the first 10 % of the interval is the start-up a robust y-range leaves out


def robust_range(t, values, keep=(), startup: float = STARTUP_FRACTION, pad: float = 0.1):
    """A y-range (lo, hi) that a start-up transient does not flatten: the range of ``values`` (arrays over
    ``t``, any leading shape) after the first ``startup`` fraction of the time span, widened to hold the
    ``keep`` values (theory limits, a final sigma) and padded by ``pad`` of its height.  None when that
    range already holds every finite value (nothing to clip)."""
    t = np.asarray(t, dtype=float)
    vals = [np.asarray(v, dtype=float) for v in values]
    if t.size < 3 or not vals:
        return None
    late = t >= t[0] + startup * (t[-1] - t[0])
    tail = np.concatenate([v[..., late].ravel() for v in vals] + [np.asarray(keep, dtype=float).ravel()])
    tail = tail[np.isfinite(tail)]
    every = np.concatenate([v.ravel() for v in vals])
    every = every[np.isfinite(every)]
    if tail.size == 0 or every.size == 0:
        return None
    lo, hi = float(tail.min()), float(tail.max())
    h = max(hi - lo, 1e-12 * max(1.0, abs(lo), abs(hi)))
    lo, hi = lo - pad * h, hi + pad * h
    if every.min() >= lo and every.max() <= hi:
        return None
    return lo, hi


def _clip_note(ax, lim, values) -> None:
    """Apply a robust y-range and say on the axes what lies beyond it."""
    ax.set_ylim(*lim)
    every = np.concatenate([np.asarray(v, dtype=float).ravel() for v in values])
    every = every[np.isfinite(every)]
    ax.text(0.99, 0.02, f"start-up transient clipped (full range {every.min():.3g} to {every.max():.3g})",
            transform=ax.transAxes, ha="right", va="bottom", fontsize=7, color="0.35")


def plot_series(path, t, euler_deg, title: str = "", sigma_deg=None, final_deg=None,
                heading_supplied: bool = False) -> None:
    """Write :func:`series_figure` to ``path`` (PNG)."""
    _save(series_figure(t, euler_deg, title, sigma_deg, final_deg, heading_supplied), path)


def series_figure(t, euler_deg, title: str = "", sigma_deg=None, final_deg=None,
                  heading_supplied: bool = False) -> Figure:
    """Roll, pitch and heading estimates (deg) against alignment time ``t`` (s): three panels.

    ``final_deg`` (roll, pitch, heading of the written state) is drawn as a marker at the end; with
    ``heading_supplied`` (a user heading) the last epoch, which holds that heading and not the
    estimator's, is left out of the line so that the supplied heading never shows as a jump.  A
    start-up transient is clipped by :func:`robust_range` (and says so).
    """
    fig = Figure(figsize=(8, 7))
    axes = fig.subplots(3, 1, sharex=True)
    t = np.asarray(t, dtype=float)
    line_t, line = (t[:-1], euler_deg[:-1]) if heading_supplied and len(t) > 1 else (t, euler_deg)
    for i, ax in enumerate(axes):
        ax.plot(line_t, line[:, i], lw=1.0, label="estimate")
        end = euler_deg[-1, i] if final_deg is None else final_deg[i]
        keep = [end]
        if sigma_deg is not None and np.isfinite(sigma_deg[i]):
            ax.axhspan(end - sigma_deg[i], end + sigma_deg[i], color="C1", alpha=0.2, label="final +-1 sigma")
            keep += [end - sigma_deg[i], end + sigma_deg[i]]
        if final_deg is not None:
            supplied = heading_supplied and i == 2
            ax.plot([t[-1]], [final_deg[i]], marker="*" if supplied else "o", ms=11 if supplied else 6,
                    color="C3" if supplied else "C0", ls="none",
                    label="supplied heading (--heading)" if supplied else "written state", zorder=4)
        lim = robust_range(line_t, [line[:, i]], keep)
        if lim is not None:
            _clip_note(ax, lim, [line[:, i]])
        ax.legend(loc="best", fontsize=8)
        ax.set_ylabel(f"{ANGLES[i]} (deg)")
        ax.grid(True, alpha=0.3)
        ax.ticklabel_format(axis="y", style="plain", useOffset=False)
    axes[-1].set_xlabel("alignment time (s)")
    axes[0].set_title(wrap_title(title or "attitude estimate against alignment time"), fontsize=10)
    fig.tight_layout()
    return fig


def plot_monte_carlo(outdir, mc) -> list[str]:
    """One PNG per angle (``mc_roll.png``, ``mc_pitch.png``, ``mc_heading.png``): the error of every run
    against time, one column per variant (without / with the roll window, ...), rows for the estimate of
    the start attitude and of the current attitude; dashed lines at +-1 sigma of the static-base limit."""
    outdir = Path(outdir)
    names = list(mc.variants)
    paths = []
    for i, ang in enumerate(ANGLES):
        rows = [("start attitude Cbn(0)", "start"), ("current attitude Cbn(t)", "current")]
        rows = [r for r in rows if any(getattr(mc.variants[n], r[1]) is not None for n in names)]
        fig = Figure(figsize=(4.2 * len(names), 3.2 * len(rows)))
        axes = np.atleast_2d(fig.subplots(len(rows), len(names), squeeze=False))
        for r, (label, which) in enumerate(rows):
            for c, name in enumerate(names):
                ax = axes[r, c]
                v = mc.variants[name]
                arr = getattr(v, which)
                if arr is None:
                    ax.set_axis_off()
                    continue
                for run in arr:
                    ax.plot(v.time, run[:, i], lw=0.6, alpha=0.6)
                band = getattr(v, "band", {}).get(which)
                if band is not None:              # a large study: the first runs' lines, every run's spread
                    mean, std = band[0][:, i], band[1][:, i]
                    ax.fill_between(v.time, mean - std, mean + std, color="0.5", alpha=0.3, lw=0,
                                    label=f"mean +- 1 sigma of all {mc.runs} runs")
                    ax.plot(v.time, mean, color="k", lw=1.2)
                    ax.legend(fontsize=7, loc="best")
                lim = mc.theory.get(name)
                keep = []
                if lim is not None:
                    s = lim["heading" if i == 2 else "tilt"]
                    ax.axhline(s, color="k", ls="--", lw=1.0)
                    ax.axhline(-s, color="k", ls="--", lw=1.0)
                    keep = [-s, s]
                drawn = [arr[:, :, i]] + ([band[0][:, i] - band[1][:, i], band[0][:, i] + band[1][:, i]]
                                          if band is not None else [])
                yr = robust_range(v.time, drawn, keep)
                if yr is not None:            # a +-150 deg start-up must not flatten the rest
                    _clip_note(ax, yr, drawn)
                ax.set_title(f"{name}: {label}", fontsize=9)
                ax.set_xlabel("alignment time (s)")
                ax.set_ylabel(f"{ang} error (deg)")
                ax.grid(True, alpha=0.3)
                ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
        shown = next(iter(mc.variants.values())).current.shape[0]
        runs = f"{mc.runs} runs" if shown == mc.runs else f"{mc.runs} runs (lines: the first {shown})"
        fig.suptitle(wrap_title(f"{mc.scenario}: {ang} error of {runs} (dashed: static-base 1-sigma limit)"),
                     fontsize=10)
        fig.tight_layout()
        p = outdir / f"mc_{ang}.png"
        _save(fig, p)
        paths.append(str(p))
    return paths
