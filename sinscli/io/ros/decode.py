"""ROS messages -> numpy: bulk ``sensor_msgs/Imu`` decoding, deserialized messages, time stamps.

Bulk numpy decoding of ``sensor_msgs/Imu`` from raw CDR (ROS 2) and ROS 1 bytes.

A generic deserializer builds one Python object per message (tens of
thousands of messages per second).  When the messages of a topic share one
layout (same ``frame_id``, hence the same byte length), every field sits at the
same offset in every message, and the whole topic decodes with a few numpy
views.  Messages that do not fit the layout are decoded one by one by the
library deserializer passed in by the caller, so the result is always the
library's decode, bit for bit (``tests/test_io_bags.py`` checks it).

Wire layouts (``sensor_msgs/Imu``: ``Header header`` then 37 ``float64``:
orientation xyzw, its covariance (9), angular_velocity xyz, its covariance
(9), linear_acceleration xyz, its covariance (9)):

- ROS 1: ``uint32 seq, uint32 sec, uint32 nsec, uint32 len, char[len]``,
  then the 37 float64 unaligned, little endian.
- CDR (ROS 2): 4-byte encapsulation header ``00 01 xx xx`` (little endian),
  ``int32 sec, uint32 nanosec, uint32 len, char[len]`` (``len`` counts the
  terminating NUL), then the 37 float64 aligned to 8 bytes relative to the end
  of the encapsulation header.

The time rules shared by the readers (header or log time, strictly
increasing stamps) are here too.  This module only slices bytes and message
objects into arrays: no file access.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ...conventions import ROS_TIMES
from ...errors import SinsError

IMU_TYPE = "sensor_msgs/msg/Imu"
NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
TWIST_TYPES = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/TwistWithCovarianceStamped")
VEL_TYPES = TWIST_TYPES                          # GNSS velocity, ENU (a GNSS receiver's twist)
BODY_VEL_TYPES = (ODOMETRY_TYPE,) + TWIST_TYPES  # body velocity (odometry): twist in the child / header frame
TIME_SOURCES = ROS_TIMES      # ros.time, sins convert --time (sinscli.conventions)

N_VALUES = 37                       # float64 fields after the header
ORIENTATION = slice(0, 4)           # x, y, z, w
GYRO = slice(13, 16)                # angular_velocity x, y, z  [rad/s]
ACCEL = slice(25, 28)               # linear_acceleration x, y, z  [m/s^2]
GYRO_COV = slice(16, 25)
ACCEL_COV = slice(28, 37)
_BODY = 8 * N_VALUES                # 296 bytes of float64 after the header
_CDR_TRAILING = 3                   # the CDR deserializer tolerates up to 3 padding bytes


@dataclass
class ImuBlock:
    """Decoded ``sensor_msgs/Imu`` messages of one topic, in file order.

    ``sec``/``nsec`` are the header stamp (int64), ``values`` the 37 float64
    fields (see the slices ``ORIENTATION``, ``GYRO``, ``ACCEL`` of this module).
    """
    sec: np.ndarray        # (N,) int64
    nsec: np.ndarray       # (N,) int64
    values: np.ndarray     # (N, 37) float64
    n_bulk: int = 0        # how many messages went through the numpy path

    def __len__(self) -> int:
        return int(self.sec.shape[0])


def stamp_seconds(sec, nsec) -> np.ndarray:
    """Seconds as float64 from integer seconds and nanoseconds (one formula for every path)."""
    return np.asarray(sec, dtype=np.int64).astype(np.float64) + np.asarray(nsec, dtype=np.int64) * 1e-9


def message_stamp(msg) -> tuple[int, int]:
    """``(sec, nsec)`` of a deserialized message's header stamp (rosbags, mcap-ros2 or genpy ``Time``)."""
    s = msg.header.stamp
    if hasattr(s, "nanosec"):
        return int(s.sec), int(s.nanosec)
    return int(s.secs), int(s.nsecs)                # genpy Time (mcap-ros1-support)


def message_times(where: str, log_ns, msgs, time_source: str) -> np.ndarray:
    """Seconds of deserialized messages from their header stamps or their log times (int64 ns)."""
    if time_source == "header":
        st = np.array([message_stamp(m) for m in msgs], dtype=np.int64).reshape(-1, 2)
        if np.any((st[:, 1] < 0) | (st[:, 1] >= 1_000_000_000)):
            raise SinsError(f"{where}: a header stamp has nanoseconds >= 1e9")
        return stamp_seconds(st[:, 0], st[:, 1])
    return stamp_seconds(log_ns // 1_000_000_000, log_ns % 1_000_000_000)


def check_time_source(time_source: str):
    if time_source not in TIME_SOURCES:
        raise SinsError(f"time source {time_source!r} unknown (expected header or log)")


def check_increasing(t: np.ndarray, where: str, what: str = "time"):
    """SinsError at the first sample whose time does not increase."""
    if t.shape[0] > 1:
        bad = np.flatnonzero(~(np.diff(t) > 0))
        if bad.size:
            k = int(bad[0]) + 1
            word = "repeats" if t[k] == t[k - 1] else "goes backwards"
            raise SinsError(f"{where}: {what} {word} at message {k} ({t[k]:.9f} s after {t[k - 1]:.9f} s); "
                            "times must be strictly increasing")


def imu_layout(encoding: str, frame_len: int) -> tuple[int, int]:
    """``(data_offset, total_length)`` of an Imu message whose ``frame_id`` length field is ``frame_len``."""
    if encoding == "ros1":
        data = 16 + frame_len
    elif encoding == "cdr":
        body = 12 + frame_len                       # offset after the string, from the end of the 4-byte header
        data = 4 + ((body + 7) // 8) * 8
    else:
        raise ValueError(f"unknown encoding {encoding!r}")
    return data, data + _BODY


def gather(buf: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """Rows ``buf[s:s+length]`` for every start ``s`` as an (N, length) uint8 array (bounds checked by numpy)."""
    starts = np.asarray(starts, dtype=np.int64)
    if starts.size and (starts.min() < 0 or starts.max() + length > buf.shape[0]):
        raise IndexError("record outside the buffer")
    if length == 0:
        return np.empty((starts.size, 0), dtype=buf.dtype)
    return np.lib.stride_tricks.sliding_window_view(buf, length)[starts]


def read_le(buf: np.ndarray, starts: np.ndarray, dtype: str) -> np.ndarray:
    """Little-endian integers of ``dtype`` ('<u4', '<u8', ...) at byte offsets ``starts`` of ``buf``."""
    size = np.dtype(dtype).itemsize
    return np.ascontiguousarray(gather(buf, starts, size)).view(dtype)[:, 0]


def decode_imu_block(block: np.ndarray, encoding: str) -> ImuBlock | None:
    """Decode an (N, L) uint8 array of same-length Imu messages, or None if they do not share one layout.

    Accepted only when every row has the same ``frame_id`` length (each
    frame_id valid UTF-8), the length that layout implies, a little-endian CDR
    encapsulation (for CDR) and nanoseconds below 1e9; anything else is left
    to the library deserializer.
    """
    n, length = block.shape
    if n == 0 or length < 16 or encoding not in ("cdr", "ros1"):
        return None
    if encoding == "cdr" and not (np.all(block[:, 0] == 0) and np.all(block[:, 1] == 1)):
        return None
    slen = np.ascontiguousarray(block[:, 12:16]).view("<u4")[:, 0]
    s0 = int(slen[0])
    if np.any(slen != s0):
        return None
    data, total = imu_layout(encoding, s0)
    if not (total == length or (encoding == "cdr" and total <= length <= total + _CDR_TRAILING)):
        return None
    frames = block[:, 16:16 + s0]
    if s0 and not np.array_equal(frames, np.broadcast_to(frames[0], (n, s0))):
        frames = np.unique(frames, axis=0)            # several frame_ids of one length
    else:
        frames = frames[:1]
    for frame in frames:
        if encoding == "cdr":
            if s0 < 1 or frame[-1] != 0:
                return None
            frame = frame[:-1]
        try:
            bytes(frame).decode()                     # the library decodes frame_id as UTF-8
        except UnicodeDecodeError:
            return None
    sec = np.ascontiguousarray(block[:, 4:8]).view("<i4" if encoding == "cdr" else "<u4")[:, 0].astype(np.int64)
    nsec = np.ascontiguousarray(block[:, 8:12]).view("<u4")[:, 0].astype(np.int64)
    if np.any(nsec >= 1_000_000_000):
        return None
    block = np.ascontiguousarray(block)
    # a strided float64 view of the 37 values of every row: no copy of the payload
    values = np.ndarray(shape=(n, N_VALUES), dtype="<f8", buffer=block, offset=data, strides=(length, 8))
    return ImuBlock(sec, nsec, values, n_bulk=n)


def imu_from_message(msg) -> tuple[int, int, np.ndarray]:
    """``(sec, nsec, values[37])`` from a deserialized Imu object (rosbags, mcap-ros2 or mcap-ros1/genpy)."""
    sec, nsec = message_stamp(msg)
    o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    vals = np.empty(N_VALUES)
    vals[0:4] = (o.x, o.y, o.z, o.w)
    vals[4:13] = np.asarray(msg.orientation_covariance, dtype=np.float64)
    vals[13:16] = (w.x, w.y, w.z)
    vals[16:25] = np.asarray(msg.angular_velocity_covariance, dtype=np.float64)
    vals[25:28] = (a.x, a.y, a.z)
    vals[28:37] = np.asarray(msg.linear_acceleration_covariance, dtype=np.float64)
    return sec, nsec, vals


def decode_imu_messages(raws: Sequence[bytes], encoding: str,
                        deserialize: Callable[[bytes], object], bulk: bool = True) -> ImuBlock:
    """Decode a list of raw Imu messages: numpy for each same-length group that shares a layout,
    ``deserialize`` (the library) for every other message.  Order is kept.

    ``bulk=False`` forces the library path for every message (the reference the bulk path must equal).
    The first and last message of each bulk group are also decoded by the library and compared bit
    for bit; a mismatch (e.g. a custom message definition named ``Imu``) sends the group to the library.
    """
    n = len(raws)
    sec = np.empty(n, dtype=np.int64)
    nsec = np.empty(n, dtype=np.int64)
    values = np.empty((n, N_VALUES))
    todo = np.ones(n, dtype=bool)
    n_bulk = 0
    if bulk and n:
        lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=n)
        for length in np.unique(lengths):
            idx_len = np.flatnonzero(lengths == length)
            if idx_len.size < 2 or length < 16:
                continue
            joined = b"".join(raws[i] for i in idx_len) if idx_len.size < n else b"".join(raws)
            block_len = np.frombuffer(joined, dtype=np.uint8).reshape(idx_len.size, int(length))
            slen = np.ascontiguousarray(block_len[:, 12:16]).view("<u4")[:, 0]
            for s in np.unique(slen):                 # CDR padding lets several frame_id lengths share a size
                sel = np.flatnonzero(slen == s)
                if sel.size < 2:
                    continue
                idx = idx_len[sel]
                block = block_len if sel.size == idx_len.size else block_len[sel]
                dec = decode_imu_block(block, encoding)
                if dec is None or not _spot_check(dec, [raws[idx[0]], raws[idx[-1]]], [0, idx.size - 1],
                                                  deserialize):
                    continue
                sec[idx], nsec[idx], values[idx] = dec.sec, dec.nsec, dec.values
                todo[idx] = False
                n_bulk += idx.size
    for i in np.flatnonzero(todo):
        sec[i], nsec[i], values[i] = imu_from_message(deserialize(raws[i]))
    return ImuBlock(sec, nsec, values, n_bulk=n_bulk)


def _spot_check(dec: ImuBlock, raws: Sequence[bytes], rows: Sequence[int],
                deserialize: Callable[[bytes], object]) -> bool:
    """True when the library decodes ``raws`` to exactly the bulk rows ``rows`` (bitwise)."""
    for raw, k in zip(raws, rows):
        s, ns, v = imu_from_message(deserialize(raw))
        if s != dec.sec[k] or ns != dec.nsec[k] or v.tobytes() != dec.values[k].tobytes():
            return False
    return True


def check_block(dec: ImuBlock, raws_first_last: Sequence[bytes], deserialize: Callable[[bytes], object]) -> bool:
    """Spot check of a bulk block made from container records (first and last rows against the library)."""
    n = len(dec)
    return n == 0 or _spot_check(dec, raws_first_last, [0, n - 1], deserialize)


def concat_blocks(blocks: Sequence[ImuBlock]) -> ImuBlock:
    """Concatenate decoded blocks in order."""
    if not blocks:
        return ImuBlock(np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, N_VALUES)))
    return ImuBlock(np.concatenate([b.sec for b in blocks]), np.concatenate([b.nsec for b in blocks]),
                    np.concatenate([b.values for b in blocks]), n_bulk=sum(b.n_bulk for b in blocks))
