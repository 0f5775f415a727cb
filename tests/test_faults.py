"""The contract under faults (issue 22): a full disk, a quota, an I/O error, a read-only target, odd path
bytes, inconsistent ROS 2 storage.  Every case: one line ``sins: error: TARGET: ...`` (the target, never a
temporary; no source line), exit status 2, and on disk nothing, or the previous complete set.

Disk full is real: a 2 MB tmpfs (``mount -t tmpfs``, root only; skipped where it cannot be mounted).  EIO
and EDQUOT are injected through the writers' own file objects (``open`` of the staged temporary) and at
the flush before the rename (``atomic._fsync``), which need no privileges."""
from __future__ import annotations

import builtins
import errno
import hashlib
import io
import os
import shutil
import sqlite3
import subprocess
import uuid
from pathlib import Path

import numpy as np
import pytest
import yaml

from test_contract import refused, sins
from test_fuzz_contract import _Failing

from sinscli.io import atomic, ros
from sinscli.batch.compare_job import describe

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
FORMATS = ("csv", "parquet", "mcap", "tum", "geojson", "kml")


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _no_temporaries(folder: Path) -> None:
    left = [p.name for p in folder.rglob("*") if ".part" in p.name]
    assert not left, left


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("faults")
    lines = (SAMPLE / "imu.csv").read_text().splitlines()
    (d / "imu.csv").write_text("\n".join(lines[:6002]) + "\n")                  # 60 s
    (d / "gnss.csv").write_text("\n".join((SAMPLE / "gnss.csv").read_text().splitlines()[:62]) + "\n")
    for name in ("init.yaml", "truth.csv"):
        shutil.copy(SAMPLE / name, d / name)
    return d


# --------------------------------------------------------------------------- a real full disk

@pytest.fixture()
def full_disk(tmp_path):
    """A 2 MB tmpfs, filled to leave ``room`` bytes (call it); unmounted after the test."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.decode(errors='replace').strip()[:80]}): the "
                    "injected faults below still run")

    def fill(room: int) -> Path:
        for p in mnt.iterdir():
            if p.name == "filler":
                p.unlink()
        free = shutil.disk_usage(mnt).free
        (mnt / "filler").write_bytes(b"\0" * max(free - room, 0))
        return mnt
    yield fill
    subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


@pytest.mark.parametrize("fmt", FORMATS)
def test_navigate_on_a_full_disk(data, full_disk, fmt):
    """CSV: TrajectoryWriter.close() drained the writer outside the atomic context (internal error, exit 1);
    Parquet: abort() swallowed the converted error.  Now one line naming the target, exit 2, no file;
    an earlier complete output there is left as it was."""
    disk = full_disk(64 * 1024)
    out = disk / f"nav.{fmt}"
    refused(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", out],
            f"{out}: cannot write the output (No space left on device)")
    assert sorted(p.name for p in disk.iterdir()) == ["filler"]
    disk = full_disk(600 * 1024)                                     # room for a short earlier run
    rc, lines = sins(["navigate", data / "imu.csv", "--init", data / "init.yaml", "--end", "+2", "-o", out, "-q"])
    assert rc == 0, lines
    before = out.read_bytes()
    full_disk(64 * 1024)
    refused(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", out],
            f"{out}: cannot write the output (No space left on device)")
    assert out.read_bytes() == before
    _no_temporaries(disk)


def test_fused_navigate_with_innovations_on_a_full_disk(data, full_disk):
    disk = full_disk(32 * 1024)
    refused(["navigate", data / "imu.csv", "--gnss", data / "gnss.csv", "--init", data / "init.yaml",
             "--innovations", disk / "innov.csv", "-o", disk / "fused.csv"], "cannot write the output (No space")
    assert sorted(p.name for p in disk.iterdir()) == ["filler"]


def test_simulate_on_a_full_disk_keeps_the_previous_complete_set(tmp_path, full_disk):
    """Before: imu.csv and gnss.csv written, truth.csv and init.yaml missing; over an earlier set that paired
    new IMU data with an old truth.  Now the files are one set."""
    scen = tmp_path / "drive.yaml"
    sc = yaml.safe_load((ROOT / "configs/scenarios/vehicle_drive.yaml").read_text())
    scen.write_text(yaml.safe_dump(sc))
    disk = full_disk(1800 * 1024)
    rc, lines = sins(["simulate", scen, "-o", disk / "sim", "--duration", "5", "-q"])
    assert rc == 0, lines
    before = _digest(disk / "sim")
    assert sorted(before) == ["gnss.csv", "imu.csv", "init.yaml", "sim_truth.yaml", "truth.csv"]
    full_disk(200 * 1024)
    line = refused(["simulate", scen, "-o", disk / "sim", "--duration", "60", "--seed", "3"],
                   "cannot write the output (No space left on device)")
    assert f"{disk / 'sim'}/" in line and ".part" not in line
    assert _digest(disk / "sim") == before
    _no_temporaries(disk)
    shutil.rmtree(disk / "sim")
    refused(["simulate", scen, "-o", disk / "sim", "--duration", "60"], "No space left on device")
    assert sorted(p.name for p in disk.iterdir()) == ["filler"]            # no empty folder either


def test_compare_convert_align_allan_on_a_full_disk(data, tmp_path, full_disk):
    """compare and convert named the hidden temporary (`.report.16018.part/timeseries.csv`); now the target."""
    rc, lines = sins(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", tmp_path / "nav.csv", "-q"])
    assert rc == 0
    disk = full_disk(48 * 1024)
    line = refused(["compare", "--truth", data / "truth.csv", tmp_path / "nav.csv", "-o", disk / "report"],
                   f"{disk / 'report'}/", "cannot write the output (No space left on device)")
    assert ".part" not in line
    t = np.arange(0.0, 60.0, 0.01)
    imu = {"time": t, "gyro": np.zeros((t.size, 3)), "accel": np.tile([0.0, 0.0, 9.79], (t.size, 1))}
    ros.write_log(tmp_path / "log.bag", imu=imu)
    line = refused(["convert", tmp_path / "log.bag", "-o", disk / "conv"], f"{disk / 'conv'}/imu.csv",
                   "No space left on device")
    assert ".part" not in line
    full_disk(8 * 1024)
    refused(["align", data / "imu.csv", "--method", "inertial", "--position", "30,114,50", "--duration", "50",
             "--heading", "30", "-o", disk / "init.yaml", "--series", disk / "series.csv", "--plot",
             disk / "align.png"], "No space left on device")
    refused(["allan", data / "imu.csv", "-o", disk / "noise"], "No space left on device")
    assert sorted(p.name for p in disk.iterdir()) == ["filler"]


def test_batch_job_on_a_full_disk_names_the_file_not_a_source_line(tmp_path, full_disk):
    """A batch job that writes its trajectory (write_trajectories) on a full disk reported
    `OSError ... at csvcore.py:333`; now the file and the reason, and the command exits 1 with the others."""
    from batchutil import write_batch
    batch = write_batch(tmp_path / "b", seeds=1, write_trajectories=True)
    disk = full_disk(40 * 1024)
    rc, lines = sins(["compare", batch, "-o", disk / "out", "--jobs", "1"])
    text = " ".join(lines)
    assert rc in (1, 2), lines
    assert "No space left on device" in text and ".py:" not in text and "OSError" not in text, lines


def test_describe_a_file_system_error_of_a_job():
    exc = OSError(errno.ENOSPC, "No space left on device", "/out/jobs/.x.nav.csv.123.part")
    assert describe(exc) == "/out/jobs/.x.nav.csv.123.part: No space left on device"
    exc = OSError(28, "Error writing bytes to file. Detail: [errno 28] No space left on device")   # pyarrow
    exc.errno = None
    assert describe(exc) == "No space left on device"


# --------------------------------------------------------------------------- injected: EIO, EDQUOT

@pytest.fixture()
def failing_writes(monkeypatch):
    """Every file a writer opens under a staged temporary name fails with the given errno after a few kB."""
    real_open = builtins.open

    def arm(code, limit=4096):
        def fake_open(file, mode="r", *args, **kwargs):
            f = real_open(file, mode, *args, **kwargs)
            if any(c in mode for c in "wax") and ".part" in os.fsdecode(os.fspath(file)):
                return _Failing(f, code, limit)
            return f
        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)
    return arm


@pytest.mark.parametrize("code, text", [(errno.EDQUOT, "Disk quota exceeded"), (errno.EIO, "Input/output error")])
@pytest.mark.parametrize("fmt", ["csv", "mcap", "tum", "geojson", "kml"])
def test_write_errors_through_the_writers_file_objects(data, tmp_path, failing_writes, fmt, code, text):
    out = tmp_path / f"nav.{fmt}"
    out.write_bytes(b"earlier complete output\n")
    failing_writes(code)
    refused(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", out],
            f"{out}: cannot write the output ({text})")
    assert out.read_bytes() == b"earlier complete output\n"
    _no_temporaries(tmp_path)


@pytest.mark.parametrize("code, text", [(errno.EIO, "Input/output error"), (errno.EDQUOT, "Disk quota exceeded"),
                                        (errno.ENOSPC, "No space left on device")])
def test_a_fault_at_the_flush_before_the_rename_keeps_the_previous_set(data, tmp_path, monkeypatch, code, text):
    """Some file systems report a full disk, a quota or a device error only when the data reach the
    device: the staged files are flushed (fsync) before any is renamed; a fault there leaves the
    previous complete set (here: a report folder and a simulated set)."""
    rc, lines = sins(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", tmp_path / "nav.csv", "-q"])
    assert rc == 0
    rc, lines = sins(["compare", "--truth", data / "truth.csv", tmp_path / "nav.csv", "-o", tmp_path / "rep", "-q"])
    assert rc == 0
    before = _digest(tmp_path / "rep")
    calls = []

    def fsync(path):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(code, os.strerror(code))
        os.fsync(os.open(path, os.O_RDONLY))
    monkeypatch.setattr(atomic, "_fsync", fsync)
    line = refused(["compare", "--truth", data / "truth.csv", tmp_path / "nav.csv", "-o", tmp_path / "rep"],
                   f"cannot write the output ({text})")
    assert f"{tmp_path / 'rep'}/" in line and ".part" not in line
    assert _digest(tmp_path / "rep") == before
    _no_temporaries(tmp_path)


def test_a_rename_failing_midway_restores_the_previous_set(tmp_path, monkeypatch):
    """The moves of a set: each earlier file is kept aside until every new one is in place; the third rename
    failing (EIO) puts the first two back."""
    out = tmp_path / "set"
    out.mkdir()
    for name in ("a.csv", "b.csv", "c.csv"):
        (out / name).write_text(f"old {name}\n")
    (out / "mine.txt").write_text("not part of the set\n")
    real = os.replace
    moved = []

    def replace(src, dst):
        if ".part" in os.fspath(src) and not os.fspath(src).endswith(".old") and \
                not os.fspath(dst).endswith(".old"):
            moved.append(dst)
            if len(moved) == 3:
                raise OSError(errno.EIO, os.strerror(errno.EIO))
        return real(src, dst)
    monkeypatch.setattr(atomic.os, "replace", replace)
    with pytest.raises(atomic.SinsError, match=r"set/c\.csv: cannot write the output \(Input/output error\)"):
        with atomic.output_set():
            with atomic.staged_dir(out, owned=("*.csv",)) as tmp:
                for name in ("a.csv", "b.csv", "c.csv"):
                    (tmp / name).write_text(f"new {name}\n")
    assert {p.name: p.read_text() for p in out.iterdir()} == {
        "a.csv": "old a.csv\n", "b.csv": "old b.csv\n", "c.csv": "old c.csv\n", "mine.txt": "not part of the set\n"}
    _no_temporaries(tmp_path)


def test_a_set_replaces_the_files_of_an_earlier_set_that_it_lacks(tmp_path):
    """convert of a log without an Imu topic over an earlier convert: the old imu.csv goes with the set
    (it would pair with the new gnss.csv); other files stay."""
    out = tmp_path / "set"
    out.mkdir()
    (out / "imu.csv").write_text("old\n")
    (out / "notes.txt").write_text("mine\n")
    with atomic.staged_dir(out, owned=("imu.csv", "gnss.csv")) as tmp:
        (tmp / "gnss.csv").write_text("new\n")
    assert sorted(p.name for p in out.iterdir()) == ["gnss.csv", "notes.txt"]


# --------------------------------------------------------------------------- read-only targets

def test_read_only_targets(data, tmp_path):
    """A file without write permission is not replaced; a read-only file system (a tmpfs mounted read-only,
    where it can be) is named as such."""
    locked = tmp_path / "locked.csv"
    locked.write_text("keep\n")
    locked.chmod(0o444)
    refused(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", locked],
            "locked.csv: cannot write the output: the file is read-only")
    assert locked.read_text() == "keep\n"
    ro = tmp_path / "ro"
    ro.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro)], capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a read-only tmpfs here")
    try:
        for args in (["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", ro / "x.csv"],
                     ["compare", "--truth", data / "truth.csv", data / "truth.csv", "-o", ro / "rep"],
                     ["simulate", ROOT / "configs/scenarios/vehicle_drive.yaml", "-o", ro / "sim", "--duration", "2"]):
            refused(args, f"cannot write in {ro} (read-only file system)")
        assert list(ro.iterdir()) == []
    finally:
        subprocess.run(["umount", "-l", str(ro)], capture_output=True)


# --------------------------------------------------------------------------- odd path bytes

ODD = ["\udcff\udcfe", "sp ace", "q?u#e%ry", "-dash", "\u00e9t\u00e9", "nl\nname", "x" * 240]


@pytest.mark.parametrize("stem", ODD, ids=["non-utf8", "space", "uri-chars", "dash", "utf8", "newline", "long"])
def test_every_path_linux_allows_works(data, tmp_path, stem):
    """Before: a non-UTF-8 byte in an input path ended in UnicodeEncodeError from pyarrow's open.  Inputs and
    outputs with such names, spaces, URI characters, a leading dash, UTF-8, a newline and 240 bytes: every
    reader and writer works, and the report shows the name as \\xNN."""
    d = tmp_path
    imu, init, gnss, truth = (d / f"{stem}.{s}" for s in ("csv", "yaml", "gnss.csv", "truth.csv"))
    shutil.copy(data / "imu.csv", imu)
    shutil.copy(data / "init.yaml", init)
    shutil.copy(data / "gnss.csv", gnss)
    shutil.copy(data / "truth.csv", truth)
    for fmt in ("csv", "parquet", "mcap"):
        rc, lines = sins(["navigate", imu, "--init", init, "-o", d / f"{stem}.nav.{fmt}", "-q"])
        assert rc == 0, (fmt, lines)
    rc, lines = sins(["navigate", imu, "--gnss", gnss, "--init", d / f"{stem}.nav.parquet", "-o",
                      d / f"{stem}.fused.csv", "-q"])
    assert rc == 0, lines
    rc, lines = sins(["compare", "--truth", truth, d / f"{stem}.nav.parquet", d / f"{stem}.nav.csv", "-o",
                      d / f"{stem}.rep", "-q"])
    assert rc == 0, lines
    page = (d / f"{stem}.rep" / "index.html").read_bytes()
    page.decode("utf-8")                                          # every text output stays valid UTF-8
    if stem.startswith("\udcff"):
        assert b"\\xff\\xfe" in page
    rc, lines = sins(["info", imu])
    assert rc == 0, lines
    missing = d / f"{stem}.missing.csv"
    line = refused(["navigate", missing, "--init", init, "-o", d / "x.csv"], "file not found")
    assert "\n" not in line


def test_odd_bytes_in_ros_log_paths(tmp_path):
    """SQLite opened by a percent-encoded URI (a '?', '#' or a non-UTF-8 byte ended the URI or failed)."""
    t = np.arange(0.0, 3.0, 0.01)
    imu = {"time": t, "gyro": np.zeros((t.size, 3)), "accel": np.tile([0.0, 0.0, 9.79], (t.size, 1))}
    for stem in ("\udcff#?%", "plain"):
        for suffix in (".db3", ".bag", ".mcap"):
            log = tmp_path / f"{stem}{suffix}"
            ros.write_log(log, imu=imu)
            rc, lines = sins(["info", log])
            assert rc == 0, (log, lines)
            rc, lines = sins(["convert", log, "-o", tmp_path / f"{stem}{suffix}.out", "-q"])
            assert rc == 0 and (tmp_path / f"{stem}{suffix}.out" / "imu.csv").is_file(), lines


def test_names_at_the_length_limit(data, tmp_path):
    """A 255-byte output name (its temporary is shortened) is written; 256 bytes is refused in one line."""
    ok = tmp_path / ("n" * 251 + ".csv")
    rc, lines = sins(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", ok, "-q"])
    assert rc == 0 and ok.is_file(), lines
    refused(["navigate", data / "imu.csv", "--init", data / "init.yaml", "-o", tmp_path / ("n" * 252 + ".csv")],
            "ile name too long")
    _no_temporaries(tmp_path)


# --------------------------------------------------------------------------- ROS 2 storage that disagrees

@pytest.fixture(scope="module")
def bag_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("ros2")
    t = np.arange(0.0, 5.0, 0.01)
    imu = {"time": t, "gyro": np.zeros((t.size, 3)), "accel": np.tile([0.0, 0.0, 9.79], (t.size, 1))}
    gnss = {"time": np.arange(5.0), "lat": np.full(5, 30.0), "lon": np.full(5, 114.0), "height": np.full(5, 5.0),
            "cov": np.tile([1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0], (5, 1))}
    ros.write_log(d / "bag", imu=imu, gnss=gnss)
    return d / "bag"


@pytest.mark.parametrize("sql, fragment", [
    ("UPDATE topics SET type = 'sensor_msgs/msg/Imuu' WHERE name = '/imu/data'",
     "topic /imu/data has the type 'sensor_msgs/msg/Imuu' in the storage file but sensor_msgs/msg/Imu in"),
    ("UPDATE topics SET serialization_format = 'ros1' WHERE name = '/imu/data'",
     "topic /imu/data: serialization format 'ros1'; a ROS 2 bag holds CDR"),
])
def test_ros2_storage_disagreeing_with_its_metadata(bag_dir, tmp_path, sql, fragment):
    """`sins info` ended in `internal error: IndexError: too many indices for array`."""
    bag = tmp_path / "bag"
    shutil.copytree(bag_dir, bag)
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute(sql)
    for args in (["info", bag], ["convert", bag, "-o", tmp_path / "out"], ["info", db]):
        if args[1] == db and "Imuu" in sql:        # a bare .db3 has no metadata.yaml: an unknown type is a topic
            rc, lines = sins(args)                 # sins does not read, listed as it is (stdout)
            assert rc == 0, lines
            continue
        refused(args, fragment)
    assert not (tmp_path / "out").exists()
