"""The ``sins`` command group: error handling, logging and progress shared by all commands."""
from __future__ import annotations

import logging
import sys

import click

from ..errors import SinsError

log = logging.getLogger("sins")


# command name -> module under sinscli.cli that defines it; imported on first use, so that
# `sins navigate` does not pay for the simulator, reports or alignment at start-up.
COMMANDS = {"navigate": "navigate", "align": "align", "simulate": "simulate", "compare": "compare",
            "info": "info", "convert": "convert", "allan": "allan"}


class _Group(click.Group):
    """A click group that loads its commands lazily and turns :class:`SinsError` into one line and exit 2."""

    def list_commands(self, ctx):
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx, name):
        if name not in self.commands and name in COMMANDS:
            import importlib
            importlib.import_module(f"{__package__}.{COMMANDS[name]}")   # registers on ``main``
        return self.commands.get(name)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except SinsError as exc:
            click.echo(f"sins: error: {exc}", err=True)
            sys.exit(SinsError.exit_code)
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort, SystemExit):
            raise
        except KeyboardInterrupt:
            click.echo("sins: interrupted", err=True)
            sys.exit(130)
        except Exception as exc:  # an internal bug: still one line, traceback with --debug
            if ctx.obj and ctx.obj.get("debug"):
                raise
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
    level = logging.DEBUG if debug else logging.INFO if verbose else logging.WARNING
    logging.basicConfig(level=level, format="sins: %(levelname)s: %(message)s", stream=sys.stderr)
    logging.getLogger("sins").setLevel(level)


def progress(length: int, label: str, quiet: bool):
    """A click progress bar on stderr (silent with ``--quiet`` or when ``length`` is small)."""
    return click.progressbar(length=max(int(length), 1), label=label, file=sys.stderr,
                             hidden=quiet, show_eta=True, show_percent=True)


quiet_option = click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
