"""Read speed of sensor_msgs/Imu topics: the bulk numpy path against the libraries' per-message decode.

Writes N (default 1,000,000) Imu messages at 200 Hz with the libraries'
serializers as a ROS 1 ``.bag`` (rosbags), a bare rosbag2 ``.db3`` (rosbags)
and an ``.mcap`` (mcap writer, CDR), then for each file measures

- ``msgs_per_s``: ``sinscli.io.ros.read_imu_block`` (open, index, bulk decode);
- ``library_msgs_per_s``: the same library iterating the topic and
  deserializing every message (rosbags ``AnyReader.messages`` +
  ``deserialize`` for .bag/.db3; ``mcap`` ``iter_decoded_messages`` with the
  mcap-ros2-support decoder for .mcap), over all messages (or the first
  ``--lib-count``);

- ``library_raw_no_decode_msgs_per_s``: the library only iterating the raw
  message bytes (no decoding), the container's own cost;

and checks that both give the same values bit for bit on that prefix.

    python benchmarks/bench_read.py [--count 1000000] [--lib-count N] [--dir DIR]
"""
from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from pathlib import Path

import numpy as np

from sinscli.io.ros import decode, read_imu_block, write_log


def library_rate(path: Path, count: int):
    """(messages/s, ImuBlock of the first ``count`` messages) through the library, one message at a time."""
    t0 = time.perf_counter()
    rows = []
    if path.suffix == ".mcap":
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _s, _c, _m, msg in itertools.islice(reader.iter_decoded_messages(topics=["/imu/data"]), count):
                rows.append(decode.imu_from_message(msg))
    else:
        from rosbags.highlevel import AnyReader
        with AnyReader([path]) as reader:
            conns = [c for c in reader.connections if c.topic == "/imu/data"]
            for conn, _t, raw in itertools.islice(reader.messages(conns), count):
                rows.append(decode.imu_from_message(reader.deserialize(raw, conn.msgtype)))
    dt = time.perf_counter() - t0
    sec = np.array([r[0] for r in rows], dtype=np.int64)
    nsec = np.array([r[1] for r in rows], dtype=np.int64)
    values = np.array([r[2] for r in rows])
    return len(rows) / dt, decode.ImuBlock(sec, nsec, values)


def library_raw_rate(path: Path, count: int) -> float:
    """Messages/s of the library iterating raw message bytes without decoding them: the container's
    own cost, which bounds any reader built on the library."""
    t0 = time.perf_counter()
    n = 0
    if path.suffix == ".mcap":
        from mcap.reader import make_reader
        with open(path, "rb") as f:
            for _ in itertools.islice(make_reader(f).iter_messages(topics=["/imu/data"]), count):
                n += 1
    else:
        from rosbags.highlevel import AnyReader
        with AnyReader([path]) as reader:
            conns = [c for c in reader.connections if c.topic == "/imu/data"]
            for _ in itertools.islice(reader.messages(conns), count):
                n += 1
    return n / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=1_000_000)
    ap.add_argument("--lib-count", type=int, default=None,
                    help="messages for the library rates (default: all; the library's open cost covers the file)")
    ap.add_argument("--dir", type=Path, default=None, help="keep the generated logs here (default: a temp dir)")
    args = ap.parse_args()
    if args.lib_count is None:
        args.lib_count = args.count
    tmp = None
    if args.dir is None:
        tmp = tempfile.TemporaryDirectory()
        args.dir = Path(tmp.name)
    args.dir.mkdir(parents=True, exist_ok=True)
    n = args.count
    rng = np.random.default_rng(7)
    t = 1.7e9 + np.arange(n) * 0.005
    imu = {"time": t, "gyro": rng.normal(0.0, 0.1, (n, 3)), "accel": rng.normal(0.0, 0.5, (n, 3)) + [0, 0, 9.8]}
    for name in ("imu.bag", "imu.db3", "imu.mcap"):
        path = args.dir / name
        if not path.exists():
            t0 = time.perf_counter()
            write_log(path, imu=imu)
            print(f"# wrote {n} messages to {path} in {time.perf_counter() - t0:.1f} s "
                  f"({path.stat().st_size / 1e6:.0f} MB)", flush=True)
    print(f"# {n} sensor_msgs/Imu messages per file; library rate from the first {args.lib_count}")
    for fmt, name in (("bag", "imu.bag"), ("db3", "imu.db3"), ("mcap", "imu.mcap")):
        path = args.dir / name
        best = 0.0
        for _ in range(2):
            t0 = time.perf_counter()
            _topic, _log_ns, block = read_imu_block(path, "/imu/data")
            best = max(best, len(block) / (time.perf_counter() - t0))
        lib_rate, ref = library_rate(path, args.lib_count)
        raw_rate = library_raw_rate(path, args.lib_count)
        m = len(ref)
        same = (np.array_equal(block.sec[:m], ref.sec) and np.array_equal(block.nsec[:m], ref.nsec)
                and block.values[:m].tobytes() == ref.values.tobytes())
        print(f"{fmt} msgs_per_s={best:.0f} library_msgs_per_s={lib_rate:.0f} ratio={best / lib_rate:.1f} "
              f"library_raw_no_decode_msgs_per_s={raw_rate:.0f} bulk_fraction={block.n_bulk / len(block):.3f} "
              f"identical={same}", flush=True)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
