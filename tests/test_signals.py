"""Signals during a long ``sins navigate``: SIGINT, SIGTERM and SIGHUP leave no file and exit 128+signal with
one line; after a SIGKILL the temporary file is found and removed by the next run to the same target."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sinscli.io.csvcore import write_table_csv

ROOT = Path(__file__).resolve().parents[1]
N_ROWS = 600_000               # 100 Hz, 100 min: several seconds of navigation and output
WAIT_S = 120.0


@pytest.fixture(scope="module")
def long_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("long")
    rng = np.random.default_rng(2)
    t = 0.01 * np.arange(1, N_ROWS + 1)
    data = {"time": t}
    for i, ax in enumerate("xyz"):
        data[f"dtheta_{ax}"] = rng.normal(0.0, 1e-6, N_ROWS)
        data[f"dvel_{ax}"] = rng.normal(0.0, 1e-5, N_ROWS) + (0.0979 if ax == "z" else 0.0)
    write_table_csv(d / "imu.csv", data)
    (d / "init.yaml").write_text("time: 0.0\nlat: 30.0\nlon: 114.0\nheight: 50.0\nvel_e: 0.0\nvel_n: 0.0\n"
                                 "vel_u: 0.0\nroll: 0.0\npitch: 0.0\nheading: 30.0\n")
    return d


def _start(log_dir: Path, out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-c", "from sinscli.cli import main; main()", "navigate",
                             str(log_dir / "imu.csv"), "--init", str(log_dir / "init.yaml"), "-q", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            stdin=subprocess.DEVNULL)


def _wait_for_output_started(proc: subprocess.Popen, folder: Path) -> Path:
    """The temporary output, once its first block is written (navigation is under way)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < WAIT_S:
        parts = [p for p in folder.iterdir() if p.name.endswith(".part")]
        if parts and parts[0].stat().st_size > 10_000:
            return parts[0]
        assert proc.poll() is None, f"navigate ended early: {proc.communicate()}"
        time.sleep(0.02)
    proc.kill()
    raise AssertionError("navigate did not start writing within the bound")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
def test_signal_during_navigate_leaves_no_file(long_log, tmp_path, sig):
    out = tmp_path / "nav.csv"
    proc = _start(long_log, out)
    part = _wait_for_output_started(proc, tmp_path)
    assert part.name.startswith(".nav.csv.") and f".{proc.pid}." in part.name    # named after the target
    t_sig = time.monotonic()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    stop_s = time.monotonic() - t_sig
    assert proc.returncode == 128 + sig, (proc.returncode, err)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines == [f"sins: interrupted ({sig.name}); no output written"], err
    assert list(tmp_path.iterdir()) == []                                   # no output, no temporary
    # it stops at the next Python bytecode: after the current block (131,072 samples) of navigation or
    # CSV formatting, then the interpreter's exit; a loaded 2-core machine stretches both
    print(f"{sig.name}: stopped {stop_s:.2f} s after the signal")
    assert stop_s < 5.0, f"stopped {stop_s:.2f} s after the signal"


def test_sigkill_leftover_is_removed_by_the_next_run(long_log, tmp_path):
    out = tmp_path / "nav.csv"
    proc = _start(long_log, out)
    part = _wait_for_output_started(proc, tmp_path)
    proc.kill()
    proc.communicate(timeout=30)
    assert part.exists()                                    # SIGKILL cannot be handled: the temporary stays
    short = tmp_path / "short"
    short.mkdir()
    with open(long_log / "imu.csv") as src, open(short / "imu.csv", "w") as dst:
        for _ in range(1001):
            dst.write(next(src))
    (short / "init.yaml").write_text((long_log / "init.yaml").read_text())
    again = _start(short, out)
    _, err = again.communicate(timeout=WAIT_S)
    assert again.returncode == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nav.csv", "short"]   # the stale temporary is gone
    assert len(out.read_text().splitlines()) == 1 + 1001
