"""Navigation stage: IMU increments + initial state -> trajectory, block by block.

This is the glue between readers and writers: it selects the IMU rows that
follow the initial time, feeds them to the numba kernel
(:func:`sinscli.nav.strapdown.run`) in blocks, and returns trajectory chunks.
Memory stays at one block whatever the log length.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import SinsError
from ..types import ImuLog, NavState, Trajectory, time_tolerance
from . import strapdown as sd
from .inertial import LaunchInertial
from .krylov import SUBSTEP_TOL
from .rotation import conv_to_flu

log = logging.getLogger("sins")

ATTITUDE_METHODS = ("dcm", "quat", "krylov", "euler")
BLOCK = 1 << 17


@dataclass
class NavOptions:
    """Algorithm choices (see ``configs/navigation.yaml`` for each key)."""
    attitude: str = "quat"          # dcm | quat | krylov | euler
    dcm_variant: str = "exact"      # exact | seed000
    coning: int = 2                 # 1..4
    subsamples: int = 1             # fast samples per attitude update
    every: int = 1                  # output every K attitude updates
    conv: int = 0                   # body convention code (rotation.FLU/RFU/FRD)
    frame: str = "enu"              # enu | launch-inertial
    angles: bool = False            # add the raw angles of the angle methods
    euler_integrator: str = "rk4"
    singularity_threshold: float = 0.01
    on_singularity: str = "continue"
    launch: dict | None = None
    krylov_substep_tol: float = SUBSTEP_TOL    # krylov: relative RK4 truncation allowed per interval

    def method_code(self) -> int:
        if self.attitude == "dcm":
            return sd.ATT_DCM_SEED000 if self.dcm_variant == "seed000" else sd.ATT_DCM
        if self.attitude == "quat":
            return sd.ATT_QUAT
        if self.attitude == "krylov":
            return sd.ATT_KRYLOV
        if self.attitude == "euler":
            return sd.ATT_EULER
        raise SinsError(f"attitude: unknown method {self.attitude!r}; expected one of {', '.join(ATTITUDE_METHODS)}")

    def check(self) -> None:
        self.method_code()
        if self.coning not in (1, 2, 3, 4):
            raise SinsError(f"coning: expected 1, 2, 3 or 4, got {self.coning!r}")
        if self.subsamples < 1 or self.every < 1:
            raise SinsError("subsamples and every must be whole numbers >= 1")
        if self.angles and self.attitude not in ("krylov", "euler"):
            raise SinsError(f"--angles: the raw angles exist only for --attitude krylov or euler, "
                            f"not {self.attitude}")
        if self.frame not in ("enu", "launch-inertial"):
            raise SinsError(f"frame: expected enu or launch-inertial, got {self.frame!r}")
        tol = self.krylov_substep_tol
        if not (isinstance(tol, (int, float)) and not isinstance(tol, bool) and 0.0 < tol < 1.0):
            raise SinsError(f"krylov_substep_tol: expected a number in (0, 1), got {tol!r}")
        if self.frame == "launch-inertial" and self.attitude not in ("dcm", "quat"):
            raise SinsError(f"--frame launch-inertial: the attitude is dcm or quat, not {self.attitude}")


class Navigator:
    """Stateful navigator: feed IMU blocks in time order, get trajectory chunks back."""

    def __init__(self, init: NavState, opts: NavOptions):
        opts.check()
        c = np.asarray(init.Cbn, dtype=np.float64)
        err = float(np.abs(c @ c.T - np.eye(3)).max())
        if err > 1e-6 or np.linalg.det(c) < 0:
            raise SinsError(f"initial attitude DCM is not orthonormal (error {err:.3g} > 1e-6)")
        if not -math.pi / 2 <= init.lat <= math.pi / 2:
            raise SinsError(f"initial latitude {math.degrees(init.lat)!r} deg is outside [-90, 90]")
        self.init = init
        self.opts = opts
        self.method = opts.method_code()
        self.state = sd.new_state(init.time, init.lat, init.lon, init.height,
                                  np.asarray(init.vel_n, dtype=float), c, self.method, opts.conv,
                                  opts.krylov_substep_tol)
        self._cflu = conv_to_flu(opts.conv)
        self._integrator = 0 if opts.euler_integrator == "euler" else 1
        self._cos_stop = opts.singularity_threshold if opts.on_singularity == "stop" else 0.0
        self._warned_singular = False
        self.stopped = False
        self.applied = 0
        self.first_time = None
        self.last_time = None
        self._emitted_initial = False
        self._source = "<memory>"
        self.inertial = None
        if opts.frame == "launch-inertial":      # the launch-inertial kernel (sinscli.nav.inertial)
            self.inertial = LaunchInertial(init, opts.launch, self.method, opts.coning, opts.subsamples,
                                           opts.every)

    def initial_row(self) -> Trajectory:
        if self.inertial is not None:
            return self.inertial.initial_row()
        s = self.init
        extra = self._angle_columns(self.state[sd.S_ANG:sd.S_ANG + 5][None, :].copy())
        return Trajectory(np.array([s.time]), np.array([s.lat]), np.array([s.lon]), np.array([s.height]),
                          np.asarray(s.vel_n, dtype=float)[None, :].copy(),
                          np.asarray(s.Cbn, dtype=float)[None, :, :].copy(), extra)

    def _angle_columns(self, ang) -> dict:
        """``--angles``: raw angles in degrees and the active set (krylov: 0 = A, 1 = B; euler: 3 angles)."""
        if not self.opts.angles:
            return {}
        d = np.degrees(ang[:, :4])
        cols = {"k_phi": d[:, 0], "k_psi": d[:, 1], "k_gamma": d[:, 2], "k_xi": d[:, 3],
                "k_set": ang[:, 4].copy()}
        if self.method == sd.ATT_EULER:
            cols["k_xi"] = np.zeros(len(ang))
            cols["k_set"] = np.full(len(ang), -1.0)
        return cols

    def feed(self, imu: ImuLog) -> Trajectory | None:
        """Navigate one block; returns its output rows (or None when it produced none)."""
        self._source = imu.source
        t_init = self.init.time
        tol = time_tolerance(t_init)
        if self.first_time is None and len(imu):
            if imu.t0 is None and len(imu) == 1:
                raise SinsError(f"{imu.source}: a single increment row (t = {float(imu.time[0])!r}): where its "
                                "interval starts cannot be told (an increment file's first interval is taken as "
                                "long as the second); give two rows or more")
            start = imu.t0 if imu.t0 is not None else imu.time[0] - (imu.time[1] - imu.time[0])
            if t_init < start - tol:
                raise SinsError(f"{imu.source}: the initial time {t_init!r} is before the log starts "
                                f"({start!r}); the init must lie within the log")
        sel = imu.time > t_init + tol
        if not sel.all():
            k0 = int(np.argmax(sel)) if sel.any() else len(imu)
            time, dth, dv = imu.time[k0:], imu.dtheta_b[k0:], imu.dvel_b[k0:]
        else:
            time, dth, dv = imu.time, imu.dtheta_b, imu.dvel_b
        if time.shape[0] == 0 or self.stopped:
            return None
        if self.first_time is None:
            self.first_time = float(time[0])
        self.last_time = float(time[-1])
        chunks = []
        for a in range(0, time.shape[0], BLOCK):
            b = min(a + BLOCK, time.shape[0])
            chunks.append(self._run(np.ascontiguousarray(time[a:b]), np.ascontiguousarray(dth[a:b]),
                                    np.ascontiguousarray(dv[a:b])))
            chunks[-1].source = self._source
            self._check_finite(chunks[-1], time[a], time[b - 1])
            if self.stopped:
                break
        self.applied += time.shape[0]
        rows = [c for c in chunks if len(c)]
        if not rows:
            return None
        return concat(rows)

    def _run(self, time, dth, dv) -> Trajectory:
        if self.inertial is not None:
            return self.inertial.run(time, dth, dv)
        per = self.opts.subsamples * self.opts.every
        cap = time.shape[0] // per + 2
        out_t = np.empty(cap)
        out_pos = np.empty((cap, 3))
        out_vel = np.empty((cap, 3))
        out_cbn = np.empty((cap, 3, 3))
        out_ang = np.empty((cap, 5))
        events = np.empty((64, sd.N_EVENT))
        n, n_ev = sd.run(time, dth, dv, self.state, self.method, self.opts.coning, self.opts.subsamples,
                         self.opts.every, self._cflu, self._integrator, self._cos_stop,
                         out_t, out_pos, out_vel, out_cbn, out_ang, events)
        self._report_angle_events(events, n_ev)
        return Trajectory(out_t[:n], out_pos[:n, 0], out_pos[:n, 1], out_pos[:n, 2], out_vel[:n], out_cbn[:n],
                          self._angle_columns(out_ang[:n]))

    def _check_finite(self, chunk: Trajectory, t_first: float, t_last: float) -> None:
        """Stop with the epoch when the kernel state turned non-finite in the block just run."""
        state = self.state if self.inertial is None else self.inertial.state
        if np.isfinite(state).all():
            return
        rows = np.column_stack([chunk.time, chunk.lat, chunk.lon, chunk.height, chunk.vel_n,
                                chunk.Cbn.reshape(len(chunk), 9)]) if len(chunk) else np.empty((0, 1))
        bad = ~np.isfinite(rows).all(axis=1)
        when = (f"at t = {float(chunk.time[int(np.argmax(bad))])!r} s" if bad.any() else
                f"between t = {float(t_first)!r} and {float(t_last)!r} s")
        raise SinsError(f"{self._source}: the navigation state became non-finite {when}: the input drives the "
                        f"mechanization outside its range (check units, time stamps and the initial state); "
                        f"nothing written")

    def _report_angle_events(self, events, n_ev) -> None:
        """Log Krylov set transfers and RK4 sub-steps (debug), and the 3-angle singularity (warning, or stop)."""
        st = self.state
        if self.method == sd.ATT_KRYLOV and st[sd.S_KSUB_N] > 0:
            log.debug("krylov: RK4 sub-steps per attitude interval in this block: max %d, mean %.4f over %d "
                      "intervals (sub-step rotation <= %.4g rad)", st[sd.S_KSUB_MAX],
                      st[sd.S_KSUB_SUM] / st[sd.S_KSUB_N], st[sd.S_KSUB_N], st[sd.S_KSUB_ANGLE])
            st[sd.S_KSUB_MAX] = st[sd.S_KSUB_SUM] = st[sd.S_KSUB_N] = 0.0
        if self.method == sd.ATT_KRYLOV and n_ev:
            for e in events[:min(n_ev, len(events))]:
                log.debug("krylov transfer at t=%.6f: set %s (%.6f, %.6f, %.6f, %.6f) deg -> set %s "
                          "(%.6f, %.6f, %.6f, %.6f) deg", e[0], "B" if e[9] == 0 else "A",
                          *np.degrees(e[1:5]), "B" if e[9] == 1 else "A", *np.degrees(e[5:9]))
            if n_ev > len(events):
                log.debug("krylov: %d more transfers in this block", n_ev - len(events))
        if self.method == sd.ATT_EULER:
            cmin, tmin = st[sd.S_COSMIN], st[sd.S_TCOSMIN]
            if st[sd.S_STOPPED] > 0:
                self.stopped = True
                log.warning("3-angle method: |cos psi| = %.3g under the threshold %g at t = %.6f s; stopped "
                            "there (--on-singularity stop)", cmin, self.opts.singularity_threshold, tmin)
            elif cmin < self.opts.singularity_threshold and not self._warned_singular:
                self._warned_singular = True
                log.warning("3-angle method: |cos psi| = %.3g fell under the threshold %g at t = %.6f s (near "
                            "its singularity); carrying on", cmin, self.opts.singularity_threshold, tmin)

    def finish(self) -> None:
        """Check that the log covered the initial time (call after the last block)."""
        if self.applied == 0:
            raise SinsError(f"{self._source}: no IMU sample after the initial time {self.init.time!r}: "
                            f"the init time is outside the log")
        n, every = self.opts.subsamples, self.opts.every
        if self.applied < n * every and not self.stopped:     # not one row after the initial one
            if self.applied < n:
                what = f"fewer than one attitude update of --subsamples {n} samples"
            else:
                what = (f"{self.applied // n:,} attitude update(s) of {n} sample(s), fewer than one output row "
                        f"every {every} updates (--every)")
            raise SinsError(f"{self._source}: {self.applied:,} IMU sample(s) after the initial time "
                            f"{self.init.time!r} s: {what}; nothing would be navigated (navigation.subsamples and "
                            f"navigation.every in the config)")


def concat(parts: list[Trajectory]) -> Trajectory:
    """Concatenate trajectory chunks."""
    if len(parts) == 1:
        return parts[0]
    extra = {}
    if parts[0].extra:
        extra = {k: np.concatenate([p.extra[k] for p in parts]) for k in parts[0].extra}
    return Trajectory(np.concatenate([p.time for p in parts]), np.concatenate([p.lat for p in parts]),
                      np.concatenate([p.lon for p in parts]), np.concatenate([p.height for p in parts]),
                      np.vstack([p.vel_n for p in parts]), np.concatenate([p.Cbn for p in parts]), extra,
                      source=next((p.source for p in parts if p.source != "<memory>"), parts[0].source))


# First-run time of `sins navigate` (cold numba cache: start-up, compile of all of its kernels, the 180 s
# sample drive), seconds, wall time measured on the idle 2-core machine (load 0.7-0.9; numba compiles on
# one thread, so the CPU time is about the same): quat 9.3, dcm 9.3, krylov 17.0, euler 10.4,
# launch-inertial 10.1.  The estimate of the first-run note (sinscli/_numba_cache.py: set_compile_note).
FIRST_RUN_SECONDS = {"quat": 9, "dcm": 9, "krylov": 17, "euler": 10, "launch-inertial": 10}


def first_run_seconds(opts: NavOptions) -> int:
    """The first-run estimate of :data:`FIRST_RUN_SECONDS` for a navigation with ``opts``."""
    return FIRST_RUN_SECONDS["launch-inertial" if opts.frame == "launch-inertial" else opts.attitude]


def stream_blocks(engine, blocks, progress=None):
    """Yield ``engine``'s trajectory chunks (its initial row first) for an iterable of IMU blocks; ``engine``
    is a :class:`Navigator` or a fusion filter (``initial_row``, ``feed``, ``finish``)."""
    yield engine.initial_row()
    for blk in blocks:
        out = engine.feed(blk)
        if progress is not None:
            progress(len(blk))
        if out is not None:
            yield out
    engine.finish()


def navigate_blocks(blocks, init: NavState, opts: NavOptions, progress=None):
    """Yield trajectory chunks (the initial row first) for an iterable of IMU blocks."""
    yield from stream_blocks(Navigator(init, opts), blocks, progress)


def navigate(imu: ImuLog, init: NavState, opts: NavOptions | None = None, progress=None) -> Trajectory:
    """Navigate a whole in-memory IMU log; returns the trajectory with the initial row first."""
    return concat(list(navigate_blocks([imu], init, opts or NavOptions(), progress)))
