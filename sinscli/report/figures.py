"""PNG figures of the errors against time (seed 000 Figs. 1-3, plus position and velocity).

Matplotlib's object API with the Agg canvas (no pyplot, no global state, safe
in worker processes and without a display).  Long runs are drawn as a min/max
envelope per pixel column, so every peak stays visible.
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.atomic import atomic_path
from .errors import ErrorSeries

MAX_POINTS = 4000          # envelope bins per line
_DEG = float(np.degrees(1.0))

#: Attitude figures in the order of seed 000: Fig. 1 pitch, Fig. 2 yaw (heading), Fig. 3 roll.
ATTITUDE_FIGURES = [
    ("att_pitch.png", "att_pitch", "Pitch error (about the horizontal right axis)"),
    ("att_heading.png", "att_heading", "Heading (yaw) error (about the vertical)"),
    ("att_roll.png", "att_roll", "Roll error (about the horizontal forward axis)"),
]


def envelope(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Down-sample ``(t, y)`` to at most ``2 max_points`` points keeping each bin's min and max."""
    n = t.shape[0]
    if n <= 2 * max_points:
        return t, y
    per = int(np.ceil(n / max_points))
    m = n // per
    tb = t[: m * per].reshape(m, per)
    yb = y[: m * per].reshape(m, per)
    i_min, i_max = np.argmin(yb, axis=1), np.argmax(yb, axis=1)
    first = np.minimum(i_min, i_max)
    second = np.maximum(i_min, i_max)
    rows = np.arange(m)
    tt = np.stack([tb[rows, first], tb[rows, second]], axis=1).reshape(-1)
    yy = np.stack([yb[rows, first], yb[rows, second]], axis=1).reshape(-1)
    return np.concatenate([tt, t[m * per:]]), np.concatenate([yy, y[m * per:]])


#: The plotted quantities: line name -> (ErrorSeries attribute, column or None).
LINE_QUANTITIES = {
    "att_roll": ("att_rph_rad", 0), "att_pitch": ("att_rph_rad", 1), "att_heading": ("att_rph_rad", 2),
    "att_angle": ("angle_rad", None),
    "pos_e": ("pos_enu_m", 0), "pos_n": ("pos_enu_m", 1), "pos_u": ("pos_enu_m", 2),
    "vel_e": ("vel_enu_mps", 0), "vel_n": ("vel_enu_mps", 1), "vel_u": ("vel_enu_mps", 2),
}


def series_lines(s: ErrorSeries, max_points: int = MAX_POINTS) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """What the figures draw of one run: the :func:`envelope` ``(t, y)`` of each of
    :data:`LINE_QUANTITIES` (SI units, attitude in rad).  A batch computes it on the worker, so only
    these few thousand points per line travel back."""
    out = {}
    for name, (attr, col) in LINE_QUANTITIES.items():
        arr = getattr(s, attr)
        out[name] = envelope(s.time, arr if col is None else arr[:, col], max_points)
    return out


def _angle_unit(lines: dict[str, dict]) -> tuple[str, float]:
    """Degrees, or arcseconds when every attitude error stays below 1 arcminute."""
    peak = max((float(np.max(ln["att_angle"][1])) for ln in lines.values() if len(ln["att_angle"][1])),
               default=0.0)
    return ("arcsec", _DEG * 3600.0) if peak * _DEG < 1.0 / 60.0 else ("deg", _DEG)


def _save(fig: Figure, path) -> None:
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)


_STYLES = ["-", "--", "-.", ":"]


def _title(ax, title: str, what: str) -> None:
    """The quantity as the axes title, the report title (shortened) above it."""
    short = title if len(title) <= 80 else title[:77] + "..."
    ax.set_title(f"{short}\n{what}" if short else what, fontsize=9)


MAX_LEGEND = 20            # lines labelled in a legend; more are told apart in timeseries.csv


def _legend(ax, n: int) -> None:
    if n <= MAX_LEGEND:
        ax.legend(fontsize=8)


def _line_plot(ax, lines: dict[str, dict], quantity: str, scale: float = 1.0) -> None:
    """One line per method; line styles cycle too, so that coinciding methods stay visible."""
    for k, (name, ln) in enumerate(lines.items()):
        t, y = ln[quantity]
        ax.plot(t, y * scale if scale != 1.0 else y, lw=1.0, ls=_STYLES[k % len(_STYLES)], label=name)
    ax.grid(True, alpha=0.3)
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))


def plot_attitude(outdir, lines: dict[str, dict], title: str = "") -> list[str]:
    """``att_pitch.png``, ``att_heading.png``, ``att_roll.png`` (Figs. 1-3) and ``att_angle.png``;
    ``lines``: method -> :func:`series_lines`."""
    unit, scale = _angle_unit(lines)
    names = []
    for fname, quantity, label in ATTITUDE_FIGURES:
        fig = Figure(figsize=(8, 4))
        ax = fig.add_subplot()
        _line_plot(ax, lines, quantity, scale)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"truth - navigation ({unit})")
        _title(ax, title, label)
        _legend(ax, len(lines))
        fig.tight_layout()
        _save(fig, outdir / fname)
        names.append(fname)
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    _line_plot(ax, lines, "att_angle", scale)
    if any(np.max(ln["att_angle"][1]) > 0 for ln in lines.values() if len(ln["att_angle"][1])):
        ax.set_yscale("log")                 # methods often differ by orders of magnitude
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"angle ({unit})")
    _title(ax, title, "Attitude error angle |phi| (log scale)")
    _legend(ax, len(lines))
    fig.tight_layout()
    _save(fig, outdir / "att_angle.png")
    return names + ["att_angle.png"]


def _three_panel(outdir, fname, lines, prefix, unit, what, title) -> str:
    fig = Figure(figsize=(8, 7))
    axes = fig.subplots(3, 1, sharex=True)
    for ax, axis in zip(axes, ("east", "north", "up")):
        _line_plot(ax, lines, f"{prefix}_{axis[0]}")
        ax.set_ylabel(f"{axis} ({unit})")
    _title(axes[0], title, f"{what} error, truth - navigation")
    _legend(axes[0], len(lines))
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    _save(fig, outdir / fname)
    return fname


def plot_position_velocity(outdir, lines: dict[str, dict], title: str = "") -> list[str]:
    """``pos_error.png`` and ``vel_error.png``: E, N, U panels, one line per method."""
    return [_three_panel(outdir, "pos_error.png", lines, "pos", "m", "Position", title),
            _three_panel(outdir, "vel_error.png", lines, "vel", "m/s", "Velocity", title)]


def plot_all(outdir, lines: dict[str, dict], title: str = "") -> list[str]:
    """Every figure of a report from ``lines`` (method -> :func:`series_lines`); returns the file names."""
    return plot_attitude(outdir, lines, title) + plot_position_velocity(outdir, lines, title)
