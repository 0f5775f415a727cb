"""GNSS receiver logs as the fixes of ``sins navigate --gnss``: u-blox UBX logs (the receiver's own NAV-PVT
solution, :mod:`sinscli.io.ubx_solution`) and NMEA 0183 text (:mod:`sinscli.io.nmea`), also NMEA sentences
interleaved with binary data.  Which the file is, the checks every fix passes (physical limits, naming the line
or byte), the report of what was skipped, and the :class:`GnssLog`.
"""
from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..config import Limits
from ..errors import SinsError
from ..inputs import input_file
from ..types import GnssLog
from . import limits as limits_mod
from .gnss_csv import POLE_USE
from .solutions import Solutions, lines
from .ubx_frames import is_ubx

log = logging.getLogger("sins")

SNIFF_BYTES = 65536
NOT_NMEA = (".csv", ".parquet", ".yaml", ".yml", ".json", ".bag", ".mcap", ".db3", ".rnx", ".obs")
_SENTENCE = re.compile(rb"\$([A-Z]{2})(GGA|RMC|VTG|GST|GSA),([ -~]*?)\*([0-9A-Fa-f]{2})")


def is_nmea(path) -> bool:
    """NMEA 0183 text: named ``.nmea``, or (any name but a CSV, Parquet, YAML, bag ...) a GGA, RMC, VTG, GST or GSA
    sentence with a valid checksum in its first 64 KiB."""
    p = Path(path)
    if p.suffix.lower() == ".nmea":
        return True
    if p.suffix.lower() in NOT_NMEA or not p.is_file():
        return False
    try:
        with open(p, "rb") as f:
            head = f.read(SNIFF_BYTES)
    except OSError:
        return False
    for m in _SENTENCE.finditer(head):
        body = m.group(0)[1:m.group(0).rindex(b"*")]
        cs = 0
        for c in body:
            cs ^= c
        if cs == int(m.group(4), 16):
            return True
    return False


def is_receiver_log(path) -> bool:
    """A file :func:`read_receiver_log` reads: a UBX log or NMEA text."""
    p = Path(path)
    return p.is_file() and (is_ubx(p) or is_nmea(p))


def read_bytes(path, what: str = "GNSS receiver log") -> tuple[Path, np.ndarray]:
    p = input_file(path, what)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise SinsError(f"{p}: cannot read the {what} ({exc.strerror or type(exc).__name__})") from None
    return p, np.frombuffer(data, dtype=np.uint8)


def receiver_solutions(path, time_system: str = "utc", date: str | None = None) -> tuple[Solutions, np.ndarray]:
    """The solutions of a receiver log and its bytes: a UBX log's NAV-PVT epochs, else its NMEA sentences.
    SinsError (one line naming the file) when it holds neither."""
    # the readers of each format (the NMEA kernels compile with numba) load only for a receiver log
    from .nmea import solutions as nmea_solutions
    from .ubx_solution import solutions as pvt_solutions
    p, buf = read_bytes(path)
    sol = pvt_solutions(buf, str(p), time_system)
    if sol is not None:
        return sol, buf
    sol = nmea_solutions(buf, str(p), date, time_system)
    ubx = is_ubx(p)
    if sol is None and ubx:
        raise SinsError(f"{p}: no UBX-NAV-PVT message (the receiver's own solution) and no NMEA GGA sentence: "
                        f"--gnss needs fixes; use --gnss-raw {p} to fuse its raw observations (RXM-RAWX), or "
                        f"`sins gnss spp {p} -o gnss.csv` for single-point fixes")
    if sol is None:
        raise SinsError(f"{p}: no NMEA GGA sentence with a valid checksum: --gnss needs the receiver's fixes "
                        f"(GGA; RMC, VTG, GST, GSA add velocity and accuracy)")
    if ubx:
        log.info("%s: no UBX-NAV-PVT message; its NMEA sentences are used", p)
    return sol, buf


def read_receiver_log(path, time_system: str = "utc", date: str | None = None, limits: Limits | None = None) -> GnssLog:
    """The fixes of a UBX log (NAV-PVT) or NMEA log as a :class:`GnssLog` in the IMU's ``time_system``
    (``utc`` | ``gps``); ``date`` (``YYYY-MM-DD``, UTC) dates an NMEA log without RMC sentences."""
    sol, buf = receiver_solutions(path, time_system, date)
    return to_gnss_log(sol, buf, limits)


def skipped_text(sol: Solutions) -> str:
    """``12 of 3,600 epochs: 10 without a fix (GGA quality 0), 2 ...``."""
    parts = ", ".join(f"{n:,} {why}" for why, n in sol.skipped.items() if n)
    return f"{sum(sol.skipped.values()):,} of {sol.total:,} {sol.kind} epochs: {parts}"


def to_gnss_log(sol: Solutions, buf: np.ndarray, limits: Limits | None = None) -> GnssLog:
    """Warnings for what was skipped, the physical limits (naming the line, or the byte of a UBX message), and
    the :class:`GnssLog`.  SinsError when no fix is left."""
    for note in sol.notes:
        log.warning(note)
    if len(sol) == 0:
        why = f" ({', '.join(f'{n:,} {w}' for w, n in sol.skipped.items() if n)})" if sol.skipped else ""
        raise SinsError(f"{sol.source}: no fix in the log's {sol.total:,} {sol.kind} epochs{why}")
    if any(sol.skipped.values()):
        log.warning("%s: skipped %s", sol.source, skipped_text(sol))
    lim = limits_mod.resolve(limits)
    label = "line" if sol.row == "line" else "message at byte"

    def checked(check):
        try:
            check(np.arange(len(sol)))
        except SinsError:                        # the message again, naming the line or byte of the epoch
            check(lines(buf, sol.where) if sol.row == "line" else sol.where)

    cols = ("latitude", "longitude", "height")
    checked(lambda r: limits_mod.check_time(sol.source, sol.time, lim, "time", r, label))
    checked(lambda r: limits_mod.check_position(sol.source, sol.lat, sol.lon, sol.height, lim, cols, r, label))
    checked(lambda r: limits_mod.check_near_pole(sol.source, sol.lat, "latitude", r, label, use=POLE_USE))
    if sol.vel is not None:
        up = np.isfinite(sol.vel[:, 2]).all()
        checked(lambda r: limits_mod.check_velocity(sol.source, sol.vel if up else sol.vel[:, :2], lim,
                                                    ("vel_e", "vel_n", "vel_u") if up else ("vel_e", "vel_n"), r,
                                                    label))
    for arr in (sol.std_pos, sol.std_vel):
        if arr is not None:
            known = np.isfinite(arr)
            checked(lambda r: limits_mod.check_sigma(sol.source, arr[known], "1-sigma",
                                                     np.broadcast_to(r[:, None], arr.shape)[known], label))
    return GnssLog(time=sol.time, lat=sol.lat, lon=sol.lon, height=sol.height, vel_n=sol.vel, std_pos=sol.std_pos,
                   std_vel=sol.std_vel, source=sol.source)
