"""Options and messages shared by the commands that run batches (``sins compare BATCH.yaml``,
``sins align --monte-carlo``): the execution back end, resuming, figures, the interrupt message."""
from __future__ import annotations

import contextlib
import gc
import logging
import sys

import click


def scheduler_options(f):
    """``--scheduler``, ``--resume`` and ``--figures``."""
    f = click.option("--figures", type=click.Choice(["auto", "all"]), default="auto", show_default=True,
                     help="auto: a figure line per run for up to 20 seeds, statistics and box plots beyond; "
                          "all: the per-run figures whatever the number of seeds.")(f)
    f = click.option("--resume", is_flag=True,
                     help="Keep the finished jobs under DIR/jobs/ of an earlier (interrupted) run of the same "
                          "batch and run only the rest.")(f)
    f = click.option("--scheduler", default=None, metavar="tcp://HOST:PORT|local:N",
                     help="Run the jobs on Dask distributed: a running scheduler (input files on a filesystem "
                          "every worker sees), or a LocalCluster of N worker processes started here. "
                          "Needs pip install 'sinscli[distributed]'.")(f)
    return f


def info_echo(quiet: bool):
    """Informational lines on stderr (where the jobs run, the dashboard), silenced by --quiet."""
    def echo(msg: str) -> None:
        if not quiet:
            click.echo(f"sins: {msg}", err=True)
    return echo


def verbose(ctx) -> bool:
    return logging.getLogger("sins").getEffectiveLevel() <= logging.INFO


@contextlib.contextmanager
def interrupted_exit():
    """SIGINT, SIGTERM or SIGHUP during a batch: one line saying what was kept and how to resume,
    exit status 128 + the signal number."""
    from ..batch.jobs import StudyInterrupted   # numpy: not for --help (tests/test_cli_startup.py)
    try:
        yield
    except StudyInterrupted as exc:
        click.echo(f"\nsins: {exc.message()}", err=True)
        gc.freeze()          # the workers are gone: skip the collection of every object at exit (~1 s)
        sys.exit(exc.exit_status)
