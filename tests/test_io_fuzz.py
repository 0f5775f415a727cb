"""Fuzzing the log readers: truncated and corrupted real and generated logs.

Every case must end, within a time bound, in either a one-line SinsError naming
the file, or a result that is not silently wrong: the same samples as the
intact log, or, for containers without checksums (uncompressed ROS 1 chunks,
lz4 chunks without a checksum, SQLite pages), exactly what the library's own
per-message decoder reads from the same corrupted bytes.  MCAP chunks are CRC
checked and bz2 chunks carry a CRC, so there a success must give the intact
samples.
"""
from __future__ import annotations

import signal
from pathlib import Path

import numpy as np
import pytest
from realdata import HUSKY_BAG

from sinscli.errors import SinsError
from sinscli.io import ros

HUSKY = HUSKY_BAG
CASE_SECONDS = 10.0
N_TRUNC, N_FLIP, N_BLOCK = 12, 48, 8        # up to 68 cases per source (8 sources with the real data)


class _Hang(Exception):
    pass


def _bounded(fn, *args, **kw):
    """Run ``fn`` with a wall-clock bound (SIGALRM): a hang fails the test instead of blocking it."""
    def on_alarm(signum, frame):
        raise _Hang()
    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, CASE_SECONDS)
    try:
        return fn(*args, **kw)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _small_real_logs(d: Path) -> list[tuple[Path, bool]]:
    """The first 200 IMU and 16 GNSS messages of the real Husky bag, raw bytes copied (bz2 ROS 1 bag),
    and the same converted to MCAP by the rosbags converter."""
    from rosbags.convert import convert
    from rosbags.rosbag1 import Reader, Writer
    out = d / "real.bag"
    with Reader(HUSKY) as r:
        conns = [c for c in r.connections if c.topic in ("/imu/data", "/fix")]
        w = Writer(out)
        w.set_compression(Writer.CompressionFormat.BZ2)
        with w:
            new = {c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                   for c in conns}
            counts = {"/imu/data": 0, "/fix": 0}
            for c, t, raw in r.messages(conns):
                if counts[c.topic] < (200 if c.topic == "/imu/data" else 16):
                    w.write(new[c.id], t, raw)
                    counts[c.topic] += 1
                if counts["/imu/data"] >= 200 and counts["/fix"] >= 16:
                    break
    convert([out], d / "realmc", "mcap", 9, None, "file", None, None, (), (), (), ())
    # rosbags writes MCAP chunks without a CRC (0): not a checksummed source
    return [(out, True), (d / "realmc" / "realmc.mcap", False)]


def _generated_logs(d: Path) -> list[tuple[Path, bool]]:
    n, m = 40, 4
    rng = np.random.default_rng(5)
    t = 100.0 + 0.01 * np.arange(n)
    imu = {"time": t, "gyro": rng.normal(0, 0.1, (n, 3)), "accel": rng.normal(0, 1, (n, 3)) + [0, 0, 9.8]}
    gnss = {"time": t[::10], "lat": 30 + 1e-5 * np.arange(m), "lon": 114 + 1e-5 * np.arange(m),
            "height": np.full(m, 10.0), "cov": np.tile([1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0], (m, 1))}
    out = []
    for name, kw, checked in [("gen.bag", {}, False), ("gen_bz2.bag", {"bag_compression": "bz2"}, True),
                              ("gen_lz4.bag", {"bag_compression": "lz4"}, False), ("gen.mcap", {}, True),
                              ("gen_ros1.mcap", {"mcap_encoding": "ros1"}, True), ("gen.db3", {}, False)]:
        ros.write_log(d / name, imu=imu, gnss=gnss, **kw)
        out.append((d / name, checked))
    return out


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    """Real logs when tests/data holds them (else generated ones only, with more cases each)."""
    d = tmp_path_factory.mktemp("fuzz_src")
    real = _small_real_logs(d) if HUSKY.is_file() else []
    return real + _generated_logs(d)


def _mutations(size: int, rng: np.random.Generator, n_flip: int = N_FLIP):
    for k in sorted({0, 8, 13, size - 1, size - 9, *rng.integers(1, size, N_TRUNC - 5).tolist()}):
        yield f"truncate to {k}", ("trunc", k)
    for _ in range(n_flip):
        pos = rng.integers(0, size, rng.integers(1, 4))
        yield f"flip bytes at {pos.tolist()}", ("flip", pos, rng.integers(1, 256, pos.size))
    for _ in range(N_BLOCK):
        p = int(rng.integers(0, max(size - 16, 1)))
        yield f"overwrite 16 bytes at {p}", ("block", p, rng.integers(0, 256, 16))


def _apply(data: bytes, mut) -> bytes:
    if mut[0] == "trunc":
        return data[: mut[1]]
    b = bytearray(data)
    if mut[0] == "flip":
        for p, x in zip(mut[1], mut[2]):
            b[p] ^= int(x)
    else:
        b[mut[1]: mut[1] + 16] = bytes(int(x) for x in mut[2])[: len(b) - mut[1]]
    return bytes(b)


def _same_imu(a, b) -> bool:
    return (len(a) == len(b) and a.t0 == b.t0 and np.array_equal(a.time, b.time)
            and a.dtheta_b.tobytes() == b.dtheta_b.tobytes() and a.dvel_b.tobytes() == b.dvel_b.tobytes())


def _same_gnss(a, b) -> bool:
    return (len(a) == len(b) and np.array_equal(a.time, b.time) and np.array_equal(a.lat, b.lat)
            and np.array_equal(a.lon, b.lon) and np.array_equal(a.height, b.height))


def _only_hit_rows_differ(path: Path, ref_block, mut) -> bool:
    """No message lost, added or shifted: the same number of messages as the intact log, and at most
    as many changed messages as bytes were changed (a changed payload byte cannot be detected without
    a checksum, by any reader)."""
    if mut[0] == "trunc":
        return False
    blk = _bounded(ros.read_imu_block, path)[2]
    if len(blk) != len(ref_block):
        return False
    changed = ((blk.sec != ref_block.sec) | (blk.nsec != ref_block.nsec)
               | (blk.values.view(np.uint64) != ref_block.values.view(np.uint64)).any(axis=1))
    n_bytes = len(mut[1]) if mut[0] == "flip" else 16
    return int(changed.sum()) <= n_bytes


def _library_agrees(path: Path, imu) -> bool:
    """True when the libraries' per-message decode of the same corrupted bytes gives ``imu``.

    First the whole library read path; if that fails on a damaged SQLite index that the bulk
    path does not use, the rosbags deserializer on every stored row (in row order).
    """
    try:
        lib = _bounded(ros.read_imu, path, bulk=False)
        return _same_imu(imu, lib)
    except SinsError:
        if path.suffix != ".db3":
            return False
    import sqlite3

    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with sqlite3.connect(path) as con:
        rows = con.execute("SELECT m.data FROM messages m JOIN topics t ON m.topic_id = t.id "
                           "WHERE t.name = '/imu/data' ORDER BY m.id").fetchall()
    msgs = [ts.deserialize_cdr(r[0], "sensor_msgs/msg/Imu") for r in rows]
    t = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs])
    gyro = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in msgs])
    return (len(msgs) == len(imu) + 1 and np.array_equal(t[1:], imu.time)
            and np.array_equal(0.5 * (gyro[1:] + gyro[:-1]) * np.diff(t)[:, None], imu.dtheta_b))


def _outcome(fn, path):
    try:
        return "ok", _bounded(fn, path)
    except SinsError as exc:
        msg = str(exc)
        assert "\n" not in msg and path.name in msg, f"{path.name}: error message {msg!r}"
        return "error", msg


def test_fuzz_readers(sources, tmp_path):
    rng = np.random.default_rng(20240601)
    n_cases = n_ok = n_err = 0
    failures = []
    n_flip = max(N_FLIP, -(-550 // len(sources)) - N_TRUNC - N_BLOCK)   # at least 500 cases in all
    for src, checked in sources:
        data = src.read_bytes()
        ref_imu = ros.read_imu(src)
        ref_gnss = ros.read_gnss(src)
        ref_block = ros.read_imu_block(src)[2]
        target = tmp_path / src.name
        for k, (label, mut) in enumerate(_mutations(len(data), rng, n_flip)):
            target.write_bytes(_apply(data, mut))
            case = f"{src.name}: {label}"
            n_cases += 1
            try:
                kind, imu = _outcome(ros.read_imu, target)
                if kind == "ok":
                    n_ok += 1
                    if not _same_imu(imu, ref_imu):
                        if checked:
                            failures.append(f"{case}: checksummed log read to different IMU samples")
                        elif not (_only_hit_rows_differ(target, ref_block, mut) or _library_agrees(target, imu)):
                            failures.append(f"{case}: bulk result differs from the library's decode")
                else:
                    n_err += 1
                if k % 3 == 0:
                    kind, gnss = _outcome(ros.read_gnss, target)
                    if kind == "ok" and checked and not _same_gnss(gnss, ref_gnss):
                        failures.append(f"{case}: checksummed log read to different GNSS fixes")
            except _Hang:
                failures.append(f"{case}: no answer within {CASE_SECONDS} s")
            except AssertionError as exc:
                failures.append(f"{case}: {exc}")
            except Exception as exc:  # noqa: BLE001 - any other exception is a traceback for the user
                failures.append(f"{case}: {type(exc).__name__}: {exc}")
    assert not failures, f"{len(failures)} of {n_cases} cases failed:\n" + "\n".join(failures[:30])
    assert n_cases >= 500
    assert n_err > 100 and n_ok > 20          # both outcomes are exercised
