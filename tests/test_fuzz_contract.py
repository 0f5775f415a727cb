"""The error contract on every input (issue 11), kept by a seeded mutation fuzzer.

Every input kind (IMU and GNSS CSV, init and config YAML with and without a ``fusion:`` section,
trajectory CSV, TUM, a static IMU log, body-velocity CSV, ``.bag``, ``.db3``, ``.mcap``) is mutated
(bit flips, byte insertions and deletions, truncation, extreme numbers, header edits, YAML structure
edits, encodings, special files) and run through ``navigate`` (plain, and fused with ``--gnss``,
``--smooth``, ``--innovations``), ``align``, ``info``, ``convert``, ``compare`` (with ``--metrics``)
and ``allan``, in process with click's runner (special files in a subprocess, so that a blocking open
cannot hang the suite); the body-velocity CSV, which no command reads yet, through its reader.  Each
run must end in one of two ways:

* exit 0, with every output number finite;
* exit 2 with one ``sins: error:`` line naming the mutated file (or the option), no traceback, no
  click usage text, numbers written plainly, and no output file.

Anything else is counted by class (non-finite output, internal error, usage form, traceback, hang,
leftover file, leaked numpy warning) and every class must be empty.  ``SINS_FUZZ_CASES`` sets the
number of cases (default 1200); ``SINS_FUZZ_REPORT`` names a JSON file for the counts.
"""
from __future__ import annotations

import collections
import contextlib
import json
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.io import ros

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
SEED = 20250611
N_CASES = int(os.environ.get("SINS_FUZZ_CASES", "1200"))
HANG_S = 30.0
NONFINITE = re.compile(r"(?<![A-Za-z_])[-+.]?(nan|inf|infinity)(?![A-Za-z_])", re.IGNORECASE)
NUMPY_REPR = re.compile(r"np\.(float|int|uint|bool)\w*\(")
EXTREMES = ["1e308", "-1e308", "1.7976931348623157e308", "nan", "NaN", "inf", "-inf", "Infinity", "1e400",
            "-1e400", "1e-400", "", "abc", "0x10", "1e30", "-1e30", "1e15", "9" * 400, " 5 ", "1,2", '"3"']
YAML_EXTREMES = [float("nan"), float("inf"), float("-inf"), 1e308, -1e308, 10 ** 400, 10 ** 30, -10 ** 30, 2 ** 63,
                 -1, 0, True, "text", None, [], {}, [1, 2], {"a": 1}, 1e-320, "1e400", "-.inf"]


class Hang(BaseException):
    """Raised by SIGALRM: a case took longer than HANG_S (not an Exception, so nothing catches it)."""


# --------------------------------------------------------------------------- seed inputs

def _csv_lines(path: Path, n: int) -> str:
    with open(path) as fh:
        return "".join(next(fh) for _ in range(n))


def make_seeds(d: Path) -> dict[str, Path]:
    """Small valid inputs of every kind (31 s of the sample drive: enough for static/inertial alignment)."""
    s = {}
    s["imu"] = d / "imu.csv"
    s["imu"].write_text(_csv_lines(SAMPLE / "imu.csv", 3102))
    inc = np.loadtxt(s["imu"], delimiter=",", skiprows=1)
    t = np.concatenate([[0.0], inc[:, 0]])
    rates = np.vstack([inc[:1, 1:], inc[:, 1:]]) / 0.01
    s["imu_rate"] = d / "imu_rate.csv"
    with open(s["imu_rate"], "w") as fh:
        fh.write("time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n")
        for k in range(t.shape[0]):
            fh.write(",".join([repr(round(float(t[k]), 2))] + [repr(float(v)) for v in rates[k]]) + "\n")
    s["gnss"] = d / "gnss.csv"
    s["gnss"].write_text(_csv_lines(SAMPLE / "gnss.csv", 33))
    s["init"] = d / "init.yaml"
    s["init"].write_text((SAMPLE / "init.yaml").read_text())
    s["config"] = d / "config.yaml"
    s["config"].write_text("imu:\n  units: {gyro: rad/s, accel: m/s^2}\n  mounting: {roll: 0.0, pitch: 0.0, yaw: 0.0}\n"
                           "  body: flu\ngnss:\n  lever_arm: [0.0, 0.0, 0.0]\n"
                           "navigation:\n  attitude: quat\n  coning: 2\n  subsamples: 1\n  every: 2\n"
                           "align:\n  method: static\n")
    s["truth"] = d / "truth.csv"
    s["truth"].write_text(_csv_lines(SAMPLE / "truth.csv", 3102))
    s["nav"] = d / "nav.csv"
    shutil.copy(s["truth"], s["nav"])
    rng = np.random.default_rng(3)
    n = 1101
    tl = 0.01 * np.arange(n)
    imu = {"time": tl, "gyro": rng.normal(0, 1e-4, (n, 3)),
           "accel": rng.normal(0, 1e-3, (n, 3)) + [0.0, 0.0, 9.7936]}
    m = 12
    gnss = {"time": np.arange(m, dtype=float), "lat": np.full(m, 30.0), "lon": np.full(m, 114.0),
            "height": np.full(m, 50.0), "cov": np.tile([1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0], (m, 1))}
    odom = {"time": 0.05 + 0.1 * np.arange(100), "vel": np.tile([0.0, 0.0, 0.0], (100, 1)),
            "child_frame_id": "base_link", "std": np.tile([0.02, 0.02, 0.02], (100, 1)),
            "orientation": np.tile([0.0, 0.0, 0.0, 1.0], (100, 1))}
    for name in ("bag", "db3", "mcap"):
        s[name] = d / f"log.{name}"
        ros.write_log(s[name], imu=imu, gnss=gnss, odom=odom)
    # fusion: a config with a fusion section (every kind of key), the sample drive's trajectory as TUM
    s["fconfig"] = d / "fusion.yaml"
    s["fconfig"].write_text(
        "gnss:\n  lever_arm: [0.0, 0.0, 0.0]\n  time_offset: 0.0\n"
        "fusion:\n  states: 15\n  gnss_pos_sigma: [1.5, 1.5, 3.0]\n  gnss_vel_sigma: [0.1, 0.1, 0.2]\n"
        "  init_sigma: {position: [2.0, 2.0, 4.0], velocity: [0.1, 0.1, 0.1], roll: 1.0, pitch: 1.0, heading: 5.0}\n"
        "  zupt: {enabled: true, sigma: 0.02, max_speed: 0.5}\n"
        "  standstill: {window: 1.0, rate_std: 0.5, accel_std: 0.3, accel_mag: 0.3}\n"
        "  nhc: {enabled: true, sigma: [0.1, 0.1], interval: 0.1}\n"
        "  vehicle: car\n  estimate: [lever_arm]\n  heading_init: {max_sigma: 20.0, max_course_sigma: 10.0, min_speed: 2.0, sigma_floor: 2.0}\n"
        "  adapt: {enabled: true, window: 30, max_scale: 10000.0, max_bias_scale: 100.0, exit_ratio: 4.0, decay: 600.0}\n  outage: 3.0\n  smoother_interval: 1.0\n"
        "  sensor:\n    gyro: {arw: 0.3, bias_sigma: 360, bias_instability: 10, bias_tau: 100}\n"
        "    accel: {vrw: 100, bias_sigma: 5000, bias_instability: 50, bias_tau: 100}\n")
    from sinscli.io.trajectory import read_trajectory, write_trajectory
    s["tum"] = d / "nav.tum"
    write_trajectory(s["tum"], read_trajectory(s["truth"]))
    # allan: 70 s of a static IMU (white noise on gravity), rates
    n = 7000
    rates = np.column_stack([rng.normal(0, 2e-3, (n, 3)), rng.normal(0, 2e-2, (n, 3)) + [0.0, 0.0, 9.7936]])
    s["static"] = d / "static.csv"
    with open(s["static"], "w") as fh:
        fh.write("time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n")
        for k in range(n):
            fh.write(",".join([repr(round(0.01 * (k + 1), 2))] + [repr(float(v)) for v in rates[k]]) + "\n")
    # body velocity (odometry) CSV
    s["odom"] = d / "odom.csv"
    with open(s["odom"], "w") as fh:
        fh.write("time,vel_x,vel_y,vel_z,std_x,std_y,std_z\n")
        for k in range(100):
            fh.write(f"{0.1 * k!r},{1.0 + 0.01 * k!r},0.01,-0.02,0.05,0.1,0.1\n")
    return s


# --------------------------------------------------------------------------- commands per input kind

OUT_EXT = [".csv", ".parquet", ".mcap", ".tum", ".geojson", ".kml"]
ALIGN = ["--position", "30,114,50", "--heading", "30", "-q"]


def commands(kind: str, f: str, s: dict, rng) -> tuple[list[str], list[str]]:
    """(args, outputs relative to the case dir) of one command that reads input ``f`` of ``kind``."""
    S = {k: str(v) for k, v in s.items()}
    ext = OUT_EXT[int(rng.integers(len(OUT_EXT)))]
    pick = int(rng.integers(10))
    if kind in ("imu", "imu_rate"):
        if pick < 6:
            return ["navigate", f, "--init", S["init"], "-q", "-o", "out" + ext], ["out" + ext]
        method = "static" if pick < 8 else "inertial"
        return ["align", f, "--method", method, *ALIGN, "-o", "out.yaml"], ["out.yaml"]
    if kind == "gnss":
        return ["align", S["imu"], "--gnss", f, "--method", "static", "--heading", "30", "-q", "-o", "out.yaml"], \
            ["out.yaml"]
    if kind == "init":
        return ["navigate", S["imu"], "--init", f, "-q", "-o", "out" + ext], ["out" + ext]
    if kind == "config":
        if pick < 6:
            return ["navigate", S["imu"], "--init", S["init"], "--config", f, "-q", "-o", "out" + ext], ["out" + ext]
        return ["align", S["imu"], "--config", f, *ALIGN, "-o", "out.yaml"], ["out.yaml"]
    if kind == "traj":
        if pick < 4:
            return ["navigate", S["imu"], "--init", f, "-q", "-o", "out.csv"], ["out.csv"]
        if pick < 6:
            return ["compare", "--truth", f, S["nav"], "-q", "-o", "rep"], ["rep"]
        if pick < 8:
            return ["compare", "--truth", S["truth"], f, "-q", "-o", "rep"], ["rep"]
        return ["compare", "--truth", S["truth"], f, "--metrics", "ate,rpe", "--align-traj",
                "se3" if pick == 9 else "none", "-q", "-o", "rep"], ["rep"]
    if kind == "fgnss":
        return fused(S["imu"], f, S["init"], pick, ext)
    if kind == "fconfig":
        args, outs = fused(S["imu"], S["gnss"], S["init"], pick, ext)
        return args + ["--config", f], outs
    if kind == "tum":
        if pick < 5:
            return ["compare", "--truth", S["truth"], f, "-q", "-o", "rep"], ["rep"]
        return ["compare", "--truth", f, S["tum"], "--metrics", "ate,rpe" if pick < 8 else "ate",
                "--rpe-unit", "m" if pick == 9 else "s", "-q", "-o", "rep"], ["rep"]
    if kind == "allan":
        return ["allan", f, "-q", "-o", "al"], ["al"]
    # ROS logs
    if pick < 2:
        return ["info", f] + (["--json"] if pick == 0 else []), []
    if pick < 4:
        return ["convert", f, "-q", "-o", "conv"], ["conv"]
    if pick < 6:
        return ["navigate", f, "--init", S["init"], "-q", "-o", "out" + ext], ["out" + ext]
    if pick < 9:                                    # fused: the log's NavSatFix topic through the filter
        return fused(f, f, S["init"], pick, ext)
    return ["align", f, "--method", "static", *ALIGN, "-o", "out.yaml"], ["out.yaml"]


def fused(imu: str, gnss: str, init: str, pick: int, ext: str) -> tuple[list[str], list[str]]:
    """``navigate --gnss``, with ``--smooth`` and ``--innovations`` on some picks."""
    args, outs = ["navigate", imu, "--gnss", gnss, "--init", init, "-q", "-o", "out" + ext], ["out" + ext]
    if pick % 2:
        args.append("--smooth")
    if pick % 3 == 0:
        args += ["--innovations", "innov.csv"]
        outs.append("innov.csv")
    return args, outs


# --------------------------------------------------------------------------- mutations

def _bytes_mutation(data: bytes, rng) -> tuple[str, bytes]:
    b = bytearray(data)
    what = int(rng.integers(4))
    if what == 0:
        pos = rng.integers(0, len(b), int(rng.integers(1, 4)))
        for p in pos:
            b[p] ^= 1 << int(rng.integers(8))
        return f"bit flips at {pos.tolist()}", bytes(b)
    if what == 1:
        p = int(rng.integers(0, len(b) + 1))
        ins = bytes(rng.integers(0, 256, int(rng.integers(1, 9))).tolist())
        return f"insert {len(ins)} bytes at {p}", bytes(b[:p] + ins + b[p:])
    if what == 2:
        p = int(rng.integers(0, len(b)))
        k = int(rng.integers(1, 17))
        return f"delete {k} bytes at {p}", bytes(b[:p] + b[p + k:])
    k = int(rng.integers(0, len(b)))
    return f"truncate to {k}", bytes(b[:k])


def _csv_mutation(text: str, rng) -> tuple[str, bytes]:
    lines = text.splitlines()
    header = lines[0].split(",")
    what = int(rng.integers(12))
    if what <= 3:                                   # an extreme value in a cell
        r = int(rng.integers(1, len(lines)))
        cells = lines[r].split(",")
        c = int(rng.integers(len(cells)))
        v = EXTREMES[int(rng.integers(len(EXTREMES)))]
        cells[c] = v
        lines[r] = ",".join(cells)
        return f"line {r + 1} column {header[c] if c < len(header) else c} = {v[:20]!r}", \
            ("\n".join(lines) + "\n").encode()
    if what == 4:                                   # a whole column extreme from a row on
        c = int(rng.integers(len(header)))
        v = EXTREMES[int(rng.integers(6))]
        r0 = int(rng.integers(1, len(lines)))
        for r in range(r0, len(lines)):
            cells = lines[r].split(",")
            if c < len(cells):
                cells[c] = v
            lines[r] = ",".join(cells)
        return f"column {header[c]} = {v} from line {r0 + 1}", ("\n".join(lines) + "\n").encode()
    if what == 5:                                   # header edits
        sub = int(rng.integers(8))
        h = list(header)
        c = int(rng.integers(len(h)))
        if sub == 0:
            h = [(" " if rng.random() < 0.5 else "\t") + x + (" " if rng.random() < 0.5 else "") for x in h]
            label = "whitespace around header names"
        elif sub == 1:
            h[c] = h[c][:-1] + "\xe9"
            lines[0] = ",".join(h)
            return f"latin-1 byte in header column {c}", ("\n".join(lines) + "\n").encode("latin-1")
        elif sub == 2:
            h.append(h[c])
            lines = [lines[0]] + [ln + ",0" for ln in lines[1:]]
            label = f"duplicate column {h[c]}"
        elif sub == 3:
            del h[c]
            label = f"column {header[c]} dropped from the header"
        elif sub == 4:
            h[c] = "x" * 200_000
            label = "a 200 kB header name"
        elif sub == 5:
            h = h + [f"extra{k}" for k in range(100_000)]
            label = "100,000 header columns"
        elif sub == 6:
            h[c] = h[c].upper()
            label = f"header {header[c]} upper case"
        else:
            h = h[::-1]
            lines = [lines[0]] + [",".join(ln.split(",")[::-1]) for ln in lines[1:]]
            label = "columns reversed (valid)"
        lines[0] = ",".join(h)
        return label, ("\n".join(lines) + "\n").encode()
    if what == 6:                                   # a giant line
        r = int(rng.integers(1, len(lines)))
        lines[r] = lines[r] + "9" * 140_000
        return f"line {r + 1} over 128 KiB", ("\n".join(lines) + "\n").encode()
    if what == 7:                                   # row order: repeat, swap, gap
        r = int(rng.integers(2, len(lines) - 1))
        label = _reorder(lines, r, int(rng.integers(3)))
        if label is None:
            del lines[r:r + 30]
            label = f"30 lines deleted at {r + 1}"
        return label, ("\n".join(lines) + "\n").encode()
    if what == 8:                                   # encodings
        sub = int(rng.integers(4))
        body = "\n".join(lines) + "\n"
        if sub == 0:
            return "utf-16", body.encode("utf-16")
        if sub == 1:
            return "BOM", b"\xef\xbb\xbf" + body.encode()
        if sub == 2:
            return "CRLF", body.replace("\n", "\r\n").encode()
        return "semicolons", body.replace(",", ";").encode()
    if what == 9 and rng.random() < 0.3:            # every value zero (an IMU that reads nothing)
        out = [lines[0]] + [",".join([ln.split(",")[0]] + ["0"] * (len(ln.split(",")) - 1)) for ln in lines[1:]]
        return "every value but the time zero", ("\n".join(out) + "\n").encode()
    if what == 9:                                   # scale: all values of a column times a big factor
        c = int(rng.integers(1, len(header)))
        f = float(10.0 ** int(rng.integers(3, 12)))
        out = [lines[0]]
        for ln in lines[1:]:
            cells = ln.split(",")
            try:
                cells[c] = repr(float(cells[c]) * f)
            except (ValueError, IndexError):
                pass
            out.append(",".join(cells))
        return f"column {header[c]} x {f:g}", ("\n".join(out) + "\n").encode()
    return _bytes_mutation(("\n".join(lines) + "\n").encode(), rng)


def _reorder(lines: list[str], r: int, sub: int) -> str | None:
    """Line ``r`` repeated (``sub`` 0) or swapped with the next (1), in place; None for other ``sub``."""
    if sub == 0:
        lines.insert(r, lines[r])
        return f"line {r + 1} repeated"
    if sub == 1:
        lines[r], lines[r + 1] = lines[r + 1], lines[r]
        return f"lines {r + 1} and {r + 2} swapped"
    return None


def _paths(obj, prefix=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


def _get_parent(obj, path):
    for k in path[:-1]:
        obj = obj[k]
    return obj


def _typo(key: str, rng) -> str:
    i = int(rng.integers(len(key)))
    return key[:i] + key[i + 1:] if len(key) > 1 and rng.random() < 0.5 else key[:i] + key[i] + key[i:]


def _yaml_mutation(text: str, rng) -> tuple[str, bytes]:
    data = yaml.safe_load(text)
    what = int(rng.integers(9))
    paths = list(_paths(data))
    if what <= 2:                                   # a value replaced by an extreme
        p = paths[int(rng.integers(len(paths)))]
        v = YAML_EXTREMES[int(rng.integers(len(YAML_EXTREMES)))]
        _get_parent(data, p)[p[-1]] = v
        return f"{'.'.join(map(str, p))} = {str(v)[:20]}", yaml.safe_dump(data, sort_keys=False).encode()
    if what == 3:                                   # key deleted, renamed with a typo, or added
        keyed = [p for p in paths if isinstance(p[-1], str)]
        p = keyed[int(rng.integers(len(keyed)))]
        parent = _get_parent(data, p)
        sub = int(rng.integers(3))
        if sub == 0:
            del parent[p[-1]]
            label = f"{'.'.join(map(str, p))} deleted"
        elif sub == 1:
            parent[_typo(p[-1], rng)] = parent.pop(p[-1])
            label = f"{'.'.join(map(str, p))} misspelt"
        else:
            parent["bogus_key"] = 1.0
            label = f"unknown key beside {'.'.join(map(str, p))}"
        return label, yaml.safe_dump(data, sort_keys=False).encode()
    if what == 4:                                   # nesting 20,000 deep
        lines = text.splitlines()
        r = int(rng.integers(len(lines)))
        deep = "[" * 20000 + "]" * 20000 if rng.random() < 0.5 else "{a: " * 20000 + "1" + "}" * 20000
        key = lines[r].split(":")[0] if ":" in lines[r] else "x"
        lines[r] = f"{key}: {deep}"
        return "a value nested 20,000 deep", ("\n".join(lines) + "\n").encode()
    if what == 5:                                   # encodings and bad bytes
        sub = int(rng.integers(4))
        if sub == 0:
            p = int(rng.integers(len(text)))
            return "a non-UTF-8 byte", text[:p].encode() + b"\xff\xfe" + text[p:].encode()
        if sub == 1:
            return "utf-16", text.encode("utf-16")
        if sub == 2:
            return "tabs for indentation", text.replace("  ", "\t").encode()
        return "BOM", b"\xef\xbb\xbf" + text.encode()
    if what == 6:                                   # the whole document replaced
        doc = [["- 1", "- 2"], ["just text"], [""], ["~"], ["[1, 2, 3]"], ["a: &x [1, 2]", "b: *x"],
               ["a: &a [1,1,1,1,1,1,1,1,1]", "b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]",
                "c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]", "d: [*c,*c,*c,*c,*c,*c,*c,*c,*c]"]][int(rng.integers(7))]
        return f"document {doc[0][:20]!r}", ("\n".join(doc) + "\n").encode()
    if what == 7:                                   # a huge integer literal
        lines = text.splitlines()
        numeric = [i for i, ln in enumerate(lines) if re.search(r":\s*-?[0-9.]+\s*$", ln)]
        r = numeric[int(rng.integers(len(numeric)))] if numeric else 0
        lines[r] = re.sub(r":\s*-?[0-9.]+\s*$", ": " + "1" + "0" * 400, lines[r])
        return f"line {r + 1} = 10^400", ("\n".join(lines) + "\n").encode()
    return _bytes_mutation(text.encode(), rng)


def _tum_mutation(text: str, rng) -> tuple[str, bytes]:
    """TUM rows (``time tx ty tz qx qy qz qw``, space separated) and sins' origin comment."""
    lines = text.splitlines()
    rows = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
    origin = next((i for i, ln in enumerate(lines) if "origin_lat_deg=" in ln), None)
    what = int(rng.integers(8))
    if what <= 2:                                   # an extreme value in a cell
        r = rows[int(rng.integers(len(rows)))]
        cells = lines[r].split()
        c = int(rng.integers(len(cells)))
        v = EXTREMES[int(rng.integers(len(EXTREMES)))] or "x"
        cells[c] = v.replace(",", " ")
        lines[r] = " ".join(cells)
        label = f"line {r + 1} column {c} = {v[:20]!r}"
    elif what == 3 and origin is not None:          # the origin line edited or removed
        sub = int(rng.integers(4))
        if sub == 0:
            del lines[origin]
            label = "origin line removed"
        else:
            key = ["origin_lat_deg", "origin_lon_deg", "origin_height_m"][sub - 1]
            v = ["95.0", "nan", "1e30", "abc", "-1e308", "400"][int(rng.integers(6))]
            lines[origin] = re.sub(rf"{key}=\S+", f"{key}={v}", lines[origin])
            label = f"origin {key}={v}"
    elif what == 4:                                 # rows repeated, swapped, a number dropped
        r = rows[int(rng.integers(1, len(rows) - 1))]
        label = _reorder(lines, r, int(rng.integers(3)))
        if label is None:
            lines[r] = " ".join(lines[r].split()[:7])
            label = f"line {r + 1} with 7 numbers"
    elif what == 5:                                 # scale a column
        c = int(rng.integers(8))
        f = float(10.0 ** int(rng.integers(3, 12)))
        for r in rows:
            cells = lines[r].split()
            cells[c] = repr(float(cells[c]) * f)
            lines[r] = " ".join(cells)
        label = f"column {c} x {f:g}"
    elif what == 6:                                 # encodings
        body = "\n".join(lines) + "\n"
        sub = int(rng.integers(3))
        return (["utf-16", "commas", "tabs"][sub],
                [body.encode("utf-16"), body.replace(" ", ",").encode(), body.replace(" ", "\t").encode()][sub])
    else:
        return _bytes_mutation(text.encode(), rng)
    return label, ("\n".join(lines) + "\n").encode()


def _log_mutation(path: Path, kind: str, rng, target: Path) -> str:
    data = path.read_bytes()
    what = int(rng.integers(6))
    if what == 0:                                    # the Imu type misspelt
        if kind == "db3":
            shutil.copy(path, target)
            with sqlite3.connect(target) as con:
                con.execute("UPDATE topics SET type = 'sensor_msgs/msg/Imx' WHERE type = 'sensor_msgs/msg/Imu'")
            return "Imu topic type misspelt"
        target.write_bytes(data.replace(b"sensor_msgs/Imu", b"sensor_msgs/Imx")
                           .replace(b"sensor_msgs/msg/Imu", b"sensor_msgs/msg/Imx"))
        return "Imu topic type misspelt"
    if what == 1 and kind == "db3":
        shutil.copy(path, target)
        with sqlite3.connect(target) as con:
            col = ["timestamp", "data"][int(rng.integers(2))]
            val = [-1, 2 ** 62, b"\x00" * 8, b""][int(rng.integers(4))]
            if col == "timestamp" and isinstance(val, bytes):
                val = 0
            if not (col == "data" and isinstance(val, int)):
                con.execute(f"UPDATE messages SET {col} = ? WHERE id = ?", (val, int(rng.integers(1, 50))))
        return f"db3 row with {col} = {val!r:.20}"
    if what == 2:                                    # an extreme float in an Imu message
        pos = [m.start() for m in re.finditer(re.escape(np.float64(9.7936).tobytes()[:5]), data)]
        if pos:
            p = pos[int(rng.integers(len(pos)))]
            v = [1e308, -1e308, np.inf, np.nan, 1e30][int(rng.integers(5))]
            b = bytearray(data)
            raw = bytearray(b[p:p + 8])
            b[p:p + 8] = np.float64(v).tobytes()
            target.write_bytes(bytes(b))
            return f"accel z of one message = {v!r} (was {np.frombuffer(bytes(raw), '<f8')[0]!r})"
    label, out = _bytes_mutation(data, rng)
    target.write_bytes(out)
    return label


SPECIAL = ["fifo", "directory", "empty", "devnull", "dangling symlink", "unreadable chars"]


def _special(target: Path, sub: int) -> str:
    if sub == 0:
        os.mkfifo(target)
    elif sub == 1:
        target.mkdir()
    elif sub == 2:
        target.write_bytes(b"")
    elif sub == 3:
        target.symlink_to("/dev/null")
    elif sub == 4:
        target.symlink_to(target.parent / "no_such_target")
    else:
        target.write_bytes(bytes(range(256)) * 4)
    return SPECIAL[sub]


# --------------------------------------------------------------------------- checks of one run

def _finite_text(path: Path) -> str | None:
    text = path.read_bytes().decode("utf-8", errors="replace")
    m = NONFINITE.search(text)
    return None if m is None else f"{path.name}: {text[max(0, m.start() - 40):m.end() + 10]!r}"


def nonfinite_in(path: Path) -> str | None:
    """Where an output holds a non-finite number (None when every number is finite)."""
    if path.is_dir():
        for p in sorted(path.rglob("*")):
            if p.is_file() and p.suffix in (".csv", ".md", ".html", ".yaml", ".json"):
                bad = _finite_text(p) if p.suffix != ".html" else None
                if bad:
                    return bad
        return None
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq
        t = pq.read_table(path)
        for c in t.column_names:
            a = t.column(c).to_numpy()
            if not np.isfinite(a).all():
                return f"{path.name}: column {c}"
        return None
    if path.suffix == ".mcap":
        from sinscli.io.foxglove import read_trajectory_mcap
        tr = read_trajectory_mcap(path)
        for name in ("time", "lat", "lon", "height", "vel_n", "Cbn"):
            if not np.isfinite(getattr(tr, name)).all():
                return f"{path.name}: {name}"
        return None
    return _finite_text(path)


def classify(rc: int, stderr: str, exc, case_dir: Path, inputs: set[str], outputs: list[str],
             names: tuple[str, ...], caught: list) -> tuple[str, str]:
    """(class, detail) of one run; classes other than 'ok' and 'refused' are contract breaks."""
    if exc is not None and not isinstance(exc, SystemExit):
        return "traceback", f"{type(exc).__name__}: {exc}"
    if "Traceback" in stderr:
        return "traceback", stderr[-300:]
    present = {p.name for p in case_dir.iterdir()}
    parts = [str(p.relative_to(case_dir)) for p in case_dir.rglob("*") if ".part" in p.name]
    if parts:
        return "leftover", f"temporary files left: {parts[:3]}"
    if rc == 0:
        for o in outputs:
            if not (case_dir / o).exists():
                return "missing-output", o
            bad = nonfinite_in(case_dir / o)
            if bad:
                return "nonfinite", bad
    leaked = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if leaked:
        return "warning", str(leaked[0].message)
    if rc == 0:
        extra = present - inputs - set(outputs)
        return ("leftover", f"extra files {sorted(extra)}") if extra else ("ok", "")
    if rc == 1 and "internal error" in stderr:
        return "internal", stderr.strip()[-300:]
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    if any(ln.startswith(("Usage:", "Try '", "Error:")) for ln in lines):
        return "usage", " | ".join(lines)[:300]
    errors = [ln for ln in lines if ln.startswith("sins: error:")]
    if rc != 2 or len(errors) != 1 or lines[-1] != errors[0]:
        return f"exit{rc}", " | ".join(lines)[-300:]
    msg = errors[0]
    if NUMPY_REPR.search(msg):
        return "numpy-repr", msg[:300]
    if len(msg) > 600:
        return "long-message", msg[:200] + "..."
    if names and not any(n in msg for n in names):
        return "unnamed", msg[:300]
    extra = present - inputs
    if extra:
        return "leftover", f"files after a refusal: {sorted(extra)}"
    return "refused", msg


def _on_alarm(signum, frame):
    raise Hang()


@contextlib.contextmanager
def _bounded(cwd: Path, timeout: float):
    """Run the block in ``cwd`` with SIGALRM after ``timeout`` s (a :class:`Hang`), warnings recorded."""
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield caught
    finally:
        os.chdir(here)
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_inprocess(args: list[str], cwd: Path, timeout: float = HANG_S):
    """(exit code, stderr, exception, warnings) of ``sins ARGS`` in this process, bounded by ``timeout``."""
    with _bounded(cwd, timeout) as caught:
        r = CliRunner().invoke(main, args, catch_exceptions=True)
    return r.exit_code, r.stderr, r.exception, caught


def run_reader(args: list[str], cwd: Path):
    """``read_body_velocity`` (no command reads a body-velocity CSV yet) in this process, as a command would:
    exit 0 when the result is finite with increasing time, 2 with the one line of a SinsError."""
    from sinscli.config import load_config
    from sinscli.errors import SinsError
    from sinscli.io.readers import read_body_velocity
    with _bounded(cwd, HANG_S) as caught:
        try:
            bv = read_body_velocity(args[1], load_config(None))
        except SinsError as exc:
            return 2, f"sins: error: {exc}\n", None, caught
        except Exception as exc:  # noqa: BLE001 - classified as a traceback
            return 1, "", exc, caught
    arrays = [bv.time, bv.vel_b] + ([bv.std] if bv.std is not None else [])
    if not all(np.isfinite(a).all() for a in arrays) or not np.all(np.diff(bv.time) > 0) or \
            (bv.std is not None and not (bv.std > 0).all()):
        return 1, "sins: internal error: the reader returned non-finite or unordered values", None, caught
    return 0, "", None, caught


def run_subprocess(args: list[str], cwd: Path):
    """The same in a child process (special files: a blocking open must not hang the suite)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    try:
        p = subprocess.run([sys.executable, "-c", "from sinscli.cli import main; main()", *args], cwd=cwd,
                           env=env, capture_output=True, text=True, timeout=HANG_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise Hang() from None
    return p.returncode, p.stderr, None, []


# --------------------------------------------------------------------------- the fuzzer

KINDS = [  # (kind, seed key, weight)
    ("imu", "imu", 16), ("imu_rate", "imu_rate", 8), ("gnss", "gnss", 7), ("init", "init", 11),
    ("config", "config", 10), ("traj", "truth", 10), ("bag", "bag", 8), ("db3", "db3", 8), ("mcap", "mcap", 8),
    ("fgnss", "gnss", 9), ("fconfig", "fconfig", 9), ("tum", "tum", 7), ("allan", "static", 4), ("odom", "odom", 6)]


def make_case(k: int, rng, seeds: dict, case_dir: Path):
    """(description, args, outputs, names that a refusal must mention, how to run: inprocess, subprocess
    (special files) or reader)."""
    weights = np.array([w for _, _, w in KINDS], dtype=float)
    kind, key, _ = KINDS[int(rng.choice(len(KINDS), p=weights / weights.sum()))]
    src = seeds[key]
    ext = src.suffix
    target = case_dir / f"in_{kind}{ext}"
    sub = rng.random()
    special = False
    if sub < 0.03:
        label = _special(target, int(rng.integers(len(SPECIAL))))
        special = True
    elif kind in ("bag", "db3", "mcap"):
        label = _log_mutation(src, kind, rng, target)
    elif kind in ("init", "config", "fconfig"):
        label, data = _yaml_mutation(src.read_text(), rng)
        target.write_bytes(data)
    elif kind == "tum":
        label, data = _tum_mutation(src.read_text(), rng)
        target.write_bytes(data)
    else:
        label, data = _csv_mutation(src.read_text(), rng)
        target.write_bytes(data)
    if kind == "odom":
        args, outputs = ["<read_body_velocity>", target.name], []
        return f"{kind}: {label}: read_body_velocity({target.name})", args, outputs, (target.name,), "reader"
    args, outputs = commands(kind, target.name, seeds, rng)
    names = (target.name,)
    if sub > 0.985 and "-o" in args:                 # output-side cases
        o = int(rng.integers(4))
        oi = args.index("-o") + 1
        if o == 0:
            (case_dir / args[oi]).mkdir()
            label += "; -o names an existing directory" if outputs and "." in args[oi] else "; -o exists"
            if "." not in args[oi]:
                (case_dir / args[oi]).rmdir()
                (case_dir / args[oi]).write_text("a file\n")
        elif o == 1:
            (case_dir / "afile").write_text("x")
            args[oi] = "afile/" + args[oi]
            label += "; -o inside a regular file"
        elif o == 2:
            args[oi] = "out.xyz" if "." in args[oi] else args[oi]
            label += "; -o with an unknown suffix"
        else:
            args[oi] = "noext"
            label += "; -o without a suffix"
        names = names + (args[oi].split("/")[0], "--output", "-o")
        outputs = [args[oi]]
    return f"{kind}: {label}: sins {' '.join(args)}", args, outputs, names, "subprocess" if special else "inprocess"


RUNNERS = {"inprocess": run_inprocess, "subprocess": run_subprocess, "reader": run_reader}


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    return make_seeds(tmp_path_factory.mktemp("fuzz_seeds"))


def test_seed_inputs_pass(seeds, tmp_path):
    """Every seed input through the commands it feeds: exit 0 and finite output (the fuzzer's baseline).

    Runs first and without the hang bound, so that a cold numba cache (a fresh install) is compiled here."""
    rng = np.random.default_rng(1)
    for kind, key, _ in KINDS:
        for _ in range(3):
            case = tmp_path / f"{kind}{_}"
            case.mkdir()
            if kind == "odom":
                args, outputs = ["<read_body_velocity>", str(seeds[key])], []
                rc, err, exc, caught = run_reader(args, case)
            else:
                args, outputs = commands(kind, str(seeds[key]), seeds, rng)
                rc, err, exc, caught = run_inprocess(args, case, timeout=1800.0)
            cls, detail = classify(rc, err, exc, case, set(), outputs, (), caught)
            assert cls == "ok", f"sins {' '.join(args)}: {cls}: {detail or err}"


@pytest.mark.slow
def test_fuzz_contract(seeds, tmp_path):
    rng = np.random.default_rng(SEED)
    counts = collections.Counter()
    by_kind = collections.defaultdict(collections.Counter)
    failures = collections.defaultdict(list)
    before = {p: p.stat().st_mtime_ns for p in seeds.values()}
    slowest = 0.0
    t_start = time.perf_counter()
    for k in range(N_CASES):
        case_dir = tmp_path / f"c{k:04d}"
        case_dir.mkdir()
        desc, args, outputs, names, how = make_case(k, rng, seeds, case_dir)
        inputs = {p.name for p in case_dir.iterdir()}
        t0 = time.perf_counter()
        try:
            rc, err, exc, caught = RUNNERS[how](args, case_dir)
            cls, detail = classify(rc, err, exc, case_dir, inputs, outputs, names, caught)
        except Hang:
            cls, detail = "hang", f"no answer within {HANG_S:g} s"
        slowest = max(slowest, time.perf_counter() - t0)
        counts[cls] += 1
        by_kind[desc.split(":")[0]][cls] += 1
        if cls not in ("ok", "refused"):
            failures[cls].append(f"#{k} {desc}: {detail}")
        shutil.rmtree(case_dir, ignore_errors=True)
    elapsed = time.perf_counter() - t_start
    assert {p: p.stat().st_mtime_ns for p in seeds.values()} == before, "a run wrote into the seed inputs"
    summary = {"cases": N_CASES, "seconds": round(elapsed, 1), "slowest_case_s": round(slowest, 2),
               "classes": dict(counts), "by_input": {k: dict(v) for k, v in sorted(by_kind.items())}}
    print(f"\nfuzz contract: {json.dumps(summary)}")
    if os.environ.get("SINS_FUZZ_REPORT"):
        Path(os.environ["SINS_FUZZ_REPORT"]).write_text(
            json.dumps({**summary, "failures": {c: v[:50] for c, v in failures.items()}}, indent=1))
    text = "\n".join(f"[{c}] {m}" for c, v in failures.items() for m in v[:12])
    assert not failures, f"{sum(map(len, failures.values()))} of {N_CASES} cases broke the contract " \
                         f"({dict(counts)}):\n{text}"
    assert counts["ok"] > N_CASES // 10 and counts["refused"] > N_CASES // 3     # both outcomes exercised


# --------------------------------------------------------------------------- faults and edges (issue 22)
#
# Two more classes of cases, each run through the commands that write:
#
# * faults: a full disk (a 2 MB tmpfs filled to leave 0 .. 1 MB, where one can be mounted), ENOSPC, EDQUOT,
#   EFBIG and EIO injected through the writers' own file objects after a random number of bytes or at the
#   flush before the rename, write-protected targets and read-only file systems, and odd path bytes (a
#   non-UTF-8 byte, URI characters, spaces, a leading dash, a newline, names near 255 bytes) on inputs and
#   outputs.  A run ends in exit 0 with complete outputs, or in one line naming the target (never a
#   temporary) with the earlier outputs at the target left byte for byte;
# * edge geometry: initial states, GNSS fixes and simulated drives at the poles (within and beyond 0.01 deg
#   of them), across the antimeridian (longitudes of +-180, 360, 540 deg) and at the height limits
#   (-20 km, 1e8 m, and past them).  Besides the contract, every output of a successful run holds
#   longitudes in [-180, 180) and latitudes within +-90.
#
# ``SINS_FUZZ_FAULT_CASES`` sets the number of cases of the full run (default 240, marker ``slow``); the suite's
# quick step runs the first N_FAULT_QUICK of the same seeded sequence.

N_FAULT_CASES = int(os.environ.get("SINS_FUZZ_FAULT_CASES", "240"))
N_FAULT_QUICK = 60
ODD_NAMES = ["\udcff\udcfe", "sp ace", "q?u#e%ry", "-lead", "\u00e9t\u00e9", "nl\nname", "n" * 230]
FAULTS = [(28, "No space left on device"), (122, "Disk quota exceeded"), (27, "File too large"),
          (5, "Input/output error")]
EDGE_LAT = [89.99, 89.9899, -89.99, 89.995, 90.0, -90.0, 90.5, 0.0, 45.0, -89.5]
EDGE_LON = [179.9999999, -180.0, 180.0, 359.9, 360.0, -360.0, 540.0, 0.0, -179.99]
EDGE_H = [-20000.0, -20000.5, 0.0, 1.0e5, 1.0e7, 1.0e8, 1.0e8 + 1.0, 50.0]


class _Failing:
    """A writer's file object whose writes fail with errno ``code`` past ``limit`` bytes (or characters)."""

    def __init__(self, real, code, limit):
        self.real, self.code, self.limit, self.n = real, code, limit, 0

    def write(self, b):
        self.n += len(b)
        if self.n > self.limit:
            raise OSError(self.code, os.strerror(self.code))
        return self.real.write(b)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self.real, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.real.close()


@contextlib.contextmanager
def _injected(code: int, limit: int | None, at_flush: bool):
    """Writes to staged temporaries fail with ``code`` past ``limit`` bytes, or the flush before the rename."""
    import builtins
    import io as io_mod
    from sinscli.io import atomic
    real_open, real_fsync = builtins.open, atomic._fsync

    def fake_open(file, mode="r", *a, **k):
        f = real_open(file, mode, *a, **k)
        if limit is not None and any(c in mode for c in "wax") and ".part" in os.fsdecode(os.fspath(file)):
            return _Failing(f, code, limit)
        return f

    def fake_fsync(path):
        raise OSError(code, os.strerror(code))
    builtins.open = io_mod.open = fake_open
    if at_flush:
        atomic._fsync = fake_fsync
    try:
        yield
    finally:
        builtins.open = io_mod.open = real_open
        atomic._fsync = real_fsync


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else b"<dir>")
            for p in sorted(folder.rglob("*")) if p.name != "filler"}


def _geometry(path: Path) -> str | None:
    """Where an output holds a longitude outside [-180, 180) or a latitude beyond 90 (None: nowhere)."""
    lat = lon = None
    try:
        if path.suffix in (".csv", ".parquet") and path.name.startswith("out"):
            from sinscli.config import Limits
            from sinscli.io.trajectory import read_trajectory
            wide = Limits(speed=1e300, height_min=-1e300, height_max=1e300)   # a diverged run
            t = read_trajectory(path, limits=wide)                 # (from a height of 1e8 m) is written as is
            lat, lon = np.degrees(t.lat), np.degrees(t.lon)
        elif path.suffix == ".geojson":
            from sinscli.io.geo import read_geojson
            _, lat, lon, _ = read_geojson(path)
        elif path.suffix == ".kml":
            from sinscli.io.geo import read_kml
            lat, lon, _ = read_kml(path)
        elif path.suffix == ".mcap":
            from sinscli.io.foxglove import read_trajectory_mcap
            t = read_trajectory_mcap(path)
            lat, lon = np.degrees(t.lat), np.degrees(t.lon)
        elif path.is_dir() and (path / "gnss.csv").is_file():            # a simulated set
            g = np.genfromtxt(path / "gnss.csv", delimiter=",", names=True)
            lat, lon = np.atleast_1d(g["lat"]), np.atleast_1d(g["lon"])
    except Exception as exc:  # noqa: BLE001 - an output sins itself cannot read back is a break
        return f"{path.name}: cannot be read back ({type(exc).__name__}: {exc})"
    if lat is None:
        return None
    if not (np.all(np.abs(lat) <= 90.0) and np.all((lon >= -180.0) & (lon < 180.0))):
        return f"{path.name}: latitude {float(np.max(np.abs(lat)))} / longitude {float(np.min(lon))} .. " \
               f"{float(np.max(lon))}"
    return None


def _edge_scenario(rng, path: Path) -> str:
    lat = float(rng.choice([89.5, 89.85, 89.899, 89.9, -89.85, 0.0, 45.0]))
    lon = float(rng.choice([179.999, -179.999, 180.0, -180.0, 359.9, 0.0]))
    h = float(rng.choice([-20000.0, -19000.0, 50.0, 1.0e5, 1.0e7, 1.0e8]))
    heading = float(rng.choice([0.0, 90.0, 180.0, 270.0, 45.0]))
    sc = {"name": "edge", "start": {"lat": lat, "lon": lon, "height": h, "heading": heading},
          "imu": {"rate": 20, "sensor": "mems"}, "gnss": {"rate": 1, "pos_noise": [1.5, 1.5, 3.0]},
          "segments": [{"type": "rest", "duration": 3}, {"type": "accelerate", "speed": 20, "duration": 4},
                       {"type": "cruise", "duration": 8}]}
    path.write_text(yaml.safe_dump(sc))
    return f"scenario at {lat}, {lon}, {h} m heading {heading}"


def make_fault_case(rng, seeds: dict, case_dir: Path, disk: Path | None):
    """(description, args, outputs relative to the output folder, output folder, names for a refusal,
    kind, setup) of one fault or edge case; ``setup`` is a context manager around the run."""
    from sinscli.errors import printable
    S = {k: str(v) for k, v in seeds.items()}
    kinds = ["inject", "flush", "readonly", "oddpath", "edge-init", "edge-gnss", "edge-sim"]
    weights = [3, 1, 1, 3, 3, 2, 2]
    if disk is not None:
        kinds.append("enospc")
        weights.append(4)
    weights = np.array(weights, float)
    kind = kinds[int(rng.choice(len(kinds), p=weights / weights.sum()))]
    ext = OUT_EXT[int(rng.integers(len(OUT_EXT)))]
    pick = int(rng.integers(8))
    writers = [
        (["navigate", S["imu"], "--init", S["init"], "-q", "-o", "out" + ext], ["out" + ext]),
        (["navigate", S["imu"], "--gnss", S["gnss"], "--init", S["init"], "-q", "--innovations", "innov.csv",
          "-o", "out" + ext], ["out" + ext, "innov.csv"]),
        (["compare", "--truth", S["truth"], S["nav"], "-q", "-o", "rep"], ["rep"]),
        (["convert", S["bag"], "-q", "-o", "conv"], ["conv"]),
        (["align", S["imu"], "--method", "inertial", *ALIGN[:-1], "--series", "series.csv", "--plot",
          "align.png", "-q", "-o", "out.yaml"], ["out.yaml", "series.csv", "align.png"]),
        (["simulate", str(ROOT / "configs/scenarios/vehicle_drive.yaml"), "--duration", "4", "-q", "-o", "sim"],
         ["sim"]),
        (["allan", S["static"], "-q", "-o", "al"], ["al"]),
        (["navigate", S["imu"], "--init", S["init"], "-q", "--every", "3", "-o", "out.csv"], ["out.csv"]),
    ]
    args, outputs = writers[pick]
    args, outputs = list(args), list(outputs)
    out_dir = case_dir
    setup = contextlib.nullcontext()
    names: tuple = ()
    if kind in ("enospc", "inject", "flush", "readonly"):
        earlier = bool(rng.random() < 0.5)
        if kind == "enospc":
            out_dir = disk
            for p in list(disk.iterdir()):
                if p.name != "filler":
                    shutil.rmtree(p) if p.is_dir() else p.unlink()
        for o in outputs if earlier else []:          # an earlier output at the target, to be kept on failure
            target = out_dir / o
            if "." in o and not o.startswith("sim"):
                target.write_bytes(b"earlier complete output\n")
            else:
                target.mkdir()
                (target / "earlier.txt").write_text("earlier\n")
        if kind == "enospc":
            room = int(rng.choice([0, 4096, 16384, 65536, 262144, 1048576]))
            (disk / "filler").unlink(missing_ok=True)
            size = max(shutil.disk_usage(disk).free - room - 16384, 0)      # (tmpfs counts whole pages)
            (disk / "filler").write_bytes(b"\0" * size)
            label = f"disk full, {room} bytes free"
        elif kind in ("inject", "flush"):
            code, text = FAULTS[int(rng.integers(len(FAULTS)))]
            limit = None if kind == "flush" else int(rng.choice([0, 100, 4096, 65536, 1 << 20]))
            setup = _injected(code, limit, kind == "flush")
            label = f"{text} " + ("at the flush before the rename" if kind == "flush" else f"after {limit} bytes")
        else:
            o = outputs[0]
            target = out_dir / o
            if "." in o and not target.exists():
                target.write_bytes(b"earlier complete output\n")
            if target.is_file():
                target.chmod(0o444)
                label = "write-protected target"
            else:
                target.mkdir(exist_ok=True)
                target.chmod(0o555)
                label = "read-only target folder"
        if kind == "enospc":
            args = [str(disk / a) if a in outputs else a for a in args]
        names = tuple(outputs) + ("cannot write",)
        return f"{kind}: {label}: sins {' '.join(args)}", args, outputs, out_dir, names, kind, setup
    if kind == "oddpath":
        stem = ODD_NAMES[int(rng.integers(len(ODD_NAMES)))]
        which = int(rng.integers(3))
        new = []
        for a in args:
            if a in S.values() and which in (0, 2):      # inputs renamed
                src = Path(a)
                dst = case_dir / f"{stem}.{src.name}"
                shutil.copy(src, dst)
                a = str(dst)
            new.append(a)
        args = new
        if which in (1, 2):                               # outputs renamed
            ren = {o: f"{stem}.{o}" for o in outputs}
            args = [ren.get(a, a) for a in args]
            outputs = [ren[o] for o in outputs]
        names = (printable(stem)[:40],)
        return f"oddpath: {stem!r} ({which}): sins {' '.join(args)}", args, outputs, out_dir, names, kind, setup
    lat, lon, h = (float(rng.choice(EDGE_LAT)), float(rng.choice(EDGE_LON)), float(rng.choice(EDGE_H)))
    if kind == "edge-init":
        init = yaml.safe_load(Path(S["init"]).read_text())
        init.update(lat=lat, lon=lon, height=h, heading=float(rng.choice([0.0, 90.0, 270.0])))
        (case_dir / "init.yaml").write_text(yaml.safe_dump(init))
        if pick < 5:
            args = ["navigate", S["imu"], "--init", "init.yaml", "-q", "-o", "out" + ext]
        else:
            args = ["navigate", S["imu"], "--gnss", S["gnss"], "--init", "init.yaml", "-q", "-o", "out" + ext]
        # refused naming the init, or (a height where the normal gravity no longer holds, the vertical
        # velocity running away) by the writers' range guard naming the output, row and epoch
        return f"edge-init: {lat}, {lon}, {h}: sins {' '.join(args)}", args, ["out" + ext], case_dir, \
            ("init.yaml", f"out{ext}: internal consistency check"), kind, setup
    if kind == "edge-gnss":
        lines = Path(S["gnss"]).read_text().splitlines()
        for r in sorted(set(rng.integers(1, len(lines), 3).tolist())):
            cells = lines[r].split(",")
            cells[1], cells[2], cells[3] = repr(lat), repr(lon), repr(h)
            lines[r] = ",".join(cells)
        (case_dir / "gnss.csv").write_text("\n".join(lines) + "\n")
        args = ["navigate", S["imu"], "--gnss", "gnss.csv", "--init", S["init"], "-q", "-o", "out" + ext]
        return f"edge-gnss: {lat}, {lon}, {h}: sins {' '.join(args)}", args, ["out" + ext], case_dir, \
            ("gnss.csv", f"out{ext}: internal consistency check"), kind, setup
    label = _edge_scenario(rng, case_dir / "edge.yaml")
    args = ["simulate", "edge.yaml", "-q", "-o", "sim"]
    return f"edge-sim: {label}", args, ["sim"], case_dir, ("edge.yaml", "start."), kind, setup


def classify_fault(rc, stderr, exc, kind, out_dir: Path, outputs, before: dict, names, caught):
    """The class of a fault or edge run (the contract of :func:`classify`, plus: a refusal leaves the
    output folder as it was; a success holds complete outputs whose positions are in range)."""
    if exc is not None and not isinstance(exc, SystemExit):
        return "traceback", f"{type(exc).__name__}: {exc}"
    if rc == 1 and "internal error" in stderr:
        return "internal", stderr.strip()[-300:]
    parts = [str(p) for p in out_dir.rglob("*") if ".part" in p.name]
    if parts:
        return "leftover", f"temporaries left: {parts[:3]}"
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    if rc == 0:
        for o in outputs:
            p = out_dir / o
            if not p.exists():
                return "missing-output", o
            bad = nonfinite_in(p) or _geometry(p)
            if bad:
                return "nonfinite" if "is not" not in bad and "latitude" not in bad else "geometry", bad
        return "ok", ""
    errors = [ln for ln in lines if ln.startswith("sins: error:")]
    if rc != 2 or len(errors) != 1 or lines[-1] != errors[0]:
        return f"exit{rc}", " | ".join(lines)[-300:]
    msg = errors[0]
    if ".part" in msg or ".py:" in msg or NUMPY_REPR.search(msg):
        return "unnamed", msg[:300]
    if names and not any(n in msg for n in names):
        return "unnamed", msg[:300]
    if kind in ("enospc", "inject", "flush", "readonly"):
        after = {k: v for k, v in _tree(out_dir).items() if k in before or any(k.startswith(o) for o in outputs)}
        if after != {k: v for k, v in before.items() if k in after or any(k.startswith(o) for o in outputs)}:
            return "changed", f"the output folder changed on a refusal: {sorted(set(after) ^ set(before))[:4]}"
    leaked = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if leaked:
        return "warning", str(leaked[0].message)
    return "refused", msg


@pytest.fixture(scope="module")
def small_disk(tmp_path_factory):
    """A 2 MB tmpfs for the disk-full cases, or None where one cannot be mounted (the injected faults run)."""
    mnt = tmp_path_factory.mktemp("fuzz_disk")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True)
    yield mnt if r.returncode == 0 else None
    if r.returncode == 0:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def test_fuzz_faults_and_edges_quick(seeds, tmp_path, small_disk):
    _fuzz_faults_and_edges(min(N_FAULT_QUICK, N_FAULT_CASES), seeds, tmp_path, small_disk)


@pytest.mark.slow
def test_fuzz_faults_and_edges(seeds, tmp_path, small_disk):
    _fuzz_faults_and_edges(N_FAULT_CASES, seeds, tmp_path, small_disk)


def _fuzz_faults_and_edges(n_cases, seeds, tmp_path, small_disk):
    rng = np.random.default_rng(SEED + 22)
    import faulthandler
    stacks = open(os.environ["SINS_FUZZ_TRACE"] + ".stacks", "w") if os.environ.get("SINS_FUZZ_TRACE") else None
    counts = collections.Counter()
    by_kind = collections.defaultdict(collections.Counter)
    failures = collections.defaultdict(list)
    t_start = time.perf_counter()
    for k in range(n_cases):
        case_dir = tmp_path / f"f{k:04d}"
        case_dir.mkdir()
        desc, args, outputs, out_dir, names, kind, setup = make_fault_case(rng, seeds, case_dir, small_disk)
        if stacks is not None:                  # the case running now, and every thread's stack on a hang
            Path(os.environ["SINS_FUZZ_TRACE"]).write_text(f"#{k} {desc}\n", errors="backslashreplace")
            faulthandler.dump_traceback_later(4 * HANG_S, file=stacks)
        before = _tree(out_dir)
        try:
            with setup:
                rc, err, exc, caught = run_inprocess(args, case_dir)
            cls, detail = classify_fault(rc, err, exc, kind, out_dir, outputs, before, names, caught)
        except Hang:
            cls, detail = "hang", f"no answer within {HANG_S:g} s"
        counts[cls] += 1
        by_kind[kind][cls] += 1
        if cls not in ("ok", "refused"):
            failures[cls].append(f"#{k} {desc}: {detail}")
        for p in case_dir.rglob("*"):
            with contextlib.suppress(OSError):
                p.chmod(0o755 if p.is_dir() else 0o644)
        shutil.rmtree(case_dir, ignore_errors=True)
    if stacks is not None:
        faulthandler.cancel_dump_traceback_later()
        stacks.close()
    elapsed = time.perf_counter() - t_start
    summary = {"cases": n_cases, "seconds": round(elapsed, 1), "disk_full_cases": small_disk is not None,
               "classes": dict(counts), "by_kind": {k: dict(v) for k, v in sorted(by_kind.items())}}
    print(f"\nfuzz faults and edges: {json.dumps(summary)}")
    if os.environ.get("SINS_FUZZ_REPORT"):
        report = Path(os.environ["SINS_FUZZ_REPORT"]).with_suffix(".faults.json")
        report.write_text(json.dumps({**summary, "failures": {c: v[:50] for c, v in failures.items()}}, indent=1))
    text = "\n".join(f"[{c}] {m}" for c, v in failures.items() for m in v[:12])
    assert not failures, f"{sum(map(len, failures.values()))} of {n_cases} cases broke the contract " \
                         f"({dict(counts)}):\n{text}"
    assert counts["ok"] > n_cases // 10 and counts["refused"] > n_cases // 10
