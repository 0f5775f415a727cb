"""What a fused run did, for a person: the summary lines and the checks after the run (no I/O).

:class:`FusionSummary` is filled by :meth:`sinscli.fusion.pipeline.Fusion.summary`; :meth:`lines` gives
several short lines (times relative to the log's start, with the ISO-8601 instant for absolute time
bases).  The checks:

* :func:`fix_residuals`: the fused antenna track against the fixes, split into fixes outside outages
  and the first fix after each outage (where the dead reckoning meets the GNSS again);
* :func:`heading_course_check`: the heading against the GNSS course on straight 10-s segments at speed,
  the mismatch in sigmas and the yaw offset it implies (a wrong mounting yaw shows here);
* :func:`ground_vehicle_hint`: whether a log without ``--vehicle`` looks like a ground vehicle's.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field

import numpy as np

from ..nav.earth import dlon, local_en, radii_py
from ..types import GnssLog, Trajectory
from ..units import DEG

UNIX_MIN, UNIX_MAX = 1.0e8, 4.0e9         # s: an absolute epoch (1973 .. 2096 in UNIX time)
WEEK = 604800.0


def clock(t: float, t0: float) -> str:
    """``+123.4 s`` after the log's start ``t0``, with the ISO-8601 instant when ``t`` is on an absolute
    base (UNIX seconds: UTC) or a GPS week (day and time of the week, GPST)."""
    rel = f"+{t - t0:.1f} s"
    if UNIX_MIN <= abs(t) < UNIX_MAX:
        iso = _dt.datetime.fromtimestamp(t, _dt.timezone.utc).isoformat(timespec="milliseconds")
        return f"{rel} ({iso.replace('+00:00', 'Z')})"
    if t0 > 1000.0 and 0.0 <= t < WEEK and t > t0:
        d, s = divmod(t, 86400.0)
        h, s = divmod(s, 3600.0)
        m, s = divmod(s, 60.0)
        return f"{rel} (GPST week day {int(d)} {int(h):02d}:{int(m):02d}:{s:06.3f})"
    return rel


def outages(time: np.ndarray, factor: float) -> list:
    """GNSS gaps longer than ``factor`` nominal (median) intervals: ``(start, length)``."""
    if len(time) < 3:
        return []
    d = np.diff(time)
    nominal = float(np.median(d))
    k = np.nonzero(d > factor * nominal)[0]
    return [(float(time[i]), float(d[i])) for i in k]


def exit_fixes(time: np.ndarray, factor: float) -> np.ndarray:
    """Boolean mask of the fixes that end an outage (the first fix after a gap of :func:`outages`)."""
    mask = np.zeros(len(time), dtype=bool)
    if len(time) >= 3:
        d = np.diff(time)
        mask[1:] = d > factor * float(np.median(d))
    return mask


def standstill_intervals(rec, window: float) -> list:
    """Intervals where the filter applied ZUPT/ZARU (detected at rest and slow enough): ``(start, end)``."""
    t = np.unique(rec["time"][(rec["type"] == "zupt") | (rec["type"] == "zaru")])
    out = []
    for x in t:
        if out and x - out[-1][1] <= 1.5 * window:
            out[-1][1] = float(x)
        else:
            out.append([float(x) - window, float(x)])
    return [tuple(iv) for iv in out]


def antenna_offsets(traj: Trajectory, gnss: GnssLog, lever, sel) -> np.ndarray:
    """``(n, 3)`` ENU offsets (m) of the fused antenna minus the fixes ``sel`` (inside the trajectory's span),
    longitudes differenced modulo 360 degrees."""
    t = gnss.time[sel]
    lat = np.interp(t, traj.time, traj.lat)
    lon0 = traj.lon[0]
    lon = lon0 + np.interp(t, traj.time, np.unwrap(traj.lon - lon0))
    h = np.interp(t, traj.time, traj.height)
    k = np.clip(np.searchsorted(traj.time, t), 0, len(traj) - 1)
    l_n = traj.Cbn[k] @ np.asarray(lever, dtype=float)
    rm, rn = radii_py(np.sin(lat))
    de = dlon(lon, np.radians(gnss.lon[sel])) * (rn + h) * np.cos(lat) + l_n[:, 0]
    dn = (lat - np.radians(gnss.lat[sel])) * (rm + h) + l_n[:, 1]
    du = h - gnss.height[sel] + l_n[:, 2]
    return np.column_stack([de, dn, du])


@dataclass
class Residuals:
    """RMS of the fused antenna track minus the fixes (m)."""
    h: float = math.nan                 # horizontal, fixes outside outages
    u: float = math.nan                 # vertical, fixes outside outages
    exit_h: float = math.nan            # horizontal, the first fix after each outage
    exit_max: float = math.nan
    n: int = 0
    n_exit: int = 0


def fix_residuals(traj: Trajectory, gnss: GnssLog, lever, inside, factor: float) -> Residuals:
    """:class:`Residuals` at the fixes ``inside`` the run (``factor``: the outage definition)."""
    out = Residuals()
    if len(traj) < 2 or not inside.any():
        return out
    sel = inside & (gnss.time >= traj.time[0]) & (gnss.time <= traj.time[-1])
    if not sel.any():
        return out
    ex = exit_fixes(gnss.time, factor)[sel]
    d = antenna_offsets(traj, gnss, lever, sel)
    hz = np.hypot(d[:, 0], d[:, 1])
    if (~ex).any():
        out.h = float(np.sqrt(np.mean(hz[~ex] ** 2)))
        out.u = float(np.sqrt(np.mean(d[~ex, 2] ** 2)))
    if ex.any():
        out.exit_h = float(np.sqrt(np.mean(hz[ex] ** 2)))
        out.exit_max = float(hz[ex].max())
    out.n, out.n_exit = int((~ex).sum()), int(ex.sum())
    return out


@dataclass
class LeverCheck:
    """The lever arm a diagnosis pass estimated (body axes, m), the configured one minus it, and its 1-sigma."""
    estimate: np.ndarray            # (3,)
    error: np.ndarray               # (3,) configured minus estimated
    sigma: np.ndarray               # (3,) (inf where the motion did not observe the axis)

    @property
    def contradicted(self) -> np.ndarray:
        """Per axis: the configured value beyond 4 sigma and :data:`LEVER_MIN` of the estimate."""
        return (np.abs(self.error) > 4.0 * self.sigma) & (np.abs(self.error) > LEVER_MIN)


LEVER_MIN = 0.05            # m: a lever arm error under this is not worth a warning


@dataclass
class HeadingCheck:
    """The heading against the GNSS course on straight segments at speed."""
    segments: int = 0
    median_offset: float = math.nan     # deg, heading minus course (wrapped)
    beyond_3sigma: float = 0.0          # fraction of segments whose offset exceeds 3 sigma
    median_sigma: float = math.nan      # deg, the claimed heading sigma there

    @property
    def mismatch(self) -> bool:
        return self.segments >= 3 and self.beyond_3sigma > 0.5


def forward_heading(traj: Trajectory, fwd: int) -> np.ndarray:
    """Azimuth (rad, clockwise from north) of the body's forward axis ``fwd`` (0 x, 1 y)."""
    return np.arctan2(traj.Cbn[:, 0, fwd], traj.Cbn[:, 1, fwd])


def heading_course_check(traj: Trajectory, gnss: GnssLog, fwd: int, heading_std_deg=None, min_speed: float = 1.0,
                         span: float = 10.0, max_turn_deg: float = 3.0, course_floor_deg: float = 1.0) -> HeadingCheck:
    """Heading minus the GNSS course on consecutive ``span``-s segments where the vehicle goes straight
    (the course, from the fixes' displacement, turns by less than ``max_turn_deg`` between the segment's
    halves) at more than ``min_speed``.  Each segment's offset is compared with 3 sigma of the claimed
    heading sigma and the course's own (fix sigmas over the displacement, plus ``course_floor_deg``)."""
    out = HeadingCheck()
    if len(gnss) < 5 or len(traj) < 2:
        return out
    t = gnss.time
    e, n = local_en(gnss.lat, gnss.lon, gnss.height)
    sp = gnss.position_sigma([1.5, 1.5, 3.0])
    sh = np.hypot(sp[:, 0], sp[:, 1]) / math.sqrt(2.0)
    head = forward_heading(traj, fwd)
    offsets, sigmas = [], []
    a = float(max(t[0], traj.time[0]))
    while a + span <= min(t[-1], traj.time[-1]):
        i, j = int(np.searchsorted(t, a)), int(np.searchsorted(t, a + span, side="right")) - 1
        a += span
        if j - i < 4:
            continue
        k = (i + j) // 2
        d1 = math.hypot(e[k] - e[i], n[k] - n[i])
        d2 = math.hypot(e[j] - e[k], n[j] - n[k])
        d = math.hypot(e[j] - e[i], n[j] - n[i])
        if d / (t[j] - t[i]) < min_speed or d1 <= 0 or d2 <= 0:
            continue
        c1 = math.atan2(e[k] - e[i], n[k] - n[i])
        c2 = math.atan2(e[j] - e[k], n[j] - n[k])
        if abs(math.remainder(c1 - c2, 2 * math.pi)) > max_turn_deg * DEG:
            continue
        course = math.atan2(e[j] - e[i], n[j] - n[i])
        m = (traj.time >= t[i]) & (traj.time <= t[j])
        if not m.any():
            continue
        hs = head[m]
        h_mean = math.atan2(np.mean(np.sin(hs)), np.mean(np.cos(hs)))
        off = math.remainder(h_mean - course, 2 * math.pi)
        csig = math.atan2(math.hypot(sh[i], sh[j]), d) + course_floor_deg * DEG
        hsig = float(np.median(heading_std_deg[m])) * DEG if heading_std_deg is not None else 0.0
        offsets.append(off)
        sigmas.append(math.hypot(csig, hsig))
    if offsets:
        off = np.array(offsets)
        sig = np.array(sigmas)
        out.segments = len(off)
        out.median_offset = float(np.degrees(np.median(off)))
        out.beyond_3sigma = float(np.mean(np.abs(off) > 3.0 * sig))
        out.median_sigma = float(np.degrees(np.median(sig)))
    return out


def ground_vehicle_hint(gnss: GnssLog) -> str | None:
    """A suggestion of ``--vehicle`` for a log fused without one that looks like a ground vehicle's: its
    height stays within a few metres of a smooth profile while it travels, at road or walking speeds."""
    if len(gnss) < 10:
        return None
    t = gnss.time
    e, n = local_en(gnss.lat, gnss.lon, gnss.height)
    dist = float(np.sum(np.hypot(np.diff(e), np.diff(n))))
    if dist < 20.0:
        return None
    speed = dist / max(float(t[-1] - t[0]), 1e-9)
    climb = float(np.max(gnss.height) - np.min(gnss.height))
    if speed > 45.0 or climb > 0.2 * dist + 30.0:
        return None
    if speed < 2.0:     # walking speed: a walker or a small robot, the log cannot tell which
        which = ("--vehicle robot (NHC, ZUPT/ZARU at rest) or --vehicle pedestrian (ZUPT at true rest, "
                 "no NHC) adds the constraints of the platform")
    else:
        which = "--vehicle car or robot adds the constraints of such a platform (NHC, ZUPT/ZARU at rest)"
    return (f"the log looks like a ground platform's ({dist:.0f} m at {speed:.1f} m/s on average, height "
            f"range {climb:.0f} m): {which}")


def few_satellite_spans(t: np.ndarray, nsat: np.ndarray) -> list:
    """Stretches of consecutive raw epochs with fewer than 4 satellites: ``(start, length s, least count)``."""
    out = []
    few = nsat < 4
    k = 0
    while k < len(t):
        if not few[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(t) and few[j + 1]:
            j += 1
        step = float(t[j + 1] - t[j]) if j + 1 < len(t) else (float(t[j] - t[j - 1]) if j > 0 else 0.0)
        out.append((float(t[k]), float(t[j] - t[k]) + step, int(nsat[k:j + 1].min())))
        k = j + 1
    return out


@dataclass
class RawSummary:
    """What a tightly coupled run did with the raw GNSS epochs (``sins navigate --gnss-raw``)."""
    epochs: int = 0                                     # raw epochs inside the run
    few: int = 0                                        # epochs with 1-3 usable satellites
    none: int = 0                                       # epochs without a usable satellite
    few_spans: list = field(default_factory=list)       # (start, length, least count) of stretches under 4
    per_system: dict = field(default_factory=dict)      # letter -> (pr used, rejected, range rate used, rejected)
    satellites: dict = field(default_factory=dict)      # letter -> distinct satellites measured
    rms: dict = field(default_factory=dict)             # "pseudorange" (m), "doppler" (m/s): accepted innovations
    clock: tuple = ()                                   # bias m, its sigma, drift m/s, its sigma (final)
    isb: list = field(default_factory=list)             # ("E-G", m, sigma m)
    ref: str = "G"
    jumps: int = 0
    notes: list = field(default_factory=list)

    def lines(self, t0: float) -> list[str]:
        out = [f"fusion: raw GNSS (tightly coupled): {self.epochs} epochs; per constellation satellites, "
               f"pseudoranges used/rejected, range rates used/rejected: " + "; ".join(
                   f"{c} {self.satellites.get(c, 0)} sats, {a}/{b}, {d}/{e}"
                   for c, (a, b, d, e) in self.per_system.items())]
        few = f"fusion: {self.few} epoch(s) with 1-3 satellites, {self.none} with none"
        if self.few_spans:
            spans = [f"{clock(a, t0)} for {d:.3g} s ({k})" for a, d, k in self.few_spans]
            more = f" and {len(spans) - 4} more" if len(spans) > 4 else ""
            few += ": " + ", ".join(spans[:4]) + more
        out.append(few + (" (each satellite is used on its own: no fix needed)" if self.few else ""))
        if self.rms:
            out.append("fusion: innovation RMS of the accepted " + ", ".join(
                f"pseudoranges {v:.3g} m" if k == "pseudorange" else f"range rates (Doppler) {v:.3g} m/s"
                for k, v in self.rms.items()))
        if self.clock:
            b, sb, d, sd = self.clock
            txt = (f"fusion: receiver clock ({self.ref}) at the end: bias {b:.6g} m ({b / 299.792458:.6g} us) "
                   f"+- {sb:.2g} m, drift {d:.4g} m/s ({d / 0.299792458:.4g} ns/s) +- {sd:.2g} m/s")
            for name, v, sv in self.isb:
                txt += f"; inter-system bias {name} {v:.3g} m ({v / 0.299792458:.3g} ns) +- {sv:.2g} m"
            if self.jumps:
                txt += f"; {self.jumps} clock jump(s) reset the bias"
            out.append(txt)
        for n in self.notes:
            out.append(f"fusion: raw GNSS: {n}")
        return out


@dataclass
class FusionSummary:
    """What a fused run did (filled by :meth:`sinscli.fusion.pipeline.Fusion.summary`)."""
    t0: float = 0.0                                     # the log's start (s, the log's clock)
    vehicle: str = "none"
    sensor: str = ""
    sensor_notes: list = field(default_factory=list)
    fixes_used: int = 0
    fixes_rejected: int = 0
    fixes_total: int = 0
    rejected_outside: int = 0                           # rejected fixes that are not outage exits
    reacquired: int = 0                                 # outage exits accepted by widening P
    rejection_runs: list = field(default_factory=list)  # (first, last time, fixes) of each run
    counts: dict = field(default_factory=dict)          # type -> (accepted, rejected) measurements
    outages: list = field(default_factory=list)         # (start, length) s
    standstill: list = field(default_factory=list)      # (start, end) s
    residuals: Residuals = field(default_factory=Residuals)
    final_sigma: dict = field(default_factory=dict)
    heading_init: str | None = None                     # how and when the heading was set from motion
    heading_init_time: float | None = None
    heading_never: str | None = None                    # why the heading was never initialized
    adaptations: list = field(default_factory=list)     # strings, each with its cause
    estimates: list = field(default_factory=list)       # strings: estimated parameters with sigma
    warnings: list = field(default_factory=list)        # strings
    hints: list = field(default_factory=list)
    heading_check: HeadingCheck | None = None
    smoothed: str = ""
    raw: RawSummary | None = None                       # tightly coupled runs

    # compatibility with callers of the first summary
    @property
    def residual_rms_h(self) -> float:
        return self.residuals.h

    @property
    def residual_rms_u(self) -> float:
        return self.residuals.u

    def _list(self, items, n=4) -> str:
        more = f" and {len(items) - n} more" if len(items) > n else ""
        return ", ".join(items[:n]) + more

    def lines(self) -> list[str]:
        c = self.t0
        out = [f"fusion: vehicle {self.vehicle}; sensor model {self.sensor}"]
        for note in self.sensor_notes:
            out.append(f"fusion: sensor model: {note}")
        r = self.residuals
        if self.raw is not None:
            out.extend(self.raw.lines(c))
        else:
            fx = f"fusion: GNSS fixes {self.fixes_used} of {self.fixes_total} used"
            if self.fixes_rejected:
                fx += f", {self.fixes_rejected} rejected ({self.rejected_outside} outside outages)"
            if self.reacquired:
                fx += f"; {self.reacquired} outage exit(s) reacquired by widening the covariance"
            out.append(fx)
        what, take = (("epochs whose pseudoranges were all rejected", "the satellite") if self.raw is not None
                      else ("rejected fixes", "the fix"))
        if self.rejection_runs:
            out.append(f"fusion: {len(self.rejection_runs)} run(s) of consecutive {what} (the filter diverged "
                       f"or the GNSS jumped), each ended by widening the covariance and taking {take}: "
                       + self._list([f"{clock(a, c)}..{clock(b, c).split(' ')[0]}" for a, b, _ in self.rejection_runs]))
        if self.raw is None:
            res = (f"fusion: residual RMS against the fixes outside outages {r.h:.3g} m horizontal, {r.u:.3g} m "
                   f"vertical")
            if r.n_exit:
                res += f"; first fix after each outage {r.exit_h:.3g} m (max {r.exit_max:.3g} m)"
            out.append(res)
        other = [f"{k} {a}/{a + b}" for k, (a, b) in self.counts.items() if k != "gnss_pos"]
        if other:
            out.append("fusion: other measurements used/total: " + ", ".join(other))
        if self.outages:
            lens = [d for _, d in self.outages]
            out.append(f"fusion: {len(self.outages)} GNSS outage(s), {min(lens):.3g}-{max(lens):.3g} s long: "
                       + self._list([f"{clock(t, c)} for {d:.3g} s" for t, d in self.outages]))
        if self.standstill:
            out.append(f"fusion: {len(self.standstill)} standstill(s) with ZUPT/ZARU: "
                       + self._list([f"+{a - c:.1f}..+{b - c:.1f} s" for a, b in self.standstill]))
        if self.heading_init:
            out.append(f"fusion: {self.heading_init}")
        for a in self.adaptations:
            out.append(f"fusion: adaptation: {a}")
        for e in self.estimates:
            out.append(f"fusion: estimated {e}")
        hc = self.heading_check
        if hc is not None and hc.segments:
            out.append(f"fusion: heading against the GNSS course on {hc.segments} straight 10-s segments: median "
                       f"{hc.median_offset:+.2f} deg, beyond 3 sigma on {100 * hc.beyond_3sigma:.0f} % (sigma "
                       f"{hc.median_sigma:.2g} deg)")
        fs = self.final_sigma
        if fs:
            out.append("fusion: final 1-sigma: position {:.3g}/{:.3g}/{:.3g} m, velocity {:.3g}/{:.3g}/{:.3g} m/s, "
                       "roll/pitch/heading {:.3g}/{:.3g}/{:.3g} deg".format(
                           *[fs[k] for k in ("pos_e_std", "pos_n_std", "pos_u_std", "vel_e_std", "vel_n_std",
                                             "vel_u_std", "roll_std", "pitch_std", "heading_std")]))
        if self.smoothed:
            out.append(f"fusion: {self.smoothed}")
        for h in self.hints:
            out.append(f"fusion: hint: {h}")
        return out

    def text(self) -> str:
        return "\n".join(self.lines())
