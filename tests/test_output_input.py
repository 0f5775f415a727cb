"""Output onto an input (issue 10): an ``-o`` that names any input of the command (IMU, GNSS, init, config,
truth; through a symlink, ``..`` or a hard link) is refused in one line, exit 2, and the input is unchanged.
One mechanism (sinscli/io/atomic.py: check_not_input, inputs noted by the CLI and by input_file)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from test_contract import refused, sins

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"


@pytest.fixture()
def d(tmp_path):
    lines = (SAMPLE / "imu.csv").read_text().splitlines()[:1002]          # 10 s
    (tmp_path / "imu.csv").write_text("\n".join(lines) + "\n")
    gnss = (SAMPLE / "gnss.csv").read_text().splitlines()[:12]
    (tmp_path / "gnss.csv").write_text("\n".join(gnss) + "\n")
    for name in ("init.yaml", "truth.csv"):
        (tmp_path / name).write_bytes((SAMPLE / name).read_bytes())
    (tmp_path / "cfg.csv").write_text("navigation:\n  every: 10\n")       # a config named like an output
    return tmp_path


def _digest(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.mark.parametrize("args, target", [
    (["navigate", "imu.csv", "--init", "init.yaml", "-o", "imu.csv"], "imu.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "-o", "sub/../imu.csv"], "imu.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "-o", "link.csv"], "imu.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "-o", "hard.csv"], "imu.csv"),
    (["navigate", "imu.csv", "--init", "truth.csv", "-o", "truth.csv"], "truth.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "--config", "cfg.csv", "-o", "cfg.csv"], "cfg.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "--gnss", "gnss.csv", "-o", "gnss.csv"], "gnss.csv"),
    (["navigate", "imu.csv", "--init", "init.yaml", "--gnss", "gnss.csv", "--innovations", "gnss.csv",
      "-o", "f.csv"], "gnss.csv"),
    (["align", "imu.csv", "--method", "static", "--position", "32,120,10", "--config", "cfg.yaml", "-o", "cfg.yaml"], "cfg.yaml"),
    (["compare", "--truth", "rep/errors.csv", "truth.csv", "-o", "rep"], "rep/errors.csv"),
    (["simulate", "rep/init.yaml", "--duration", "2", "-o", "rep"], "rep/init.yaml"),     # a folder output
])
def test_output_onto_input_refused(d, args, target):
    (d / "sub").mkdir()
    (d / "link.csv").symlink_to("imu.csv")
    os.link(d / "imu.csv", d / "hard.csv")
    (d / "cfg.yaml").write_text("imu:\n  body: flu\n")
    (d / "rep").mkdir()
    (d / "rep" / "errors.csv").write_bytes((d / "truth.csv").read_bytes())
    (d / "rep" / "init.yaml").write_bytes((ROOT / "configs" / "scenarios" / "vehicle_drive.yaml").read_bytes())
    before = _digest(d), _digest(d / "rep")
    refused(args, "the output would overwrite the input", target.split("/")[-1], cwd=d)
    assert (_digest(d), _digest(d / "rep")) == before
    assert not [p for p in d.rglob("*.part*")]


def test_distinct_output_still_written(d):
    rc, lines = sins(["navigate", "imu.csv", "--init", "init.yaml", "-q", "-o", "nav.csv"], cwd=d)
    assert rc == 0, lines
    # the same command again, now reading its former output as the init: the registry is per command
    rc, lines = sins(["navigate", "imu.csv", "--init", "nav.csv", "-q", "-o", "nav2.csv"], cwd=d)
    assert rc == 0, lines
    assert (d / "nav2.csv").stat().st_size > 0


def test_library_may_rewrite_what_it_read(d):
    """Outside a command (library use) reading a trajectory and writing it back is not refused."""
    from sinscli.io.trajectory import read_trajectory, write_trajectory
    rc, lines = sins(["navigate", "imu.csv", "--init", "init.yaml", "-q", "-o", "nav.csv"], cwd=d)
    assert rc == 0, lines
    t = read_trajectory(d / "nav.csv")
    write_trajectory(d / "nav.csv", t)
    assert len(read_trajectory(d / "nav.csv")) == len(t)
