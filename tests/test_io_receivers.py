"""GNSS receiver logs (issue 30): NMEA 0183 against pynmea2, u-blox NAV-PVT against pyubx2, damaged sentences,
time, heights, accuracy, horizontal-only velocity (CSV, ROS, NMEA), and the commands (info, convert, navigate)."""
from __future__ import annotations

import calendar
import logging
import math
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.config import load_config
from sinscli.errors import SinsError
from sinscli.io import nmea as N
from sinscli.io import nmea_kernels as K
from sinscli.io.gnss_csv import read_gnss_csv, write_gnss_csv
from sinscli.io.nmea import Sentences, format_sentences, write_nmea
from sinscli.io.receiver import is_receiver_log, read_receiver_log
from sinscli.io.timebase import GPS_EPOCH_UNIX, to_gps, to_utc
from sinscli.io.ubx_solution import solution_frames, summary, write_ubx_solutions
from sinscli.types import GnssLog

pynmea2 = pytest.importorskip("pynmea2")
pyubx2 = pytest.importorskip("pyubx2")

# the examples of NMEA 0183 (as the standard's users quote them: GGA, RMC, VTG, GSA; GST of the Trimble/NovAtel
# reference manuals)
EXAMPLES = [
    "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",
    "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A",
    "$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48",
    "$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031*6A",
    "$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39",
    "$GPGGA,092750.000,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*76",
    "$GPRMC,092750.000,A,5321.6802,N,00630.3372,W,0.02,31.66,280511,,,A*43",
    "$GNGGA,001043.00,4404.14036,N,12118.85961,W,1,12,0.98,1113.0,M,-21.3,M,,*47",
    "$GNRMC,001031.00,A,4404.13993,N,12118.86023,W,0.146,,100117,,,A*7B",
]


def _cs(body: str) -> str:
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"{c:02X}"


def _sentence(body: str) -> str:
    return f"${body}*{_cs(body)}"


def _ours(lines):
    """Our parse of sentences (one per line): ``{line index: (kind, row of the table)}``, and the Sentences."""
    text = "\r\n".join(lines) + "\r\n"
    buf = np.frombuffer(text.encode("latin-1"), np.uint8)
    s = Sentences(buf)
    starts = np.cumsum([0] + [len(x) + 2 for x in lines[:-1]])
    out = {}
    for k in (K.K_GGA, K.K_RMC, K.K_VTG, K.K_GST, K.K_GSA):
        for off, row in zip(s.offset[k], s.table[k]):
            out[int(np.searchsorted(starts, off))] = (k, row)
    return out, s


def _tod(t):
    return t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6


def _f(x):
    return np.nan if x in (None, "") else float(x)


def _valid_angle(text, hemi, letters):
    """What pynmea2 does not check: the hemisphere letter, minutes of arc below 60, degrees up to 90 (180)."""
    if not text:
        return True
    split = text.index(".") - 2 if "." in text else len(text) - 2
    return (hemi in letters and float(text[split:]) < 60.0
            and int(text[:split] or 0) <= (90 if letters == "NS" else 180))


def _expected(line: str):
    """pynmea2's reading of a line as our table row, or None when pynmea2 refuses it or a field we read (or the
    field is not what NMEA 0183 puts there: a hemisphere other than N/S, E/W, minutes of arc of 60 or more,
    degrees beyond 90 (180), a GGA
    quality beyond 0..8, an RMC status other than A/V, VTG units other than T, N, K, fewer fields than NMEA 0183 v2.0 has, no leading
    '$', a '$' or a byte that is not printable inside: pynmea2 reads those without checking)."""
    body = line[1:line.index("*")] if "*" in line else line
    if not line.startswith("$") or "$" in body or any(not 32 <= ord(c) <= 126 for c in line):    # reserved '$', bytes not printable
        return None
    try:
        m = pynmea2.parse(line, check=True)
        kind = {"GGA": K.K_GGA, "RMC": K.K_RMC, "VTG": K.K_VTG, "GST": K.K_GST, "GSA": K.K_GSA}[m.sentence_type]
        if kind in (K.K_GGA, K.K_RMC) and not (_valid_angle(m.lat, m.lat_dir, "NS")
                                               and _valid_angle(m.lon, m.lon_dir, "EW")):
            return None
        if len(m.data) < K.MIN_FIELDS[kind]:                 # a field lost: the rest shifted
            return None
        if kind == K.K_GGA and not 0 <= int(m.gps_qual) <= 8:
            return None
        if kind == K.K_RMC and m.status not in ("A", "V"):
            return None
        if kind == K.K_VTG and not (m.true_track_sym in ("T", "") and m.spd_over_grnd_kts_sym in ("N", "")
                                    and m.spd_over_grnd_kmph_sym in ("K", "")):
            return None
        if kind == K.K_GGA:
            lat = m.latitude if m.lat else np.nan
            lon = m.longitude if m.lon else np.nan
            return kind, [_tod(m.timestamp) if m.timestamp else np.nan, lat, lon, float(m.gps_qual),
                          _f(m.num_sats), _f(m.horizontal_dil), _f(m.altitude), _f(m.geo_sep)]
        if kind == K.K_RMC:
            d = m.datestamp
            year = d.year + 100 if d and 1969 <= d.year < 1980 else (d.year if d else 0)   # GPS began in 1980
            return kind, [_tod(m.timestamp) if m.timestamp else np.nan, 1.0 if m.status == "A" else 0.0,
                          m.latitude if m.lat else np.nan, m.longitude if m.lon else np.nan, _f(m.spd_over_grnd),
                          _f(m.true_course), year * 10000 + d.month * 100 + d.day if d else np.nan]
        if kind == K.K_VTG:
            return kind, [_f(m.true_track), _f(m.spd_over_grnd_kts), _f(m.spd_over_grnd_kmph)]
        if kind == K.K_GST:
            return kind, [_tod(m.timestamp), _f(m.std_dev_latitude), _f(m.std_dev_longitude),
                          _f(m.std_dev_altitude)]
        return kind, [_f(m.mode_fix_type), _f(m.pdop), _f(m.hdop), _f(m.vdop)]
    except (pynmea2.ParseError, pynmea2.ChecksumError, pynmea2.SentenceTypeError, ValueError, TypeError,
            AttributeError, KeyError, IndexError):
        return None


def _same(ours, exp):
    k, row = ours
    ek, erow = exp
    n = len(erow)
    return k == ek and np.allclose(row[:n], np.asarray(erow, dtype=float), rtol=0, atol=1e-9, equal_nan=True)


def test_standard_examples_read_as_pynmea2_reads_them():
    ours, s = _ours(EXAMPLES)
    assert len(ours) == len(EXAMPLES) and s.checksum[0] == 0 and s.garbled[0] == 0
    for i, line in enumerate(EXAMPLES):
        exp = _expected(line)
        assert exp is not None and _same(ours[i], exp), (line, ours[i], exp)
    k, gga = ours[0]
    assert gga[1] == 48 + 7.038 / 60 and gga[2] == 11 + 31.0 / 60 and gga[6] == 545.4 and gga[7] == 46.9
    assert ours[5][1][2] == -(6 + 30.3372 / 60)              # W is negative
    assert ours[1][1][6] == 19940323 and ours[8][1][5] != ours[8][1][5]     # the empty course: NaN


YEARS = list(range(0, 60)) + list(range(80, 100))    # two-digit years read alike by both (pynmea2: 69-99 ->
                                                     # 19yy; ours, as RTKLIB: 80-99 -> 19yy, GPS began in 1980)


def _random_sentences(rng, n):
    talkers = ["GP", "GN", "GL", "GA", "GB", "GQ"]
    out = []
    for _ in range(n):
        tk = talkers[rng.integers(len(talkers))]
        hh, mm, ss = rng.integers(24), rng.integers(60), rng.uniform(0, 59.99)
        t = f"{hh:02d}{mm:02d}{ss:05.2f}"
        lat, lon = rng.uniform(-89.9, 89.9), rng.uniform(-179.9, 179.9)
        la = f"{int(abs(lat)):02d}{(abs(lat) % 1) * 60:0{8}.5f},{'N' if lat >= 0 else 'S'}"
        lo = f"{int(abs(lon)):03d}{(abs(lon) % 1) * 60:0{8}.5f},{'E' if lon >= 0 else 'W'}"
        kind = rng.integers(5)
        if kind == 0:
            out.append(_sentence(f"{tk}GGA,{t},{la},{lo},{rng.integers(0, 9)},{rng.integers(4, 30):02d},"
                                 f"{rng.uniform(0.5, 5):.2f},{rng.uniform(-100, 3000):.3f},M,"
                                 f"{rng.uniform(-100, 80):.1f},M,,"))
        elif kind == 1:
            out.append(_sentence(f"{tk}RMC,{t},A,{la},{lo},{rng.uniform(0, 80):.3f},{rng.uniform(0, 360):.2f},"
                                 f"{rng.integers(1, 28):02d}{rng.integers(1, 13):02d}{rng.choice(YEARS):02d},,,A"))
        elif kind == 2:
            v = rng.uniform(0, 80)
            out.append(_sentence(f"{tk}VTG,{rng.uniform(0, 360):.2f},T,,M,{v:.3f},N,{v * 1.852:.3f},K,A"))
        elif kind == 3:
            out.append(_sentence(f"{tk}GST,{t},{rng.uniform(0, 9):.2f},{rng.uniform(0, 9):.3f},"
                                 f"{rng.uniform(0, 9):.3f},{rng.uniform(0, 180):.1f},{rng.uniform(0.001, 9):.3f},"
                                 f"{rng.uniform(0.001, 9):.3f},{rng.uniform(0.001, 9):.3f}"))
        else:
            out.append(_sentence(f"{tk}GSA,A,3,01,02,03,,,,,,,,,,{rng.uniform(1, 4):.2f},{rng.uniform(0.5, 3):.2f},"
                                 f"{rng.uniform(0.8, 5):.2f},1"))
    return out


def test_random_sentences_of_every_talker_match_pynmea2():
    lines = _random_sentences(np.random.default_rng(3), 3000)
    ours, s = _ours(lines)
    assert len(ours) == len(lines) and s.checksum[0] == 0 and s.garbled[0] == 0
    for i, line in enumerate(lines):
        exp = _expected(line)
        assert exp is not None and _same(ours[i], exp), (line, ours[i], exp)


def _damage(rng, line: str) -> str:
    b = bytearray(line.encode())
    op = rng.integers(5)
    if op == 0:                                       # one byte flipped
        k = rng.integers(len(b))
        b[k] ^= 1 << int(rng.integers(7))
    elif op == 1:                                     # cut short
        b = b[:rng.integers(1, len(b))]
    elif op == 2:                                     # binary bytes inserted
        k = rng.integers(1, len(b))
        b[k:k] = bytes(rng.integers(0, 256, rng.integers(1, 6)).astype(np.uint8))
    elif op == 3:                                     # two bytes changed so that the checksum still holds
        i, j = sorted(rng.choice(np.arange(1, b.index(b"*")), 2, replace=False))
        bit = 1 << int(rng.integers(4))
        b[i] ^= bit
        b[j] ^= bit
    else:                                             # a field dropped (the checksum recomputed)
        body = line[1:line.index("*")].split(",")
        del body[rng.integers(1, len(body))]
        return _sentence(",".join(body))
    return b.decode("latin-1")


def _heads(line: str) -> int:
    """Sentence heads in a line: '$', five printable characters that are not delimiters, ','."""
    return sum(1 for k, c in enumerate(line) if c == "$" and len(line) > k + 6 and line[k + 6] == "," and all(
        33 <= ord(x) <= 126 and x not in "$,*!\\" for x in line[k + 1:k + 6]))


def test_fuzz_damaged_sentences_are_skipped_and_counted_never_misread():
    """Damaged sentences among good ones: what pynmea2 accepts (checksum and every field we read) we read to
    the same values; what it refuses we skip; every refused sentence whose head (``$ttsss,``) survived is
    counted as damaged (unless its checksum still holds over another address: a valid sentence of another
    formatter), and no good sentence is lost."""
    rng = np.random.default_rng(11)
    good = _random_sentences(rng, 2000)
    lines, damaged = [], []
    for line in good:
        if rng.random() < 0.3:
            line = _damage(rng, line)
            damaged.append(len(lines))
        lines.append(line.replace("\r", "").replace("\n", ""))
    ours, s = _ours(lines)
    refused_with_head = other = 0
    for i, line in enumerate(lines):
        exp = _expected(line)
        if exp is None:
            assert i not in ours, (line, ours.get(i))
            head = _heads(line)               # a '$' inside starts another (damaged) sentence
            refused_with_head += head
            # a checksum that still holds over an address that is no longer ours (GPGGA -> GPGGQ): a valid sentence
            # of another formatter, not a damaged one
            star = line.find("*")
            intact = star > 0 and line[star + 1:star + 3].upper() == _cs(line[1:star]) and all(
                32 <= ord(c) <= 126 and c != "$" for c in line[1:star])
            ours_addr = line[1:3].isalpha() and line[1:3].isupper() and line[1] != "P" and line[3:6] in (
                "GGA", "RMC", "VTG", "GST", "GSA")
            other += bool(head) and intact and not ours_addr
        else:
            assert i in ours and _same(ours[i], exp), (line, ours.get(i), exp)
    assert all(i in ours for i in range(len(lines)) if i not in damaged)
    counted = s.checksum[0] + s.garbled[0]
    print(f"fuzz: {len(damaged)} damaged, {refused_with_head} refused with a head, {other} of another formatter, "
          f"{counted} counted")
    assert counted == refused_with_head - other
    assert len(damaged) > 500 and refused_with_head > 400


def _log(tmp_path, lines, name="log.nmea"):
    p = tmp_path / name
    p.write_bytes(("\r\n".join(lines) + "\r\n").encode("latin-1"))
    return p


def _epoch(hms, date="140524", lat="4807.03800", lon="01131.00000", q=1, alt="545.4", sep="46.9", sog="010.0",
           cog="090.0", gst=True, talker="GN", rmc=True):
    out = [_sentence(f"{talker}GGA,{hms},{lat},N,{lon},E,{q},08,0.9,{alt},M,{sep},M,,")]
    if rmc:
        out.append(_sentence(f"{talker}RMC,{hms},A,{lat},N,{lon},E,{sog},{cog},{date},,,A"))
    if gst:
        out.append(_sentence(f"{talker}GST,{hms},1.0,2.0,1.0,0.0,1.200,0.800,2.500"))
    return out


def _utc(y, mo, d, h, mi, s):
    return float(calendar.timegm((y, mo, d, h, mi, 0))) + s


def test_time_height_velocity_and_gst_accuracy(tmp_path):
    p = _log(tmp_path, _epoch("235959.50", "311223") + _epoch("000000.50", "010124", cog="", sog="0.050"))
    g = read_receiver_log(p)
    assert g.time.tolist() == [_utc(2023, 12, 31, 23, 59, 59.5), _utc(2024, 1, 1, 0, 0, 0.5)]
    assert g.height[0] == 545.4 + 46.9 and g.lat[0] == 48 + 7.038 / 60
    v = 10.0 * 1852.0 / 3600.0                        # 10 knots east
    assert np.allclose(g.vel_n[0, :2], [v, 0.0], atol=1e-12) and np.isnan(g.vel_n[:, 2]).all()
    # no course (and a speed below 0.2 m/s): velocity (0, 0) with the speed, at least 0.2 m/s, as its sigma
    assert g.vel_n[1, :2].tolist() == [0.0, 0.0] and g.std_vel[1, :2].tolist() == [0.2, 0.2]
    assert np.isnan(g.std_vel[0]).all()              # the configured sigma
    assert g.std_pos.tolist() == [[0.8, 1.2, 2.5]] * 2   # GST: sigma lon (E), lat (N), alt (U)
    gps = read_receiver_log(p, time_system="gps")     # GPS time read as POSIX seconds: 18 leap seconds in 2023
    assert (gps.time - g.time).tolist() == [18.0, 18.0]


def test_midnight_without_rmc_takes_the_config_date(tmp_path):
    lines = _epoch("235959.00", rmc=False) + _epoch("000001.00", rmc=False)
    p = _log(tmp_path, lines)
    with pytest.raises(SinsError, match=r"log\.nmea: .*no RMC sentence with a date.*config's gnss\.date"):
        read_receiver_log(p)
    g = read_receiver_log(p, date="2024-02-28")
    assert g.time.tolist() == [_utc(2024, 2, 28, 23, 59, 59), _utc(2024, 2, 29, 0, 0, 1)]
    assert g.vel_n is None


def test_an_rmc_date_dates_the_epochs_before_it(tmp_path):
    lines = _epoch("235958.00", rmc=False) + _epoch("235959.00", "010324")
    g = read_receiver_log(_log(tmp_path, lines))
    assert g.time.tolist() == [_utc(2024, 3, 1, 23, 59, 58), _utc(2024, 3, 1, 23, 59, 59)]
    assert g.vel_n is None                            # velocity in 1 of 2 fixes: below 90 %, not used


def test_heights_without_geoid_separation_warn_once(tmp_path, caplog):
    lines = _epoch("100000.00", sep="") + _epoch("100001.00", sep="")
    with caplog.at_level(logging.WARNING, logger="sins"):
        g = read_receiver_log(_log(tmp_path, lines))
    assert g.height.tolist() == [545.4, 545.4]
    notes = [r.message for r in caplog.records if "geoid separation" in r.message]
    assert len(notes) == 1 and "above mean sea level" in notes[0]
    mixed = _epoch("100000.00", sep="") + _epoch("100001.00", sep="-20.0") + _epoch("100002.00", sep="")
    assert read_receiver_log(_log(tmp_path, mixed, "m.nmea")).height.tolist() == [525.4] * 3


def test_dop_accuracy_per_quality_and_skipped_epochs(tmp_path, caplog):
    lines = []
    for k, q in enumerate([4, 5, 2, 1, 0, 6]):
        lines += _epoch(f"1200{k:02d}.00", gst=False, q=q)
    lines.insert(1, _sentence("GNGSA,A,3,01,02,03,04,,,,,,,,,1.5,0.9,1.2,1"))     # VDOP 1.2 for the first epoch
    with caplog.at_level(logging.WARNING, logger="sins"):
        g = read_receiver_log(_log(tmp_path, lines))
    assert len(g) == 4
    h = 0.9 / math.sqrt(2.0)
    assert np.allclose(g.std_pos[0], [h * 0.02, h * 0.02, 1.2 * 0.02])           # RTK fixed, VDOP of GSA
    assert np.allclose(g.std_pos[1], [h * 0.5, h * 0.5, 2 * 0.9 * 0.5])          # RTK float, VDOP = 2 HDOP
    assert np.allclose(g.std_pos[2, 0], h * 1.0) and np.allclose(g.std_pos[3, 0], h * 3.0)
    msg = [r.message for r in caplog.records if "skipped" in r.message]
    assert len(msg) == 1 and "2 of 6 NMEA epochs" in msg[0] and "1 without a fix" in msg[0] \
        and "1 estimated" in msg[0]


def test_damaged_sentences_one_warning_with_lines(tmp_path, caplog):
    lines = _epoch("100000.00") + _epoch("100001.00")
    lines[2] = lines[2][:-2] + ("00" if lines[2][-2:] != "00" else "11")         # GST: bad checksum, line 3
    lines[5] = lines[5][:30]                                                      # GST cut short, line 6
    with caplog.at_level(logging.WARNING, logger="sins"):
        g = read_receiver_log(_log(tmp_path, lines))
    assert len(g) == 2 and np.allclose(g.std_pos[:, 0], 0.9 * 3.0 / math.sqrt(2.0))   # no GST: HDOP x UERE
    msg = [r.message for r in caplog.records if "damaged" in r.message]
    assert msg == [f"{tmp_path / 'log.nmea'}: skipped 2 damaged NMEA sentences: 1 with a bad checksum (the first "
                   f"at line 3), 1 truncated or garbled (the first at line 6)"]


def test_sentences_between_binary_data(tmp_path):
    rng = np.random.default_rng(5)
    text = _epoch("100000.00") + _epoch("100001.00") + _epoch("100002.00")
    plain = read_receiver_log(_log(tmp_path, text))
    blob = bytearray()
    for line in text:
        noise = rng.integers(0, 256, 300).astype(np.uint8)
        noise[::37] = 0x24                                 # '$' bytes in the binary data
        blob += noise.tobytes() + (line + "\r\n").encode()
    p = tmp_path / "mixed.ubx"
    p.write_bytes(bytes(blob))
    g = read_receiver_log(p)
    assert np.array_equal(g.time, plain.time) and np.array_equal(g.lat, plain.lat)
    assert np.array_equal(g.vel_n, plain.vel_n, equal_nan=True) and np.array_equal(g.std_pos, plain.std_pos)


def test_content_detection(tmp_path):
    p = _log(tmp_path, _epoch("100000.00"), "session.txt")
    assert is_receiver_log(p)
    c = tmp_path / "gnss.txt"
    c.write_text("time,lat,lon,height\n0,1,2,3\n")
    assert not is_receiver_log(c)


def test_no_fix_and_no_date_exit_2_nothing_written(tmp_path):
    p = _log(tmp_path, [_sentence("GPGGA,,,,,,0,00,99.99,,,,,,")] * 3 + _epoch("100000.00", q=0))
    r = CliRunner().invoke(main, ["convert", str(p), "-o", str(tmp_path / "g.csv")])
    assert r.exit_code == 2 and not (tmp_path / "g.csv").exists()
    assert r.output.strip().splitlines()[-1] == (f"sins: error: {p}: no fix in the log's 4 NMEA epochs (4 without a "
                                                 f"fix (GGA quality 0))")
    q = _log(tmp_path, _epoch("100000.00", rmc=False), "nodate.nmea")
    r = CliRunner().invoke(main, ["convert", str(q), "-o", str(tmp_path / "g.csv")])
    assert r.exit_code == 2 and "gnss.date" in r.output and not (tmp_path / "g.csv").exists()
    cfg = tmp_path / "c.yaml"
    cfg.write_text("gnss:\n  date: 2024-05-14\nimu:\n  time_system: gps\n")
    r = CliRunner().invoke(main, ["convert", str(q), "--config", str(cfg), "-o", str(tmp_path / "g.csv")])
    assert r.exit_code == 0, r.output
    back = read_gnss_csv(tmp_path / "g.csv")
    assert back.time.tolist() == [_utc(2024, 5, 14, 10, 0, 0) + 18.0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("gnss:\n  date: 14.05.2024\n")
    with pytest.raises(SinsError, match=r"key gnss\.date: expected a UTC date YYYY-MM-DD"):
        load_config(bad)


# ------------------------------------------------------------------------------------------------ NAV-PVT

T0 = _utc(2024, 5, 14, 10, 0, 0)


def _pvt(k, t_utc, **kw):
    """A pyubx2 NAV-PVT message at UTC ``t_utc`` (GPS time = UTC + 18 s in 2024)."""
    from pyubx2 import GET, UBXMessage
    gps = t_utc - GPS_EPOCH_UNIX + 18.0
    tm = np.datetime64(int(round(t_utc * 1000)), "ms").astype(object)
    f = dict(iTOW=int(round((gps % 604800) * 1000)), year=tm.year, month=tm.month, day=tm.day, hour=tm.hour,
             min=tm.minute, second=tm.second, nano=tm.microsecond * 1000, validDate=1, validTime=1, fullyResolved=1,
             fixType=3, gnssFixOk=1, carrSoln=0, numSV=20, lon=11.5 + 1e-6 * k, lat=48.1 + 2e-6 * k,
             height=500123 + k, hMSL=453000, hAcc=14 + k, vAcc=21, velN=1200 + k, velE=-300, velD=45, gSpeed=1237,
             sAcc=35, pDOP=1.3)
    f.update(kw)
    return UBXMessage("NAV", "NAV-PVT", GET, **f)


def _hp(t_utc, lat, lon, height_mm, lat_hp, lon_hp, h_hp):
    """A pyubx2 NAV-HPPOSLLH message: ``lat_hp``, ``lon_hp`` in 1e-9 deg, ``h_hp`` in 0.1 mm."""
    from pyubx2 import GET, UBXMessage
    gps = t_utc - GPS_EPOCH_UNIX + 18.0
    return UBXMessage("NAV", "NAV-HPPOSLLH", GET, iTOW=int(round((gps % 604800) * 1000)), lon=lon, lat=lat,
                      height=height_mm, hMSL=height_mm - 47000, _HPlon=lon_hp * 1e-9, _HPlat=lat_hp * 1e-9,
                      _HPheight=h_hp * 0.1, _HPhMSL=0.0, hAcc=12.3, vAcc=45.6)


def test_nav_pvt_as_pyubx2_writes_it(tmp_path, caplog):
    msgs = [_pvt(k, T0 + 0.1 * k) for k in range(10)]
    msgs[3] = _pvt(3, T0 + 0.3, fixType=0, gnssFixOk=0)                 # no fix
    msgs[4] = _pvt(4, T0 + 0.4, invalidLlh=1)                            # invalid position
    msgs[5] = _pvt(5, T0 + 0.5, validDate=0)                             # no date
    msgs[6] = _pvt(6, T0 + 0.6, carrSoln=2, diffSoln=1)                  # RTK fixed
    msgs[7] = _pvt(7, T0 + 0.7, fixType=1)                               # dead reckoning only
    p = tmp_path / "f9p.ubx"
    raw = b"".join(m.serialize() for m in msgs)
    bad = bytearray(_pvt(10, T0 + 1.0).serialize())
    bad[40] ^= 0xFF                                                       # a corrupt frame
    p.write_bytes(raw + bytes(bad) + _pvt(11, T0 + 1.1).serialize()[:50])  # ... and one cut by the end
    with caplog.at_level(logging.WARNING, logger="sins"):
        g = read_receiver_log(p)
    keep = [0, 1, 2, 6, 8, 9]
    assert len(g) == len(keep)
    for i, k in enumerate(keep):
        m = msgs[k]
        assert abs(g.time[i] - (T0 + 0.1 * k)) < 1e-6
        assert abs(g.lat[i] - m.lat) < 1e-12 and abs(g.lon[i] - m.lon) < 1e-12
        assert g.height[i] == m.height / 1000.0
        assert g.vel_n[i].tolist() == [m.velE / 1000.0, m.velN / 1000.0, -m.velD / 1000.0]
        assert g.std_pos[i].tolist() == [m.hAcc / 1000.0, m.hAcc / 1000.0, m.vAcc / 1000.0]
        assert g.std_vel[i].tolist() == [m.sAcc / 1000.0] * 3
    msg = " ".join(r.message for r in caplog.records)
    assert "damaged NAV-PVT frames (bad checksum or cut)" in msg and "2 damaged" in msg
    assert "fix type no fix" in msg and "fix type dead reckoning only" in msg and "invalidLlh set" in msg \
        and "no valid UTC date and time" in msg
    s = summary(np.frombuffer(p.read_bytes(), np.uint8))
    assert s["messages"] == 10 and s["usable"] == 6 and s["carrier_solution"] == {"none": 5, "fixed": 1}
    assert s["fix_types"] == {"no fix": 1, "dead reckoning only": 1, "3D": 8} and abs(s["rate_hz"] - 10.0) < 1e-4
    r = CliRunner().invoke(main, ["info", str(p)])
    assert r.exit_code == 0 and "fix types: 3D 8, dead reckoning only 1, no fix 1" in r.output.replace(
        "no fix 1, dead reckoning only 1, 3D 8", "3D 8, dead reckoning only 1, no fix 1")
    assert "carrier solution (usable epochs): none 5, fixed 1" in r.output and "10 Hz" in r.output


def test_hpposllh_gives_the_full_precision(tmp_path):
    from pyubx2 import UBXReader
    data = b""
    for k in range(3):
        t = T0 + k
        m = _pvt(k, t)
        data += m.serialize() + _hp(t, round(m.lat, 7), round(m.lon, 7), 500123 + k, 37 - k, -41 + k, 7 - k).serialize()
    p = tmp_path / "hp.ubx"
    p.write_bytes(data)
    g = read_receiver_log(p)
    with open(p, "rb") as f:                       # pyubx2's decoding: lat, lon, height with their HP parts
        hp = [m for _, m in UBXReader(f) if m.identity == "NAV-HPPOSLLH"]
    assert len(g) == 3 and [round((m.lat * 1e9) % 100) for m in hp] == [37, 36, 35]
    assert np.allclose(g.lat, [m.lat for m in hp], rtol=0, atol=1e-13)
    assert np.allclose(g.lon, [m.lon for m in hp], rtol=0, atol=1e-13)
    assert np.allclose(g.height, [m.height / 1e3 for m in hp], rtol=0, atol=1e-9)
    assert g.height[0] == 500.1237 and g.std_pos[0].tolist() == [0.0123, 0.0123, 0.0456]    # 0.1 mm units


def test_ubx_without_nav_pvt_names_gnss_raw_and_spp(tmp_path):
    from ubx_encode import frame
    p = tmp_path / "raw.ubx"
    p.write_bytes(frame(0x02, 0x15, struct.pack("<dHbBBB2x", 1000.0, 2300, 18, 0, 1, 1)))
    with pytest.raises(SinsError) as e:
        read_receiver_log(p)
    assert "--gnss-raw" in str(e.value) and "sins gnss spp" in str(e.value) and str(p) in str(e.value)


def _sim_log(n=40, rate=10.0, seed=2):
    rng = np.random.default_rng(seed)
    t = T0 + np.arange(n) / rate
    return GnssLog(t, 48.1 + rng.normal(0, 1e-4, n), -11.5 + rng.normal(0, 1e-4, n), 500 + rng.normal(0, 1, n),
                   vel_n=rng.normal(0, 8, (n, 3)), std_pos=np.tile([1.5, 1.5, 3.0], (n, 1)),
                   std_vel=np.tile([0.05] * 3, (n, 1)))


@pytest.mark.parametrize("system", ["utc", "gps"])
def test_writers_read_back_within_the_formats_resolution(tmp_path, system):
    """The simulator's NAV-PVT and NMEA writers: read back by our readers and by pyubx2 / pynmea2 (independent
    decoders) to the fixes within each field's rounding."""
    g = _sim_log()
    write_ubx_solutions(tmp_path / "s.ubx", g, to_gps(g.time, system))
    u = read_receiver_log(tmp_path / "s.ubx", system)
    assert np.abs(u.time - g.time).max() <= 5e-4                      # iTOW: 1 ms
    assert np.abs(u.lat - g.lat).max() <= 0.5e-9 and np.abs(u.lon - g.lon).max() <= 0.5e-9      # HPPOSLLH
    assert np.abs(u.height - g.height).max() <= 0.5e-4 and np.abs(u.vel_n - g.vel_n).max() <= 0.5e-3
    from pyubx2 import UBXReader
    with open(tmp_path / "s.ubx", "rb") as f:
        pv = [m for _, m in UBXReader(f) if m.identity == "NAV-PVT"]
    assert len(pv) == len(g) and all(abs(m.lat - a) <= 0.51e-7 for m, a in zip(pv, g.lat))     # NAV-PVT: 1e-7 deg
    write_nmea(tmp_path / "s.nmea", g, to_utc(g.time, system), geoid_separation=-30.0)
    m = read_receiver_log(tmp_path / "s.nmea", system)
    assert np.abs(m.time - g.time).max() <= 0.005                     # hhmmss.ss
    res = 1e-5 / 60.0                                                 # 1e-5 minutes of arc
    assert np.abs(m.lat - g.lat).max() <= res / 2 + 1e-15 and np.abs(m.lon - g.lon).max() <= res / 2 + 1e-15
    assert np.abs(m.height - g.height).max() <= 0.05 + 1e-9          # 0.1 m altitude (the separation exact)
    v = np.abs(m.vel_n[:, :2] - g.vel_n[:, :2]).max()
    assert v <= 0.0005 * 1852 / 3600 + 0.005 * math.pi / 180 * 20     # 0.001 kn, 0.01 deg at up to ~20 m/s
    lines = (tmp_path / "s.nmea").read_text().splitlines()
    gga = [pynmea2.parse(x, check=True) for x in lines if "GGA" in x]
    assert np.allclose([x.latitude for x in gga], m.lat, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------ horizontal velocity

def test_csv_horizontal_velocity_round_trip(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("time,lat,lon,height,vel_e,vel_n,std_vel_e,std_vel_n\n0,30,114,10,1.5,-2.0,0.1,0.2\n1,30,114,10,1,2,0.1,0.2\n")
    g = read_gnss_csv(p)
    assert g.vel_n[:, :2].tolist() == [[1.5, -2.0], [1.0, 2.0]] and np.isnan(g.vel_n[:, 2]).all()
    assert np.isnan(g.std_vel[:, 2]).all() and g.std_vel[0, :2].tolist() == [0.1, 0.2]
    write_gnss_csv(tmp_path / "back.csv", g)
    assert (tmp_path / "back.csv").read_text().splitlines()[0] == "time,lat,lon,height,vel_e,vel_n,std_vel_e,std_vel_n"
    q = tmp_path / "bad.csv"
    q.write_text("time,lat,lon,height,vel_e\n0,30,114,10,1.5\n")
    with pytest.raises(SinsError, match=r"has vel_e but not all of vel_e, vel_n, vel_u \(or vel_e, vel_n alone"):
        read_gnss_csv(q)


def test_ros_twist_with_unknown_vertical(tmp_path):
    from sinscli.io import ros
    n = 5
    t = 100.0 + np.arange(n)
    gnss = {"time": t, "lat": np.full(n, 30.0), "lon": np.full(n, 114.0), "height": np.full(n, 10.0)}
    vel = {"time": t, "vel": np.column_stack([np.ones(n), 2 * np.ones(n), np.full(n, np.nan)]),
           "std": np.column_stack([np.full(n, 0.1), np.full(n, 0.1), np.full(n, np.nan)])}
    ros.write_log(tmp_path / "g.bag", gnss=gnss, vel=vel)
    g = ros.read_gnss(tmp_path / "g.bag", vel_topic="/fix_velocity")
    assert np.allclose(g.vel_n[:, :2], [[1.0, 2.0]] * n) and np.isnan(g.vel_n[:, 2]).all()
    assert np.allclose(g.std_vel[:, :2], 0.1) and np.isnan(g.std_vel[:, 2]).all()


def test_receiver_log_in_the_wrong_time_system_names_imu_time_system(tmp_path):
    from sinscli.io.imu_csv import write_imu_rates_csv
    n = 2001
    t = T0 + np.arange(n) / 50.0                                  # 40 s: the spans overlap 18 s apart
    write_imu_rates_csv(tmp_path / "imu.csv", t, np.zeros((n, 3)), np.tile([0.0, 0.0, 9.79], (n, 1)))
    g = GnssLog(T0 + np.arange(41.0), np.full(41, 30.0), np.full(41, 114.0), np.full(41, 50.0))
    write_nmea(tmp_path / "g.nmea", g, g.time)                   # UTC, as the IMU
    (tmp_path / "init.yaml").write_text(f"time: {T0}\nlat: 30.0\nlon: 114.0\nheight: 50.0\nvel_e: 0\nvel_n: 0\n"
                                        f"vel_u: 0\nroll: 0\npitch: 0\nheading: 0\n")
    (tmp_path / "c.yaml").write_text("imu:\n  time_system: gps\n")
    r = CliRunner().invoke(main, ["navigate", str(tmp_path / "imu.csv"), "--gnss", str(tmp_path / "g.nmea"), "--init",
                                  str(tmp_path / "init.yaml"), "--config", str(tmp_path / "c.yaml"), "-o",
                                  str(tmp_path / "out.csv")])
    assert r.exit_code == 2 and not (tmp_path / "out.csv").exists()
    line = r.output.strip().splitlines()[-1]
    assert "18 s ahead" in line and line.endswith("imu.time_system: utc (now gps)")
