"""ROS log containers: ROS 1 bags, ROS 2 bags (.db3 / .mcap directories) and MCAP files.

Containers are read by the field's libraries: ``rosbags`` (``AnyReader``) for
ROS 1 ``.bag`` files, ROS 2 bag directories and bare ``.db3`` files, and
``mcap`` (with ``mcap-ros1-support`` / ``mcap-ros2-support`` decoders) for
``.mcap`` files; rosbag2 ``.db3`` storage is also read directly through
SQLite for the bulk path.  ``sensor_msgs/Imu`` topics are decoded in bulk by
:mod:`sinscli.io.ros.decode` from the raw message bytes that the library's own
indexes point to (chunks decompressed and CRC-checked by the library); any
message that does not fit the bulk layout goes through the library's
deserializer, so the result is always the library's decode.

Every failure of a library on a user file becomes one :class:`SinsError`
line naming the file and the topic (:func:`guard`).
"""
from __future__ import annotations

import contextlib
import heapq
import io
import os
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from ...errors import SinsError, quote
from ...inputs import input_file, load_yaml
from . import decode
from .decode import ImuBlock

LOG_SUFFIXES = (".bag", ".db3", ".mcap")
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
def guard(path, topic: str | None, what: str):
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
        block = decode.decode_imu_messages(raws, info.encoding, self.deserializer(topic), bulk=bulk)
        return np.asarray(times, dtype=np.int64), block

    def _imu_block_fast(self, topic: str):
        return None


class _RosbagsLog(_Log):
    """ROS 1 bag, ROS 2 bag directory or bare ``.db3``/``.mcap`` storage file through ``rosbags.AnyReader``."""

    def __init__(self, path: Path):
        from rosbags.highlevel import AnyReader
        self.path = path
        what = "cannot open log (truncated, corrupt or unsupported)"
        if path.suffix.lower() == ".bag":
            what += "; a ROS 1 bag with a damaged index can be rebuilt with `rosbag reindex` (or rosbags-convert)"
        self._alias_dir = None
        with guard(path, None, what):
            self.reader = AnyReader([self._plain_name(path)])
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
            with guard(path, None, "cannot read topic list"):
                for name, ti in self.reader.topics.items():
                    if ti.msgtype is None:
                        raise SinsError(f"{path}: topic {name} has several message types")
                    self.topics[name] = TopicInfo(name, normalize_type(ti.msgtype), int(ti.msgcount),
                                                  "cdr" if self.is2 else "ros1", {"connections": ti.connections})
            if self.is2:
                self._check_storage()
        except BaseException:
            with contextlib.suppress(Exception):
                self.reader.close()
            raise

    def _check_storage(self) -> None:
        """A ROS 2 sqlite3 storage file agrees with the topics read (from metadata.yaml, for a bag folder) and
        holds CDR: otherwise a topic's messages would be read as nothing, or decoded as the wrong bytes."""
        st = self._storage_files()
        if st is None or st[0] != "sqlite3":
            return
        where = f"{self.path / 'metadata.yaml'}" if self.meta is not None else "the log's type definitions"
        for f in st[1]:
            if not f.is_file():
                continue
            with guard(f, None, "cannot read the sqlite3 storage"):
                with contextlib.closing(_sqlite_connect(f)) as con:
                    rows = con.execute("SELECT name, type, serialization_format FROM topics").fetchall()
            for name, typ, ser in rows:
                name, typ, ser = (x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x)
                                  for x in (name, typ, ser))
                if ser != "cdr":
                    raise SinsError(f"{f}: topic {name}: serialization format {quote(ser, 30)}; a ROS 2 bag holds "
                                    "CDR ('cdr'), the only serialization sins reads")
                info = self.topics.get(name)
                if info is not None and normalize_type(typ) != info.msgtype:
                    raise SinsError(f"{f}: topic {name} has the type {quote(typ, 50)} in the storage file but "
                                    f"{info.msgtype} in {where}; the bag's files disagree")

    def _metadata(self) -> dict:
        with guard(self.path, None, "cannot read metadata.yaml"):
            meta = load_yaml(self.path / "metadata.yaml", "bag metadata")["rosbag2_bagfile_information"]
        return meta

    def _plain_name(self, path: Path) -> Path:
        """``path``, or for a name that is not UTF-8 (which rosbags cannot open: SQLite and its metadata take
        text) a symbolic link to it with a plain name in a private temporary folder."""
        try:
            str(path).encode("utf-8")
            return path
        except UnicodeEncodeError:
            import tempfile
            self._alias_dir = tempfile.mkdtemp(prefix="sins-log-")
            alias = Path(self._alias_dir) / ("log" + (path.suffix if path.suffix.isascii() else ""))
            os.symlink(os.path.abspath(path), alias)
            return alias

    def close(self):
        try:
            self.reader.close()
        finally:
            if self._alias_dir is not None:
                import shutil
                shutil.rmtree(self._alias_dir, ignore_errors=True)

    def iter_raw(self, topic):
        conns = self.topics[topic].extra["connections"]
        with guard(self.path, topic, "cannot read messages (truncated or corrupt log)"):
            for _conn, t, raw in self.reader.messages(conns):
                yield t, raw

    def deserializer(self, topic):
        msgtype = self.topics[topic].extra["connections"][0].msgtype
        reader, path = self.reader, self.path

        def deser(raw):
            with guard(path, topic, "cannot decode message"):
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
            with guard(self.path, topic, "cannot read the bag index"):
                entries = list(heapq.merge(*[self.reader.readers[0].indexes[c.id] for c in conns]))
            return np.fromiter((e.time for e in entries), dtype=np.int64, count=len(entries))
        st = self._storage_files()
        if st is not None and st[0] == "sqlite3":
            with guard(self.path, topic, "cannot read the sqlite3 storage"):
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
                with guard(self.path, topic, "cannot read the sqlite3 storage"):
                    part = _sqlite_bulk(f, topic, deser)
            elif storage == "mcap":
                with _McapLog(f) as m:
                    part = m._imu_block_fast(topic) if topic in m.topics else \
                        (np.empty(0, np.int64), decode.concat_blocks([]))
            else:
                return None
            if part is None:
                return None
            parts.append(part)
        if not parts:
            return None
        return np.concatenate([p[0] for p in parts]), decode.concat_blocks([p[1] for p in parts])

    def _bag_bulk(self, topic):
        """Imu records of a ROS 1 bag sliced with numpy from the chunks the library indexed and decompresses."""
        from rosbags.rosbag1.reader import Header
        reader = self.reader.readers[0]
        conns = self.topics[topic].extra["connections"]
        if len(conns) != 1:
            return None
        cid = conns[0].id
        deser = self.deserializer(topic)
        with guard(self.path, topic, "cannot read messages (truncated or corrupt bag)"):
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
                hlen = decode.read_le(buf, offs, "<u4")
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
                headers = decode.gather(buf, offs + 4, h0)
                tpos = template[2]
                mask = np.ones(h0, dtype=bool)
                mask[tpos:tpos + 8] = False
                if not np.array_equal(headers[:, mask], np.broadcast_to(template[1][mask], (b - a, int(mask.sum())))):
                    return None
                hsec = np.ascontiguousarray(headers[:, tpos:tpos + 4]).view("<u4")[:, 0].astype(np.int64)
                hnsec = np.ascontiguousarray(headers[:, tpos + 4:tpos + 8]).view("<u4")[:, 0].astype(np.int64)
                if np.any(hsec * 1_000_000_000 + hnsec != times[a:b]):
                    return None
                dlen = decode.read_le(buf, offs + 4 + h0, "<u4")
                d0 = int(dlen[0])
                if np.any(dlen != d0):
                    return None
                dstart = offs + 8 + h0
                block = decode.gather(buf, dstart, d0)
                dec = decode.decode_imu_block(block, "ros1")
                if dec is None or not decode.check_block(
                        dec, [block[0].tobytes(), block[-1].tobytes()], deser):
                    return None
                sec_blocks.append(dec)
        return times.copy(), decode.concat_blocks(sec_blocks)


def _sqlite_connect(path: Path) -> sqlite3.Connection:
    from ...inputs import sqlite_uri
    con = sqlite3.connect(sqlite_uri(path), uri=True)
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
            return np.empty(0, np.int64), decode.concat_blocks([])
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
        return np.empty(0, np.int64), decode.concat_blocks([])
    t = np.concatenate(times)
    block = np.frombuffer(b"".join(blobs) if len(blobs) > 1 else blobs[0], dtype=np.uint8).reshape(-1, length)
    order = np.argsort(t, kind="stable")
    if np.any(order != np.arange(t.shape[0])):
        t, block = t[order], block[order]
    dec = decode.decode_imu_block(block, "cdr")
    if dec is None or not decode.check_block(dec, [block[0].tobytes(), block[-1].tobytes()], deser):
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
        with guard(path, None, "cannot open log (truncated, corrupt or not MCAP)"):
            self.f = open(path, "rb")
        try:
            with guard(path, None, "cannot open log (truncated, corrupt or not MCAP)"):
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
        with guard(self.path, topic, "cannot read messages (truncated or corrupt MCAP)"):
            for _schema, _channel, msg in self.reader.iter_messages(topics=[topic], log_time_order=True):
                yield msg.log_time, msg.data

    def deserializer(self, topic):
        cid = self.channels[topic][0]
        ch = self.summary.channels[cid]
        schema = self.summary.schemas.get(ch.schema_id)
        decoder = None
        with guard(self.path, topic, "cannot build a decoder for the schema"), \
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
            with guard(path, topic, "cannot decode message"):
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
        with guard(self.path, topic, "cannot read the MCAP index"):
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
        with guard(self.path, topic, "cannot read messages (truncated or corrupt MCAP)"):
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
                rlen = decode.read_le(buf, offs + 1, "<u8").astype(np.int64)
                if np.any(rlen != rlen[0]) or rlen[0] < 22 + 16 or (length is not None and rlen[0] - 22 != length):
                    return None
                length = int(rlen[0]) - 22
                if np.any(decode.read_le(buf, offs + 9, "<u2") != cids[0]):
                    return None
                lt = decode.read_le(buf, offs + 15, "<u8").astype(np.int64)
                if np.any(lt != r[:, 0]):
                    return None
                blocks.append(decode.gather(buf, offs + 31, length))
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
        dec = decode.decode_imu_block(block, info.encoding)
        if dec is None or not decode.check_block(dec, [block[0].tobytes(), block[-1].tobytes()], deser):
            return None
        return t, dec


def open_log(path) -> _Log:
    """Open a log with the right library; SinsError when it does not exist or cannot be read."""
    p = input_file(path, "ROS log", allow_dir=True)      # a FIFO or device would block or fail deep inside
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
