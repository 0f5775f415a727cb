"""Figures of the alignment: the attitude against alignment time, and the Monte Carlo errors (seed 001
Figs. 1-3).  Matplotlib's object API on the Agg canvas (no pyplot state); files written atomically."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.atomic import atomic_path

ANGLES = ("roll", "pitch", "heading")


def _save(fig: Figure, path) -> None:
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def plot_series(path, t, euler_deg, title: str = "", sigma_deg=None) -> None:
    """Roll, pitch and heading estimates (deg) against alignment time ``t`` (s): three panels."""
    fig = Figure(figsize=(8, 7))
    axes = fig.subplots(3, 1, sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t, euler_deg[:, i], lw=1.0)
        if sigma_deg is not None and np.isfinite(sigma_deg[i]):
            end = euler_deg[-1, i]
            ax.axhspan(end - sigma_deg[i], end + sigma_deg[i], color="C1", alpha=0.2, label="final +-1 sigma")
            ax.legend(loc="best", fontsize=8)
        ax.set_ylabel(f"{ANGLES[i]} (deg)")
        ax.grid(True, alpha=0.3)
        ax.ticklabel_format(axis="y", style="plain", useOffset=False)
    axes[-1].set_xlabel("alignment time (s)")
    axes[0].set_title(title or "attitude estimate against alignment time", fontsize=10)
    fig.tight_layout()
    _save(fig, path)


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
                if lim is not None:
                    s = lim["heading" if i == 2 else "tilt"]
                    ax.axhline(s, color="k", ls="--", lw=1.0)
                    ax.axhline(-s, color="k", ls="--", lw=1.0)
                ax.set_title(f"{name}: {label}", fontsize=9)
                ax.set_xlabel("alignment time (s)")
                ax.set_ylabel(f"{ang} error (deg)")
                ax.grid(True, alpha=0.3)
                ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
        shown = next(iter(mc.variants.values())).current.shape[0]
        runs = f"{mc.runs} runs" if shown == mc.runs else f"{mc.runs} runs (lines: the first {shown})"
        fig.suptitle(f"{mc.scenario}: {ang} error of {runs} (dashed: static-base 1-sigma limit)", fontsize=10)
        fig.tight_layout()
        p = outdir / f"mc_{ang}.png"
        _save(fig, p)
        paths.append(str(p))
    return paths
