"""The progress bar of a run whose length was an estimate ends at 100 % (sinscli.cli.base.finish_progress)."""
import io

import click

from sinscli.cli.base import finish_progress


def _bar(out, length):
    return click.progressbar(length=length, label="navigating", file=out, show_percent=True, show_eta=False)


def test_short_estimate_and_long_estimate_both_end_at_100_percent(monkeypatch):
    import click._termui_impl as impl
    monkeypatch.setattr(impl, "isatty", lambda f: True)                  # render as on a terminal
    for estimate, done in ((1000, 800), (1000, 1250)):
        out = io.StringIO()
        with _bar(out, estimate) as bar:
            bar.update(done)
            finish_progress(bar)
            assert bar.length == done and bar.pos == done
        last = out.getvalue().rstrip().split("\r")[-1]
        assert "100%" in last, (estimate, done, last)


def test_exact_estimate_left_alone():
    out = io.StringIO()
    with _bar(out, 500) as bar:
        bar.update(500)
        finish_progress(bar)
        assert bar.length == 500
