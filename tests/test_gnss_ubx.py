"""UBX logs: RXM-RAWX and RXM-SFRBX (GPS LNAV) decoded into the RINEX tables; truncated messages skipped and
counted; `sins gnss spp` and `sins convert` on a UBX log (RINEX 3.04 written and read back)."""
from __future__ import annotations

import logging

import numpy as np
import pytest
from click.testing import CliRunner

from sinscli.cli import main
from sinscli.gnss import ephemeris as E
from sinscli.gnss import spp as S
from sinscli.gnss.pipeline import run_spp
from sinscli.io.rinex import read_nav, read_obs
from sinscli.io.ubx import read_ubx
from sinscli.sim.raw_gnss import static_receiver

from ubx_encode import bds_frames, inav_words, lnav_ion_page, lnav_subframes, rawx, sfrbx_bds, sfrbx_inav, sfrbx_lnav


def _log(sim, every_subframes=30):
    obs, nav = sim.obs, sim.nav
    c1c, l1c, d1c, s1c = (obs.types[0].index(c) for c in ("C1C", "L1C", "D1C", "S1C"))
    out = []
    for e in range(len(obs)):
        r = np.arange(obs.start[e], obs.start[e + 1])
        if e % every_subframes == 0:
            t = obs.time[e]
            for prn in sorted(set(obs.prn[r].tolist())):
                rows = nav.eph[(nav.eph[:, E.PRN] == prn)]
                row = rows[np.argmin(np.abs(rows[:, E.TOE] - t))]
                for sub in lnav_subframes(row):
                    out.append(sfrbx_lnav(prn, sub))
            out.append(sfrbx_lnav(int(obs.prn[r[0]]), lnav_ion_page(nav.ion_gps)))
        sats = [(0, int(obs.prn[i]), 0) for i in r]
        out.append(rawx(obs.time[e], sats, obs.values[r, c1c], obs.values[r, l1c], obs.values[r, d1c],
                        obs.values[r, s1c]))
    return out


@pytest.fixture(scope="module")
def sim():
    return static_receiver(37.4, -122.2, 30.0, 120, {"systems": "G", "clock_bias": 1e-4}, seed=8)


def test_ubx_decodes_observations_and_lnav(sim, tmp_path):
    """Every RAWX measurement comes back (pseudorange, carrier, Doppler in the RAWX formats), every LNAV
    ephemeris to its ICD quantization, and the fixes equal those from the tables the log was made of."""
    p = tmp_path / "log.ubx"
    p.write_bytes(b"".join(_log(sim)))
    obs, nav = read_ubx(p)
    assert len(obs) == len(sim.obs)
    np.testing.assert_array_equal(obs.prn, sim.obs.prn)
    np.testing.assert_allclose(obs.values[:, 0], sim.obs.values[:, 0], rtol=0, atol=1e-6)      # R8
    np.testing.assert_allclose(obs.values[:, 2], sim.obs.values[:, 2], rtol=1e-6, atol=1e-3)  # R4
    sel = np.isin(sim.nav.eph[:, E.TOE], nav.eph[:, E.TOE])
    ref = {(int(r[E.PRN]), r[E.TOE]): r for r in sim.nav.eph[sel]}
    assert len(nav) >= 8
    for row in nav.eph:
        r0 = ref[(int(row[E.PRN]), row[E.TOE])]
        assert abs(row[E.SQRTA] - r0[E.SQRTA]) <= 2.0 ** -19
        assert abs(row[E.M0] - r0[E.M0]) <= np.pi * 2.0 ** -31
        assert abs(row[E.AF0] - r0[E.AF0]) <= 2.0 ** -31
        assert row[E.IODE] == r0[E.IODE] and row[E.TOC] == r0[E.TOC]
    # the same weights on both sides (the LNAV URA index and the integer C/N0 of RAWX change them)
    opts = S.spp_options(iono="klobuchar", elev_mask_deg=5.0, use_ura=False, cn0_ref=0.0)
    np.testing.assert_allclose(nav.ion_gps, sim.nav.ion_gps, rtol=1e-3)   # RINEX prints 4 digits
    a = run_spp(obs, nav, systems=[0], options=opts)
    b = run_spp(sim.obs, sim.nav, systems=[0], options=opts)
    ok = a.fix & b.fix
    assert ok.mean() > 0.95
    assert np.abs(a.pos[ok] - b.pos[ok]).max() < 0.05        # the ICD quantization of the orbit: cm


def test_truncated_and_corrupt_messages_are_skipped_and_counted(sim, tmp_path, caplog):
    """A RAWX message cut short in the middle of the log, and one with a flipped byte: skipped, counted in one
    warning line naming the file and the epoch after which they came; the rest of the log is read."""
    msgs = _log(sim)
    idx = [i for i, m in enumerate(msgs) if m[3] == 0x15]
    cut = idx[50]
    bad = bytearray(msgs[idx[70]])
    bad[30] ^= 0xFF
    msgs[idx[70]] = bytes(bad)
    data = b"".join(msgs[:cut]) + msgs[cut][:40] + b"".join(msgs[cut + 1:])
    p = tmp_path / "cut.ubx"
    p.write_bytes(data)
    with caplog.at_level(logging.WARNING, logger="sins"):
        obs, nav = read_ubx(p)
    text = " ".join(r.getMessage() for r in caplog.records)
    assert "skipped" in text and str(p) in text and "GPST" in text
    assert len(obs) >= len(sim.obs) - 4 and len(obs) < len(sim.obs)


def test_spp_and_convert_cli_on_ubx(sim, tmp_path):
    """`sins gnss spp LOG.ubx` without --nav (its own SFRBX), `sins convert LOG.ubx -o DIR` writes RINEX 3.04
    obs/nav that read back to the same tables, and `sins info` describes it."""
    p = tmp_path / "log.ubx"
    p.write_bytes(b"".join(_log(sim)))
    out = tmp_path / "gnss.csv"
    r = CliRunner().invoke(main, ["gnss", "spp", str(p), "-o", str(out), "--elev-mask", "5", "-q"])
    assert r.exit_code == 0, r.output
    assert out.read_text().count("\n") >= 110
    d = tmp_path / "rnx"
    r = CliRunner().invoke(main, ["convert", str(p), "-o", str(d)])
    assert r.exit_code == 0, r.output
    obs2 = read_obs(d / "obs.rnx")
    nav2 = read_nav(d / "nav.rnx")
    obs1, nav1 = read_ubx(p)
    np.testing.assert_allclose(obs2.values, obs1.values, atol=6e-4, rtol=0)
    np.testing.assert_allclose(nav2.eph, nav1.eph, rtol=1e-11, atol=1e-20)
    r = CliRunner().invoke(main, ["info", str(p)])
    assert r.exit_code == 0, r.output
    assert "RXM-RAWX" in r.output and "GPS" in r.output


def test_galileo_inav_words_decode_to_the_ephemeris(sim, tmp_path):
    """Galileo I/NAV word types 1-5 (E1-B page pairs with their CRC-24Q) decode to the ephemeris to the ICD's
    quantization, and the satellite positions agree to a few mm; a page with a bad CRC is skipped and counted."""
    from sinscli.gnss.orbits import sat_state
    gps = sim.nav.eph[0].copy()
    row = gps.copy()
    row[E.SYS], row[E.PRN], row[E.IODE], row[E.TGD1], row[E.TGD2] = 2, 11, 77, 3.2e-9, 3.6e-9
    row[E.TOC] = row[E.TOE]
    msgs = [rawx(row[E.TOE] + 10.0, [], [], [], [], [])]
    msgs += [sfrbx_inav(11, w) for w in inav_words(row)]
    bad = bytearray(sfrbx_inav(11, inav_words(row)[0]))
    bad[20] ^= 0x10
    msgs.insert(1, bytes(bad[:-2]) + bytes(_checksum(bytes(bad[2:-2]))))
    p = tmp_path / "gal.ubx"
    p.write_bytes(b"".join(msgs))
    obs, nav = read_ubx(p)
    assert len(nav) == 1 and nav.skipped["checksum"][0] == 1
    got = nav.eph[0]
    assert got[E.SYS] == 2 and got[E.PRN] == 11 and got[E.IODE] == 77 and got[E.TOE] == row[E.TOE]
    assert abs(got[E.TGD2] - row[E.TGD2]) <= 2.0 ** -32 and abs(got[E.AF0] - row[E.AF0]) <= 2.0 ** -34
    for dt in (0.0, 1800.0, -1800.0):
        a = np.array(sat_state(nav.eph, 0, row[E.TOE] + dt)[:3])
        g = row.copy()
        g[E.SYS] = 2
        b = np.array(sat_state(g[None, :], 0, row[E.TOE] + dt)[:3])
        assert np.linalg.norm(a - b) < 0.05


def _checksum(body: bytes):
    a = b = 0
    for x in body:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return [a, b]


@pytest.mark.parametrize("prn", [21, 3])      # a MEO satellite (D1 subframes 1-3) and a GEO one (D2 pages 1-10)
def test_beidou_d1_d2_words_decode_to_the_ephemeris(sim, tmp_path, prn):
    """BeiDou D1 (MEO/IGSO) and D2 (GEO) words decode to the ephemeris to the ICD's quantization; BDT toe
    becomes GPST (+14 s); the satellite positions agree to a few cm."""
    from sinscli.gnss.orbits import sat_state
    row = sim.nav.eph[0].copy()
    row[E.SYS], row[E.PRN], row[E.IODE], row[E.IODC] = 3, prn, 17, 9
    row[E.TGD1], row[E.TGD2] = 2.5e-9, -1.1e-9
    row[E.TOE] = round((row[E.TOE] - 14.0) / 8.0) * 8.0 + 14.0
    row[E.TOC] = row[E.TOE]
    t = row[E.TOE] + 30.0
    sow0 = int((t - 14.0) % 604800.0) // 6 * 6
    msgs = [rawx(t, [], [], [], [], [])]
    msgs += [sfrbx_bds(prn, w) for w in bds_frames(row, sow0)]
    p = tmp_path / "bds.ubx"
    p.write_bytes(b"".join(msgs))
    obs, nav = read_ubx(p)
    assert len(nav) == 1
    got = nav.eph[0]
    assert got[E.SYS] == 3 and got[E.PRN] == prn and got[E.TOE] == row[E.TOE] and got[E.IODE] == 17
    assert abs(got[E.TGD1] - row[E.TGD1]) < 0.06e-9 and abs(got[E.TGD2] - row[E.TGD2]) < 0.06e-9
    assert abs(got[E.AF1] - row[E.AF1]) <= 2.0 ** -50 and abs(got[E.ECC] - row[E.ECC]) <= 2.0 ** -33
    g = row.copy()
    for dt in (0.0, 1800.0):
        a = np.array(sat_state(nav.eph, 0, row[E.TOE] + dt)[:3])
        b = np.array(sat_state(g[None, :], 0, row[E.TOE] + dt)[:3])
        assert np.linalg.norm(a - b) < 0.05
