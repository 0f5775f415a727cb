"""RINEX readers: 3.x and 2.11, gzip and Hatanaka, and the bad inputs of issue 20 (one line each, file, line,
epoch; exit status 2 from the CLI; ephemerides with bad health or IODE mismatch skipped and counted)."""
from __future__ import annotations

import gzip
import logging
from pathlib import Path

import numpy as np
import pytest
from realdata import RINEX_STATIC
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.errors import SinsError
from sinscli.io.rinex import read_nav, read_obs

DATA = RINEX_STATIC
OBS = DATA / "slac1350.20o"
NAV = DATA / "brdc1350.20n"
pytestmark = pytest.mark.skipif(not OBS.is_file(), reason="tests/data/rinex_static not present")


def test_rinex3_values_against_the_text():
    """Spot values of the first epoch as written in the file."""
    obs = read_obs(OBS)
    assert len(obs) == 121 and obs.n_records == 975 + 1083 + 661
    r = int(np.nonzero((obs.sys == 0) & (obs.prn == 6))[0][0])
    t = obs.types[0]
    assert obs.values[r, t.index("C1C")] == 21994470.328
    assert obs.values[r, t.index("C5X")] == 21994480.176
    assert obs.values[r, t.index("S5X")] == 51.1
    assert obs.time[1] - obs.time[0] == 30.0


def test_gzip_and_hatanaka_read_the_same(tmp_path):
    import hatanaka
    ref = read_obs(OBS)
    (tmp_path / "a.20o.gz").write_bytes(gzip.compress(OBS.read_bytes()))
    crx = hatanaka.rnx2crx(OBS.read_bytes())
    (tmp_path / "a.20d").write_bytes(crx if isinstance(crx, bytes) else crx.encode())
    (tmp_path / "a.20d.gz").write_bytes(gzip.compress((tmp_path / "a.20d").read_bytes()))
    for name in ("a.20o.gz", "a.20d", "a.20d.gz"):
        o = read_obs(tmp_path / name)
        np.testing.assert_array_equal(o.values, ref.values)
        np.testing.assert_array_equal(o.time, ref.time)


def _rinex2(obs, path):
    """A mixed RINEX 2.11 file (C1, L1, S1 of GPS, GLONASS, Galileo; 20-25 satellites an epoch, so the satellite
    list continues on a second line) written here in the 2.11 layout, with an event record (flag 4) inside."""
    lines = [f"{2.11:9.2f}{'':11}{'OBSERVATION DATA':<20}{'M (MIXED)':<20}RINEX VERSION / TYPE",
             f"{'     3    C1    L1    S1':<60}# / TYPES OF OBSERV", f"{'':60}END OF HEADER"]
    from sinscli.gnss.timesys import calendar
    cols = {s: [obs.types[s].index(c) for c in codes] for s, codes in
            ((0, ("C1C", "L1C", "S1C")), (1, ("C1C", "L1C", "S1C")), (2, ("C1X", "L1X", "S1X")))}
    letters = "GRE"
    for e in range(len(obs)):
        r = list(range(obs.start[e], obs.start[e + 1]))
        y, mo, d, h, mi, s = calendar(obs.time[e])
        sats = "".join(f"{letters[obs.sys[i]]}{int(obs.prn[i]):02d}" for i in r)
        head = f" {y % 100:02d} {mo:2d} {d:2d} {h:2d} {mi:2d}{s:11.7f}  0{len(r):3d}"
        lines.append(head + sats[:36])
        for k in range(36, len(sats), 36):
            lines.append(" " * 32 + sats[k:k + 36])
        for i in r:
            lines.append("".join(f"{obs.values[i, jj]:14.3f}  " for jj in cols[int(obs.sys[i])]).rstrip())
        if e == 3:
            lines.append(f"{'':26}  4  2")
            lines += [f"{'an event record':<60}COMMENT", f"{'another':<60}COMMENT"]
    path.write_text("\n".join(lines) + "\n")


def test_rinex211_reads_like_the_rinex3(tmp_path):
    ref = read_obs(OBS)
    _rinex2(ref, tmp_path / "a.20o")
    o = read_obs(tmp_path / "a.20o")
    assert o.types[0] == ["C1C", "L1C", "S1C"] and o.types[2] == ["C1X", "L1X", "S1X"]
    assert np.diff(ref.start).max() > 12                    # continuation lines of the satellite list
    np.testing.assert_array_equal(o.prn, ref.prn)
    np.testing.assert_array_equal(o.sys, ref.sys)
    for s, code in ((0, "C1C"), (1, "C1C"), (2, "C1X")):
        m = ref.sys == s
        np.testing.assert_array_equal(o.values[m, 0], ref.values[m, ref.types[s].index(code)])
    np.testing.assert_array_equal(o.time, ref.time)


def test_rinex3_event_records_are_skipped(tmp_path):
    text = OBS.read_text()
    k = text.index("> 2020 05 14 22 00 30.0000000")
    p = tmp_path / "ev.20o"
    p.write_text(text[:k] + "> 2020 05 14 22 00 15.0000000  4  2\n" + f"{'event':<60}COMMENT\n"
                 + f"{'more':<60}COMMENT\n" + text[k:])
    a, b = read_obs(OBS), read_obs(p)
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(a.time, b.time)


def _corrupt(tmp_path, old, new, count=1):
    text = OBS.read_text()
    assert old in text
    p = tmp_path / "bad.20o"
    p.write_text(text.replace(old, new, count))
    return p


def _cli_error(path):
    r = CliRunner().invoke(main, ["gnss", "spp", str(path), "--nav", str(NAV), "-o", str(path.parent / "o.csv")])
    assert r.exit_code == 2, r.output
    assert not (path.parent / "o.csv").exists()
    assert "Traceback" not in r.output
    return r.output.strip().splitlines()[-1]


def test_impossible_satellite_count(tmp_path):
    p = _corrupt(tmp_path, "> 2020 05 14 22 00 30.0000000  0 23", "> 2020 05 14 22 00 30.0000000  0 29")
    msg = _cli_error(p)
    assert msg.startswith(f"sins: error: {p}: line ") and "impossible satellite count 29" in msg
    assert "2020-05-14 22:00:00.000 GPST" in msg      # the epoch before it


def test_pseudorange_out_of_range(tmp_path):
    p = _corrupt(tmp_path, "G12  20199070.203", "G12  40199070.203")
    msg = _cli_error(p)
    assert msg == (f"sins: error: {p}: line 28, column 4: epoch 2020-05-14 22:00:00.000 GPST, G12 C1C: "
                   f"pseudorange 40199070.203 m is outside 15,000-30,000 km")


def test_truncated_file(tmp_path):
    text = OBS.read_text()
    p = tmp_path / "cut.20o"
    p.write_text(text[:text.index("> 2020 05 14 22 01 00") + 300])
    msg = _cli_error(p)
    assert "truncated" in msg and "2020-05-14 22:00:30.000 GPST" in msg


def test_ephemeris_health_and_iode_skipped_and_counted(tmp_path, caplog):
    text = NAV.read_text().splitlines()
    # the first record (G02, lines 9-16): IODE 50 (line 10, field 1) against IODC 50 (line 15, field 4)
    text[9] = text[9].replace("0.500000000000D+02", "0.510000000000D+02", 1)
    p = tmp_path / "bad.20n"
    p.write_text("\n".join(text) + "\n")
    with caplog.at_level(logging.WARNING, logger="sins"):
        nav = read_nav(p)
    msgs = [r.getMessage() for r in caplog.records]
    assert any("IODE 51 does not match IODC 50" in m and "G02" in m and str(p) in m for m in msgs)
    assert any("skipped 16 ephemerides with a bad health flag" in m for m in msgs)
    assert nav.skipped["iode"][0] == 1 and nav.skipped["health"][0] == 16


def test_navigation_file_given_as_observations(tmp_path):
    with pytest.raises(SinsError, match="navigation file"):
        read_obs(NAV)
