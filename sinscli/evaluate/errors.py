"""Navigation errors against a truth trajectory: time matching and the seed-000 error quantities.

Pure numerical code (numpy, one numba kernel), no I/O.  Every error is
*truth minus navigation*, as in Tables 1-2 of seed 000:

- ``dC = Cbn_true - Cbn_nav`` (the nine ``C11 ... C33`` rows);
- position in metres east, north, up: ``(lon_t - lon_n)(RN + h_t) cos L_t``,
  ``(lat_t - lat_n)(RM + h_t)``, ``h_t - h_n`` with the WGS-84 radii at the
  truth point (:func:`sinscli.nav.earth.enu_offset`);
- velocity east, north, up in m/s;
- attitude from the DCM difference, never from Euler differences: the
  small-angle vector ``phi_n`` with ``Cbn_true = exp([phi_n x]) Cbn_nav``
  (:func:`sinscli.nav.rotation.attitude_error_many`), its angle ``|phi_n|``,
  and its components in the truth's *level heading frame*, signed like the
  physical Euler angle errors (truth minus navigation): ``roll`` about the
  horizontal forward direction, ``pitch`` about the horizontal right
  direction (nose up positive), ``heading`` about the vertical (clockwise
  positive).  With ``phi_n = -dH up + dP r_h + dR f`` (heading, pitch, roll
  sequence) they are exactly ``dR cos P``, ``dP`` and ``dH - dR sin P``, so
  near level they equal the Euler differences; they are a rotation of
  ``phi_n``, bounded at every attitude (no blow-up at pitch +-90 deg), and do
  not oscillate with the spin of a rolling vehicle as body-axis components do.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import SinsError
from ..io import aided_columns
from ..io.timebase import describe as describe_time_base
from ..nav.earth import dlon as earth_dlon, enu_offset, lla_to_local_enu
from ..nav.rotation import (attitude_error_many, dcm_to_euler_many, dcm_to_rotvec, level_heading_frame, mm3,
                            rotvec_to_dcm)
from ..types import Trajectory

REL_TIME_TOL = 1e-9     # epochs match when |t_truth - t_nav| <= 1e-9 max(1 s, |t|) ...
STEP_TIME_TOL = 1e-3    # ... and at most 1e-3 of the shortest sample interval of either file

DCM_ROWS = [f"C{i}{j}" for i in range(1, 4) for j in range(1, 4)]
#: Row keys of the error table (errors.csv), in the order of seed 000 Tables 1-2, then the maxima.
ROWS = (DCM_ROWS
        + ["pos_E", "pos_N", "pos_U", "vel_E", "vel_N", "vel_U",
           "max_pos_E", "max_pos_N", "max_pos_U", "max_vel_E", "max_vel_N", "max_vel_U",
           "max_att_deg"])
ROW_UNITS = dict({k: "1" for k in DCM_ROWS},
                 pos_E="m", pos_N="m", pos_U="m", vel_E="m/s", vel_N="m/s", vel_U="m/s",
                 max_pos_E="m", max_pos_N="m", max_pos_U="m",
                 max_vel_E="m/s", max_vel_N="m/s", max_vel_U="m/s", max_att_deg="deg")
#: Rows of the trajectory metrics (``sins compare --metrics``; :mod:`.compare_metrics`).
METRIC_STATISTICS = ("rmse", "mean", "median", "std", "min", "max")
ROW_UNITS.update({f"{g}_{s}": u for g, u in (("ate", "m"), ("rpe_trans", "m"), ("rpe_rot", "deg"))
                  for s in METRIC_STATISTICS}, align_scale="1")


@dataclass
class ErrorSeries:
    """Errors (truth minus navigation) at the matched epochs of one navigation run."""
    time: np.ndarray          # (N,) s, the navigation epochs that matched the truth
    dC: np.ndarray            # (N, 3, 3) Cbn_true - Cbn_nav
    pos_enu_m: np.ndarray     # (N, 3) position error E, N, U, m
    vel_enu_mps: np.ndarray   # (N, 3) velocity error E, N, U, m/s
    att_n_rad: np.ndarray     # (N, 3) small-angle vector phi_n in ENU axes, rad
    att_rph_rad: np.ndarray   # (N, 3) phi in the truth level heading frame: roll, pitch, heading, rad
    angle_rad: np.ndarray     # (N,) attitude error angle |phi_n|, rad
    # the navigator's own 1-sigma claim at the same epochs (aided trajectories only; None otherwise)
    pos_std_m: np.ndarray | None = None     # (N, 3) E, N, U, m
    vel_std_mps: np.ndarray | None = None   # (N, 3) E, N, U, m/s
    att_std_rad: np.ndarray | None = None   # (N, 3) roll, pitch, heading, rad
    # the truth's position E, N, U (m) in the fixed local frame at the truth file's first point (plan view)
    track_enu_m: np.ndarray | None = None   # (N, 3)

    def __len__(self) -> int:
        return int(self.time.shape[0])

    @property
    def has_sigma(self) -> bool:
        return any(x is not None for x in (self.pos_std_m, self.vel_std_mps, self.att_std_rad))


# --------------------------------------------------------------------------- time matching

def time_tolerance(t_truth: np.ndarray, t_nav: np.ndarray) -> float:
    """Matching tolerance in seconds: ``1e-9 max(1, |t|)``, capped at 1e-3 of the shortest step."""
    tmax = max(1.0, float(np.max(np.abs(t_truth))), float(np.max(np.abs(t_nav))))
    tol = REL_TIME_TOL * tmax
    steps = [np.min(np.diff(t)) for t in (t_truth, t_nav) if t.shape[0] > 1]
    if steps:
        tol = min(tol, STEP_TIME_TOL * float(min(steps)))
    return tol


def explain_no_common_epochs(t_truth, t_nav, truth_name: str, nav_name: str, tol: float) -> str:
    """The one-line message for a navigation file with no epoch in common with the truth."""
    a, b = float(t_truth[0]), float(t_truth[-1])
    c, d = float(t_nav[0]), float(t_nav[-1])
    spans = f"truth {truth_name} spans {a!r} .. {b!r} s, navigation spans {c!r} .. {d!r} s"
    if c > b or d < a:
        gap = max(c - b, a - d)
        longest = max(b - a, d - c, 1.0)
        from_zero = (abs(a) <= 1.0 + (b - a), abs(c) <= 1.0 + (d - c))   # a file that counts from its start
        if (abs(a) >= 1e8) != (abs(c) >= 1e8) or (from_zero[0] != from_zero[1] and gap > 10.0 * longest):
            return (f"{nav_name}: no common epochs with the truth: different time bases "
                    f"(truth in {describe_time_base(a, b)}, navigation in {describe_time_base(c, d)}; {spans}); "
                    "write both files with the same time origin")
        return f"{nav_name}: no common epochs with the truth: the time spans do not overlap ({spans})"
    return (f"{nav_name}: no common epochs with the truth within {tol:.3g} s although the spans overlap "
            f"({spans}); the samples fall between truth epochs: pass --interpolate to interpolate the truth")


def match_epochs(t_truth: np.ndarray, t_nav: np.ndarray, truth_name: str = "truth",
                 nav_name: str = "navigation") -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(i_truth, i_nav)`` of the epochs present in both (within :func:`time_tolerance`).

    Raises :class:`SinsError` naming the navigation file when none match,
    saying whether the time bases differ or the spans do not overlap.
    """
    tol = time_tolerance(t_truth, t_nav)
    j = np.searchsorted(t_truth, t_nav)
    lo = np.clip(j - 1, 0, t_truth.shape[0] - 1)
    hi = np.clip(j, 0, t_truth.shape[0] - 1)
    nearest = np.where(np.abs(t_truth[lo] - t_nav) <= np.abs(t_truth[hi] - t_nav), lo, hi)
    ok = np.abs(t_truth[nearest] - t_nav) <= tol
    if not ok.any():
        raise SinsError(explain_no_common_epochs(t_truth, t_nav, truth_name, nav_name, tol))
    return nearest[ok], np.nonzero(ok)[0]


@njit(cache=True)
def interp_dcm_many(c0, c1, s):
    """``C0 exp(s log(C0^T C1))`` for each k: rotation along the geodesic, s in [0, 1]."""
    n = c0.shape[0]
    out = np.empty((n, 3, 3))
    for k in range(n):
        rel = mm3(c0[k].T.copy(), c1[k])
        out[k] = mm3(c0[k], rotvec_to_dcm(s[k] * dcm_to_rotvec(rel)))
    return out


def interpolation_weights(t_src: np.ndarray, t: np.ndarray, truth_name: str = "truth",
                          nav_name: str = "navigation"):
    """``(inside, tq, j, j1, s)``: the indices of ``t`` inside the span of ``t_src``, those times, and the
    bracketing samples ``j, j1`` of ``t_src`` with the fraction ``s`` in [0, 1] between them."""
    tol = time_tolerance(t_src, t)
    inside = np.nonzero((t >= t_src[0] - tol) & (t <= t_src[-1] + tol))[0]
    if inside.shape[0] == 0:
        raise SinsError(explain_no_common_epochs(t_src, t, truth_name, nav_name, tol))
    tq = np.clip(t[inside], t_src[0], t_src[-1])
    n = t_src.shape[0]
    j = np.clip(np.searchsorted(t_src, tq, side="right") - 1, 0, max(n - 2, 0))
    j1 = np.minimum(j + 1, n - 1)
    dt = t_src[j1] - t_src[j]
    s = np.where(dt > 0, (tq - t_src[j]) / np.where(dt > 0, dt, 1.0), 0.0)
    return inside, tq, j, j1, s


def interpolate_truth(truth: Trajectory, t: np.ndarray, truth_name: str = "truth",
                      nav_name: str = "navigation") -> tuple[Trajectory, np.ndarray]:
    """The truth at times ``t`` inside its span: linear in position and velocity, geodesic in attitude.

    Returns the interpolated trajectory and the indices of ``t`` it covers.
    """
    inside, tq, j, j1, s = interpolation_weights(truth.time, t, truth_name, nav_name)

    def lin(x):
        sw = s.reshape((-1,) + (1,) * (x.ndim - 1))
        return x[j] + sw * (x[j1] - x[j])

    dlon = earth_dlon(truth.lon[j1], truth.lon[j])                  # across the antimeridian
    out = Trajectory(time=tq, lat=lin(truth.lat), lon=truth.lon[j] + s * dlon, height=lin(truth.height),
                     vel_n=lin(truth.vel_n), Cbn=interp_dcm_many(truth.Cbn[j], truth.Cbn[j1], s),
                     source=truth.source)
    return out, inside


def _subset(traj: Trajectory, idx: np.ndarray) -> Trajectory:
    return Trajectory(time=traj.time[idx], lat=traj.lat[idx], lon=traj.lon[idx], height=traj.height[idx],
                      vel_n=traj.vel_n[idx], Cbn=traj.Cbn[idx],
                      extra={k: np.asarray(v)[idx] for k, v in traj.extra.items()}, source=traj.source)


# --------------------------------------------------------------------------- error quantities

def position_error_enu(lat_t, lon_t, h_t, lat_n, lon_n, h_n) -> np.ndarray:
    """Truth minus navigation position in metres E, N, U, with the radii at the truth point (rad, m)."""
    return enu_offset(lat_t, lon_t, h_t, lat_n, lon_n, h_n)


def level_components(cbn_true: np.ndarray, att_n: np.ndarray, conv: int = 0) -> np.ndarray:
    """``phi_n`` in the truth's level heading frame: (roll, pitch, heading) errors, rad.

    With the truth heading H (physical, from :func:`dcm_to_euler_many` with the
    files' body convention ``conv``): roll = phi . (sin H, cos H, 0) (horizontal
    forward), pitch = phi . (cos H, -sin H, 0) (horizontal right), heading = -phi_U.
    """
    heading = dcm_to_euler_many(np.ascontiguousarray(cbn_true), conv)[:, 2]
    return np.einsum("nij,nj->ni", level_heading_frame(heading), att_n)


def error_series(truth: Trajectory, nav: Trajectory, conv: int = 0) -> ErrorSeries:
    """Errors of ``nav`` against ``truth`` given at the same epochs (already matched), with the navigator's
    1-sigma columns (docs/formats.md aided trajectory) when ``nav`` has them."""
    att_n = attitude_error_many(np.ascontiguousarray(truth.Cbn), np.ascontiguousarray(nav.Cbn))
    att_std = aided_columns.group(nav.extra, aided_columns.ATT_STD)
    return ErrorSeries(
        time=nav.time.copy(),
        dC=truth.Cbn - nav.Cbn,
        pos_enu_m=position_error_enu(truth.lat, truth.lon, truth.height, nav.lat, nav.lon, nav.height),
        vel_enu_mps=truth.vel_n - nav.vel_n,
        att_n_rad=att_n,
        att_rph_rad=level_components(truth.Cbn, att_n, conv),
        angle_rad=np.sqrt(np.sum(att_n * att_n, axis=1)),
        pos_std_m=aided_columns.group(nav.extra, aided_columns.POS_STD),
        vel_std_mps=aided_columns.group(nav.extra, aided_columns.VEL_STD),
        att_std_rad=None if att_std is None else np.radians(att_std),
    )


def compare_trajectories(truth: Trajectory, nav: Trajectory, conv: int = 0, interpolate: bool = False,
                         truth_name: str | None = None, nav_name: str | None = None) -> ErrorSeries:
    """Match ``nav`` to ``truth`` by time (exactly, or interpolating the truth) and compute the errors."""
    truth_name = truth_name or truth.source
    nav_name = nav_name or nav.source
    if interpolate:
        truth_m, i_nav = interpolate_truth(truth, nav.time, truth_name, nav_name)
    else:
        i_truth, i_nav = match_epochs(truth.time, nav.time, truth_name, nav_name)
        truth_m = _subset(truth, i_truth)
    out = error_series(truth_m, _subset(nav, i_nav), conv)
    out.track_enu_m = lla_to_local_enu(truth_m.lat, truth_m.lon, truth_m.height,
                                       float(truth.lat[0]), float(truth.lon[0]), float(truth.height[0]))
    return out


# --------------------------------------------------------------------------- headline figures

#: The quantities of a report's summary in words: key -> (what, unit).
HEADLINE = {"att": ("attitude error angle", "deg"), "hor": ("horizontal position error", "m"),
            "ver": ("vertical position error", "m"), "vel": ("velocity error", "m/s")}


def headline_errors(s: ErrorSeries) -> np.ndarray:
    """Max and RMS over the run of each :data:`HEADLINE` magnitude: ``[max_att, rms_att, max_hor, rms_hor,
    max_ver, rms_ver, max_vel, rms_vel]`` (attitude angle in deg; horizontal ``hypot(E, N)``; vertical
    ``|U|``; velocity the 3-D norm)."""
    mags = [np.degrees(s.angle_rad), np.hypot(s.pos_enu_m[:, 0], s.pos_enu_m[:, 1]), np.abs(s.pos_enu_m[:, 2]),
            np.sqrt(np.sum(s.vel_enu_mps ** 2, axis=1))]
    return np.array([f(m) for m in mags for f in (np.max, lambda x: np.sqrt(np.mean(x * x)))], dtype=float)


# --------------------------------------------------------------------------- the table

@dataclass
class ErrorTable:
    """Seed-000 error table: ``values[r, m]`` is row ``rows[r]`` of method ``methods[m]``.

    ``epoch`` is None for a table of trajectory metrics alone (TUM inputs).
    """
    epoch: float | None
    methods: list[str]
    values: np.ndarray        # (len(ROWS), len(methods))
    rows: tuple = tuple(ROWS)


def common_epoch(series: dict[str, ErrorSeries], epoch: float | None = None) -> float:
    """The table epoch: ``epoch`` if every run has it, else (None) the last epoch common to all runs."""
    items = list(series.items())
    times = [s.time for _, s in items]
    tol = min(time_tolerance(times[0], t) for t in times)
    if epoch is not None:
        for name, s in items:
            if np.min(np.abs(s.time - epoch)) > tol:
                raise SinsError(f"--epoch {epoch!r}: not an epoch of method '{name}' "
                                f"(its common epochs with the truth span {float(s.time[0])!r} .. {float(s.time[-1])!r} s)")
        return float(times[0][np.argmin(np.abs(times[0] - epoch))])
    common = times[0]
    for t in times[1:]:
        j = np.clip(np.searchsorted(t, common), 0, t.shape[0] - 1)
        j0 = np.clip(j - 1, 0, t.shape[0] - 1)
        keep = (np.abs(t[j] - common) <= tol) | (np.abs(t[j0] - common) <= tol)
        common = common[keep]
    if common.shape[0] == 0:
        raise SinsError("the navigation files have no epoch in common with each other and the truth; "
                        "pass --epoch or compare them separately")
    return float(common[-1])


def error_column(s: ErrorSeries, epoch: float) -> np.ndarray:
    """One table column: the errors at ``epoch`` (nearest matched epoch) and the maxima over the run."""
    k = int(np.argmin(np.abs(s.time - epoch)))
    return np.concatenate([
        s.dC[k].reshape(9), s.pos_enu_m[k], s.vel_enu_mps[k],
        np.max(np.abs(s.pos_enu_m), axis=0), np.max(np.abs(s.vel_enu_mps), axis=0),
        [np.degrees(np.max(s.angle_rad))],
    ])


def build_table(series: dict[str, ErrorSeries], epoch: float | None = None) -> ErrorTable:
    """The error table of several runs at a common epoch (default the last common one)."""
    t = common_epoch(series, epoch)
    values = np.stack([error_column(s, t) for s in series.values()], axis=1)
    return ErrorTable(epoch=t, methods=list(series), values=values)


# --------------------------------------------------------------------------- the navigator's sigma claim

#: (group, error attribute, sigma attribute, axis labels): what a 1-sigma column claims about which error.
SIGMA_GROUPS = (("pos", "pos_enu_m", "pos_std_m", ("E", "N", "U")),
                ("vel", "vel_enu_mps", "vel_std_mps", ("E", "N", "U")),
                ("att", "att_rph_rad", "att_std_rad", ("roll", "pitch", "heading")))
CONSISTENCY_ROWS = ([f"in3sigma_{g}_{a}" for g, _e, _s, axes in SIGMA_GROUPS for a in axes]
                    + [f"nees_{g}" for g, _e, _s, _a in SIGMA_GROUPS])
CONSISTENCY_UNITS = dict({k: "fraction" for k in CONSISTENCY_ROWS if k.startswith("in3")},
                         **{f"nees_{g}": "1" for g, _e, _s, _a in SIGMA_GROUPS})


@dataclass
class ConsistencyTable:
    """Whether each navigator's 1-sigma tells the truth: ``values[r, m]`` is row ``CONSISTENCY_ROWS[r]``.

    ``in3sigma_*``: fraction of epochs whose error lies inside +-3 sigma (0.9973 for a Gaussian error and an
    honest sigma); ``nees_*``: the average over epochs of ``sum_i (e_i / s_i)^2`` over the three axes (3 for
    an honest claim; the files carry no cross-covariance, so it is the diagonal NEES).  NaN where a method
    has no such sigma column.
    """
    methods: list[str]
    values: np.ndarray        # (len(CONSISTENCY_ROWS), len(methods))
    rows: tuple = tuple(CONSISTENCY_ROWS)


def normalized_errors(s: ErrorSeries, group: str) -> np.ndarray | None:
    """``(N, 3)`` error / claimed sigma of a group (pos, vel, att), or None without that sigma."""
    for g, err_attr, std_attr, _axes in SIGMA_GROUPS:
        if g == group:
            std = getattr(s, std_attr)
            return None if std is None else getattr(s, err_attr) / std
    raise KeyError(group)


def consistency_column(s: ErrorSeries) -> np.ndarray:
    """One column of :class:`ConsistencyTable` (NaN for the groups without a sigma)."""
    inside, nees = [], []
    for g, _e, _s, _axes in SIGMA_GROUPS:
        z = normalized_errors(s, g)
        if z is None or len(s) == 0:
            inside += [np.nan] * 3
            nees.append(np.nan)
        else:
            inside += list(np.mean(np.abs(z) <= 3.0, axis=0))
            nees.append(float(np.mean(np.sum(z * z, axis=1))))
    return np.array(inside + nees)


def build_consistency(series: dict[str, ErrorSeries]) -> ConsistencyTable | None:
    """The consistency table of the runs that carry sigma columns (None when none does)."""
    return consistency_table({name: consistency_column(s) if s.has_sigma else None for name, s in series.items()})


def consistency_table(columns: dict[str, np.ndarray | None]) -> ConsistencyTable | None:
    """The consistency table from each method's :func:`consistency_column` (None for a run without sigma
    columns: its cells are empty); None when no run has any (a batch's workers send the columns)."""
    if all(c is None for c in columns.values()):
        return None
    empty = np.full(len(CONSISTENCY_ROWS), np.nan)
    return ConsistencyTable(methods=list(columns),
                            values=np.stack([empty if c is None else c for c in columns.values()], axis=1))
