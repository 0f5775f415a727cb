"""RINEX readers and writers: observations 2.11 and 3.02-3.05, navigation (GPS LNAV, Galileo I/NAV and
F/NAV, BeiDou D1/D2, QZSS; GLONASS records counted and skipped), gzip / Unix-compress / Hatanaka input;
RINEX 3.04 output.

The observation body is parsed by numba kernels over the file's bytes (:mod:`sinscli.io.rinex_kernels`);
headers and navigation records (a few thousand lines) in Python.  Every problem is one line naming the
file, the line, the column and the epoch (``sinscli.errors.SinsError``).
"""
from __future__ import annotations

import gzip
import logging
import math
from pathlib import Path

import numpy as np

from ..errors import SinsError, quote
from ..gnss import ephemeris as E
from ..gnss.ephemeris import NavData, finish_table, healthy_py
from ..gnss.observations import ObsData
from ..gnss.signals import (SYS_BDS, SYS_CHARS, SYS_GAL, SYS_GLO, SYS_GPS, SYS_QZS, high_orbit, sat_name,
                            sys_index)
from ..gnss.timesys import BDT_OFFSET, DEFAULT_LEAP, SECONDS_PER_WEEK, calendar, epoch_text, gps_seconds
from . import rinex_kernels as K
from ..inputs import input_file
from .atomic import atomic_path, check_finite

log = logging.getLogger("sins")

# pseudorange windows (m): MEO satellites, and GEO/IGSO/QZSS/SBAS (signals/high_orbit)
PR_WINDOW_MEO = (15.0e6, 30.0e6)
PR_WINDOW_HIGH = (30.0e6, 45.0e6)

# RINEX 2 observation types -> RINEX 3 codes, per system (RINEX 3.04 A.10 and the 2.11 text)
_V2_CODES = {
    "G": {"C1": "C1C", "P1": "C1W", "L1": "L1C", "D1": "D1C", "S1": "S1C", "C2": "C2X", "P2": "C2W",
          "L2": "L2W", "D2": "D2W", "S2": "S2W", "C5": "C5X", "L5": "L5X", "D5": "D5X", "S5": "S5X"},
    "R": {"C1": "C1C", "P1": "C1P", "L1": "L1C", "D1": "D1C", "S1": "S1C", "C2": "C2C", "P2": "C2P",
          "L2": "L2P", "D2": "D2P", "S2": "S2P"},
    "E": {"C1": "C1X", "L1": "L1X", "D1": "D1X", "S1": "S1X", "C5": "C5X", "L5": "L5X", "D5": "D5X",
          "S5": "S5X", "C7": "C7X", "L7": "L7X", "D7": "D7X", "S7": "S7X", "C8": "C8X", "L8": "L8X",
          "D8": "D8X", "S8": "S8X", "C6": "C6X", "L6": "L6X", "D6": "D6X", "S6": "S6X"},
    "C": {"C1": "C2I", "L1": "L2I", "D1": "D2I", "S1": "S2I", "C2": "C2I", "L2": "L2I", "D2": "D2I",
          "S2": "S2I", "C7": "C7I", "L7": "L7I", "D7": "D7I", "S7": "S7I", "C6": "C6I", "L6": "L6I",
          "D6": "D6I", "S6": "S6I"},
    "J": {"C1": "C1C", "L1": "L1C", "D1": "D1C", "S1": "S1C", "C2": "C2X", "L2": "L2X", "D2": "D2X",
          "S2": "S2X", "C5": "C5X", "L5": "L5X", "D5": "D5X", "S5": "S5X"},
    "S": {"C1": "C1C", "L1": "L1C", "D1": "D1C", "S1": "S1C", "C5": "C5I", "L5": "L5I", "D5": "D5I",
          "S5": "S5I"},
}


# --- bytes --------------------------------------------------------------------------------------------------

def read_bytes(path, what: str = "RINEX file") -> bytes:
    """The text of a RINEX file as bytes: plain, gzip (``.gz``), Unix compress (``.Z``) or Hatanaka
    (``.crx``/``.##d``, alone or compressed), each recognised by its content."""
    p = input_file(path, what)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise SinsError(f"{p}: cannot read the {what} ({exc.strerror or type(exc).__name__})") from None
    if data[:2] == b"\x1f\x8b":
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, ValueError) as exc:
            raise SinsError(f"{p}: not a readable gzip file ({exc})") from None
    elif data[:2] == b"\x1f\x9d":
        data = _decompress(p, data, "Unix-compressed")
    if data[:80].find(b"COMPACT RINEX FORMAT") >= 0 or data[:80].find(b"CRINEX VERS") >= 0:
        data = _decompress(p, data, "Hatanaka-compressed")
    return data


def _decompress(p: Path, data: bytes, kind: str) -> bytes:
    try:
        import hatanaka  # hatanaka only for a Hatanaka-compressed file
    except ImportError:           # pragma: no cover - a declared dependency
        raise SinsError(f"{p}: {kind} RINEX needs the 'hatanaka' package (pip install hatanaka)") from None
    try:
        out = hatanaka.decompress(data)
    except Exception as exc:      # the package raises ValueError / HatanakaException / OSError
        raise SinsError(f"{p}: cannot decompress the {kind} file ({' '.join(str(exc).split())[:200]})") from None
    return out if isinstance(out, bytes) else out.encode("latin-1")


def _header_lines(p, data: bytes, what: str):
    """``(lines, body_offset)``: the header lines (str) and the byte offset of the first body line."""
    lines = []
    pos = 0
    n = len(data)
    while pos < n:
        q = data.find(b"\n", pos)
        q = n if q < 0 else q
        text = data[pos:q].rstrip(b"\r").decode("latin-1")
        lines.append(text)
        pos = q + 1
        if text[60:].strip() == "END OF HEADER":
            return lines, pos
        if len(lines) > 5000:
            break
    raise SinsError(f"{p}: line {len(lines)}: no 'END OF HEADER' label: not a RINEX {what}")


def _version_type(p, lines, what):
    first = lines[0] if lines else ""
    if first[60:].strip() != "RINEX VERSION / TYPE":
        raise SinsError(f"{p}: line 1, column 61: expected the label 'RINEX VERSION / TYPE' (not a RINEX {what})")
    try:
        version = float(first[:9])
    except ValueError:
        raise SinsError(f"{p}: line 1, column 1: RINEX version {quote(first[:9].strip())} is not a number") from None
    return version, first[20:21], first[40:41]


# --- observations ---------------------------------------------------------------------------------------------

def read_obs(path) -> ObsData:
    """Read a RINEX observation file (2.11 or 3.02-3.05; compressed as :func:`read_bytes` says)."""
    p = Path(path)
    data = read_bytes(p, "RINEX observation file")
    lines, body = _header_lines(p, data, "observation file")
    version, ftype, fsys = _version_type(p, lines, "observation file")
    if ftype != "O":
        raise SinsError(f"{p}: line 1, column 21: file type {quote(ftype)}: expected 'O' (observations)"
                        + ("; this is a navigation file: give it with --nav" if ftype in "NGLC" else ""))
    if not (2.0 <= version < 2.2 or 3.0 <= version < 4.0):
        raise SinsError(f"{p}: line 1, column 1: RINEX version {version:g}: expected 2.11 or 3.02-3.05")
    header = {"version": version, "system": fsys.strip() or "G"}
    types: dict[int, list[str]] = {}
    v2_types: list[str] = []
    time_sys = "GPS"
    i = 0
    while i < len(lines):
        ln = lines[i]
        label = ln[60:].strip()
        if label == "SYS / # / OBS TYPES":
            letter = ln[0]
            try:
                count = int(ln[3:6])
            except ValueError:
                raise SinsError(f"{p}: line {i + 1}, column 4: the number of observation types "
                                f"{quote(ln[3:6].strip())} is not a number") from None
            codes = ln[7:60].split()
            while len(codes) < count and i + 1 < len(lines) and lines[i + 1][60:].strip() == "SYS / # / OBS TYPES":
                i += 1
                codes += lines[i][7:60].split()
            s = sys_index(letter)
            if s < 0:
                raise SinsError(f"{p}: line {i + 1}, column 1: unknown satellite system {quote(letter)}")
            if len(codes) != count or any(len(c) != 3 for c in codes):
                raise SinsError(f"{p}: line {i + 1}: {count} observation types announced, {len(codes)} listed "
                                f"or a code is not 3 characters")
            types[s] = codes
        elif label == "# / TYPES OF OBSERV":
            try:
                count = int(ln[:6])
            except ValueError:
                raise SinsError(f"{p}: line {i + 1}, column 1: the number of observation types "
                                f"{quote(ln[:6].strip())} is not a number") from None
            v2_types = ln[6:60].split()
            while len(v2_types) < count and i + 1 < len(lines) and lines[i + 1][60:].strip() == "# / TYPES OF OBSERV":
                i += 1
                v2_types += lines[i][6:60].split()
            if len(v2_types) != count:
                raise SinsError(f"{p}: line {i + 1}: {count} observation types announced, {len(v2_types)} listed")
        elif label == "APPROX POSITION XYZ":
            try:
                header["approx_xyz"] = [float(ln[0:14]), float(ln[14:28]), float(ln[28:42])]
            except ValueError:
                pass
        elif label == "ANTENNA: DELTA H/E/N":
            try:
                header["antenna_delta_hen"] = [float(ln[0:14]), float(ln[14:28]), float(ln[28:42])]
            except ValueError:
                pass
        elif label == "MARKER NAME":
            header["marker"] = ln[:60].strip()
        elif label == "REC # / TYPE / VERS":
            header["receiver"] = ln[20:40].strip()
        elif label == "ANT # / TYPE":
            header["antenna"] = ln[20:40].strip()
        elif label == "INTERVAL":
            try:
                header["interval"] = float(ln[:10])
            except ValueError:
                pass
        elif label == "TIME OF FIRST OBS":
            time_sys = ln[48:51].strip() or ("GPS" if header["system"] in "GM " else
                                             {"R": "GLO", "E": "GAL", "C": "BDT", "J": "QZS"}.get(header["system"], "GPS"))
        elif label == "LEAP SECONDS":
            try:
                header["leap_seconds"] = int(ln[:6])
            except ValueError:
                pass
        elif label == "GLONASS SLOT / FRQ #":
            f = ln[4:60].split()
            for k in range(0, len(f) - 1, 2):
                try:
                    header.setdefault("glo_freq", {})[int(f[k][1:])] = int(f[k + 1])
                except ValueError:
                    pass
        i += 1
    header["time_system"] = time_sys
    buf = np.frombuffer(data, dtype=np.uint8)
    max_rows = data.count(b"\n", body) + 2
    line0 = len(lines) + 1
    if version >= 3.0:
        if not types:
            raise SinsError(f"{p}: no 'SYS / # / OBS TYPES' header line: the observation types are unknown")
        ntypes = np.full(128, -1, dtype=np.int64)
        for s, codes in types.items():
            ntypes[ord(SYS_CHARS[s])] = len(codes)
        nmax = max(len(c) for c in types.values())
        res = K.parse_obs3(buf, body, line0, ntypes, nmax, max_rows)
    else:
        if not v2_types:
            raise SinsError(f"{p}: no '# / TYPES OF OBSERV' header line: the observation types are unknown")
        letters = "GRESJC" if header["system"] == "M" else header["system"]
        known = np.zeros(128, dtype=np.bool_)
        for c in letters:
            known[ord(c)] = True
        for c in letters:
            table = _V2_CODES.get(c, {})
            types[sys_index(c)] = [table.get(t, (t + "X") if len(t) == 2 else t) for t in v2_types]
        res = K.parse_obs2(buf, body, line0, len(v2_types), ord(header["system"] if header["system"] != "M" else "G"),
                           known, max_rows)
    err, eline, ecol, eval_, ne, nr, t, flag, clk, ep_line, start, rsys, rprn, rline, vals, lli = res
    if err != K.OK:
        _raise_obs_error(p, data, body, line0, err, eline, ecol, eval_, t, ne)
    offset = {"GPS": 0.0, "GAL": 0.0, "QZS": 0.0, "IRN": 0.0, "BDT": BDT_OFFSET,
              "GLO": float(header.get("leap_seconds", DEFAULT_LEAP)) - 10800.0,
              "UTC": float(header.get("leap_seconds", DEFAULT_LEAP))}.get(time_sys)
    if offset is None:
        raise SinsError(f"{p}: time system {quote(time_sys)} in 'TIME OF FIRST OBS': expected GPS, GAL, BDT, "
                        f"QZS, GLO or UTC")
    sysmap = np.full(256, -1, dtype=np.int8)
    for k, c in enumerate(SYS_CHARS):
        sysmap[ord(c)] = k
    packed = lli[:nr]                       # LLI + 8 SSI (rinex_kernels._obs_field)
    obs = ObsData(time=t[:ne] + offset, start=start[:ne + 1].copy(), sys=sysmap[rsys[:nr]], prn=rprn[:nr],
                  values=vals[:nr], lli=(packed & 7).astype(np.int8), ssi=(packed >> 3).astype(np.int8),
                  types=types, flag=flag[:ne], line=rline[:nr],
                  epoch_line=ep_line[:ne], header=header, source=str(p), glo_freq=header.get("glo_freq", {}))
    check_obs(obs)
    return obs


def _raise_obs_error(p, data, body, line0, err, eline, ecol, eval_, t, ne):
    last = f" (after the epoch {epoch_text(t[ne - 1])})" if ne > 0 else ""
    where = f"{p}: line {eline}" + (f", column {ecol}" if ecol > 0 else "")
    if err == K.E_EPOCH:
        raise SinsError(f"{where}: expected an epoch line{last}")
    if err == K.E_NUMBER:
        raise SinsError(f"{where}: not a number{last}")
    if err == K.E_COUNT:
        n = int(eval_)
        raise SinsError(f"{where}: impossible satellite count {n} for the epoch{last}: "
                        + ("not a count" if n < 0 else "the records that follow do not match it"))
    if err == K.E_SAT:
        c = int(eval_)
        raise SinsError(f"{where}: satellite of system {quote(chr(c) if 32 <= c < 127 else '?')} with a bad "
                        f"number, or a system the header does not list{last}")
    if err == K.E_TRUNC:
        raise SinsError(f"{where}: the file ends inside an epoch of {int(eval_)} satellites{last} (truncated file)")
    if err == K.E_FLAG:
        raise SinsError(f"{where}: epoch flag {int(eval_)}: expected 0-6{last}")
    if err == K.E_DATE:
        raise SinsError(f"{where}: impossible epoch date or time{last}")
    raise SinsError(f"{where}: cannot read the observations{last}")


def check_obs(obs: ObsData) -> None:
    """Pseudoranges outside 15,000-30,000 km (30,000-45,000 km for GEO/IGSO/QZSS/SBAS satellites) are refused
    naming the file, line, column and epoch; a pseudorange of exactly 0 means 'not observed' (NaN).  Epoch times
    must increase."""
    if len(obs) > 1:
        bad = np.nonzero(np.diff(obs.time) <= 0.0)[0]
        if bad.size:
            k = int(bad[0]) + 1
            line = int(obs.epoch_line[k]) if obs.epoch_line is not None else 0
            raise SinsError(f"{obs.source}: line {line}: epoch {epoch_text(obs.time[k])} is not after the "
                            f"previous one ({epoch_text(obs.time[k - 1])})")
    ep = None
    for s, codes in obs.types.items():
        mine = obs.sys == s
        if not mine.any():
            continue
        high = np.array([high_orbit(s, int(prn)) for prn in range(256)])
        for j, code in enumerate(codes):
            if code[0] != "C":
                continue
            v = obs.values[:, j]
            zero = mine & (v == 0.0)
            if zero.any():
                v[zero] = np.nan
            hi = high[np.clip(obs.prn, 0, 255)]
            lo_b = np.where(hi, PR_WINDOW_HIGH[0], PR_WINDOW_MEO[0])
            hi_b = np.where(hi, PR_WINDOW_HIGH[1], PR_WINDOW_MEO[1])
            bad = mine & ~np.isnan(v) & ((v < lo_b) | (v > hi_b))
            if bad.any():
                r = int(np.argmax(bad))
                if ep is None:
                    ep = obs.epoch_of_record()
                col = (4 + 16 * j) if obs.header.get("version", 3) >= 3 else 1 + 16 * (j % 5)
                line = int(obs.line[r]) + (0 if obs.header.get("version", 3) >= 3 else j // 5) \
                    if obs.line is not None else 0
                window = PR_WINDOW_HIGH if hi[r] else PR_WINDOW_MEO
                raise SinsError(f"{obs.source}: line {line}, column {col}: epoch {epoch_text(obs.time[ep[r]])}, "
                                f"{sat_name(s, int(obs.prn[r]))} {code}: pseudorange {v[r]:.3f} m is outside "
                                f"{window[0] / 1e3:,.0f}-{window[1] / 1e3:,.0f} km")


# --- navigation -----------------------------------------------------------------------------------------------

def _nav_float(p, line_no, text, col, what):
    s = text.strip().replace("D", "E").replace("d", "e")
    if not s:
        return 0.0
    try:
        v = float(s)
    except ValueError:
        raise SinsError(f"{p}: line {line_no}, column {col}: {what} {quote(text.strip())} is not a number") from None
    if not math.isfinite(v):
        raise SinsError(f"{p}: line {line_no}, column {col}: {what} is not finite")
    return v


def _fields(p, lines, i, start_col, nlines):
    """The 19-character fields of ``nlines`` broadcast-orbit lines from line index ``i`` (4 per line)."""
    out = []
    for k in range(nlines):
        if i + k >= len(lines):
            raise SinsError(f"{p}: line {i + k + 1}: the file ends inside a navigation record (truncated file)")
        ln = lines[i + k]
        for f in range(4):
            a = start_col + 19 * f
            out.append(_nav_float(p, i + k + 1, ln[a:a + 19], a + 1, "field"))
    return out


def read_nav(paths) -> NavData:
    """Read one or more RINEX navigation files (2.x GPS 'N' / GLONASS 'G', 3.x mixed).  Ephemerides with a bad
    health flag or an IODE that does not match the IODC (GPS/QZSS) are skipped and counted (one warning line
    each kind, naming the file and the epoch of the first)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    rows = []
    ion = {}
    skipped: dict[str, list] = {}
    leap = None
    glo = 0
    sources = []
    for path in paths:
        p = Path(path)
        sources.append(str(p))
        data = read_bytes(p, "RINEX navigation file")
        text = data.decode("latin-1").splitlines()
        hdr, _ = _header_lines(p, data, "navigation file")
        version, ftype, fsys = _version_type(p, hdr, "navigation file")
        if ftype not in "NGLC" or (version >= 3 and ftype != "N"):
            raise SinsError(f"{p}: line 1, column 21: file type {quote(ftype)}: expected a navigation file ('N')"
                            + ("; this is an observation file" if ftype == "O" else ""))
        for k, ln in enumerate(hdr):
            label = ln[60:].strip()
            if label in ("ION ALPHA", "ION BETA"):
                vals = [_nav_float(p, k + 1, ln[2 + 12 * j:14 + 12 * j], 3 + 12 * j, label) for j in range(4)]
                k0 = 0 if label == "ION ALPHA" else 4
                ion.setdefault("GPS", [0.0] * 8)[k0:k0 + 4] = vals
            elif label == "IONOSPHERIC CORR":
                kind = ln[:4].strip()
                vals = [_nav_float(p, k + 1, ln[5 + 12 * j:17 + 12 * j], 6 + 12 * j, label) for j in range(4)]
                key = {"GPSA": ("GPS", 0), "GPSB": ("GPS", 4), "BDSA": ("BDS", 0), "BDSB": ("BDS", 4),
                       "GAL": ("GAL", 0)}.get(kind)
                if key:
                    arr = ion.setdefault(key[0], [0.0] * 8)
                    arr[key[1]:key[1] + 4] = vals
            elif label == "LEAP SECONDS":
                try:
                    leap = float(int(ln[:6]))
                except ValueError:
                    pass
        i = len(hdr)
        v2_letter = {"N": "G", "G": "R", "L": "E", "C": "C"}.get(ftype, "G") if version < 3 else None
        while i < len(text):
            ln = text[i]
            if not ln.strip():
                i += 1
                continue
            if version >= 3:
                letter = ln[0]
                s = sys_index(letter)
                if s < 0:
                    raise SinsError(f"{p}: line {i + 1}, column 1: unknown satellite system {quote(letter)}")
                try:
                    prn = int(ln[1:3])
                    y, mo, d, h, mi, sec = (int(ln[4:8]), int(ln[9:11]), int(ln[12:14]), int(ln[15:17]),
                                            int(ln[18:20]), float(ln[21:23]))
                except ValueError:
                    raise SinsError(f"{p}: line {i + 1}, column 2: expected a satellite and an epoch "
                                    f"(RINEX 3 navigation record)") from None
                first = [_nav_float(p, i + 1, ln[23 + 19 * j:42 + 19 * j], 24 + 19 * j, "clock field")
                         for j in range(3)]
                col0 = 4
            else:
                letter = v2_letter
                s = sys_index(letter)
                try:
                    prn = int(ln[0:2])
                    yy = int(ln[3:5])
                    y = yy + (2000 if yy < 80 else 1900)
                    mo, d, h, mi, sec = int(ln[6:8]), int(ln[9:11]), int(ln[12:14]), int(ln[15:17]), float(ln[17:22])
                except ValueError:
                    raise SinsError(f"{p}: line {i + 1}, column 1: expected a satellite and an epoch "
                                    f"(RINEX 2 navigation record)") from None
                first = [_nav_float(p, i + 1, ln[22 + 19 * j:41 + 19 * j], 23 + 19 * j, "clock field")
                         for j in range(3)]
                col0 = 3
            nl = {SYS_GLO: 3, 5: 3}.get(s, 7)      # GLONASS and SBAS records: 3 orbit lines; the others 7
            if s == 6:                             # NavIC: 7 lines as GPS
                nl = 7
            if not (1 <= mo <= 12 and 1 <= d <= 31 and 0 <= h <= 23 and 0 <= mi <= 59 and 0 <= sec < 61):
                raise SinsError(f"{p}: line {i + 1}: impossible epoch date or time")
            orbit = _fields(p, text, i + 1, col0, nl)
            rec_line = i + 1
            i += 1 + nl
            if s == SYS_GLO:
                glo += 1
                continue
            if s not in (SYS_GPS, SYS_GAL, SYS_BDS, SYS_QZS):
                continue
            toc = gps_seconds(y, mo, d, h, mi, sec) + (BDT_OFFSET if s == SYS_BDS else 0.0)
            row = _kepler_row(s, prn, toc, first, orbit)
            name = f"{sat_name(s, prn)} ephemeris of {epoch_text(toc)}"
            if not healthy_py(row):
                skipped.setdefault("health", []).append(f"{p}: line {rec_line}: {name}: health flag "
                                                        f"{int(row[E.HEALTH])}")
                continue
            if s in (SYS_GPS, SYS_QZS) and int(row[E.IODE]) != int(row[E.IODC]) % 256:
                skipped.setdefault("iode", []).append(f"{p}: line {rec_line}: {name}: IODE {int(row[E.IODE])} "
                                                      f"does not match IODC {int(row[E.IODC])}")
                continue
            if row[E.SQRTA] < 1000.0 or not 0.0 <= row[E.ECC] < 1.0:
                skipped.setdefault("orbit", []).append(f"{p}: line {rec_line}: {name}: sqrt(A) "
                                                       f"{row[E.SQRTA]:g}, e {row[E.ECC]:g} is no orbit")
                continue
            rows.append(row)
    report_skipped(skipped, "ephemerides")
    nav = NavData(eph=finish_table(rows), source=", ".join(sources), glonass=glo,
                  skipped={k: (len(v), v[0]) for k, v in skipped.items()}, leap_seconds=leap)
    nav.ion_gps = np.asarray(ion["GPS"]) if "GPS" in ion else None
    nav.ion_bds = np.asarray(ion["BDS"]) if "BDS" in ion else None
    nav.ion_gal = np.asarray(ion["GAL"][:3]) if "GAL" in ion else None
    return nav


_SKIP_TEXT = {"health": "with a bad health flag", "iode": "with an IODE that does not match the IODC",
              "orbit": "with impossible orbit elements", "truncated": "truncated", "checksum": "with a bad checksum",
              "parity": "with a bad parity"}


def report_skipped(skipped: dict, what: str) -> None:
    """One warning line per kind of skipped item: the count and the first one (its file and epoch)."""
    for kind, items in skipped.items():
        n = len(items)
        more = f" (and {n - 1} more)" if n > 1 else ""
        log.warning("skipped %d %s %s: %s%s", n, what, _SKIP_TEXT.get(kind, kind), items[0], more)


def _kepler_row(s, prn, toc, clock, o):
    """A table row from a RINEX record: ``clock`` = af0, af1, af2; ``o`` the broadcast-orbit fields 1..7
    (RINEX 3.04 tables A6 (GPS), A8 (Galileo), A14 (BeiDou))."""
    row = np.zeros(E.NCOL)
    row[E.SYS], row[E.PRN], row[E.TOC] = s, prn, toc
    row[E.AF0], row[E.AF1], row[E.AF2] = clock
    (iode, crs, deltan, m0, cuc, ecc, cus, sqrta, toe_sow, cic, omega0, cis, i0, crc, omega, omegadot, idot,
     codes, week, l2p, ura, health, tgd1, iodc_or_tgd2, ttr) = o[:25]
    row[E.IODE], row[E.CRS], row[E.DELTAN], row[E.M0] = iode, crs, deltan, m0
    row[E.CUC], row[E.ECC], row[E.CUS], row[E.SQRTA] = cuc, ecc, cus, sqrta
    row[E.CIC], row[E.OMEGA0], row[E.CIS], row[E.I0] = cic, omega0, cis, i0
    row[E.CRC], row[E.OMEGA], row[E.OMEGADOT], row[E.IDOT] = crc, omega, omegadot, idot
    row[E.URA], row[E.HEALTH], row[E.TGD1], row[E.TTR] = ura, health, tgd1, ttr
    if s == SYS_GAL:
        row[E.SOURCE] = int(codes)             # data sources
        row[E.TGD2] = iodc_or_tgd2             # BGD E5b/E1
        row[E.IODC] = iode
    elif s == SYS_BDS:
        row[E.TGD2] = iodc_or_tgd2             # TGD2 B2/B3
        row[E.IODC] = iode                     # AODC is in the clock's slot: keep AODE
    else:
        row[E.IODC] = iodc_or_tgd2
    # toe: week + seconds of week (GPS week for GPS/QZSS/Galileo in RINEX 3.04; BDT week for BeiDou)
    w = week
    if s == SYS_BDS:
        toe = w * SECONDS_PER_WEEK + toe_sow + BDT_OFFSET + 1356 * SECONDS_PER_WEEK
    else:
        toe = w * SECONDS_PER_WEEK + toe_sow
    # a week field that disagrees with toc by half a week or more (a rollover in the file): take toc's week
    while toe - toc > SECONDS_PER_WEEK / 2:
        toe -= SECONDS_PER_WEEK
    while toc - toe > SECONDS_PER_WEEK / 2:
        toe += SECONDS_PER_WEEK
    row[E.TOE] = toe
    row[E.WEEK] = math.floor(toe / SECONDS_PER_WEEK)
    return row


# --- writers (RINEX 3.04) ---------------------------------------------------------------------------------

def _hline(text: str, label: str) -> str:
    return f"{text:<60.60}{label:<20}\n"


def _cal(t):
    return calendar(float(t))


def obs_text_chunks(obs: ObsData, program: str = "sins"):
    """RINEX 3.04 observation file text of ``obs`` (GPS time), in chunks."""
    h = obs.header
    letters = sorted(obs.types)
    mixed = len(letters) > 1
    out = [_hline(f"{3.04:9.2f}{'':11}{'OBSERVATION DATA':<20}{('M' if mixed else SYS_CHARS[letters[0]]):<20}",
                  "RINEX VERSION / TYPE"),
           _hline(f"{program:<20}{'':<20}{'':<20}", "PGM / RUN BY / DATE"),
           _hline(h.get("marker", "UNKNOWN"), "MARKER NAME"),
           _hline(f"{'':<20}{'':<40}", "OBSERVER / AGENCY"),
           _hline(f"{'':<20}{h.get('receiver', ''):<20}{'':<20}", "REC # / TYPE / VERS"),
           _hline(f"{'':<20}{h.get('antenna', ''):<20}", "ANT # / TYPE")]
    xyz = h.get("approx_xyz", [0.0, 0.0, 0.0])
    out.append(_hline("".join(f"{v:14.4f}" for v in xyz), "APPROX POSITION XYZ"))
    out.append(_hline("".join(f"{v:14.4f}" for v in h.get("antenna_delta_hen", [0.0, 0.0, 0.0])),
                      "ANTENNA: DELTA H/E/N"))
    for s in letters:
        codes = obs.types[s]
        for k in range(0, len(codes), 13):
            first = f"{SYS_CHARS[s]}  {len(codes):3d}" if k == 0 else "      "
            out.append(_hline(first + "".join(f" {c}" for c in codes[k:k + 13]), "SYS / # / OBS TYPES"))
    if "interval" in h:
        out.append(_hline(f"{h['interval']:10.3f}", "INTERVAL"))
    if len(obs):
        y, mo, d, hh, mi, ss = _cal(obs.time[0])
        out.append(_hline(f"{y:6d}{mo:6d}{d:6d}{hh:6d}{mi:6d}{ss:13.7f}     GPS", "TIME OF FIRST OBS"))
    for s in letters:
        out.append(_hline(f"{SYS_CHARS[s]}", "SYS / PHASE SHIFT"))
    if SYS_GLO in obs.types:
        slots = sorted(obs.glo_freq.items())
        out.append(_hline(f"{len(slots):3d} " + "".join(f"R{k:02d} {f:2d} " for k, f in slots[:8]),
                          "GLONASS SLOT / FRQ #"))
        out.append(_hline(" C1C    0.000 C1P    0.000 C2C    0.000 C2P    0.000", "GLONASS COD/PHS/BIS"))
    out.append(_hline("", "END OF HEADER"))
    yield "".join(out)
    chunk = []
    for e in range(len(obs)):
        a, b = int(obs.start[e]), int(obs.start[e + 1])
        y, mo, d, hh, mi, ss = _cal(obs.time[e])
        ss = round(ss, 7)
        chunk.append(f"> {y:4d} {mo:02d} {d:02d} {hh:02d} {mi:02d}{ss:11.7f}  0{b - a:3d}\n")
        for r in range(a, b):
            s = int(obs.sys[r])
            parts = [f"{SYS_CHARS[s]}{int(obs.prn[r]):02d}"]
            for j in range(len(obs.types[s])):
                v = obs.values[r, j]
                if v != v:
                    parts.append(" " * 16)
                else:
                    li = int(obs.lli[r, j])
                    si = int(obs.ssi[r, j]) if obs.ssi is not None else 0
                    parts.append(f"{v:14.3f}{li if li else ' '}{si if si else ' '}")
            chunk.append("".join(parts).rstrip() + "\n")
        if len(chunk) > 20000:
            yield "".join(chunk)
            chunk = []
    yield "".join(chunk)


def _d19(v: float) -> str:
    """A navigation field in the D19.12 form (exponent with E, as RINEX 3.04 allows)."""
    s = f"{v:19.12E}"
    return s if len(s) == 19 else f"{v:18.11E}".rjust(19)


def nav_text(nav: NavData, program: str = "sins") -> str:
    """RINEX 3.04 navigation file text of ``nav`` (GPS, Galileo, BeiDou, QZSS records)."""
    out = [_hline(f"{3.04:9.2f}{'':11}{'N: GNSS NAV DATA':<20}{'M: MIXED':<20}", "RINEX VERSION / TYPE"),
           _hline(f"{program:<20}", "PGM / RUN BY / DATE")]
    for key, arr in (("GPS", nav.ion_gps), ("BDS", nav.ion_bds)):
        if arr is not None:
            out.append(_hline(f"{key}A " + "".join(f"{v:12.4E}" for v in arr[:4]), "IONOSPHERIC CORR"))
            out.append(_hline(f"{key}B " + "".join(f"{v:12.4E}" for v in arr[4:8]), "IONOSPHERIC CORR"))
    if nav.ion_gal is not None:
        out.append(_hline("GAL  " + "".join(f"{v:12.4E}" for v in list(nav.ion_gal) + [0.0]), "IONOSPHERIC CORR"))
    if nav.leap_seconds is not None:
        out.append(_hline(f"{int(nav.leap_seconds):6d}", "LEAP SECONDS"))
    out.append(_hline("", "END OF HEADER"))
    for row in nav.eph:
        s, prn = int(row[E.SYS]), int(row[E.PRN])
        toc = row[E.TOC] - (BDT_OFFSET if s == SYS_BDS else 0.0)
        y, mo, d, hh, mi, ss = _cal(toc)
        out.append(f"{SYS_CHARS[s]}{prn:02d} {y:4d} {mo:02d} {d:02d} {hh:02d} {mi:02d} {int(round(ss)):02d}"
                   + _d19(row[E.AF0]) + _d19(row[E.AF1]) + _d19(row[E.AF2]) + "\n")
        if s == SYS_BDS:
            toe = row[E.TOE] - BDT_OFFSET
            week = math.floor(toe / SECONDS_PER_WEEK)
            toe_sow = toe - week * SECONDS_PER_WEEK
            week -= 1356
        else:
            week = math.floor(row[E.TOE] / SECONDS_PER_WEEK)
            toe_sow = row[E.TOE] - week * SECONDS_PER_WEEK
        if s == SYS_GAL:
            codes, slot, last = row[E.SOURCE], row[E.TGD2], row[E.IODE]
        elif s == SYS_BDS:
            codes, slot, last = 0.0, row[E.TGD2], row[E.IODC]
        else:
            codes, slot, last = 0.0, row[E.IODC], row[E.IODC]
        lines = [(row[E.IODE], row[E.CRS], row[E.DELTAN], row[E.M0]),
                 (row[E.CUC], row[E.ECC], row[E.CUS], row[E.SQRTA]),
                 (toe_sow, row[E.CIC], row[E.OMEGA0], row[E.CIS]),
                 (row[E.I0], row[E.CRC], row[E.OMEGA], row[E.OMEGADOT]),
                 (row[E.IDOT], codes, float(week), 0.0),
                 (row[E.URA], row[E.HEALTH], row[E.TGD1], slot),
                 (row[E.TTR] if row[E.TTR] else toe_sow, 0.0)]
        del last
        for vals in lines:
            out.append("    " + "".join(_d19(v) for v in vals) + "\n")
    return "".join(out)


def write_obs(path, obs: ObsData) -> None:
    """Write ``obs`` as a RINEX 3.04 observation file (atomically; gzip when the name ends in .gz)."""
    if not np.isfinite(obs.time).all():
        raise SinsError(f"{path}: internal consistency check: an epoch time is not finite; nothing written")
    with atomic_path(path) as tmp:
        opener = gzip.open if str(path).endswith(".gz") else open
        with opener(tmp, "wt", encoding="ascii", newline="\n") as f:
            for chunk in obs_text_chunks(obs):
                f.write(chunk)


def write_nav(path, nav: NavData) -> None:
    """Write ``nav`` as a RINEX 3.04 navigation file (atomically)."""
    check_finite(path, {"ephemeris": nav.eph})
    with atomic_path(path) as tmp:
        opener = gzip.open if str(path).endswith(".gz") else open
        with opener(tmp, "wt", encoding="ascii", newline="\n") as f:
            f.write(nav_text(nav))


def is_rinex(path) -> str | None:
    """``'obs'``, ``'nav'`` or None: what a file is by its first line (compressed files by their name)."""
    p = Path(path)
    try:
        with open(p, "rb") as f:
            head = f.read(200)
    except OSError:
        return None
    if head[:2] in (b"\x1f\x8b", b"\x1f\x9d"):
        try:
            head = read_bytes(p)[:200]
        except SinsError:
            return None
    if b"COMPACT RINEX" in head[:80] or b"CRINEX" in head[:80]:
        return "obs"
    first = head.split(b"\n", 1)[0].decode("latin-1")
    if first[60:].strip() != "RINEX VERSION / TYPE":
        return None
    return "obs" if first[20:21] == "O" else "nav" if first[20:21] in "NGLC" else None
