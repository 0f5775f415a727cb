"""Receiver solutions as the NMEA and UBX NAV-PVT readers find them, before :mod:`sinscli.io.receiver` checks
them into a :class:`~sinscli.types.GnssLog`."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Solutions:
    """One receiver solution per epoch, as a reader found them (before the checks of :func:`to_gnss_log`)."""
    time: np.ndarray              # (N,) s, the IMU's time system
    lat: np.ndarray               # (N,) deg
    lon: np.ndarray               # (N,) deg
    height: np.ndarray            # (N,) m (ellipsoidal, unless a note says otherwise)
    vel: np.ndarray | None        # (N, 3) m/s ENU; up NaN: horizontal only
    std_pos: np.ndarray | None    # (N, 3) m ENU; NaN rows: unknown (the configured sigma)
    std_vel: np.ndarray | None    # (N, 3) m/s ENU; NaN: unknown
    where: np.ndarray             # (N,) byte offset of each epoch's position in the file
    row: str                      # "line" (text: offsets shown as lines) or "byte"
    source: str
    kind: str                     # "NMEA" | "UBX-NAV-PVT"
    skipped: dict = field(default_factory=dict)    # reason -> epochs
    total: int = 0                # epochs seen
    notes: list = field(default_factory=list)      # warning lines (damaged sentences, heights)

    def __len__(self) -> int:
        return int(self.time.shape[0])


def lines(buf: np.ndarray, offsets) -> np.ndarray:
    """1-based line numbers of byte offsets into ``buf``."""
    return np.searchsorted(np.flatnonzero(buf == 10), np.asarray(offsets), side="left") + 1


def line_of(buf: np.ndarray, offset: int) -> int:
    return int(lines(buf, [offset])[0])
