"""Trajectory metrics of SLAM/VIO evaluation: ATE after Umeyama alignment, and RPE.

Pure numerical code on arrays (no I/O), defined exactly as evo (Grupp 2017)
defines ``evo_ape`` and ``evo_rpe``, so that the same pair of trajectories gives
the same statistics (``tests/test_report_metrics.py`` checks this against evo):

- **Alignment** (Umeyama 1991, eqs 34-43): the rotation ``R``, translation ``t``
  and (``sim3``) scale ``s`` minimizing ``sum |p_ref - (s R p_est + t)|^2``;
  the estimate's poses become ``(R C_est, s R p_est + t)`` (evo's
  ``PosePath3D.align``: scale, then the SE(3) transformation on the left).
- **ATE** (evo's APE w.r.t. the translation part): ``|p_est - p_ref|`` at each
  matched epoch, after the alignment.
- **RPE** (TUM RGB-D benchmark, Sturm 2012; evo's RPE): for each pose pair
  ``(i, j)``, ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with ``Q`` the reference and
  ``P`` the estimate; the translation part ``|trans(E)|`` (m) and the rotation
  angle ``|log rot(E)|`` (deg), evo's ``trans_part`` and ``angle_deg``.
  Consecutive pairs ``delta`` apart: in frames (evo ``f``), in travelled path
  length (evo ``m``: accumulated distance along the pair trajectory, reset at
  each pair), or in seconds (``s``: the first epoch at least ``delta`` after the
  previous one; with evenly spaced epochs the pairs of ``f`` with ``delta/dt``).
  Pairs come from the reference path (evo's ``--pairs_from_reference``: the
  same pairs for every method of a table) or from the estimate (evo's default).

Statistics are evo's: rmse, mean, median, std (population), min, max.
Poses are body (FLU) axes in one common metric frame: ``rot`` turns a body
vector into that frame, ``pos`` is the body origin in metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import SinsError
from ..nav.rotation import attitude_error_many
from .errors import METRIC_STATISTICS as STATISTICS

ALIGN_MODES = ("none", "se3", "sim3")
RPE_UNITS = ("s", "m", "f")
PAIRS_FROM = ("ref", "est")


@dataclass
class Poses:
    """Poses at epochs: body (FLU) axes in a common metric frame."""
    time: np.ndarray     # (N,) s
    pos: np.ndarray      # (N, 3) m
    rot: np.ndarray      # (N, 3, 3) body -> frame
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(self.time.shape[0])

    def subset(self, idx) -> "Poses":
        return Poses(self.time[idx], self.pos[idx], self.rot[idx], self.source)


@dataclass
class Alignment:
    """``p_ref ~ scale R p_est + t``."""
    mode: str
    R: np.ndarray        # (3, 3)
    t: np.ndarray        # (3,) m
    scale: float


@dataclass
class TrajectoryMetrics:
    """ATE and RPE of one estimate against the reference at matched epochs."""
    alignment: Alignment
    time: np.ndarray              # (N,) matched epochs
    ref_pos: np.ndarray           # (N, 3) m
    est_pos: np.ndarray           # (N, 3) m, aligned
    ate_m: np.ndarray | None      # (N,) |p_est - p_ref|, m
    rpe_i: np.ndarray | None      # (M,) pair start indices into ``time``
    rpe_j: np.ndarray | None      # (M,) pair end indices
    rpe_trans_m: np.ndarray | None   # (M,) m
    rpe_rot_deg: np.ndarray | None   # (M,) deg

    def statistics(self) -> dict[str, dict[str, float]]:
        """``{"ate": {...}, "rpe_trans": {...}, "rpe_rot": {...}}`` for the metrics computed."""
        out = {}
        if self.ate_m is not None:
            out["ate"] = statistics(self.ate_m)
        if self.rpe_trans_m is not None:
            out["rpe_trans"] = statistics(self.rpe_trans_m)
            out["rpe_rot"] = statistics(self.rpe_rot_deg)
        return out


def statistics(err: np.ndarray) -> dict[str, float]:
    """evo's statistics of an error array: rmse, mean, median, std (population), min, max."""
    e = np.asarray(err, dtype=np.float64)
    return {"rmse": float(np.sqrt(np.mean(e * e))), "mean": float(np.mean(e)), "median": float(np.median(e)),
            "std": float(np.std(e)), "min": float(np.min(e)), "max": float(np.max(e))}


# --------------------------------------------------------------------------- alignment

def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """``(R, t, s)`` minimizing ``sum |dst - (s R src + t)|^2`` (Umeyama 1991, eqs 34-43); (N, 3) each.

    Raises :class:`SinsError` when the points do not fix a rotation (fewer than
    two independent directions: a single point or a straight line), as evo does.
    """
    n = src.shape[0]
    mean_s, mean_d = src.mean(axis=0), dst.mean(axis=0)
    xs, yd = src - mean_s, dst - mean_d
    var_s = float(np.sum(xs * xs)) / n                          # eq 36
    cov = yd.T @ xs / n                                         # eq 38
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < 2:
        raise SinsError("the positions do not fix a rotation (all on one point or one straight line): "
                        "Umeyama alignment is not possible; use --align-traj none")
    s_mat = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:              # eq 43: a proper rotation
        s_mat[2, 2] = -1.0
    r = u @ s_mat @ vt                                          # eq 40
    c = float(np.trace(np.diag(d) @ s_mat)) / var_s if with_scale else 1.0   # eq 42
    t = mean_d - c * r @ mean_s                                 # eq 41
    return r, t, c


def align_poses(est: Poses, ref: Poses, mode: str) -> tuple[Poses, Alignment]:
    """The estimate transformed onto the reference (``none``: unchanged), and the alignment."""
    if mode not in ALIGN_MODES:
        raise SinsError(f"--align-traj: expected one of {', '.join(ALIGN_MODES)}, got {mode!r}")
    if mode == "none":
        return est, Alignment("none", np.eye(3), np.zeros(3), 1.0)
    try:
        r, t, s = umeyama(est.pos, ref.pos, mode == "sim3")
    except SinsError as exc:                     # name the trajectory that cannot be aligned
        raise SinsError(f"{est.source}: {exc} (against {ref.source})") from None
    pos = (s * est.pos) @ r.T + t
    rot = np.einsum("ij,njk->nik", r, est.rot)
    return Poses(est.time, pos, rot, est.source), Alignment(mode, r, t, s)


# --------------------------------------------------------------------------- RPE pairs

@njit(cache=True)
def _path_pairs(pos, delta):
    """evo's consecutive path-length pairs: accumulate |p_k - p_{k-1}|, a pair end when it reaches delta."""
    n = pos.shape[0]
    ids = np.empty(n, dtype=np.int64)
    ids[0] = 0
    m = 1
    path = 0.0
    for k in range(1, n):
        dx = pos[k, 0] - pos[k - 1, 0]
        dy = pos[k, 1] - pos[k - 1, 1]
        dz = pos[k, 2] - pos[k - 1, 2]
        path += np.sqrt(dx * dx + dy * dy + dz * dz)
        if path >= delta:
            ids[m] = k
            m += 1
            path = 0.0
    return ids[:m]


@njit(cache=True)
def _time_pairs(t, delta, tol):
    """Consecutive time pairs: from the last pair end, the first epoch at least ``delta - tol`` later."""
    n = t.shape[0]
    ids = np.empty(n, dtype=np.int64)
    ids[0] = 0
    m = 1
    last = t[0]
    for k in range(1, n):
        if t[k] - last >= delta - tol:
            ids[m] = k
            m += 1
            last = t[k]
    return ids[:m]


def rpe_pairs(time: np.ndarray, pos: np.ndarray, delta: float, unit: str,
              time_tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Consecutive pose pairs ``(i, j)`` ``delta`` apart in ``unit`` (``s``, ``m`` or ``f``)."""
    if unit not in RPE_UNITS:
        raise SinsError(f"--rpe-unit: expected one of {', '.join(RPE_UNITS)}, got {unit!r}")
    if not (delta > 0 and np.isfinite(delta)):
        raise SinsError(f"--rpe-delta: expected a positive number, got {delta!r}")
    n = time.shape[0]
    if unit == "f":
        if float(delta) != int(delta):
            raise SinsError(f"--rpe-delta {delta!r}: must be a whole number of frames with --rpe-unit f")
        ids = np.arange(0, n, int(delta), dtype=np.int64)
    elif unit == "m":
        ids = _path_pairs(np.ascontiguousarray(pos, dtype=np.float64), float(delta))
    else:
        ids = _time_pairs(np.ascontiguousarray(time, dtype=np.float64), float(delta), float(time_tol))
    return ids[:-1], ids[1:]


def rpe_errors(ref: Poses, est: Poses, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation (m) and rotation angle (deg) of ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` for each pair."""
    def relative(p: Poses):
        r_i = p.rot[i]
        rel_r = np.einsum("nji,njk->nik", r_i, p.rot[j])                   # R_i^T R_j
        rel_t = np.einsum("nji,nj->ni", r_i, p.pos[j] - p.pos[i])          # R_i^T (t_j - t_i)
        return rel_r, rel_t

    q_r, q_t = relative(ref)
    p_r, p_t = relative(est)
    # trans(E) = Rq^T (tp - tq): its norm is |tp - tq|; rot(E) = Rq^T Rp has the angle of Rp Rq^T.
    trans = np.sqrt(np.sum((p_t - q_t) ** 2, axis=1))
    phi = attitude_error_many(np.ascontiguousarray(p_r), np.ascontiguousarray(q_r))
    return trans, np.degrees(np.sqrt(np.sum(phi * phi, axis=1)))


# --------------------------------------------------------------------------- everything

def trajectory_metrics(ref: Poses, est: Poses, metrics=("ate", "rpe"), align: str = "none",
                       rpe_delta: float = 1.0, rpe_unit: str = "s", pairs_from: str = "ref",
                       time_tol: float = 0.0) -> TrajectoryMetrics:
    """ATE and/or RPE of ``est`` against ``ref``, given at the same (matched) epochs."""
    if len(ref) != len(est):
        raise ValueError("ref and est must be matched epoch by epoch")
    if pairs_from not in PAIRS_FROM:
        raise SinsError(f"--rpe-pairs: expected one of {', '.join(PAIRS_FROM)}, got {pairs_from!r}")
    if len(ref) < 2:
        raise SinsError(f"{est.source}: {len(ref)} epoch(s) in common with the truth; the trajectory metrics "
                        "need at least 2")
    aligned, alignment = align_poses(est, ref, align)
    ate = np.sqrt(np.sum((aligned.pos - ref.pos) ** 2, axis=1)) if "ate" in metrics else None
    i = j = trans = rot = None
    if "rpe" in metrics:
        base = ref if pairs_from == "ref" else aligned
        i, j = rpe_pairs(base.time, base.pos, rpe_delta, rpe_unit, time_tol)
        if i.shape[0] == 0:
            raise SinsError(f"{est.source}: RPE over --rpe-delta {rpe_delta:g} {rpe_unit} gives no pose pair "
                            f"(the matched trajectory spans {float(ref.time[-1] - ref.time[0]):.6g} s, "
                            f"{len(ref)} epochs); use a smaller delta")
        trans, rot = rpe_errors(ref, aligned, i, j)
    return TrajectoryMetrics(alignment, ref.time.copy(), ref.pos, aligned.pos, ate, i, j, trans, rot)
