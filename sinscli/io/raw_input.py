"""Open raw GNSS observations and their ephemerides: RINEX observation + navigation files, or a u-blox UBX
log (ephemerides from its own RXM-SFRBX, optionally more from RINEX navigation files)."""
from __future__ import annotations

from ..errors import SinsError
from ..gnss.ephemeris import merge_nav
from . import rinex
from .ubx import is_ubx, read_ubx


def read_raw(obs_path, nav_paths=()):
    """``(ObsData, NavData)`` of a RINEX observation file with RINEX navigation files, or of a UBX log (whose
    RXM-SFRBX ephemerides are merged with any navigation files given)."""
    navs = []
    if is_ubx(obs_path):
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
