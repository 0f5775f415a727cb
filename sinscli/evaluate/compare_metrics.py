"""Trajectory metrics inside ``sins compare``: poses in one frame, matched epochs, table rows, summary.

Inputs are trajectories with latitude and longitude (CSV/Parquet,
:class:`~sinscli.types.Trajectory`) or TUM files (:class:`TumTrack`, e.g. from
a SLAM or VIO system).  The metrics of :mod:`.metrics` need poses in one metric
frame:

- *geodetic*: when every input is placed on the earth (a trajectory, or a TUM
  file with sins' ``# origin_lat_deg=...`` line), positions are ENU metres about
  the truth's first point (:func:`sinscli.io.tum.lla_to_local_enu`) and
  attitudes the FLU body axes in that same fixed frame,
  ``C_b^{n0} = C_e^{n0} (C_e^n)^T Cbn C_FLU^{conv T}`` (the local level frame
  turns with the position; over 1 km the difference is 1.6e-4 rad);
- *local*: when every input is a TUM file and one of them has no origin, the
  files' own frame, as they are (they must share it; alignment takes care of a
  rigid offset).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SinsError
from ..io.tum import tum_rotations, tum_to_trajectory
from ..nav.earth import enu_rotation, lla_to_local_enu
from ..nav.rotation import body_flu_in_enu
from ..types import Trajectory
from .errors import ErrorTable, interp_dcm_many, interpolation_weights, match_epochs, time_tolerance
from .metrics import STATISTICS, Poses, TrajectoryMetrics, trajectory_metrics

METRICS = ("ate", "rpe")
#: Table rows (errors.csv keys) of the metrics, after the seed-000 rows.
METRIC_GROUPS = {"ate": [("ate", "m")], "rpe": [("rpe_trans", "m"), ("rpe_rot", "deg")]}


@dataclass
class TumTrack:
    """The rows of a TUM file: ``time tx ty tz qx qy qz qw`` and sins' origin line if present."""
    time: np.ndarray
    pos: np.ndarray              # (N, 3)
    q_xyzw: np.ndarray           # (N, 4)
    origin: tuple | None         # (lat rad, lon rad, h m)
    source: str

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass
class MetricOptions:
    """``--metrics``, ``--align-traj``, ``--rpe-delta``, ``--rpe-unit``, ``--rpe-pairs``."""
    metrics: tuple = METRICS
    align: str = "none"
    rpe_delta: float = 1.0
    rpe_unit: str = "s"
    pairs_from: str = "ref"


def parse_metrics(text: str) -> tuple:
    """``"ate,rpe"`` -> ``("ate", "rpe")``, refusing unknown names."""
    names = tuple(dict.fromkeys(x.strip().lower() for x in str(text).split(",") if x.strip()))
    bad = [x for x in names if x not in METRICS]
    if bad or not names:
        raise SinsError(f"--metrics {text!r}: expected a comma-separated list of {', '.join(METRICS)}")
    return names


# --------------------------------------------------------------------------- poses in one frame

def trajectory_poses(traj: Trajectory, origin: tuple, conv: int) -> Poses:
    """Poses of a trajectory in the ENU frame at ``origin`` (lat rad, lon rad, h m), FLU body axes."""
    pos = lla_to_local_enu(traj.lat, traj.lon, traj.height, *origin)
    c_n0_n = np.einsum("ij,nkj->nik", enu_rotation(origin[0], origin[1]), enu_rotation(traj.lat, traj.lon))
    rot = np.einsum("nij,njk->nik", c_n0_n, body_flu_in_enu(traj.Cbn, conv))
    return Poses(traj.time, pos, rot, traj.source)


def common_frame(truth, navs: list, conv: int) -> tuple[Poses, list[Poses], str]:
    """``(truth poses, nav poses, what the frame is)`` for trajectories and/or TUM tracks."""
    items = [truth, *navs]
    placed = [isinstance(x, Trajectory) or x.origin is not None for x in items]
    if all(isinstance(x, TumTrack) for x in items) and not all(placed):
        poses = [Poses(x.time, x.pos, tum_rotations(x.q_xyzw), x.source) for x in items]
        return poses[0], poses[1:], "positions and attitudes in the TUM files' own frame"
    if not all(placed):
        bad = next(x for x, ok in zip(items, placed) if not ok)
        raise SinsError(f"{bad.source}: a TUM file without a '# origin_lat_deg=...' line cannot be compared with "
                        "a trajectory that has latitude and longitude; give the truth as a TUM file in the same "
                        "frame")
    trajs = [x if isinstance(x, Trajectory) else tum_to_trajectory(x.time, x.pos, x.q_xyzw, x.origin, 0, x.source)
             for x in items]
    convs = [conv if isinstance(x, Trajectory) else 0 for x in items]      # TUM attitudes are FLU
    t0 = trajs[0]
    origin = (float(t0.lat[0]), float(t0.lon[0]), float(t0.height[0]))
    poses = [trajectory_poses(tr, origin, c) for tr, c in zip(trajs, convs)]
    where = (f"positions in the local ENU frame at the truth's first point (lat {np.degrees(origin[0]):.8f} deg, "
             f"lon {np.degrees(origin[1]):.8f} deg, h {origin[2]:.3f} m), FLU body axes")
    return poses[0], poses[1:], where


def match_poses(ref: Poses, est: Poses, interpolate: bool, ref_name: str, est_name: str) -> tuple[Poses, Poses]:
    """The reference and the estimate at common epochs (exact match, or the reference interpolated)."""
    if interpolate:
        inside, tq, j, j1, s = interpolation_weights(ref.time, est.time, ref_name, est_name)
        pos = ref.pos[j] + s[:, None] * (ref.pos[j1] - ref.pos[j])
        rot = interp_dcm_many(np.ascontiguousarray(ref.rot[j]), np.ascontiguousarray(ref.rot[j1]), s)
        return Poses(tq, pos, rot, ref.source), est.subset(inside)
    i_ref, i_est = match_epochs(ref.time, est.time, ref_name, est_name)
    return ref.subset(i_ref), est.subset(i_est)


def compute_metrics(ref: Poses, est: Poses, opts: MetricOptions, interpolate: bool,
                    ref_name: str, est_name: str) -> TrajectoryMetrics:
    """Match, align and measure one estimate against the reference."""
    ref_m, est_m = match_poses(ref, est, interpolate, ref_name, est_name)
    est_m.source = est_name
    return trajectory_metrics(ref_m, est_m, opts.metrics, opts.align, opts.rpe_delta, opts.rpe_unit,
                              opts.pairs_from, time_tolerance(ref_m.time, ref_m.time))


# --------------------------------------------------------------------------- table and summary

def metric_row_keys(opts: MetricOptions) -> list[str]:
    """errors.csv keys of the metrics asked for (``ate_rmse`` ... ``rpe_rot_max``, ``align_scale``)."""
    keys = [f"{g}_{s}" for m in opts.metrics for g, _ in METRIC_GROUPS[m] for s in STATISTICS]
    return keys + (["align_scale"] if opts.align == "sim3" else [])


def metric_values(res: TrajectoryMetrics, keys: list[str]) -> np.ndarray:
    st = res.statistics()
    out = []
    for k in keys:
        if k == "align_scale":
            out.append(res.alignment.scale)
        else:
            group, stat = k.rsplit("_", 1)
            out.append(st[group][stat])
    return np.array(out)


def with_metric_rows(table: ErrorTable | None, results: dict[str, TrajectoryMetrics],
                     opts: MetricOptions) -> ErrorTable:
    """The seed-000 table (or, for TUM inputs, None) extended by the metric rows of every method."""
    keys = metric_row_keys(opts)
    values = np.stack([metric_values(results[m], keys) for m in results], axis=1)
    if table is None:
        return ErrorTable(epoch=None, methods=list(results), values=values, rows=tuple(keys))
    if list(results) != table.methods:
        raise ValueError("methods of the table and of the metrics differ")
    return ErrorTable(epoch=table.epoch, methods=table.methods, values=np.vstack([table.values, values]),
                      rows=tuple(table.rows) + tuple(keys))


def describe(opts: MetricOptions, frame: str) -> str:
    """One sentence on how the metrics were computed (for the report's notes)."""
    align = {"none": "no alignment", "se3": "SE(3) Umeyama alignment of each trajectory to the truth",
             "sim3": "Sim(3) Umeyama alignment (rotation, translation and scale) of each trajectory to the truth"}
    parts = [f"Trajectory metrics ({frame}; {align[opts.align]}):"]
    if "ate" in opts.metrics:
        parts.append("ATE = |p_nav - p_truth| at every matched epoch (evo_ape, translation part);")
    if "rpe" in opts.metrics:
        unit = {"s": "s", "m": "m of travelled path", "f": "epochs"}[opts.rpe_unit]
        parts.append(f"RPE over consecutive pairs {opts.rpe_delta:g} {unit} apart, pairs taken from the "
                     f"{'truth' if opts.pairs_from == 'ref' else 'navigation'} path: translation part (m) and "
                     "rotation angle (deg) of (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) (evo_rpe trans_part and angle_deg).")
    return " ".join(parts)


def summary_lines(results: dict[str, TrajectoryMetrics], opts: MetricOptions) -> list[str]:
    """One plain sentence per method with the headline figures."""
    lines = []
    for name, res in results.items():
        st = res.statistics()
        bits = []
        if "ate" in st:
            bits.append(f"ATE RMSE {st['ate']['rmse']:.4g} m (max {st['ate']['max']:.4g} m)")
        if "rpe_trans" in st:
            bits.append(f"RPE per {opts.rpe_delta:g} {opts.rpe_unit} RMSE {st['rpe_trans']['rmse']:.4g} m and "
                        f"{st['rpe_rot']['rmse']:.4g} deg ({len(res.rpe_i)} pairs)")
        if opts.align == "sim3":
            bits.append(f"scale {res.alignment.scale:.6g}")
        lines.append(f"{name}: " + ", ".join(bits) + f" over {len(res.time)} epochs")
    if len(results) > 1 and "ate" in opts.metrics:
        best = min(results, key=lambda m: results[m].statistics()["ate"]["rmse"])
        lines.append(f"Lowest ATE RMSE: {best}.")
    return lines
