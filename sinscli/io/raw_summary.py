"""`sins info` and `sins convert` for raw GNSS files (RINEX observation/navigation, UBX logs)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SinsError
from ..gnss.signals import SYS_CHARS, SYS_NAMES
from ..gnss.timesys import epoch_text


def raw_kind(path) -> str | None:
    """``'ubx'``, ``'obs'``, ``'nav'`` or None."""
    from .rinex import is_rinex
    from .ubx import is_ubx
    p = Path(path)
    if not p.is_file():
        return None
    if is_ubx(p):
        return "ubx"
    return is_rinex(p)


def raw_summary(path) -> dict:
    """What a raw GNSS file holds: epochs, span, interval, satellites and signals per system, ephemerides."""
    from .rinex import read_nav, read_obs
    kind = raw_kind(path)
    nav = None
    if kind == "ubx":
        from .ubx import read_ubx
        obs, nav = read_ubx(path)
        fmt = "u-blox UBX log (RXM-RAWX, RXM-SFRBX)"
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
                "per_epoch": float(mine.sum() / max(len(obs), 1)), "signals": codes}
    if nav is not None:
        s["ephemerides"] = {SYS_NAMES[int(k)]: int((nav.eph[:, 0] == k).sum()) for k in np.unique(nav.eph[:, 0])}
        s["skipped"] = {k: v[0] for k, v in nav.skipped.items()}
        s["klobuchar"] = nav.ion_gps is not None
    return s


def format_raw_summary(s: dict) -> str:
    lines = [f"{s['path']}: {s['format']}"]
    if "epochs" in s:
        lines.append(f"{s['epochs']} epochs from {s['start']} to {s['end']} ({s['duration']:.1f} s), interval "
                     f"{s['interval'] if s['interval'] is not None else '-'} s, {s['gaps']} gaps")
        for name, d in s["systems"].items():
            lines.append(f"  {name}: {d['satellites']} satellites, {d['per_epoch']:.1f} per epoch; "
                         f"{' '.join(d['signals'])}")
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
    from .atomic import staged_dir
    from .rinex import read_nav, read_obs, write_nav, write_obs
    from .ubx import read_ubx
    obs, nav = read_ubx(log_path)
    with staged_dir(outdir) as tmp:
        write_obs(tmp / "obs.rnx", obs)
        back = read_obs(tmp / "obs.rnx")
        if back.values.shape != obs.values.shape or not np.allclose(back.values, obs.values, atol=6e-4, rtol=0,
                                                                     equal_nan=True):
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
