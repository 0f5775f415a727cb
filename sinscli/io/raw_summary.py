"""`sins info` and `sins convert` for raw GNSS files (RINEX observation/navigation, UBX logs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..gnss.signals import SYS_CHARS, SYS_NAMES
from ..gnss.timesys import epoch_text
from .atomic import staged_dir
from .receiver import is_nmea, read_bytes
from .ubx_frames import has_message, is_ubx
from .ubx_solution import summary as pvt_summary


def raw_kind(path) -> str | None:
    """``'ubx'``, ``'nmea'``, ``'obs'``, ``'nav'`` or None."""
    from .rinex import is_rinex  # the RINEX/UBX readers (numba kernels, pyubx2) only for a raw GNSS log
    p = Path(path)
    if not p.is_file():
        return None
    if is_ubx(p):
        return "ubx"
    if is_nmea(p):
        return "nmea"
    return is_rinex(p)


def raw_summary(path) -> dict:
    """What a raw GNSS file holds: epochs, span, interval, satellites and signals per system, ephemerides; for a
    UBX log also the receiver's own solutions (NAV-PVT), for an NMEA log its sentences and fix qualities."""
    from .rinex import read_nav, read_obs  # the RINEX/UBX readers (numba kernels, pyubx2) only for a raw GNSS log
    kind = raw_kind(path)
    nav = obs = None
    solutions = None
    if kind == "nmea":
        from .nmea import summary as nmea_summary     # the NMEA kernels only for an NMEA log
        _, buf = read_bytes(path, "NMEA log")
        return {"path": str(path), "format": "NMEA 0183 log", "nmea": nmea_summary(buf)}
    if kind == "ubx":
        from .ubx import read_ubx  # the RINEX/UBX readers (numba kernels, pyubx2) only for a raw GNSS log
        _, buf = read_bytes(path, "UBX log")
        solutions = pvt_summary(buf)
        if has_message(buf, 0x02, 0x15) or solutions is None:
            obs, nav = read_ubx(path)
        fmt = "u-blox UBX log (" + ", ".join(x for x, have in (("NAV-PVT", solutions is not None),
                                                                ("RXM-RAWX, RXM-SFRBX", obs is not None)) if have) + ")"
    elif kind == "obs":
        obs = read_obs(path)
        fmt = f"RINEX {obs.header.get('version', 3):g} observations"
    elif kind == "nav":
        nav = read_nav(path)
        obs = None
        fmt = "RINEX navigation"
    else:
        raise SinsError(f"{path}: not a RINEX or UBX file")
    s = {"path": str(path), "format": fmt}
    if solutions is not None:
        s["solutions"] = solutions
    if obs is not None:
        dt = np.diff(obs.time)
        s.update(epochs=len(obs), start=epoch_text(obs.time[0]) if len(obs) else None,
                 end=epoch_text(obs.time[-1]) if len(obs) else None,
                 duration=float(obs.time[-1] - obs.time[0]) if len(obs) else 0.0,
                 interval=float(np.median(dt)) if dt.size else None,
                 gaps=int((dt > 1.5 * np.median(dt)).sum()) if dt.size else 0, systems={})
        for sy, codes in sorted(obs.types.items()):
            mine = obs.sys == sy
            if not mine.any():
                continue
            s["systems"][SYS_NAMES[sy]] = {
                "satellites": int(np.unique(obs.prn[mine]).size),
                "per_epoch": float(mine.sum() / max(len(obs), 1)), "signals": codes,
                "phase": _phase_summary(obs, sy, codes, mine)}
    if nav is not None:
        s["ephemerides"] = {SYS_NAMES[int(k)]: int((nav.eph[:, 0] == k).sum()) for k in np.unique(nav.eph[:, 0])}
        s["skipped"] = {k: v[0] for k, v in nav.skipped.items()}
        s["klobuchar"] = nav.ion_gps is not None
    return s


def _phase_summary(obs, sy, codes, mine) -> dict:
    """Per carrier-phase signal of system ``sy``: the share of its satellite-epochs with a valid phase, the phases
    the receiver flagged as a loss of lock (LLI bit 0: a slip) and as of unresolved half cycle (LLI bit 1)."""
    out = {}
    n = int(mine.sum())
    for j, c in enumerate(codes):
        if c[0] != "L":
            continue
        ok = mine & ~np.isnan(obs.values[:, j])
        lli = obs.lli[ok, j]
        out[c] = {"share": float(ok.sum() / max(n, 1)), "slips": int(np.count_nonzero(lli & 1)),
                  "half_cycle": int(np.count_nonzero(lli & 2))}
    return out


def _counts(d: dict) -> str:
    return ", ".join(f"{k} {v:,}" for k, v in d.items()) or "none"


def format_raw_summary(s: dict) -> str:
    lines = [f"{s['path']}: {s['format']}"]
    if s.get("nmea") is not None:
        m = s["nmea"]
        lines.append(f"sentences: {_counts(m['sentences'])}; {m['other_sentences']:,} of other types; damaged: "
                     f"{m['bad_checksum']:,} with a bad checksum, {m['garbled']:,} truncated or garbled")
        lines.append(f"GGA epochs per quality: {_counts(m['qualities'])}; rate "
                     f"{'-' if m['rate_hz'] is None else format(m['rate_hz'], '.3g')} Hz; first RMC date "
                     f"{m['first_date'] or '- (none: give gnss.date)'}; geoid separation "
                     f"{'given' if m['geoid_separation'] else 'absent (heights above mean sea level)'}")
        lines.append("use: sins navigate IMU --gnss LOG, sins convert LOG -o gnss.csv")
    elif "nmea" in s:
        lines.append("no NMEA sentence")
    if "solutions" in s:
        m = s["solutions"]
        span = (f" from {epoch_text(m['start_gps'])} to {epoch_text(m['end_gps'])}" if m["start_gps"] is not None
                else "")
        rate = "-" if m["rate_hz"] is None else format(m["rate_hz"], ".3g")
        lines.append(f"receiver solutions (NAV-PVT): {m['messages']:,} epochs, {m['usable']:,} usable, {rate} Hz"
                     f"{span}")
        lines.append(f"  fix types: {_counts(m['fix_types'])}")
        lines.append(f"  carrier solution (usable epochs): {_counts(m['carrier_solution'])}; differential "
                     f"{m['differential']:,}; NAV-HPPOSLLH {m['hpposllh']:,}"
                     + (f"; {m['damaged']:,} damaged NAV-PVT frames" if m["damaged"] else ""))
        lines.append("  use: sins navigate IMU --gnss LOG (these solutions), sins convert LOG --solution -o gnss.csv")
    if "epochs" in s:
        lines.append(f"{s['epochs']} epochs from {s['start']} to {s['end']} ({s['duration']:.1f} s), interval "
                     f"{s['interval'] if s['interval'] is not None else '-'} s, {s['gaps']} gaps")
        for name, d in s["systems"].items():
            lines.append(f"  {name}: {d['satellites']} satellites, {d['per_epoch']:.1f} per epoch; "
                         f"{' '.join(d['signals'])}")
            if d.get("phase"):
                lines.append("    carrier phase (valid share of satellite-epochs, slips flagged by the receiver, "
                             "half cycle unresolved): " + "; ".join(
                                 f"{c} {p['share'] * 100:.1f} %, {p['slips']} slips, {p['half_cycle']} half"
                                 for c, p in d["phase"].items()))
    if "ephemerides" in s:
        eph = ", ".join(f"{k} {v}" for k, v in s["ephemerides"].items()) or "none decoded"
        lines.append(f"ephemerides: {eph}" + ("; Klobuchar coefficients" if s.get("klobuchar") else ""))
        for k, v in s.get("skipped", {}).items():
            lines.append(f"  skipped ({k}): {v}")
    if "RXM" in s["format"]:
        lines.append("messages used: RXM-RAWX (observations), RXM-SFRBX (GPS/QZSS LNAV, Galileo I/NAV, BeiDou D1/D2)")
    return "\n".join(lines)


def convert_ubx(log_path, outdir) -> list[Path]:
    """A UBX log -> DIR/obs.rnx and DIR/nav.rnx (RINEX 3.04), each read back and compared before it is kept."""
    # the RINEX/UBX readers (numba kernels, pyubx2) only for a raw GNSS log
    from .rinex import read_nav, read_obs, write_nav, write_obs
    from .ubx import read_ubx  # the RINEX/UBX readers (numba kernels, pyubx2) only for a raw GNSS log
    obs, nav = read_ubx(log_path)
    with staged_dir(outdir) as tmp:
        write_obs(tmp / "obs.rnx", obs)
        back = read_obs(tmp / "obs.rnx")
        have = ~np.isnan(obs.values)        # the flags travel with a value (a blank field has none)
        if back.values.shape != obs.values.shape or not np.allclose(back.values, obs.values, atol=6e-4, rtol=0,
                                                                     equal_nan=True) \
                or not np.array_equal(back.lli[have], obs.lli[have]) \
                or (obs.ssi is not None and not np.array_equal(back.ssi[have], obs.ssi[have])):
            raise SinsError(f"{outdir / 'obs.rnx'}: internal consistency check: the RINEX file does not read back "
                            f"to the observations of {log_path}; nothing written")
        if len(nav):
            write_nav(tmp / "nav.rnx", nav)
            back_nav = read_nav(tmp / "nav.rnx")
            if back_nav.eph.shape != nav.eph.shape or not np.allclose(back_nav.eph, nav.eph, rtol=1e-11,
                                                                       atol=1e-20):
                raise SinsError(f"{outdir / 'nav.rnx'}: internal consistency check: the RINEX file does not read "
                                f"back to the ephemerides of {log_path}; nothing written")
    out = [outdir / "obs.rnx"] + ([outdir / "nav.rnx"] if len(nav) else [])
    return out, obs, nav


__all__ = ["raw_kind", "raw_summary", "format_raw_summary", "convert_ubx", "SYS_CHARS"]
