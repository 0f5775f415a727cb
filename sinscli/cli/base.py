"""The ``sins`` command group: error handling, logging and progress shared by all commands."""
from __future__ import annotations

import atexit
import codecs
import contextlib
import importlib
import logging
import os
import signal
import sys
import threading
from pathlib import Path

import click

from .. import NUMBA_CACHE_NOTE
from .._numba_cache import CompileProgress, announce_compiles
from ..errors import SinsError

log = logging.getLogger("sins")


# command name -> module under sinscli.cli that defines it; imported on first use, so that
# `sins navigate` does not pay for the simulator, reports or alignment at start-up.
COMMANDS = {"navigate": "navigate", "align": "align", "simulate": "simulate", "compare": "compare",
            "info": "info", "convert": "convert", "allan": "allan", "gnss": "gnss"}

# commands that run numba kernels: the first compile in a process says so (sinscli/_numba_cache.py)
COMPILING_COMMANDS = frozenset({"navigate", "align", "simulate", "compare", "allan", "spp"})

# CPU seconds each command's first run spends compiling when no kernel of it is cached (an editable
# install, another numba than the one the wheel was built with): the estimate of its refreshed progress
# line, scaled there by the load.  Measured by _build/precompile.py (issue 21), each command after the ones
# before it in its lane; plain navigation's own figure per method is nav/pipeline.py's FIRST_RUN_SECONDS.
COMPILE_SECONDS = {"navigate": 9, "navigate --gnss": 50, "align": 30, "simulate": 35, "compare": 15, "allan": 5,
                   "gnss spp": 45}

# The first paragraph of each command's help, for the listing of `sins --help`: with it the
# listing imports no command module (numpy, numba, the simulator, the ROS readers), so it takes
# ~0.1 s instead of ~0.6 s.  click shortens it exactly as it would the command's own help;
# tests/test_cli_startup.py checks that the listing equals the one click makes from the
# commands themselves.  A command missing here is imported for the listing.
SHORT_HELP = {
    "allan": "Allan deviation of a static IMU log: noise terms and a sensor.yaml in the presets' schema.",
    "align": "Initial alignment: the attitude (and state) where navigation starts, with its 1-sigma.",
    "compare": "Compare navigation results with a truth: error tables, time series, figures, index.html.",
    "convert": "Convert a ROS 1 bag, ROS 2 bag (directory or .db3) or MCAP LOG into docs/formats.md CSV files: "
               "DIR/imu.csv (increments, axes as in the messages) and DIR/gnss.csv (when the log has a "
               "NavSatFix topic).",
    "info": "Show the topics, message types, counts, rates, time span and gaps of a ROS 1 bag, ROS 2 bag "
            "(directory or .db3) or MCAP LOG, and for Imu topics the mean specific force and angular rate "
            "at the start (a quick look at units and mounting).",
    "gnss": "Raw GNSS observations: single-point positioning (see docs/raw_gnss.md).",
    "navigate": "Navigate IMU increments from an initial state and write the trajectory.",
    "simulate": "Simulate SCENARIO.yaml: IMU increments, GNSS fixes and the exact truth (see docs/simulate.md).",
}


_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())    # click >= 8.2


def _exit_now(code) -> None:
    """End the process with ``code`` once its work is done: stdio flushed, the ``atexit`` handlers run
    (logging, Dask clients, temporary folders), then ``os._exit``.  The interpreter's own teardown (freeing
    every object and module: numba, llvmlite, pyarrow, matplotlib) is skipped: it held the process 2-9 s
    after its last line on a loaded machine (issue 22), and there is nothing left in it to keep."""
    status = code if isinstance(code, int) else (0 if code is None else 1)
    if code is not None and not isinstance(code, int):
        with contextlib.suppress(Exception):
            print(code, file=sys.stderr)
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(status)


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP: raised in the main thread, so every ``atomic_path`` removes its
    temporary file on the way out, as for Ctrl-C."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = int(signum)


def _bytes_as_escapes(exc):
    """Codec error handler: a path byte that is not UTF-8 (held by Python as a surrogate) printed as ``\\xNN``,
    as :func:`sinscli.errors.printable` writes it into files."""
    if isinstance(exc, UnicodeEncodeError):
        bad = exc.object[exc.start:exc.end]
        return "".join(f"\\x{ord(c) - 0xDC00:02x}" if 0xDC80 <= ord(c) <= 0xDCFF else f"\\u{ord(c):04x}"
                       for c in bad), exc.end
    raise exc


def _printable_stderr() -> None:
    """stdout and stderr write a name's non-UTF-8 bytes as ``\\xNN`` (not Python's ``\\udcNN``, and never a
    UnicodeEncodeError: `sins info` prints file names on stdout)."""
    try:
        codecs.lookup_error("sins-bytes")
    except LookupError:
        codecs.register_error("sins-bytes", _bytes_as_escapes)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, ValueError, OSError):
            stream.reconfigure(errors="sins-bytes")


def _raise_interrupted(signum, frame):
    raise Interrupted(signum)


@contextlib.contextmanager
def _signals_as_interrupt():
    """SIGTERM and SIGHUP handled like SIGINT while a command runs (the old handlers restored after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        with contextlib.suppress(ValueError, OSError):
            old[sig] = signal.signal(sig, _raise_interrupted)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _interrupted(exc: BaseException) -> None:
    signum = getattr(exc, "signum", signal.SIGINT)
    name = signal.Signals(signum).name
    click.echo(f"sins: interrupted ({name}); no output written", err=True)
    sys.exit(128 + signum)


# parameters of the commands that name outputs; every other path parameter is an input, which no
# output of the command may overwrite (sinscli/io/atomic.py: check_not_input)
OUTPUT_PARAMS = frozenset({"output", "outdir", "innovations_path", "series", "plot"})


class _Command(click.Command):
    """A command that notes its input paths (every ``click.Path`` parameter not in :data:`OUTPUT_PARAMS`)
    before it runs, so that an output naming one of them is refused, whatever the command."""

    def invoke(self, ctx):
        from ..inputs import end_inputs, reset_inputs   # PyYAML: not for --help (tests/test_cli_startup.py)
        from ..io.atomic import output_set              # numpy: not for --help either
        paths = []
        for param in self.params:
            if param.name in OUTPUT_PARAMS or not isinstance(param.type, click.Path):
                continue
            value = ctx.params.get(param.name)
            paths.extend(value if isinstance(value, (tuple, list)) else [value])
        reset_inputs(p for p in paths if p is not None)
        try:
            with output_set():          # every output of the command appears at its end, or none
                if self.name not in COMPILING_COMMANDS or ctx.params.get("quiet"):
                    return super().invoke(ctx)
                path = ctx.command_path.split(" ", 1)[1] if " " in ctx.command_path else self.name   # "gnss spp"
                note = f"sins: compiling the kernels of sins {path} (first run only; later runs load them)"
                key = "navigate --gnss" if path == "navigate" and ctx.params.get("gnss_path") else path
                progress = CompileProgress(sys.stderr, COMPILE_SECONDS.get(key))
                with announce_compiles(lambda text: click.echo(text, err=True), note, progress):
                    return super().invoke(ctx)
        finally:
            end_inputs()


class _Group(click.Group):
    """A click group that loads its commands lazily and turns :class:`SinsError`, click's own usage
    errors and internal failures into one ``sins: ...`` line (exit 2, 2 and 1)."""

    command_class = _Command

    def list_commands(self, ctx):
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx, name):
        if name not in self.commands and name in COMMANDS:
            importlib.import_module(f"{__package__}.{COMMANDS[name]}")   # registers on ``main``
        return self.commands.get(name)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        if args is None:                # the `sins` program (arguments from sys.argv): end as soon as it is done
            try:
                self._main(args, prog_name, complete_var, **extra)
            except SystemExit as exc:
                _exit_now(exc.code)
            raise AssertionError("unreachable")      # _main always ends in SystemExit
        self._main(args, prog_name, complete_var, **extra)

    def _main(self, args, prog_name, complete_var, **extra):
        with _signals_as_interrupt():
            try:
                rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            except _NO_ARGS_IS_HELP as exc:            # bare `sins`: the help text
                click.echo(exc.ctx.get_help() if exc.ctx else exc.format_message())
                sys.exit(0)
            except click.ClickException as exc:       # usage errors, bad option values, unreadable paths
                where = exc.ctx.command_path.partition(" ")[2] if getattr(exc, "ctx", None) else ""
                where = f"{where}: " if where else ""
                click.echo(f"sins: error: {where}{' '.join(exc.format_message().split())}", err=True)
                sys.exit(SinsError.exit_code)
            except (click.exceptions.Abort, KeyboardInterrupt) as exc:
                _interrupted(exc.__context__ if isinstance(exc, click.exceptions.Abort) and
                             isinstance(exc.__context__, KeyboardInterrupt) else exc)
        sys.exit(rv if isinstance(rv, int) else 0)

    def format_commands(self, ctx, formatter):
        """The command list of ``sins --help``, from :data:`SHORT_HELP` for commands not loaded yet."""
        rows = []
        for name in self.list_commands(ctx):
            if name in self.commands or name not in SHORT_HELP:
                cmd = self.get_command(ctx, name)
                if cmd is not None and not cmd.hidden:
                    rows.append((name, cmd))
            else:                    # shortened by click as the command's own help would be
                rows.append((name, click.Command(name, help=SHORT_HELP[name])))
        if rows:
            limit = formatter.width - 6 - max(len(name) for name, _ in rows)
            with formatter.section("Commands"):
                formatter.write_dl([(name, cmd.get_short_help_str(limit)) for name, cmd in rows])

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except SinsError as exc:
            click.echo(f"sins: error: {exc}", err=True)
            sys.exit(SinsError.exit_code)
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort, SystemExit):
            raise
        except KeyboardInterrupt as exc:
            _interrupted(exc)
        except Exception as exc:  # an internal bug: still one line, traceback with --debug
            if ctx.obj and ctx.obj.get("debug"):
                raise
            from ..io.atomic import is_fault, os_errno, target_of   # numpy: only on an internal failure
            if is_fault(exc):     # the file system (a device error reading an input, a folder removed): not a bug
                name = getattr(exc, "filename", None)
                where = f"{target_of(Path(name))}: " if name else ""
                click.echo(f"sins: error: {where}{os.strerror(os_errno(exc))}", err=True)
                sys.exit(SinsError.exit_code)
            click.echo(f"sins: internal error: {type(exc).__name__}: {exc} (rerun with --debug for a traceback)",
                       err=True)
            sys.exit(1)


@click.group(cls=_Group)
@click.option("--debug", is_flag=True, help="Debug logging, and tracebacks on internal errors.")
@click.option("-v", "--verbose", is_flag=True, help="Informational logging on stderr.")
@click.version_option(package_name="sinscli", prog_name="sins")
@click.pass_context
def main(ctx, debug, verbose):
    """sins: strapdown inertial navigation of IMU/GNSS logs."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    _printable_stderr()
    level = logging.DEBUG if debug else logging.INFO if verbose else logging.WARNING
    # the root logger stays at WARNING: --debug is for sins, not for numba's compiler dumps
    logging.basicConfig(level=logging.WARNING, format="sins: %(levelname)s: %(message)s", stream=sys.stderr)
    logging.getLogger("sins").setLevel(level)
    if NUMBA_CACHE_NOTE:
        log.warning(NUMBA_CACHE_NOTE)


def stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def progress(length: int, label: str, quiet: bool):
    """A click progress bar on stderr: drawn on a terminal only (click would print its label as a bare line
    into a log file or pipe); silent with ``--quiet``."""
    return click.progressbar(length=max(int(length), 1), label=label, file=sys.stderr,
                             hidden=quiet or not stderr_is_terminal(), show_eta=True, show_percent=True)


def finish_progress(bar) -> None:
    """End a bar whose length was an estimate (e.g. rows from the file size) at 100 %: the length
    becomes the count actually done."""
    if bar.pos != bar.length and bar.pos > 0:
        bar.length = bar.pos
        bar.render_progress()


def summary_line(imu, rows: int, t0: float, t1: float, output) -> None:
    """The last line of a successful ``sins navigate``: what was read, the rows written, their span, where
    (after the outputs are in place)."""
    from ..io.atomic import commit_outputs  # numpy: the atomic writers load when outputs are written, not for --help (tests/test_cli_startup.py)
    commit_outputs()
    click.echo(f"sins: navigated {os.fspath(imu)}: wrote {rows:,} rows, t = {t0:.3f} .. {t1:.3f} s "
               f"({t1 - t0:.3f} s), to {os.fspath(output)}", err=True)


quiet_option = click.option("-q", "--quiet", is_flag=True,
                            help="No progress bar, no first-run compile note, no summary line.")
