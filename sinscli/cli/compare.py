"""``sins compare``: navigation results against a truth (seed 000 Tables 1-2, Figs. 1-3), or a batch."""
from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import SinsError, printable
from .base import main, progress, quiet_option
from .batch_options import info_echo, interrupted_exit, scheduler_options, verbose

BODY = {"flu": 0, "rfu": 1, "frd": 2}


def _labels(navs: list[Path], given: tuple[str, ...]) -> list[str]:
    """Column names: ``--label`` values in order, else the file stems made unique."""
    if given:
        if len(given) != len(navs):
            raise SinsError(f"--label given {len(given)} time(s) for {len(navs)} NAV file(s); give one per NAV file")
        if len(set(given)) != len(given):
            raise SinsError(f"--label values must differ, got {', '.join(given)}")
        return list(given)
    out = []
    for p in navs:
        name = printable(p.stem)
        if name in out:
            name = f"{printable(p.parent.name)}/{name}"
        k = 2
        base = name
        while name in out:
            name = f"{base}-{k}"
            k += 1
        out.append(name)
    return out


@main.command("compare")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--truth", type=click.Path(path_type=Path),
              help="Truth trajectory (CSV or Parquet, docs/formats.md). Without it, INPUTS is one BATCH.yaml.")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(path_type=Path, file_okay=False),
              help="Report directory (created; report files in it are replaced).")
@click.option("--label", multiple=True, help="Column name of each NAV file, in order (default: file stems).")
@click.option("--epoch", type=float, default=None,
              help="Epoch (s) of the table rows (default: the last epoch common to all NAV files).")
@click.option("--interpolate", is_flag=True,
              help="Interpolate the truth at the navigation epochs (default: exact time match only).")
@click.option("--body", type=click.Choice(sorted(BODY)), default=None,
              help="Body axes of a file that does not tell them (no 'body' column or Parquet metadata, and "
                   "attitude columns that do not match its roll/pitch/heading); default flu (docs/formats.md). "
                   "Each file's own axes are used otherwise, so files of different conventions compare.")
@click.option("--timeseries-every", type=click.IntRange(min=1), default=1, show_default=True,
              help="Write every N-th epoch to timeseries.csv (tables and figures use all).")
@click.option("--title", default=None, help="Report title (default: the files compared, by name).")
@click.option("--gnss", "gnss_path", type=click.Path(path_type=Path), default=None,
              help="GNSS fixes (CSV, docs/formats.md) drawn in the plan view, their outages shaded on the time plots.")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Batch: worker processes of the local pool (default: all cores).")
@click.option("--metrics", "metrics", default=None, metavar="ate,rpe",
              help="Trajectory metrics (evo's definitions) added to the table: ate, rpe or both. "
                   "Default: none, or ate,rpe when an input is a TUM file.")
@click.option("--align-traj", type=click.Choice(["none", "se3", "sim3"]), default="none", show_default=True,
              help="Umeyama alignment of each trajectory to the truth before the metrics.")
@click.option("--rpe-delta", type=float, default=1.0, show_default=True,
              help="RPE pair spacing, in --rpe-unit.")
@click.option("--rpe-unit", type=click.Choice(["s", "m", "f"]), default="s", show_default=True,
              help="RPE pair spacing unit: seconds, metres of travelled path, or epochs (frames).")
@click.option("--rpe-pairs", type=click.Choice(["ref", "est"]), default="ref", show_default=True,
              help="Take the RPE pairs from the truth path (the same pairs for every method) or from each "
                   "trajectory (evo's default).")
@click.option("--start", default=None, metavar="T",
              help="Compare from T on (time of the files' clock, or +S after the truth's first epoch): the "
                   "tables, maxima and figures cover the window only.")
@click.option("--end", default=None, metavar="T", help="Compare up to T (time, or +S after the truth's first epoch).")
@click.option("--time-offset", type=float, default=None,
              help="Seconds added to every truth time on reading (a truth whose clock differs from the IMU's; "
                   "config truth.time_offset, as gnss.time_offset for GNSS).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="Config YAML whose truth section says the truth's frame (enu|ned), angle units (deg|rad) "
                   "and time offset (configs/navigation.yaml).")
@scheduler_options
@quiet_option
@click.pass_context
def compare(ctx, inputs, truth, outdir, label, epoch, interpolate, body, timeseries_every, title, gnss_path, jobs,
            metrics, align_traj, rpe_delta, rpe_unit, rpe_pairs, start, end, time_offset, config_path, scheduler,
            resume, figures, quiet):
    """Compare navigation results with a truth: error tables, time series, figures, index.html.

    \b
      sins compare --truth truth.csv nav_quat.csv nav_dcm.csv -o report/
      sins compare configs/batch/seed000.yaml -o seed000/ --jobs 2
      sins compare study.yaml -o out/ --scheduler tcp://10.0.0.5:8786 --resume

    Errors are truth minus navigation.  Exit status: 0 success; 2 bad input
    (nothing written); in batch mode 1 when some jobs failed (the others are
    still reported, the failures listed in summary.md and on stderr).
    """
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..io.atomic import prepare_output
    prepare_output(outdir, directory=True)      # before any work: a file, no permission
    if truth is None:
        if len(inputs) != 1 or inputs[0].suffix.lower() not in (".yaml", ".yml"):
            raise SinsError("give --truth TRUTH with one or more NAV files, or a single BATCH.yaml")
        for opt, val in (("--label", label), ("--epoch", epoch), ("--interpolate", interpolate),
                         ("--title", title), ("--gnss", gnss_path), ("--metrics", metrics), ("--align-traj", align_traj != "none"),
                         ("--rpe-delta", rpe_delta != 1.0), ("--rpe-unit", rpe_unit != "s"),
                         ("--rpe-pairs", rpe_pairs != "ref"), ("--start", start), ("--end", end),
                         ("--time-offset", time_offset), ("--config", config_path)):
            if val:
                raise SinsError(f"{opt}: not used with a batch file; set it in {inputs[0]}")
        _batch(inputs[0], outdir, jobs, scheduler, resume, figures, quiet, ctx)
        return
    for opt, val in (("--jobs", jobs), ("--scheduler", scheduler), ("--resume", resume),
                     ("--figures", figures != "auto")):
        if val:
            raise SinsError(f"{opt}: only used with a batch file (sins compare BATCH.yaml -o DIR)")
    if any(p.suffix.lower() in (".yaml", ".yml") for p in inputs):
        raise SinsError(f"{next(p for p in inputs if p.suffix.lower() in ('.yaml', '.yml'))}: a batch file "
                        "is given alone, without --truth")
    mopts = None
    if metrics is not None or any(_is_tum(p) for p in (truth, *inputs)):
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..evaluate.compare_metrics import MetricOptions, parse_metrics
        mopts = MetricOptions(parse_metrics(metrics or "ate,rpe"), align_traj, rpe_delta, rpe_unit, rpe_pairs)
    elif (align_traj, rpe_delta, rpe_unit, rpe_pairs) != ("none", 1.0, "s", "ref"):
        raise SinsError("--align-traj and --rpe-* set how the trajectory metrics are computed: "
                        "give --metrics ate,rpe too")
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..config import load_config, merge
    from ..nav.window import make_window
    window = make_window(start, end, None)
    truth_cfg = merge(load_config(config_path), "truth", time_offset=time_offset)["truth"]
    _single(truth, list(inputs), outdir, label, epoch, interpolate, BODY[body or "flu"], timeseries_every, title,
            quiet, mopts, gnss_path, window, truth_cfg)


def _is_tum(path: Path) -> bool:
    """TUM trajectories (evo, SLAM/VIO systems): ``.tum`` and ``.txt`` files."""
    return path.suffix.lower() in (".tum", ".txt")


def _read(path: Path, section=None):
    """A trajectory (CSV/Parquet) or the rows of a TUM file; ``section`` (the config's ``truth``) its frame and
    angle units."""
    if _is_tum(path):
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..io.tum import read_tum
        from ..evaluate.compare_metrics import TumTrack
        return TumTrack(*read_tum(path), source=str(path))
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..frames import convention
    from ..io.trajectory import read_trajectory
    return read_trajectory(path, None, *convention(section))


def _legend(navs: list[Path], names: list[str], given: tuple[str, ...]) -> dict[str, str]:
    """How figures and the page name each method: its ``--label``, else its file as given (or the file
    name when the path is long)."""
    if given:
        return dict(zip(names, names))
    out = {}
    for name, p in zip(names, navs):
        text = printable(p) if len(str(p)) <= 60 else printable(p.name)
        out[name] = text if text not in out.values() else name
    return out


def default_title(truth_path: Path, legend: dict[str, str]) -> str:
    """The report title naming the files: ``a.csv, b.csv against the truth truth.csv``."""
    return f"{', '.join(legend.values())} against the truth {printable(Path(truth_path).name)}"


def _single(truth_path, navs, outdir, label, epoch, interpolate, conv, every, title, quiet, mopts, gnss_path=None,
            window=None, truth_cfg=None):
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..evaluate.errors import compare_trajectories
    from ..report.report import write_report
    from ..types import Trajectory

    names = _labels(navs, label)
    legend = _legend(navs, names, label)
    truth = _read(truth_path, truth_cfg)
    trajs = [_read(p) for p in navs]
    time_offset = (truth_cfg or {}).get("time_offset", 0.0)
    if window is not None and window.active:    # absolute, against the truth's first epoch (after its offset)
        window = window.resolve(float(truth.time[0]) + float(time_offset or 0.0))
    window_note = _apply_window(truth, truth_path, trajs, navs, window, time_offset)
    window_note += _to_flu([truth, *trajs], [truth_path, *navs], conv)
    conv = 0                                    # every attitude is now of the FLU body axes
    if window is not None and window.active and title is None:        # the maxima are over the window
        title = f"{default_title(truth_path, legend)}, window {window.text()}"
    gnss = None
    if gnss_path is not None:
        if not isinstance(truth, Trajectory):
            raise SinsError(f"--gnss {gnss_path}: the plan view with GNSS needs a truth with latitude and longitude "
                            "(not a TUM file)")
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..io.gnss_csv import read_gnss_csv
        from ..report.compare_page import gnss_overlay
        gnss = gnss_overlay(read_gnss_csv(gnss_path), truth, printable(gnss_path.name))
    full = all(isinstance(x, Trajectory) for x in (truth, *trajs))    # the seed-000 table needs lat/lon, velocity
    series, results, frame = {}, {}, ""
    with progress(len(navs) + 1, "compare", quiet) as bar:
        if mopts is not None:
            # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
            from ..evaluate.compare_metrics import common_frame, compute_metrics
            ref, poses, frame = common_frame(truth, trajs, conv)
        for k, (name, path, nav) in enumerate(zip(names, navs, trajs)):
            if full:
                series[name] = compare_trajectories(truth, nav, conv=conv, interpolate=interpolate,
                                                     truth_name=printable(truth_path), nav_name=printable(path))
            if mopts is not None:
                results[name] = compute_metrics(ref, poses[k], mopts, interpolate, printable(truth_path), printable(path))
            bar.update(1)
        notes = [f"{legend[n]}: {printable(p)}" for n, p in zip(names, navs) if legend[n] != printable(p)] + window_note
        if interpolate:
            notes.append("The truth was interpolated at the navigation epochs.")
        if mopts is not None:
            # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
            from ..evaluate.compare_metrics import describe
            notes.append(describe(mopts, frame))
        if not full:
            notes.append("TUM inputs hold no latitude, longitude or velocity: the seed-000 rows (DCM elements, "
                         "ENU position and velocity errors) are omitted; the table holds the trajectory metrics.")
        table = write_report(outdir, series, title or default_title(truth_path, legend), epoch, every,
                             notes, metrics=results or None, metric_options=mopts, frame=frame, legend=legend,
                             truth_name=printable(truth_path), gnss=gnss)
        bar.update(1)
    at = "" if table.epoch is None else f" at t = {float(table.epoch)!r} s"
    from ..io.atomic import commit_outputs  # numpy: the atomic writers load when outputs are written, not for --help (tests/test_cli_startup.py)
    commit_outputs()                          # the report in place before the line that points to it
    click.echo(f"sins: compare: {len(navs)} method(s){at} -> {outdir}/index.html", err=True)
    if results:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        from ..evaluate.compare_metrics import summary_lines
        for line in summary_lines(results, mopts):
            click.echo(f"sins: compare: {line}", err=True)


def _to_flu(tracks, paths, default: int) -> list[str]:
    """Turn each trajectory's attitude into that of its FLU body axes (the file's own convention: its marker,
    else its angles, else ``default``), in place, so that files of different conventions compare.  Returns
    the report's note on the conventions."""
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..io.trajectory import BODY_NAMES
    from ..nav.rotation import body_flu_in_enu
    from ..types import Trajectory
    said = []
    for tr, path in zip(tracks, paths):
        if not isinstance(tr, Trajectory):
            continue                              # TUM attitudes are FLU
        code = tr.body if tr.body is not None else default
        how = {"marker": "its marker", "angles": "its attitude columns"}.get(tr.body_from, "--body or docs/formats.md")
        said.append(f"{printable(Path(path).name)} {BODY_NAMES[code].upper()} ({how})")
        if code != 0:
            tr.Cbn = body_flu_in_enu(tr.Cbn, code)
        tr.body, tr.body_from = 0, "converted"
    return [f"Body axes: {', '.join(said)}; attitudes compared as those of the FLU axes."] if said else []


def _apply_window(truth, truth_path, trajs, navs, window, time_offset) -> list[str]:
    """Shift the truth's times by ``time_offset`` and cut every track to the window, in place; refuse a
    window or an offset that leaves no common epoch.  Returns the report's notes on them."""
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..errors import num
    from ..nav.window import Window, check_in_log, cut_track
    notes = []
    if time_offset:
        truth.time = truth.time + float(time_offset)
        notes.append(f"The truth's times were shifted by {num(float(time_offset))} s (--time-offset).")
    window = (window or Window()).resolve(float(truth.time[0]))
    if window.active:
        check_in_log(window, float(truth.time[0]), float(truth.time[-1]), str(truth_path))
        cut_track(truth, window, str(truth_path))
        for nav, path in zip(trajs, navs):
            cut_track(nav, window, str(path))
        notes.append(f"Window: {window.text()} (tables, maxima and figures cover it only).")
    for nav, path in zip(trajs, navs):                  # (without an offset evaluate/errors.py diagnoses it)
        if time_offset and (nav.time[-1] < truth.time[0] or nav.time[0] > truth.time[-1]):
            shift = f" after the truth time offset of {num(float(time_offset))} s (--time-offset, truth.time_offset)"
            raise SinsError(f"{path}: no epoch in common with the truth {truth_path}{shift} (navigation "
                            f"{num(float(nav.time[0]))} to {num(float(nav.time[-1]))} s, truth "
                            f"{num(float(truth.time[0]))} to {num(float(truth.time[-1]))} s)")
    return notes


def _batch(batch_path, outdir, jobs, scheduler, resume, figures, quiet, ctx):
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..batch.compare import count_jobs, load_batch, run_batch

    spec = load_batch(batch_path)

    def on_error(msg):
        click.echo(f"\nsins: error: {msg}", err=True)

    with interrupted_exit(), progress(count_jobs(spec), "batch", quiet) as bar:
        result = run_batch(spec, outdir, jobs=jobs, on_progress=bar.update, on_error=on_error,
                           scheduler=scheduler, resume=resume, figures=figures, on_info=info_echo(quiet),
                           verbose=verbose(ctx))
    n_fail = len(result.failed) + len(result.report_errors)
    from ..io.atomic import commit_outputs  # numpy: the atomic writers load when outputs are written, not for --help (tests/test_cli_startup.py)
    commit_outputs()
    resumed = f" ({result.resumed} resumed from {outdir}/jobs, {result.ran} run)" if result.resumed else ""
    click.echo(f"sins: compare: {len(result.jobs)} jobs{resumed}, {len(result.failed)} failed; "
               f"{len(result.reports)} report(s) -> {outdir}/index.html", err=True)
    if n_fail:
        sys.exit(1)
