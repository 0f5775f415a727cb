"""Open raw observations and their ephemerides: RINEX observation + navigation files, or a u-blox UBX log
(ephemerides from its own RXM-SFRBX, optionally more from RINEX navigation files)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SinsError
from .ephemeris import NavData, finish_table


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
    k = head.find(b"\xb5\x62", 0, 64)
    while 0 <= k < 64:
        if k + 6 <= len(head):
            n = head[k + 4] | (head[k + 5] << 8)
            frame = head[k + 2:k + 6 + n]
            if k + 8 + n <= len(head):
                a = b = 0
                for x in frame:
                    a = (a + x) & 0xFF
                    b = (b + a) & 0xFF
                if head[k + 6 + n] == a and head[k + 7 + n] == b:
                    return True
        k = head.find(b"\xb5\x62", k + 1, 64)
    return False


def merge_nav(navs: list[NavData]) -> NavData:
    """One navigation table from several (the ionosphere parameters of the first that has them)."""
    navs = [n for n in navs if n is not None]
    if len(navs) == 1:
        return navs[0]
    out = NavData(eph=finish_table(np.concatenate([n.eph for n in navs])) if navs else np.zeros((0, 31)),
                  source=", ".join(n.source for n in navs))
    for key in ("ion_gps", "ion_bds", "ion_gal", "leap_seconds"):
        for n in navs:
            if getattr(n, key) is not None:
                setattr(out, key, getattr(n, key))
                break
    return out


def read_raw(obs_path, nav_paths=()):
    """``(ObsData, NavData)`` of a RINEX observation file with RINEX navigation files, or of a UBX log (whose
    RXM-SFRBX ephemerides are merged with any navigation files given)."""
    from ..io import rinex
    navs = []
    if is_ubx(obs_path):
        from ..io.ubx import read_ubx
        obs, nav = read_ubx(obs_path)
        navs.append(nav)
    else:
        obs = rinex.read_obs(obs_path)
        if not nav_paths:
            raise SinsError(f"{obs_path}: RINEX observations need --nav with the broadcast ephemerides "
                            f"(a RINEX navigation file)")
    if nav_paths:
        navs.append(rinex.read_nav(list(nav_paths)))
    nav = merge_nav(navs)
    if len(nav) == 0:
        raise SinsError(f"{', '.join(str(p) for p in nav_paths) or obs_path}: no usable GPS, Galileo, BeiDou or "
                        f"QZSS ephemeris")
    return obs, nav
