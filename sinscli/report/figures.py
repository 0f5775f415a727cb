"""PNG figures of the errors against time (seed 000 Figs. 1-3, plus position and velocity).

For a run that carries the navigator's own 1-sigma (an aided trajectory), its
claim is drawn around zero: a shaded +-3 sigma band and dotted +-1 sigma lines.
The figures only draw: every number comes from :class:`ErrorSeries`, through
:func:`series_lines` (computed on a batch's worker).

Matplotlib's object API with the Agg canvas (no pyplot, no global state, safe
in worker processes and without a display).  Long runs are drawn as a min/max
envelope per pixel column, so every peak stays visible.
"""
from __future__ import annotations

import textwrap
import warnings

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..evaluate.errors import ErrorSeries
from ..io.atomic import atomic_path

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
#: The navigator's own 1-sigma of a plotted quantity (aided runs only): line name -> (attribute, column).
#: Its line is ``<name>_std``.
SIGMA_QUANTITIES = {
    "att_roll": ("att_std_rad", 0), "att_pitch": ("att_std_rad", 1), "att_heading": ("att_std_rad", 2),
    "pos_e": ("pos_std_m", 0), "pos_n": ("pos_std_m", 1), "pos_u": ("pos_std_m", 2),
    "vel_e": ("vel_std_mps", 0), "vel_n": ("vel_std_mps", 1), "vel_u": ("vel_std_mps", 2),
}
#: The plan view of a run (every ``stride``-th matched epoch, at most :data:`MAX_POINTS`): the truth's east
#: and north in the fixed local frame at its first point, and the navigation's (truth minus the error).
TRACK_NAMES = ["track_e", "track_n", "track_nav_e", "track_nav_n"]
#: Every line a run may have, in their order.
LINE_NAMES = list(LINE_QUANTITIES) + [f"{n}_std" for n in SIGMA_QUANTITIES] + TRACK_NAMES


def track_lines(s: ErrorSeries, max_points: int = MAX_POINTS) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The :data:`TRACK_NAMES` lines of one run (empty without ``s.track_enu_m``).  The navigation's
    plan position is the truth's minus the ENU position error (exact to ``|d|^2/R`` and the turn of the
    level frame over the track, far below a plotted pixel)."""
    if s.track_enu_m is None or not len(s):
        return {}
    idx = np.arange(0, len(s), max(1, int(np.ceil(len(s) / max_points))))
    t, trk, err = s.time[idx], s.track_enu_m[idx], s.pos_enu_m[idx]
    return {"track_e": (t, trk[:, 0]), "track_n": (t, trk[:, 1]),
            "track_nav_e": (t, trk[:, 0] - err[:, 0]), "track_nav_n": (t, trk[:, 1] - err[:, 1])}


def series_lines(s: ErrorSeries, max_points: int = MAX_POINTS) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """What the figures draw of one run: the :func:`envelope` ``(t, y)`` of each of
    :data:`LINE_QUANTITIES` (SI units, attitude in rad), and of each claimed 1-sigma of
    :data:`SIGMA_QUANTITIES` that the run carries (``<name>_std``).  A batch computes it on the worker,
    so only these few thousand points per line travel back."""
    out = {}
    for name, (attr, col) in LINE_QUANTITIES.items():
        arr = getattr(s, attr)
        out[name] = envelope(s.time, arr if col is None else arr[:, col], max_points)
    for name, (attr, col) in SIGMA_QUANTITIES.items():
        arr = getattr(s, attr)
        if arr is not None and len(s):
            out[f"{name}_std"] = envelope(s.time, arr[:, col], max_points)
    out.update(track_lines(s, max_points))
    return out


def _angle_unit(lines: dict[str, dict]) -> tuple[str, float]:
    """Degrees, or arcseconds when every attitude error stays below 1 arcminute."""
    peak = max((float(np.max(ln["att_angle"][1])) for ln in lines.values() if len(ln["att_angle"][1])),
               default=0.0)
    return ("arcsec", _DEG * 3600.0) if peak * _DEG < 1.0 / 60.0 else ("deg", _DEG)


def _tight(fig: Figure) -> None:
    """``tight_layout``, quietly: with a very long method name the margins cannot fit and matplotlib would
    print a warning on stderr; the figure is then drawn as laid out."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        fig.tight_layout()


def _save(fig: Figure, path) -> None:
    FigureCanvasAgg(fig)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)


_STYLES = ["-", "--", "-.", ":"]


def wrap_title(text: str, width: int = 90) -> str:
    """A long title broken into lines of at most ``width`` characters (never cut)."""
    return "\n".join(textwrap.wrap(text, width, break_long_words=True, break_on_hyphens=False)) or text


def _title(ax, title: str, what: str) -> None:
    """The quantity as the axes title, the report title (wrapped, never cut) above it."""
    ax.set_title(f"{wrap_title(title)}\n{what}" if title else what, fontsize=9)


MAX_LEGEND = 20            # lines labelled in a legend; more are told apart in timeseries.csv


def _legend(ax, n: int) -> None:
    if n <= MAX_LEGEND:
        ax.legend(fontsize=8)


def _line_plot(ax, lines: dict[str, dict], quantity: str, scale: float = 1.0) -> None:
    """One line per method; line styles cycle too, so that coinciding methods stay visible.

    A method whose lines hold the claimed 1-sigma of the quantity (``<quantity>_std``) gets it drawn as a
    shaded +-3 sigma band and thin +-1 sigma lines around zero, in the method's colour.
    """
    for k, (name, ln) in enumerate(lines.items()):
        t, y = ln[quantity]
        (line,) = ax.plot(t, y * scale if scale != 1.0 else y, lw=1.0, ls=_STYLES[k % len(_STYLES)], label=name,
                          zorder=3)
        sd = ln.get(f"{quantity}_std")
        if sd is not None:
            ts, ys = sd[0], (sd[1] * scale if scale != 1.0 else sd[1])
            color = line.get_color()
            ax.fill_between(ts, -3.0 * ys, 3.0 * ys, color=color, alpha=0.12, lw=0, label=f"{name} +-3 sigma",
                            zorder=1)
            ax.plot(ts, ys, color=color, lw=0.6, ls=":", alpha=0.8, label=f"{name} +-1 sigma", zorder=2)
            ax.plot(ts, -ys, color=color, lw=0.6, ls=":", alpha=0.8, zorder=2)
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
        _tight(fig)
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
    _tight(fig)
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
    _tight(fig)
    _save(fig, outdir / fname)
    return fname


def plot_position_velocity(outdir, lines: dict[str, dict], title: str = "") -> list[str]:
    """``pos_error.png`` and ``vel_error.png``: E, N, U panels, one line per method."""
    return [_three_panel(outdir, "pos_error.png", lines, "pos", "m", "Position", title),
            _three_panel(outdir, "vel_error.png", lines, "vel", "m/s", "Velocity", title)]


def plot_all(outdir, lines: dict[str, dict], title: str = "") -> list[str]:
    """Every figure of a report from ``lines`` (method -> :func:`series_lines`); returns the file names."""
    return plot_attitude(outdir, lines, title) + plot_position_velocity(outdir, lines, title)


def plot_metrics(outdir, results: dict, title: str = "", frame: str = "") -> list[str]:
    """``ate.png`` (ATE against time), ``rpe.png`` (RPE per pair) and ``trajectory_xy.png`` (plan view of
    the truth and every aligned trajectory) from :class:`~.metrics.TrajectoryMetrics` per method."""
    names = []
    ate = {m: r for m, r in results.items() if r.ate_m is not None}
    if ate:
        fig = Figure(figsize=(8, 4))
        ax = fig.add_subplot()
        for k, (name, r) in enumerate(ate.items()):
            t, y = envelope(r.time, r.ate_m)
            ax.plot(t, y, lw=1.0, ls=_STYLES[k % len(_STYLES)], label=name)
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("ATE (m)")
        _title(ax, title, "Absolute trajectory error |p_nav - p_truth|"
               + ("" if next(iter(ate.values())).alignment.mode == "none"
                  else f" after {next(iter(ate.values())).alignment.mode} alignment"))
        ax.legend(fontsize=8)
        _tight(fig)
        _save(fig, outdir / "ate.png")
        names.append("ate.png")
    rpe = {m: r for m, r in results.items() if r.rpe_i is not None}
    if rpe:
        fig = Figure(figsize=(8, 6))
        axes = fig.subplots(2, 1, sharex=True)
        for k, (name, r) in enumerate(rpe.items()):
            te = r.time[r.rpe_j]
            for ax, vals in zip(axes, (r.rpe_trans_m, r.rpe_rot_deg)):
                t, y = envelope(te, vals)
                ax.plot(t, y, lw=1.0, ls=_STYLES[k % len(_STYLES)], label=name)
        axes[0].set_ylabel("translation (m)")
        axes[1].set_ylabel("rotation (deg)")
        for ax in axes:
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("time at the pair's end (s)")
        _title(axes[0], title, "Relative pose error per pair")
        axes[0].legend(fontsize=8)
        _tight(fig)
        _save(fig, outdir / "rpe.png")
        names.append("rpe.png")
    first = next(iter(results.values()))
    fig = Figure(figsize=(7, 7))
    ax = fig.add_subplot()
    step = max(1, len(first.time) // (4 * MAX_POINTS))         # a plan view needs no more points than that
    ax.plot(first.ref_pos[::step, 0], first.ref_pos[::step, 1], "k-", lw=2.0, alpha=0.5, label="truth")
    for k, (name, r) in enumerate(results.items()):
        step = max(1, len(r.time) // (4 * MAX_POINTS))
        ax.plot(r.est_pos[::step, 0], r.est_pos[::step, 1], lw=1.0, ls=_STYLES[k % len(_STYLES)],
                label=name + ("" if r.alignment.mode == "none" else f" ({r.alignment.mode}-aligned)"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x / east (m)")
    ax.set_ylabel("y / north (m)")
    _title(ax, title, "Plan view" + (f": {frame}" if frame and len(frame) < 60 else ""))
    ax.legend(fontsize=8)
    _tight(fig)
    _save(fig, outdir / "trajectory_xy.png")
    return names + ["trajectory_xy.png"]
