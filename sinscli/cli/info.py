"""``sins info LOG``: what a ROS bag / MCAP log holds (topics, rates, gaps, IMU units and mounting)."""
from __future__ import annotations

import json
from pathlib import Path

import click

from .base import main


def _f(x, fmt):
    return "-" if x is None else format(x, fmt)


def format_summary(s: dict) -> str:
    """Human-readable text of :func:`sinscli.io.ros.log_summary`."""
    lines = [f"{s['path']}: {s['format']}, {s['messages']} messages"
             + (f", {s['duration']:.3f} s from {s['start']:.6f} to {s['end']:.6f} (log time)"
                if s["duration"] is not None else "")]
    w = max([len(r["topic"]) for r in s["topics"]] + [5])
    wt = max([len(r["type"]) for r in s["topics"]] + [4])
    lines.append(f"{'topic':<{w}}  {'type':<{wt}}  {'count':>8}  {'rate Hz':>9}  {'span s':>10}  "
                 f"{'max gap s':>9}  {'gaps':>4}")
    for r in s["topics"]:
        span = (r["end"] - r["start"]) if r["start"] is not None else None
        lines.append(f"{r['topic']:<{w}}  {r['type']:<{wt}}  {r['count']:>8}  {_f(r['rate_hz'], '9.3f')}  "
                     f"{_f(span, '10.3f')}  {_f(r['max_gap'], '9.4f')}  {r['gaps']:>4}")
    lines.append("(gaps: intervals longer than 5 median intervals)")
    for topic, m in s["imu"].items():
        a, g = m["mean_accel"], m["mean_gyro"]
        axis = max(range(3), key=lambda i: abs(a[i]))
        sign = "+" if a[axis] > 0 else "-"
        lines.append(f"IMU {topic}: means over the first {m['messages']} messages, message axes:")
        lines.append(f"  specific force ({a[0]:.4f}, {a[1]:.4f}, {a[2]:.4f}) m/s^2, |f| = {m['accel_norm']:.4f}")
        lines.append(f"  angular rate   ({g[0]:.6f}, {g[1]:.6f}, {g[2]:.6f}) rad/s, |w| = {m['gyro_norm']:.6f}")
        hint = f"  at rest the up axis is {sign}{'xyz'[axis]}"
        if not 9.0 < m["accel_norm"] < 10.6:
            hint += "; |f| is far from g: moving, or units are not m/s^2"
        elif not (axis == 2 and sign == ("-" if s.get("body") == "frd" else "+")):
            hint += "; set imu.mounting in the config so that the body axes match imu.body"
        lines.append(hint)
    if "rest" in s:
        rest = s["rest"]
        total = sum(b - a for a, b in rest)
        shown = ", ".join(f"{a:.3f}-{b:.3f}" for a, b in rest[:8]) + (f", ... ({len(rest) - 8} more)"
                                                                       if len(rest) > 8 else "")
        lines.append(f"rest windows (the fusion's standstill detector): {len(rest)}, {total:.1f} s in all"
                     + (f": {shown} s" if rest else "; the log never rests (align --method static will refuse)"))
    return "\n".join(lines)


@main.command("info")
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--imu-window", type=click.FloatRange(min=0.0), default=1.0, show_default=True,
              help="Seconds at the start of each Imu topic over which the means are taken (at least 10 messages).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="IMU CSV: the config that reads it (imu.columns, imu.units, imu.mounting).")
def info_cmd(log, as_json, imu_window, config_path):
    """Show the topics, message types, counts, rates, time span and gaps of a ROS 1 bag, ROS 2 bag
    (directory or .db3) or MCAP LOG, and for Imu topics the mean specific force and angular rate at
    the start (a quick look at units and mounting).  For an IMU CSV: its rate, gaps, rest windows and
    the same means (in the axes of the config's mounting, if any).

    \b
    Examples:
      sins info husky_imu_gps.bag
      sins info imu.csv --config nav.yaml
    """
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..io.raw_summary import format_raw_summary, raw_kind, raw_summary
    if raw_kind(log) is not None:                  # RINEX observations/navigation, UBX logs
        s = raw_summary(log)
        click.echo(json.dumps(s, indent=2) if as_json else format_raw_summary(s))
        return
    from ..io.readers import _is_log   # loaded when the command runs, as the rest
    if _is_log(log):
        from ..io.ros import log_summary   # the ROS back ends: only for a bag or MCAP
        s = log_summary(log, imu_window=imu_window)
    else:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..config import load_config
        from ..evaluate.imu_summary import csv_summary
        s = csv_summary(log, load_config(config_path), imu_window=imu_window)
    click.echo(json.dumps(s, indent=2) if as_json else format_summary(s))
