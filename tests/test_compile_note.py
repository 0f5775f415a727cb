"""The first-run compile note (issue 14): said once, before a kernel compiles, never for a cached one; and
the one-line summary of a successful `sins navigate` (rows, span, output), silenced by --quiet."""
from pathlib import Path

import numpy as np
from click.testing import CliRunner
from numba import njit

from sinscli import _numba_cache
from sinscli.cli import main
from sinscli.io.trajectory import read_trajectory

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"


def test_first_compile_is_announced_once_and_a_compiled_kernel_never(monkeypatch):
    monkeypatch.setattr(_numba_cache, "_announced", False)
    said = []

    @njit                                   # no cache: compiles at its first call with new types
    def twice(x):
        return 2.0 * x

    @njit
    def thrice(x):
        return 3.0 * x

    with _numba_cache.announce_compiles(said.append, "compiling"):
        assert twice(1.5) == 3.0            # compiles: the note, before the result
        assert said == ["compiling"]
        assert thrice(1.0) == 3.0           # another compile in the same process: not repeated
    assert said == ["compiling"]

    monkeypatch.setattr(_numba_cache, "_announced", False)
    with _numba_cache.announce_compiles(said.append, "again"):
        assert twice(2.0) == 4.0            # compiled already for float64: no compile, no note
        assert thrice(np.float64(4.0)) == 12.0
    assert said == ["compiling"]
    with _numba_cache.announce_compiles(said.append, "int"):
        assert twice(3) == 6.0              # new argument type: a compile
    assert said == ["compiling", "int"]


def test_the_command_s_own_note_replaces_the_generic_one_for_that_command_only(monkeypatch):
    """sins navigate names its kernels and the estimate: one note, its own, never the generic one too; the
    text does not outlive the command."""
    monkeypatch.setattr(_numba_cache, "_announced", False)
    said = []

    @njit
    def once(x):
        return x + 1.0

    @njit
    def later(x):
        return x + 2.0

    with _numba_cache.announce_compiles(said.append, "generic"):
        _numba_cache.set_compile_note("navigation kernels, about 9 s")
        assert once(1.0) == 2.0
        assert later(1.0) == 3.0
    assert said == ["navigation kernels, about 9 s"]
    monkeypatch.setattr(_numba_cache, "_announced", False)
    with _numba_cache.announce_compiles(said.append, "next command"):
        assert later(1) == 3
    assert said == ["navigation kernels, about 9 s", "next command"]


def test_summary_line_names_rows_span_and_output_and_quiet_silences_it(tmp_path):
    out = tmp_path / "nav.csv"
    args = ["navigate", str(SAMPLE / "imu.csv"), "--init", str(SAMPLE / "init.yaml"), "-o", str(out)]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    traj = read_trajectory(out)
    last = [ln for ln in r.output.splitlines() if ln.strip()][-1]
    n = len(traj.time)
    assert last == (f"sins: navigated {SAMPLE / 'imu.csv'}: wrote {n:,} rows, t = {traj.time[0]:.3f} .. "
                    f"{traj.time[-1]:.3f} s ({traj.time[-1] - traj.time[0]:.3f} s), to {out}"), last
    r = CliRunner().invoke(main, args + ["-q"])
    assert r.exit_code == 0
    assert "navigated" not in r.output and "compiling" not in r.output


def test_fused_run_ends_with_the_summary_line_too(tmp_path):
    out = tmp_path / "fused.csv"
    args = ["navigate", str(SAMPLE / "imu.csv"), "--gnss", str(SAMPLE / "gnss.csv"), "--init",
            str(SAMPLE / "init.yaml"), "-o", str(out)]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    traj = read_trajectory(out)
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert lines[-2].startswith("sins: fusion: ")
    assert lines[-1] == (f"sins: navigated {SAMPLE / 'imu.csv'}: wrote {len(traj.time):,} rows, t = "
                         f"{traj.time[0]:.3f} .. {traj.time[-1]:.3f} s ({traj.time[-1] - traj.time[0]:.3f} s), "
                         f"to {out}"), lines[-1]
    r = CliRunner().invoke(main, args + ["-q"])
    assert r.exit_code == 0 and "navigated" not in r.output


def test_progress_line_is_refreshed_while_compiling_and_scaled_by_the_load(monkeypatch):
    """Issue 21: a compile left at run time is never a silent minute: a line with the seconds so far against
    the estimate, redrawn while numba compiles (here every 0.05 s), the estimate scaled by load / CPUs."""
    import io
    import time

    monkeypatch.setattr(_numba_cache, "_announced", False)
    monkeypatch.setattr(_numba_cache.os, "getloadavg", lambda: (8.0, 8.0, 8.0))
    monkeypatch.setattr(_numba_cache.os, "cpu_count", lambda: 2)
    out = io.StringIO()
    progress = _numba_cache.CompileProgress(out, estimate_s=3.0, every_s=0.05)
    assert progress.estimate() == 12.0                 # 3 s idle x load 8 on 2 CPUs

    @njit
    def slow_to_compile(x):
        return x * 2.0

    from numba.core import event

    class _Slow(event.Listener):       # stretch the compile so that the line must be redrawn (one of the two
        def on_start(self, ev):        # sleeps falls inside the progress line's start/end, whatever the order
            time.sleep(0.3)            # in which numba calls the listeners)

        def on_end(self, ev):
            time.sleep(0.3)

    said = []
    with event.install_listener("numba:compile", _Slow()):
        with _numba_cache.announce_compiles(said.append, "compiling", progress):
            assert slow_to_compile(2.0) == 4.0
            after_compile = out.getvalue()
            time.sleep(0.2)                            # no compile under way: no more lines
    lines = out.getvalue().splitlines()
    assert said == ["compiling"]
    assert len(lines) >= 3 and out.getvalue() == after_compile, out.getvalue()
    assert all(ln.startswith("sins: kernels: ") and ln.endswith("of about 12 s (first run only)") for ln in lines)
    assert 0.25 <= progress.seconds() < 5.0


def test_progress_on_a_terminal_redraws_one_line_and_ends_it():
    import io
    import time

    class Tty(io.StringIO):
        def isatty(self):
            return True

    out = Tty()
    progress = _numba_cache.CompileProgress(out, estimate_s=None)
    progress.start()
    time.sleep(1.3)                       # one redraw (every second on a terminal)
    progress.end()
    progress.close()
    text = out.getvalue()
    assert text.startswith("\rsins: kernels: 1 s so far (first run only)\x1b[K") and text.endswith("\n")
    assert text.count("\n") == 1          # one line, redrawn in place, ended once
