"""Read IMU and GNSS from ROS 1 bags, ROS 2 bags (.db3 / .mcap directories) and MCAP files.

Containers are read by the field's libraries: ``rosbags`` (``AnyReader``) for
ROS 1 ``.bag`` files, ROS 2 bag directories and bare ``.db3`` files, and
``mcap`` (with ``mcap-ros1-support`` / ``mcap-ros2-support`` decoders) for
``.mcap`` files.  ``sensor_msgs/Imu`` topics are decoded in bulk by
:mod:`sinscli.io.ros_bulk` from the raw message bytes that the library's own
indexes point to (chunks decompressed and CRC-checked by the library); any
message that does not fit the bulk layout goes through the library's
deserializer, so the result is always the library's decode.

Every failure of a library on a user file becomes one :class:`SinsError`
line naming the file and the topic.
"""
from __future__ import annotations

import contextlib
import heapq
import io
import logging
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
import yaml

from ..errors import SinsError
from ..types import GnssLog, ImuLog
from . import ros_bulk
from .ros_bulk import ImuBlock, stamp_seconds

log = logging.getLogger("sins")

LOG_SUFFIXES = (".bag", ".db3", ".mcap")
IMU_TYPE = "sensor_msgs/msg/Imu"
NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
VEL_TYPES = ("geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/TwistWithCovarianceStamped",
             "nav_msgs/msg/Odometry")
TIME_SOURCES = ("header", "log")
_KNOWN_MCAP_COMPRESSION = ("", "zstd", "lz4")
_GROUP_CONCAT_MAX_BYTES = 800_000_000       # below SQLite's 1e9-byte string limit


def is_log(path) -> bool:
    """True for a ``.bag``, ``.db3`` or ``.mcap`` path, or a ROS 2 bag directory (with ``metadata.yaml``)."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in LOG_SUFFIXES


def normalize_type(name: str) -> str:
    """``pkg/Type`` (ROS 1) -> ``pkg/msg/Type`` (ROS 2 spelling used throughout)."""
    parts = name.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def _short(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if len(text) > 160:
        text = text[:157] + "..."
    return f"{type(exc).__name__}: {text}" if not isinstance(exc, SinsError) else text


@contextlib.contextmanager
def _guard(path, topic: str | None, what: str):
    """Turn any library exception into one SinsError line naming file and topic."""
    try:
        yield
    except SinsError:
        raise
    except Exception as exc:  # noqa: BLE001 - a library failing on a user file is bad input
        where = f"{path}" + (f": topic {topic}" if topic else "")
        raise SinsError(f"{where}: {what} ({_short(exc)})") from exc


@dataclass
class TopicInfo:
    name: str
    msgtype: str          # normalized, e.g. sensor_msgs/msg/Imu
    count: int
    encoding: str         # "ros1" or "cdr"
    extra: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- backends

class _Log:
    """A log opened by a library; subclasses give topics, raw messages and the library decode."""

    path: Path
    kind: str
    topics: dict[str, TopicInfo]

    def close(self) -> None:  # pragma: no cover - overridden
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        with contextlib.suppress(Exception):
            self.close()
        return False

    # library per-message path -------------------------------------------------
    def iter_raw(self, topic: str) -> Iterator[tuple[int, bytes]]:
        raise NotImplementedError

    def deserializer(self, topic: str) -> Callable[[bytes], object]:
        raise NotImplementedError

    def log_times(self, topic: str) -> np.ndarray:
        """Log (receive) times of a topic's messages in read order, int64 ns."""
        return np.fromiter((t for t, _ in self.iter_raw(topic)), dtype=np.int64)

    def decode_all(self, topic: str) -> tuple[np.ndarray, list]:
        """Every message of ``topic`` through the library: (log ns, objects)."""
        deser = self.deserializer(topic)
        times, msgs = [], []
        for t, raw in self.iter_raw(topic):
            times.append(t)
            msgs.append(deser(raw))
        self._check_count(topic, len(msgs))
        return np.asarray(times, dtype=np.int64), msgs

    def _check_count(self, topic: str, n: int) -> None:
        """The library's iterator must yield as many messages as the log's index/statistics count
        (an MCAP chunk without CRC whose record lengths are damaged is otherwise read short, silently)."""
        expected = self.topics[topic].count
        if expected and n != expected:
            raise SinsError(f"{self.path}: topic {topic}: log is damaged: its index counts {expected} messages "
                            f"but {n} could be read")

    def imu_block(self, topic: str, bulk: bool = True) -> tuple[np.ndarray, ImuBlock]:
        """All Imu messages of ``topic``: (log ns, decoded block).

        ``bulk=False`` is the library reference (one message at a time).
        """
        if bulk:
            fast = self._imu_block_fast(topic)
            if fast is not None:
                return fast
        times, raws = [], []
        for t, raw in self.iter_raw(topic):
            times.append(t)
            raws.append(raw)
        info = self.topics[topic]
        self._check_count(topic, len(raws))
        block = ros_bulk.decode_imu_messages(raws, info.encoding, self.deserializer(topic), bulk=bulk)
        return np.asarray(times, dtype=np.int64), block

    def _imu_block_fast(self, topic: str):
        return None


class _RosbagsLog(_Log):
    """ROS 1 bag, ROS 2 bag directory or bare ``.db3``/``.mcap`` storage file through ``rosbags.AnyReader``."""

    def __init__(self, path: Path):
        from rosbags.highlevel import AnyReader
        self.path = path
        with _guard(path, None, "cannot open log (truncated, corrupt or unsupported)"):
            self.reader = AnyReader([path])
            self.reader.open()
        self.is2 = self.reader.is2
        try:
            self.meta = self._metadata() if path.is_dir() else None
        except BaseException:
            with contextlib.suppress(Exception):
                self.reader.close()
            raise
        if not self.is2:
            self.kind = "ROS 1 bag"
        elif self.meta is not None:
            self.kind = f"ROS 2 bag ({self.meta.get('storage_identifier', '?')})"
        else:
            self.kind = f"ROS 2 storage file ({path.suffix})"
        self.topics = {}
        try:
            with _guard(path, None, "cannot read topic list"):
                for name, ti in self.reader.topics.items():
                    if ti.msgtype is None:
                        raise SinsError(f"{path}: topic {name} has several message types")
                    self.topics[name] = TopicInfo(name, normalize_type(ti.msgtype), int(ti.msgcount),
                                                  "cdr" if self.is2 else "ros1", {"connections": ti.connections})
        except BaseException:
            with contextlib.suppress(Exception):
                self.reader.close()
            raise

    def _metadata(self) -> dict:
        with _guard(self.path, None, "cannot read metadata.yaml"):
            meta = yaml.safe_load((self.path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        return meta

    def close(self):
        self.reader.close()

    def iter_raw(self, topic):
        conns = self.topics[topic].extra["connections"]
        with _guard(self.path, topic, "cannot read messages (truncated or corrupt log)"):
            for _conn, t, raw in self.reader.messages(conns):
                yield t, raw

    def deserializer(self, topic):
        msgtype = self.topics[topic].extra["connections"][0].msgtype
        reader, path = self.reader, self.path

        def deser(raw):
            with _guard(path, topic, "cannot decode message"):
                return reader.deserialize(raw, msgtype)
        return deser

    # bulk access --------------------------------------------------------------
    def _storage_files(self) -> tuple[str, list[Path]] | None:
        """(storage id, files) when the files can be read directly (no rosbag2 compression)."""
        if not self.is2:
            return None
        if self.meta is None:
            return ("sqlite3" if self.path.suffix == ".db3" else "mcap"), [self.path]
        if (self.meta.get("compression_mode") or "").lower() not in ("", "none"):
            return None
        files = [self.path / Path(x).name for x in self.meta.get("relative_file_paths", [])]
        return self.meta.get("storage_identifier"), files

    def log_times(self, topic):
        if not self.is2:
            conns = self.topics[topic].extra["connections"]
            with _guard(self.path, topic, "cannot read the bag index"):
                entries = list(heapq.merge(*[self.reader.readers[0].indexes[c.id] for c in conns]))
            return np.fromiter((e.time for e in entries), dtype=np.int64, count=len(entries))
        st = self._storage_files()
        if st is not None and st[0] == "sqlite3":
            with _guard(self.path, topic, "cannot read the sqlite3 storage"):
                return np.concatenate([_sqlite_times(f, topic) for f in st[1]] or [np.empty(0, np.int64)])
        if st is not None and st[0] == "mcap":
            parts = []
            for f in st[1]:
                with _McapLog(f) as m:
                    if topic in m.topics:
                        parts.append(m.log_times(topic))
            return np.concatenate(parts) if parts else np.empty(0, np.int64)
        return super().log_times(topic)

    def _imu_block_fast(self, topic):
        if not self.is2:
            return self._bag_bulk(topic)
        st = self._storage_files()
        if st is None:
            return None
        storage, files = st
        deser = self.deserializer(topic)
        parts = []
        for f in files:
            if storage == "sqlite3":
                with _guard(self.path, topic, "cannot read the sqlite3 storage"):
                    part = _sqlite_bulk(f, topic, deser)
            elif storage == "mcap":
                with _McapLog(f) as m:
                    part = m._imu_block_fast(topic) if topic in m.topics else \
                        (np.empty(0, np.int64), ros_bulk.concat_blocks([]))
            else:
                return None
            if part is None:
                return None
            parts.append(part)
        if not parts:
            return None
        return np.concatenate([p[0] for p in parts]), ros_bulk.concat_blocks([p[1] for p in parts])

    def _bag_bulk(self, topic):
        """Imu records of a ROS 1 bag sliced with numpy from the chunks the library indexed and decompresses."""
        from rosbags.rosbag1.reader import Header
        reader = self.reader.readers[0]
        conns = self.topics[topic].extra["connections"]
        if len(conns) != 1:
            return None
        cid = conns[0].id
        deser = self.deserializer(topic)
        with _guard(self.path, topic, "cannot read messages (truncated or corrupt bag)"):
            entries = reader.indexes[cid]
            n = len(entries)
            if n == 0:
                return None
            idx = np.array(entries, dtype=np.int64).reshape(n, 3)      # (time ns, chunk_pos, offset)
            times = idx[:, 0]
            # runs of consecutive entries in the same chunk (the library reads them in this order)
            cut = np.flatnonzero(np.diff(idx[:, 1])) + 1
            starts = np.concatenate([[0], cut])
            ends = np.concatenate([cut, [n]])
            sec_blocks = []
            template = None
            for a, b in zip(starts, ends):
                chunk = reader.chunks[int(idx[a, 1])]
                reader.bio.seek(chunk.datapos)
                raw = reader.bio.read(chunk.datasize)
                if len(raw) != chunk.datasize:
                    raise SinsError(f"{self.path}: topic {topic}: bag is truncated (chunk at byte "
                                    f"{chunk.datapos} is cut short)")
                buf = np.frombuffer(chunk.decompressor(raw), dtype=np.uint8)
                offs = idx[a:b, 2]
                hlen = ros_bulk.read_le(buf, offs, "<u4")
                h0 = int(hlen[0])
                if np.any(hlen != h0) or h0 > 4096:
                    return None
                if template is None:
                    hdr = Header.read(io.BytesIO(buf[offs[0]:offs[0] + 4 + h0].tobytes()))
                    if hdr.get_uint8("op") != 2 or hdr.get_uint32("conn") != cid:
                        return None
                    hbytes = buf[offs[0] + 4:offs[0] + 4 + h0].tobytes()
                    tpos = hbytes.find(b"time=")
                    if tpos < 0 or hbytes.count(b"time=") != 1:
                        return None
                    template = (h0, np.frombuffer(hbytes, np.uint8).copy(), tpos + 5)
                if h0 != template[0]:
                    return None
                headers = ros_bulk.gather(buf, offs + 4, h0)
                tpos = template[2]
                mask = np.ones(h0, dtype=bool)
                mask[tpos:tpos + 8] = False
                if not np.array_equal(headers[:, mask], np.broadcast_to(template[1][mask], (b - a, int(mask.sum())))):
                    return None
                hsec = np.ascontiguousarray(headers[:, tpos:tpos + 4]).view("<u4")[:, 0].astype(np.int64)
                hnsec = np.ascontiguousarray(headers[:, tpos + 4:tpos + 8]).view("<u4")[:, 0].astype(np.int64)
                if np.any(hsec * 1_000_000_000 + hnsec != times[a:b]):
                    return None
                dlen = ros_bulk.read_le(buf, offs + 4 + h0, "<u4")
                d0 = int(dlen[0])
                if np.any(dlen != d0):
                    return None
                dstart = offs + 8 + h0
                block = ros_bulk.gather(buf, dstart, d0)
                dec = ros_bulk.decode_imu_block(block, "ros1")
                if dec is None or not ros_bulk.check_block(
                        dec, [block[0].tobytes(), block[-1].tobytes()], deser):
                    return None
                sec_blocks.append(dec)
        return times.copy(), ros_bulk.concat_blocks(sec_blocks)


def _sqlite_connect(path: Path) -> sqlite3.Connection:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    con.text_factory = bytes
    return con


def _sqlite_topic_ids(con, topic: str) -> list[int]:
    return [int(r[0]) for r in con.execute("SELECT id FROM topics WHERE name = ?", (topic,)).fetchall()]


def _sqlite_times(path: Path, topic: str) -> np.ndarray:
    """Timestamps of a topic in the order ``rosbags`` reads them (timestamp, then row id)."""
    with contextlib.closing(_sqlite_connect(path)) as con:
        ids = _sqlite_topic_ids(con, topic)
        if not ids:
            return np.empty(0, np.int64)
        q = ",".join("?" * len(ids))
        rows = con.execute(f"SELECT timestamp FROM messages WHERE topic_id IN ({q}) ORDER BY timestamp", ids)
        return np.array([r[0] for r in rows.fetchall()], dtype=np.int64)


def _sqlite_bulk(path: Path, topic: str, deser) -> tuple[np.ndarray, ImuBlock] | None:
    """Imu rows of a rosbag2 sqlite3 file: SQLite concatenates the blobs in one scan, numpy slices them.

    Rows are read in row-id order and stably sorted by timestamp, which is the
    order of ``ORDER BY timestamp`` over the timestamp index that the library uses.
    """
    with contextlib.closing(_sqlite_connect(path)) as con:
        enc = con.execute("PRAGMA encoding").fetchone()[0]
        if enc not in ("UTF-8", b"UTF-8"):
            return None
        ids = _sqlite_topic_ids(con, topic)
        if len(ids) != 1:
            return None
        tid = ids[0]
        idmin, idmax = con.execute("SELECT min(id), max(id) FROM messages").fetchone()
        first = con.execute("SELECT length(data) FROM messages WHERE topic_id = ? LIMIT 1", (tid,)).fetchone()
        if idmin is None or first is None:
            return np.empty(0, np.int64), ros_bulk.concat_blocks([])
        length = None
        times, blobs = [], []
        step = max(1, _GROUP_CONCAT_MAX_BYTES // max(int(first[0]), 1))   # rows per query (one query usually)
        for lo in range(int(idmin), int(idmax) + 1, step):
            n, lmin, lmax, blob, ts = con.execute(
                "SELECT count(*), min(length(data)), max(length(data)), group_concat(data, x''), "
                "group_concat(timestamp) FROM (SELECT data, timestamp FROM messages "
                "WHERE topic_id = ? AND id BETWEEN ? AND ? ORDER BY id)", (tid, lo, lo + step - 1)).fetchone()
            if n == 0:
                continue
            if lmin != lmax or (length is not None and lmin != length) or lmin < 16 or n * lmin > 950_000_000:
                return None
            length = int(lmin)
            t = np.fromstring(ts, dtype=np.int64, sep=",")
            if not isinstance(blob, bytes) or len(blob) != n * length or t.shape[0] != n:
                return None
            blobs.append(blob)
            times.append(t)
    if not blobs:
        return np.empty(0, np.int64), ros_bulk.concat_blocks([])
    t = np.concatenate(times)
    block = np.frombuffer(b"".join(blobs) if len(blobs) > 1 else blobs[0], dtype=np.uint8).reshape(-1, length)
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(t.shape[0])):
        t, block = t[order], block[order]
    dec = ros_bulk.decode_imu_block(block, "cdr")
    if dec is None or not ros_bulk.check_block(dec, [block[0].tobytes(), block[-1].tobytes()], deser):
        return None
    return t, dec


class _McapLog(_Log):
    """An ``.mcap`` file through the ``mcap`` package (CRC-checked), decoded by mcap-ros1/ros2 support."""

    def __init__(self, path: Path):
        from mcap.reader import make_reader
        from mcap_ros1.decoder import DecoderFactory as Ros1Factory
        from mcap_ros2.decoder import DecoderFactory as Ros2Factory
        self.path = path
        self.kind = "MCAP"
        with _guard(path, None, "cannot open log (truncated, corrupt or not MCAP)"):
            self.f = open(path, "rb")
        try:
            with _guard(path, None, "cannot open log (truncated, corrupt or not MCAP)"):
                self.factories = [Ros2Factory(), Ros1Factory()]
                self.reader = make_reader(self.f, validate_crcs=True, decoder_factories=self.factories)
                self.summary = self.reader.get_summary()
            self._scan_topics()
        except BaseException:
            self.f.close()
            raise

    def _scan_topics(self):
        path = self.path
        if self.summary is None:
            raise SinsError(f"{path}: MCAP file has no summary section (truncated recording?); "
                            "recover it with `mcap recover` first")
        for ci in self.summary.chunk_indexes:
            if ci.compression not in _KNOWN_MCAP_COMPRESSION:
                raise SinsError(f"{path}: unknown chunk compression {ci.compression!r} "
                                f"(known: none, zstd, lz4)")
        counts = dict(self.summary.statistics.channel_message_counts) if self.summary.statistics else {}
        self.topics = {}
        self.channels: dict[str, list[int]] = {}
        for cid, ch in sorted(self.summary.channels.items()):
            schema = self.summary.schemas.get(ch.schema_id)
            name = normalize_type(schema.name) if schema is not None else "?"
            enc = {"cdr": "cdr", "ros1": "ros1"}.get(ch.message_encoding, ch.message_encoding)
            if ch.topic in self.topics:
                info = self.topics[ch.topic]
                if info.msgtype != name or info.encoding != enc:
                    raise SinsError(f"{path}: topic {ch.topic} has several message types")
                info.count += int(counts.get(cid, 0))
                self.channels[ch.topic].append(cid)
            else:
                self.topics[ch.topic] = TopicInfo(ch.topic, name, int(counts.get(cid, 0)), enc)
                self.channels[ch.topic] = [cid]

    def close(self):
        self.f.close()

    def iter_raw(self, topic):
        with _guard(self.path, topic, "cannot read messages (truncated or corrupt MCAP)"):
            for _schema, _channel, msg in self.reader.iter_messages(topics=[topic], log_time_order=True):
                yield msg.log_time, msg.data

    def deserializer(self, topic):
        cid = self.channels[topic][0]
        ch = self.summary.channels[cid]
        schema = self.summary.schemas.get(ch.schema_id)
        decoder = None
        with _guard(self.path, topic, "cannot build a decoder for the schema"), \
                contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
            # (the schema parsers print their complaints; the SinsError line says it instead)
            for factory in self.factories:
                decoder = factory.decoder_for(ch.message_encoding, schema)
                if decoder is not None:
                    break
        if decoder is None:
            raise SinsError(f"{self.path}: topic {topic}: no decoder for message encoding "
                            f"{ch.message_encoding!r} (schema {schema.encoding if schema else None!r})")
        path = self.path

        def deser(raw):
            with _guard(path, topic, "cannot decode message"):
                return decoder(raw)
        return deser

    def _index_entries(self, topic):
        """Per chunk: (chunk index, [(log_time, offset)]) from the library's message index records."""
        from mcap.data_stream import ReadDataStream
        from mcap.opcode import Opcode
        from mcap.records import MessageIndex
        cids = self.channels[topic]
        out = []
        for ci in self.summary.chunk_indexes:
            recs = []
            for cid in cids:
                off = ci.message_index_offsets.get(cid)
                if off is None:
                    continue
                self.f.seek(off)
                stream = ReadDataStream(self.f)
                if stream.read1() != Opcode.MESSAGE_INDEX:
                    raise SinsError(f"{self.path}: topic {topic}: message index at byte {off} is corrupt")
                stream.read8()
                mi = MessageIndex.read(stream)
                if mi.channel_id != cid:
                    raise SinsError(f"{self.path}: topic {topic}: message index at byte {off} is corrupt")
                recs.extend(mi.records)
            if recs:
                out.append((ci, recs))
        return out

    def log_times(self, topic):
        with _guard(self.path, topic, "cannot read the MCAP index"):
            if not self.summary.chunk_indexes or any(not ci.message_index_offsets
                                                     for ci in self.summary.chunk_indexes):
                return super().log_times(topic)
            parts = [np.array(recs, dtype=np.int64).reshape(-1, 2) for _ci, recs in self._index_entries(topic)]
            if not parts:
                return np.empty(0, np.int64)
            t = np.concatenate([p[:, 0] for p in parts])
            return np.sort(t, kind="stable")

    def _imu_block_fast(self, topic):
        """Imu message records sliced with numpy from chunks that the library reads, decompresses and CRC-checks.

        Order: (log_time, chunk offset, record offset), the order of the library's log-time iterator.
        """
        from mcap.data_stream import ReadDataStream
        from mcap.records import Chunk
        from mcap.stream_reader import get_chunk_data_stream
        info = self.topics[topic]
        cids = self.channels[topic]
        if len(cids) != 1 or not self.summary.chunk_indexes:
            return None
        if any(not ci.message_index_offsets for ci in self.summary.chunk_indexes):
            return None
        deser = self.deserializer(topic)
        with _guard(self.path, topic, "cannot read messages (truncated or corrupt MCAP)"):
            times, keys, blocks = [], [], []
            length = None
            for ci, recs in self._index_entries(topic):
                self.f.seek(ci.chunk_start_offset + 9)
                chunk = Chunk.read(ReadDataStream(self.f))
                stream, size = get_chunk_data_stream(chunk, validate_crc=True)
                buf = np.frombuffer(stream.read(size), dtype=np.uint8)
                if buf.shape[0] != size or size != ci.uncompressed_size:
                    raise SinsError(f"{self.path}: topic {topic}: chunk at byte {ci.chunk_start_offset} is corrupt")
                r = np.array(recs, dtype=np.int64).reshape(-1, 2)
                offs = r[:, 1]
                if offs.min() < 0 or offs.max() + 31 > size or np.any(buf[offs] != 0x05):
                    return None
                rlen = ros_bulk.read_le(buf, offs + 1, "<u8").astype(np.int64)
                if np.any(rlen != rlen[0]) or rlen[0] < 22 + 16 or (length is not None and rlen[0] - 22 != length):
                    return None
                length = int(rlen[0]) - 22
                if np.any(ros_bulk.read_le(buf, offs + 9, "<u2") != cids[0]):
                    return None
                lt = ros_bulk.read_le(buf, offs + 15, "<u8").astype(np.int64)
                if np.any(lt != r[:, 0]):
                    return None
                blocks.append(ros_bulk.gather(buf, offs + 31, length))
                times.append(lt)
                keys.append(np.stack([np.full(len(offs), ci.chunk_start_offset, np.int64), offs], axis=1))
        if not blocks:
            return None
        t = np.concatenate(times)
        if info.count and t.shape[0] != info.count:
            return None                   # the index disagrees with the statistics: the library decides
        k = np.concatenate(keys)
        block = np.concatenate(blocks)
        order = np.lexsort((k[:, 1], k[:, 0], t))
        t, block = t[order], block[order]
        dec = ros_bulk.decode_imu_block(block, info.encoding)
        if dec is None or not ros_bulk.check_block(dec, [block[0].tobytes(), block[-1].tobytes()], deser):
            return None
        return t, dec


def open_log(path) -> _Log:
    """Open a log with the right library; SinsError when it does not exist or cannot be read."""
    p = Path(path)
    if not p.exists():
        raise SinsError(f"{p}: no such file or directory")
    if p.is_dir():
        if not (p / "metadata.yaml").is_file():
            raise SinsError(f"{p}: not a ROS 2 bag directory (no metadata.yaml)")
        return _RosbagsLog(p)
    suffix = p.suffix.lower()
    if suffix == ".mcap":
        return _McapLog(p)
    if suffix in (".bag", ".db3"):
        return _RosbagsLog(p)
    raise SinsError(f"{p}: not a ROS log (expected .bag, .db3, .mcap or a ROS 2 bag directory)")


def log_topics(path) -> dict[str, str]:
    """``{topic: message type}`` of a log (types in ROS 2 spelling, e.g. ``sensor_msgs/msg/Imu``)."""
    with open_log(path) as lg:
        return {n: i.msgtype for n, i in lg.topics.items()}


# --------------------------------------------------------------------------- topic choice

def _topic_list(lg: _Log) -> str:
    return ", ".join(f"{n} ({i.msgtype})" for n, i in sorted(lg.topics.items())) or "none"


def choose_topic(lg: _Log, topic: str | None, types, role: str, option: str) -> str:
    """The named topic (checked for type) or the single topic of one of ``types``."""
    types = (types,) if isinstance(types, str) else tuple(types)
    if topic is not None:
        if topic not in lg.topics:
            raise SinsError(f"{lg.path}: topic {topic} not found; topics: {_topic_list(lg)}")
        if lg.topics[topic].msgtype not in types:
            raise SinsError(f"{lg.path}: topic {topic} is {lg.topics[topic].msgtype}, expected "
                            f"{' or '.join(types)} for {role}")
        return topic
    cands = sorted(n for n, i in lg.topics.items() if i.msgtype in types)
    if len(cands) == 1:
        return cands[0]
    if not cands:
        raise SinsError(f"{lg.path}: no {' or '.join(types)} topic for {role}; topics: {_topic_list(lg)}")
    raise SinsError(f"{lg.path}: several {' or '.join(types)} topics ({', '.join(cands)}); choose one with {option}")


def _check_time_source(time_source: str):
    if time_source not in TIME_SOURCES:
        raise SinsError(f"time source {time_source!r} unknown (expected header or log)")


def _check_increasing(t: np.ndarray, where: str, what: str = "time"):
    """SinsError at the first sample whose time does not increase."""
    if t.shape[0] > 1:
        bad = np.flatnonzero(~(np.diff(t) > 0))
        if bad.size:
            k = int(bad[0]) + 1
            word = "repeats" if t[k] == t[k - 1] else "goes backwards"
            raise SinsError(f"{where}: {what} {word} at message {k} ({t[k]:.9f} s after {t[k - 1]:.9f} s); "
                            "times must be strictly increasing")


# --------------------------------------------------------------------------- IMU

def read_imu_block(path, topic=None, bulk=True):
    """``(topic, log ns, ImuBlock)`` of an Imu topic (raw decode, no checks): used by tests and ``info``."""
    with open_log(path) as lg:
        topic = choose_topic(lg, topic, IMU_TYPE, "IMU", "--imu-topic")
        with _guard(lg.path, topic, "cannot decode sensor_msgs/Imu messages"):
            t, block = lg.imu_block(topic, bulk=bulk)
    return topic, t, block


def read_imu(path, topic=None, time_source="header", start=None, end=None, bulk=True,
             allow_gaps=True) -> ImuLog:
    """Read a ``sensor_msgs/Imu`` topic as increments (rates integrated by ``rates_to_increments``).

    Axes stay as in the message; the caller applies mounting and body convention.
    ``start``/``end`` (s, same time source) keep samples with ``start <= t <= end``.
    Gaps over 5 nominal intervals follow the CSV rule (:class:`sinscli.io.imu_csv.TimeChecker`):
    refused unless ``allow_gaps``, which bridges them with a warning naming each.
    ``source`` is ``"file:topic"``.
    """
    from .imu_csv import TimeChecker, rates_to_increments
    _check_time_source(time_source)
    path = Path(path)
    topic, log_ns, block = read_imu_block(path, topic, bulk=bulk)
    where = f"{path}: topic {topic}"
    if len(block) == 0:
        raise SinsError(f"{where}: topic has no messages")
    if time_source == "header":
        if np.any((block.nsec < 0) | (block.nsec >= 1_000_000_000)):
            k = int(np.flatnonzero((block.nsec < 0) | (block.nsec >= 1_000_000_000))[0])
            raise SinsError(f"{where}: header stamp of message {k} has nanoseconds {block.nsec[k]} (>= 1e9)")
        t = stamp_seconds(block.sec, block.nsec)
    else:
        t = stamp_seconds(log_ns // 1_000_000_000, log_ns % 1_000_000_000)
    gyro = block.values[:, ros_bulk.GYRO]
    accel = block.values[:, ros_bulk.ACCEL]
    keep = np.ones(t.shape[0], dtype=bool)
    if start is not None:
        keep &= t >= float(start)
    if end is not None:
        keep &= t <= float(end)
    if not keep.all():
        t, gyro, accel = t[keep], gyro[keep], accel[keep]
    if t.shape[0] == 0:
        raise SinsError(f"{where}: no messages between {start} and {end} s ({time_source} time; "
                        f"the topic spans {stamp_seconds(block.sec[:1], block.nsec[:1])[0]:.3f} .. "
                        f"{stamp_seconds(block.sec[-1:], block.nsec[-1:])[0]:.3f} s in header time)")
    if t.shape[0] < 2:
        raise SinsError(f"{where}: only one message in the requested interval; need at least two")
    _check_increasing(t, where, f"{time_source} stamp")
    TimeChecker(where, allow_gaps, what=f"{time_source} stamp", row_label="message").check(t, 0)
    finite = np.isfinite(gyro).all(axis=1) & np.isfinite(accel).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise SinsError(f"{where}: message {k} has a non-finite angular_velocity or linear_acceleration")
    time_end, dtheta, dvel, t0 = rates_to_increments(t, np.ascontiguousarray(gyro), np.ascontiguousarray(accel))
    return ImuLog(time=time_end, dtheta_b=dtheta, dvel_b=dvel, t0=t0, source=f"{path}:{topic}", kind="rates")


# --------------------------------------------------------------------------- GNSS

def _stamp(msg) -> tuple[int, int]:
    s = msg.header.stamp
    if hasattr(s, "nanosec"):
        return int(s.sec), int(s.nanosec)
    return int(s.secs), int(s.nsecs)


def _times(lg: _Log, topic: str, log_ns, msgs, time_source: str) -> np.ndarray:
    where = f"{lg.path}: topic {topic}"
    if time_source == "header":
        st = np.array([_stamp(m) for m in msgs], dtype=np.int64).reshape(-1, 2)
        if np.any((st[:, 1] < 0) | (st[:, 1] >= 1_000_000_000)):
            raise SinsError(f"{where}: a header stamp has nanoseconds >= 1e9")
        return stamp_seconds(st[:, 0], st[:, 1])
    return stamp_seconds(log_ns // 1_000_000_000, log_ns % 1_000_000_000)


def _quat_xyzw_to_dcm(q: np.ndarray) -> np.ndarray:
    from ..nav.rotation import quat_to_dcm_many
    wxyz = np.ascontiguousarray(q[:, [3, 0, 1, 2]], dtype=np.float64)
    n = np.linalg.norm(wxyz, axis=1)
    if np.any(~np.isfinite(n) | (n < 1e-6)):
        raise ValueError("invalid orientation quaternion")
    return quat_to_dcm_many(wxyz / n[:, None])


def _velocity(lg: _Log, topic: str, time_source: str):
    """(time s, vel (N,3), std (N,3) or None) from a TwistStamped / TwistWithCovarianceStamped / Odometry topic.

    Odometry twist is in the child (body) frame: it is turned into the parent frame with the pose
    orientation, and the parent frame is taken as ENU.
    """
    info = lg.topics[topic]
    where = f"{lg.path}: topic {topic}"
    log_ns, msgs = lg.decode_all(topic)
    if not msgs:
        raise SinsError(f"{where}: topic has no messages")
    t = _times(lg, topic, log_ns, msgs, time_source)
    std = None
    if info.msgtype == "geometry_msgs/msg/TwistStamped":
        v = np.array([(m.twist.linear.x, m.twist.linear.y, m.twist.linear.z) for m in msgs], dtype=np.float64)
    else:
        v = np.array([(m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z) for m in msgs],
                     dtype=np.float64)
        cov = np.array([np.asarray(m.twist.covariance, dtype=np.float64).reshape(6, 6)[:3, :3] for m in msgs])
        if info.msgtype == "nav_msgs/msg/Odometry":
            q = np.array([(m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z,
                           m.pose.pose.orientation.w) for m in msgs], dtype=np.float64)
            try:
                c = _quat_xyzw_to_dcm(q)
            except ValueError:
                raise SinsError(f"{where}: an Odometry pose orientation is not a valid quaternion") from None
            v = np.einsum("nij,nj->ni", c, v)
            cov = np.einsum("nij,njk,nlk->nil", c, cov, c)
        var = np.einsum("nii->ni", cov)
        if np.all(var == 0):
            std = None
        else:
            bad = ~np.isfinite(var).all(axis=1) | (var <= 0).any(axis=1)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise SinsError(f"{where}: message {k} has a zero, negative or NaN velocity variance "
                                f"({var[k].tolist()})")
            std = np.sqrt(var)
    if not np.isfinite(v).all():
        k = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise SinsError(f"{where}: message {k} has a non-finite velocity")
    _check_increasing(t, where, f"{time_source} stamp")
    return t, v, std


def _interp_rows(t_out, t_in, y):
    """Linear interpolation of the rows of ``y`` at ``t_out``; NaN outside ``[t_in[0], t_in[-1]]``."""
    out = np.empty((t_out.shape[0], y.shape[1]))
    for j in range(y.shape[1]):
        out[:, j] = np.interp(t_out, t_in, y[:, j], left=np.nan, right=np.nan)
    return out


def read_gnss(path, topic=None, vel_topic=None, time_source="header") -> GnssLog:
    """Read a ``sensor_msgs/NavSatFix`` topic (and optionally a velocity topic) as a :class:`GnssLog`.

    Fixes with status "no fix" (-1) are dropped (count logged).  The ENU position
    covariance diagonal gives ``std_pos`` (absent when every fix says
    COVARIANCE_TYPE_UNKNOWN).  Velocity (``vel_topic``: TwistStamped,
    TwistWithCovarianceStamped or Odometry, ENU) is interpolated linearly at the
    fix times; fixes outside the velocity topic's time span are dropped (count logged).
    """
    _check_time_source(time_source)
    path = Path(path)
    with open_log(path) as lg:
        topic = choose_topic(lg, topic, NAVSAT_TYPE, "GNSS", "--gnss-topic")
        where = f"{path}: topic {topic}"
        with _guard(path, topic, "cannot decode sensor_msgs/NavSatFix messages"):
            return _read_navsat(lg, topic, where, vel_topic, time_source)


def _read_navsat(lg: _Log, topic: str, where: str, vel_topic, time_source) -> GnssLog:
    """The body of :func:`read_gnss` on an open log."""
    path = lg.path
    log_ns, msgs = lg.decode_all(topic)
    if not msgs:
        raise SinsError(f"{where}: topic has no messages")
    status = np.array([int(m.status.status) for m in msgs])
    fix = status >= 0
    n_drop = int((~fix).sum())
    if n_drop:
        log.warning("%s: dropped %d of %d NavSatFix messages with status 'no fix'", where, n_drop, len(msgs))
    if not fix.any():
        raise SinsError(f"{where}: no NavSatFix message has a fix (all {len(msgs)} have status 'no fix')")
    t_all = _times(lg, topic, log_ns, msgs, time_source)
    keep = np.flatnonzero(fix)
    msgs = [msgs[i] for i in keep]
    t = t_all[keep]
    lla = np.array([(m.latitude, m.longitude, m.altitude) for m in msgs], dtype=np.float64)
    bad = ~np.isfinite(lla).all(axis=1)
    if bad.any():
        k = int(keep[np.flatnonzero(bad)[0]])
        raise SinsError(f"{where}: message {k} has a fix with NaN or infinite latitude/longitude/altitude")
    if np.any(np.abs(lla[:, 0]) > 90) or np.any(np.abs(lla[:, 1]) > 180):
        k = int(keep[np.flatnonzero((np.abs(lla[:, 0]) > 90) | (np.abs(lla[:, 1]) > 180))[0]])
        raise SinsError(f"{where}: message {k} has latitude/longitude out of range")
    _check_increasing(t, where, f"{time_source} stamp")
    ctype = np.array([int(m.position_covariance_type) for m in msgs])
    cov = np.array([np.asarray(m.position_covariance, dtype=np.float64) for m in msgs]).reshape(-1, 9)
    std = None
    known = ctype != 0
    if known.any():
        var = cov[:, [0, 4, 8]]
        bad = known & (~np.isfinite(var).all(axis=1) | (var <= 0).any(axis=1))
        if bad.any():
            k = int(keep[np.flatnonzero(bad)[0]])
            raise SinsError(f"{where}: message {k} has a zero, negative or NaN position covariance "
                            f"({var[np.flatnonzero(bad)[0]].tolist()}) with covariance type "
                            f"{ctype[np.flatnonzero(bad)[0]]}")
        if known.all():
            std = np.sqrt(var)
        else:
            log.warning("%s: %d fixes have unknown covariance; std columns left out",
                        where, int((~known).sum()))
    vel = std_vel = None
    if vel_topic is not None:
        vtopic = choose_topic(lg, vel_topic, VEL_TYPES, "GNSS velocity", "--vel-topic")
        tv, v, sv = _velocity(lg, vtopic, time_source)
        vel = _interp_rows(t, tv, v)
        std_vel = _interp_rows(t, tv, sv) if sv is not None else None
        covered = ~np.isnan(vel[:, 0])
        if not covered.any():
            raise SinsError(f"{path}: topic {vtopic}: velocity times do not overlap the fixes of {topic}")
        if not covered.all():
            log.warning("%s: dropped %d fixes outside the time span of the velocity topic %s",
                        where, int((~covered).sum()), vtopic)
            t, lla, vel = t[covered], lla[covered], vel[covered]
            std = std[covered] if std is not None else None
            std_vel = std_vel[covered] if std_vel is not None else None
    return GnssLog(time=t, lat=lla[:, 0].copy(), lon=lla[:, 1].copy(), height=lla[:, 2].copy(),
                   vel_n=vel, std_pos=std, std_vel=std_vel, source=f"{path}:{topic}")


# --------------------------------------------------------------------------- summary

def _topic_stats(t_ns: np.ndarray) -> dict:
    out = {"start": None, "end": None, "rate_hz": None, "median_dt": None, "max_gap": None, "gaps": 0}
    if t_ns.size == 0:
        return out
    t = stamp_seconds(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
    out["start"], out["end"] = float(t[0]), float(t[-1])
    if t.size > 1:
        dt = np.diff(t)
        med = float(np.median(dt))
        out["median_dt"] = med
        out["rate_hz"] = (t.size - 1) / (t[-1] - t[0]) if t[-1] > t[0] else None
        out["max_gap"] = float(dt.max())
        out["gaps"] = int((dt > 5.0 * med).sum()) if med > 0 else 0
    return out


def log_summary(path, imu_window: float = 1.0) -> dict:
    """Topics, types, counts, rates, time span, gaps; for Imu topics the mean specific force and
    angular rate over the first ``imu_window`` seconds (at least 10 messages), message axes."""
    path = Path(path)
    with open_log(path) as lg:
        topics = []
        imu = {}
        for name, info in sorted(lg.topics.items()):
            t_ns = lg.log_times(name)
            row = {"topic": name, "type": info.msgtype, "count": int(t_ns.size)}
            row.update(_topic_stats(t_ns))
            topics.append(row)
            if info.msgtype == IMU_TYPE and t_ns.size:
                deser = lg.deserializer(name)
                t_end = t_ns[0] + int(imu_window * 1e9)
                vals, stamps = [], []
                for k, (ts, raw) in enumerate(lg.iter_raw(name)):
                    if ts > t_end and k >= 10:
                        break
                    s, ns, v = ros_bulk.imu_from_message(deser(raw))
                    vals.append(v)
                    stamps.append((s, ns))
                vals = np.array(vals)
                acc = vals[:, ros_bulk.ACCEL].mean(axis=0)
                gyr = vals[:, ros_bulk.GYRO].mean(axis=0)
                imu[name] = {"messages": len(vals), "mean_accel": acc.tolist(), "mean_gyro": gyr.tolist(),
                             "accel_norm": float(np.linalg.norm(acc)), "gyro_norm": float(np.linalg.norm(gyr))}
        starts = [r["start"] for r in topics if r["start"] is not None]
        ends = [r["end"] for r in topics if r["end"] is not None]
    return {"path": str(path), "format": lg.kind,
            "start": min(starts) if starts else None, "end": max(ends) if ends else None,
            "duration": (max(ends) - min(starts)) if starts else None,
            "messages": int(sum(r["count"] for r in topics)), "topics": topics, "imu": imu}


# --------------------------------------------------------------------------- writing logs

def _typestore(ros1: bool):
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)


def _ns(t) -> np.ndarray:
    """Seconds (float64) -> integer nanoseconds, rounded."""
    return np.round(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def _header(ts, ros1: bool, t_ns: int, frame_id: str, seq: int):
    time_cls = ts.types["builtin_interfaces/msg/Time"]
    stamp = time_cls(sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000))
    hdr = ts.types["std_msgs/msg/Header"]
    if ros1:
        return hdr(seq=seq, stamp=stamp, frame_id=frame_id)
    return hdr(stamp=stamp, frame_id=frame_id)


def _imu_messages(ts, ros1, imu, frame_id):
    """sensor_msgs/Imu objects from ``time`` (s), ``gyro`` (rad/s), ``accel`` (m/s^2), optional ``orientation`` xyzw."""
    t_ns = _ns(imu["time"])
    gyro = np.asarray(imu["gyro"], dtype=np.float64)
    accel = np.asarray(imu["accel"], dtype=np.float64)
    ori = np.asarray(imu.get("orientation", np.tile([0.0, 0.0, 0.0, 1.0], (len(t_ns), 1))), dtype=np.float64)
    cov = np.asarray(imu.get("covariance", np.zeros(9)), dtype=np.float64)
    cls = ts.types["sensor_msgs/msg/Imu"]
    q_cls, v_cls = ts.types["geometry_msgs/msg/Quaternion"], ts.types["geometry_msgs/msg/Vector3"]
    for k in range(len(t_ns)):
        g, a, o = gyro[k], accel[k], ori[k]
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  orientation=q_cls(x=float(o[0]), y=float(o[1]), z=float(o[2]), w=float(o[3])),
                  orientation_covariance=cov,
                  angular_velocity=v_cls(x=float(g[0]), y=float(g[1]), z=float(g[2])),
                  angular_velocity_covariance=cov,
                  linear_acceleration=v_cls(x=float(a[0]), y=float(a[1]), z=float(a[2])),
                  linear_acceleration_covariance=cov)


def _navsat_messages(ts, ros1, gnss, frame_id="gps"):
    """NavSatFix objects from ``time, lat, lon, height``, optional ``status``, ``cov`` (N,9), ``cov_type``."""
    t_ns = _ns(gnss["time"])
    n = len(t_ns)
    status = np.asarray(gnss.get("status", np.zeros(n)), dtype=np.int64)
    cov = np.asarray(gnss.get("cov", np.zeros((n, 9))), dtype=np.float64).reshape(n, 9)
    ctype = np.asarray(gnss.get("cov_type", np.where(cov.any(axis=1), 2, 0)), dtype=np.int64)
    cls, st_cls = ts.types["sensor_msgs/msg/NavSatFix"], ts.types["sensor_msgs/msg/NavSatStatus"]
    for k in range(n):
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  status=st_cls(status=int(status[k]), service=1),
                  latitude=float(gnss["lat"][k]), longitude=float(gnss["lon"][k]), altitude=float(gnss["height"][k]),
                  position_covariance=cov[k].copy(), position_covariance_type=int(ctype[k]))


def _twist_messages(ts, ros1, vel, frame_id="gps"):
    """geometry_msgs/TwistWithCovarianceStamped objects from ``time``, ``vel`` (N,3 ENU) and optional ``std`` (N,3)."""
    t_ns = _ns(vel["time"])
    v = np.asarray(vel["vel"], dtype=np.float64)
    std = vel.get("std")
    cls = ts.types["geometry_msgs/msg/TwistWithCovarianceStamped"]
    twc, tw = ts.types["geometry_msgs/msg/TwistWithCovariance"], ts.types["geometry_msgs/msg/Twist"]
    v_cls = ts.types["geometry_msgs/msg/Vector3"]
    for k in range(len(t_ns)):
        cov = np.zeros(36)
        if std is not None:
            cov[[0, 7, 14]] = np.asarray(std[k], dtype=np.float64) ** 2
        yield cls(header=_header(ts, ros1, int(t_ns[k]), frame_id, k),
                  twist=twc(twist=tw(linear=v_cls(x=float(v[k, 0]), y=float(v[k, 1]), z=float(v[k, 2])),
                                     angular=v_cls(x=0.0, y=0.0, z=0.0)), covariance=cov))


def write_log(path, imu=None, gnss=None, vel=None, *, imu_topic="/imu/data", gnss_topic="/fix",
              vel_topic="/fix_velocity", frame_id="imu_link", mcap_encoding="cdr", storage="sqlite3",
              log_delay=0.0, bag_compression=None) -> None:
    """Write IMU (and GNSS) arrays as a ROS log, serialized by the libraries.

    ``path`` suffix: ``.bag`` (ROS 1, rosbags), ``.mcap`` (``mcap`` writer,
    ``mcap_encoding`` "cdr" or "ros1"), ``.db3`` (a bare rosbag2 sqlite3 file)
    or no suffix (a ROS 2 bag directory with ``storage`` "sqlite3" or "mcap").
    Log times are each dict's ``log_time`` (default: its ``time``, the header
    stamps) plus ``log_delay`` seconds.  Used by tests and
    benchmarks, and by anyone who wants simulated data as a bag.
    """
    import shutil
    import tempfile
    path = Path(path)
    suffix = path.suffix.lower()
    ros1 = suffix == ".bag" or (suffix == ".mcap" and mcap_encoding == "ros1")
    ts = _typestore(ros1)
    streams = []
    if imu is not None:
        streams.append((imu_topic, "sensor_msgs/msg/Imu",
                        _ns(np.asarray(imu.get("log_time", imu["time"])) + log_delay),
                        _imu_messages(ts, ros1, imu, frame_id)))
    if gnss is not None:
        streams.append((gnss_topic, "sensor_msgs/msg/NavSatFix",
                        _ns(np.asarray(gnss.get("log_time", gnss["time"])) + log_delay),
                        _navsat_messages(ts, ros1, gnss)))
    if vel is not None:
        streams.append((vel_topic, "geometry_msgs/msg/TwistWithCovarianceStamped",
                        _ns(np.asarray(vel.get("log_time", vel["time"])) + log_delay), _twist_messages(ts, ros1, vel)))
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr

    def one(i, typ, times, msgs):
        for t, m in zip(times, msgs):
            yield int(t), i, serialize(m, typ)

    def merged():
        """(log ns, stream index, serialized bytes) in log-time order."""
        iters = [one(i, typ, times, msgs) for i, (_top, typ, times, msgs) in enumerate(streams)]
        return heapq.merge(*iters, key=lambda x: (x[0], x[1]))

    if suffix == ".bag":
        from rosbags.rosbag1 import Writer as Writer1
        path.unlink(missing_ok=True)
        w = Writer1(path)
        if bag_compression:
            w.set_compression(getattr(Writer1.CompressionFormat, bag_compression.upper()))
        with w:
            conns = [w.add_connection(top, typ, typestore=ts) for top, typ, _t, _m in streams]
            for t, i, raw in merged():
                w.write(conns[i], t, raw)
    elif suffix == ".mcap":
        from mcap.writer import Writer as McapWriter
        with open(path, "wb") as f:
            w = McapWriter(f)
            w.start(profile="ros1" if ros1 else "ros2", library="sinscli")
            chans = []
            for top, typ, _t, _m in streams:
                text, _ = ts.generate_msgdef(typ, ros_version=1 if ros1 else 2)
                name = typ.replace("/msg/", "/") if ros1 else typ
                sid = w.register_schema(name=name, encoding="ros1msg" if ros1 else "ros2msg", data=text.encode())
                chans.append(w.register_channel(topic=top, message_encoding="ros1" if ros1 else "cdr",
                                                schema_id=sid))
            seqs = [0] * len(streams)
            for t, i, raw in merged():
                w.add_message(channel_id=chans[i], log_time=t, data=bytes(raw), publish_time=t, sequence=seqs[i])
                seqs[i] += 1
            w.finish()
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2
        bare = suffix == ".db3"
        target = Path(tempfile.mkdtemp(dir=path.parent)) / "bag" if bare else path
        if not bare and target.exists():
            shutil.rmtree(target)
        plugin = StoragePlugin.SQLITE3 if (bare or storage == "sqlite3") else StoragePlugin.MCAP
        with Writer2(target, version=9, storage_plugin=plugin) as w:
            conns = [w.add_connection(top, typ, typestore=ts) for top, typ, _t, _m in streams]
            for t, i, raw in merged():
                w.write(conns[i], t, raw)
        if bare:
            path.unlink(missing_ok=True)
            shutil.move(str(target / "bag.db3"), str(path))
            shutil.rmtree(target.parent)
