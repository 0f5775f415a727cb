"""Tiny batches for the batch tests, the installed ``sins`` script, and report comparison."""
from __future__ import annotations

import filecmp
import os
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

SINS = str(Path(sys.executable).with_name("sins"))        # the installed console script

TINY = {"name": "tiny", "start": {"lat": 34.0, "lon": 108.0, "height": 500.0, "heading": 30.0, "speed": 20.0},
        "imu": {"rate": 100, "sensor": "mems"}, "gnss": {"rate": 1},
        "segments": [{"type": "turn", "duration": 3.0, "rate": 10.0}]}
METHODS = [{"name": "quat2", "attitude": "quat", "coning": 2},
           {"name": "dcm000", "attitude": "dcm", "dcm_variant": "seed000", "coning": 1}]
TIMING = {"nav_seconds", "worker_seconds", "host", "seconds"}      # the columns that differ between two runs


def write_batch(d: Path, seeds=3, files: bool = False, duration: float = 3.0, methods=METHODS, **extra) -> Path:
    """``d/batch.yaml``: the tiny scenario x ``seeds`` (and, with ``files``, a dataset of files written
    by ``sins simulate``) x ``methods``."""
    d.mkdir(parents=True, exist_ok=True)
    scen = dict(TINY, segments=[dict(TINY["segments"][0], duration=duration)])
    (d / "tiny.yaml").write_text(yaml.safe_dump(scen))
    datasets = [{"scenario": "tiny.yaml"}]
    if files:
        subprocess.run([SINS, "simulate", str(d / "tiny.yaml"), "-o", str(d / "files"), "--seed", "7", "-q"],
                       check=True, timeout=300)
        datasets.append({"name": "files", "imu": "files/imu.csv", "truth": "files/truth.csv",
                         "init": "files/init.yaml"})
    batch = {"title": "tiny batch", "datasets": datasets, "methods": methods, "seeds": seeds, **extra}
    (d / "batch.yaml").write_text(yaml.safe_dump(batch))
    return d / "batch.yaml"


def report_files(out: Path) -> list[str]:
    """Every file of a report but the job results, the timings and the Parquet data."""
    return sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()
                  and p.parts[len(out.parts)] not in ("jobs", "results.parquet") and p.name != "timing.csv")


def parquet_data(path: Path) -> pd.DataFrame:
    frame = pd.read_parquet(path)
    frame = frame[[c for c in frame.columns if c not in TIMING]]
    frame["method"] = frame["method"].astype(str)
    return frame.reset_index(drop=True)


def assert_same_report(a: Path, b: Path) -> None:
    """Byte for byte, but the timings (timing.csv, and the time and host columns of results.parquet)."""
    fa, fb = report_files(a), report_files(b)
    assert fa == fb
    _, mismatch, errors = filecmp.cmpfiles(a, b, fa, shallow=False)
    assert not mismatch and not errors, (mismatch, errors)
    if (a / "results.parquet").exists():
        pd.testing.assert_frame_equal(parquet_data(a / "results.parquet"), parquet_data(b / "results.parquet"))


def start_sins(args: list[str], cwd: Path, **kw) -> subprocess.Popen:
    """The installed ``sins`` in its own session (so that a test can signal its process group)."""
    return subprocess.Popen([SINS, *map(str, args)], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, **kw)


def stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait(10)
