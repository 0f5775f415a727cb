"""u-blox UBX framing without a parser library: the Fletcher checksum, whether a file is a UBX log, and the
frames of one fixed-length message found by a vectorized scan (u-blox F9 interface description, "UBX frame
structure": sync 0xB5 0x62, class, id, little-endian length, payload, CK_A, CK_B over class .. payload).

Kept light (numpy only): :func:`is_ubx` decides which reader opens a GNSS log, before any parser is loaded.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

SYNC = b"\xb5\x62"
CHUNK = 65536            # frames checked per block (bounds the memory of the gathered frames)


def fletcher(buf: np.ndarray):
    """UBX checksum (8-bit Fletcher, RFC 1145) over class, id, length and payload: ``(CK_A, CK_B)`` of a 1-D
    uint8 array, or two arrays for the rows of a 2-D one (``CK_A = sum x_i``, ``CK_B = sum (n - i) x_i``,
    mod 256)."""
    x = np.asarray(buf, dtype=np.int64)
    n = x.shape[-1]
    a = x.sum(axis=-1) & 0xFF
    b = (x @ np.arange(n, 0, -1, dtype=np.int64)) & 0xFF
    if x.ndim == 1:
        return int(a), int(b)
    return a, b


def is_ubx(path) -> bool:
    """A UBX log: named ``.ubx``, or a whole UBX frame with a valid checksum starting within its first 64 bytes
    (a log may begin with the tail of a message or NMEA text)."""
    p = Path(path)
    if p.suffix.lower() == ".ubx":
        return True
    try:
        with open(p, "rb") as f:
            head = f.read(4096)
    except OSError:
        return False
    k = head.find(SYNC, 0, 64)
    while 0 <= k < 64:
        if k + 6 <= len(head):
            n = head[k + 4] | (head[k + 5] << 8)
            if k + 8 + n <= len(head):
                a, b = fletcher(np.frombuffer(head[k + 2:k + 6 + n], dtype=np.uint8))
                if head[k + 6 + n] == a and head[k + 7 + n] == b:
                    return True
        k = head.find(SYNC, k + 1, 64)
    return False


def has_message(buf: np.ndarray, cls: int, mid: int) -> bool:
    """Whether ``buf`` holds a header of message ``(cls, mid)`` (sync, class, id; not checked further)."""
    k = np.flatnonzero(buf[:-3] == 0xB5) if buf.shape[0] >= 4 else np.zeros(0, np.int64)
    return bool(((buf[k + 1] == 0x62) & (buf[k + 2] == cls) & (buf[k + 3] == mid)).any())


def find_frames(buf: np.ndarray, cls: int, mid: int, length: int):
    """The payloads of every ``(cls, mid)`` message of payload ``length`` bytes in ``buf`` (uint8), in file
    order: ``(payloads (m, length) uint8, byte offsets (m,), bad checksums, truncated)``.  A frame whose
    checksum fails is skipped and counted; so is one cut by the end of the file.  A header announcing another
    length is not this message (a later protocol version, or binary data that happens to look like one)."""
    n = buf.shape[0]
    raw = buf.base if isinstance(buf.base, bytes) and len(buf.base) == n else None
    if n < 8 or (raw is not None and raw.find(bytes([0xB5, 0x62, cls, mid])) < 0):     # none (memchr-fast)
        return np.zeros((0, length), np.uint8), np.zeros(0, np.int64), 0, 0
    k = np.flatnonzero(buf[:-5] == 0xB5)                 # few in text; then the rest of the header
    k = k[(buf[k + 1] == 0x62) & (buf[k + 2] == cls) & (buf[k + 3] == mid)]
    k = k[(buf[k + 4].astype(np.int64) | (buf[k + 5].astype(np.int64) << 8)) == length]
    whole = k + length + 8 <= n
    truncated = int((~whole).sum())
    k = k[whole]
    if k.size == 0:
        return np.zeros((0, length), np.uint8), k.astype(np.int64), 0, truncated
    windows = np.lib.stride_tricks.sliding_window_view(buf, length + 8)
    keep = []
    for c in range(0, k.size, CHUNK):
        kk = k[c:c + CHUNK]
        fr = windows[kk]
        a, b = fletcher(fr[:, 2:length + 6])
        keep.append((a == fr[:, length + 6]) & (b == fr[:, length + 7]))
    good = np.concatenate(keep)
    k = k[good]
    payloads = windows[k][:, 6:6 + length].copy() if k.size else np.zeros((0, length), np.uint8)
    return payloads, k.astype(np.int64), int((~good).sum()), truncated


def build_frames(cls: int, mid: int, payloads: np.ndarray) -> np.ndarray:
    """Whole UBX frames ``(m, length + 8)`` uint8 of the ``(m, length)`` payloads of one message (the inverse of
    :func:`find_frames`)."""
    m, length = payloads.shape
    head = np.tile(np.array([0xB5, 0x62, cls, mid, length & 0xFF, length >> 8], np.uint8), (m, 1))
    body = np.hstack([head, payloads])
    a, b = fletcher(body[:, 2:])
    return np.hstack([body, a.astype(np.uint8)[:, None], b.astype(np.uint8)[:, None]])
