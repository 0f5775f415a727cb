"""The fused GNSS/INS loop: one numba kernel over plain arrays (no I/O).

:func:`fuse` runs the strapdown mechanization of :mod:`sinscli.nav.strapdown` (its fast-rate
``load_fast/fast_sample/save_fast`` and the per-interval :func:`~sinscli.nav.strapdown.interval_update`,
no second mechanization) on increments compensated by the filter's bias and scale-factor estimates
(``(dtheta - b_g dt) / (1 + s_g)``, likewise ``dvel``), propagates the error covariance
(:mod:`sinscli.fusion.model`) and applies the measurements (:mod:`sinscli.fusion.updates`) at their own
times: a measurement inside an IMU interval splits that interval's increments at its time (as KF-GINS
does), closes the attitude interval there and propagates P to it.  Every estimate is fed back into
the mechanization's state (position, velocity, ``Cbn`` and ``q`` together, compensated-summation
residues cleared) and into the parameter estimates (lever arm, GNSS time offset); the error state is
zero again (closed loop).

Nothing is allocated per sample or per update: the matrices the filter works in are the slices of one
workspace (:func:`workspace`), 3-vectors and Cbn are tuples on the stack.  The flat vectors are laid
out by name (:class:`sinscli.layout.Layout`): the configuration ``cv`` (:data:`CV`), the filter's
scalars ``fs`` (:data:`FS`), the measurement rows (:data:`ROW`).

Measurement rows (``meas``, float64, sorted by time then kind): ``[time, kind, z (3), s (3), aux
(2)]`` with ``kind`` one of the ``MT_*`` codes and ``s`` 1-sigmas (see :mod:`sinscli.fusion.pipeline`
for what each kind carries).  Raw GNSS rows (tightly coupled, :mod:`sinscli.fusion.raw`) carry one
satellite's corrected pseudorange or range rate each and point with ``aux[0]`` into a satellite table
(:data:`SAT`: its position and velocity at transmission) passed beside the rows: the table is filled once
per log, the rows of the other kinds stay 10 floats; the filter then has the receiver clock bias and drift
and an inter-system bias per extra constellation as states (:func:`_propagate_clock`, :func:`_raw_model`).

Robustness (docs/fusion.md):

* **gate**: a measurement whose normalized innovation squared (NIS) exceeds ``chi2(gate_probability,
  m)`` is rejected; ``rejection_run`` consecutive rejected GNSS fixes add each axis' squared innovation
  to the position variance and accept the fix (a diverged filter, or a GNSS jump that stays);
* **robust weight** (IGG-III): between the ``robust.probability`` quantile and the gate, the noise of
  the measurement is inflated smoothly instead of the measurement being taken at full weight;
* **measurement-noise adaptation**: per kind (GNSS position, GNSS velocity, NHC, odometry) the
  variance scale of R is estimated by covariance matching over windows of measurements, never below
  1 (the stated sigma), at most ``adapt.max_scale``: where the innovations say the measurements are
  noisier than stated, R grows, never the process noise;
* **outage exit**: the first fix after a GNSS outage tests the dead-reckoning prediction; an exit
  fix beyond the gate widens the navigation block of P by its ratio to the predicted variance and is
  accepted (reacquisition), and a ratio over ``adapt.exit_ratio`` raises the scale of the drift process
  noise only (bias instability, scale factor, misalignment: the terms that make dead reckoning drift),
  at most ``adapt.max_bias_scale`` times its base and decaying back to the base with ``adapt.decay``
  (:func:`_exit_drift_scale`); the base is 1, or what a first pass over the whole log found
  (:func:`sinscli.fusion.pipeline.calibrate_drift`).

Every change of a scale and every reacquisition is an event (:data:`EV_NAMES`).
"""
import numpy as np
from numba import njit

from ..layout import Layout
from ..nav import strapdown as sd
from ..gnss.model import geo_range, range_rate
from ..gnss.orbits import earth_rate
from ..gnss.signals import N_SYS
from ..nav.earth import OMEGA_IE, dlon_nb, gravity, radii
from ..nav.rotation import (dcm_to_euler, dcm_to_quat, euler_to_dcm, m_mul, m_trans, m_tvec, m_vec, orthonormalize_t,
                            quat_mul_t, quat_normalize_t, quat_to_dcm_t, rotvec_to_dcm_t, rotvec_to_quat_t)
from ..nav.linalg import cholesky
from . import tdcp
from .antenna import _antenna_velocity, _cross, _dvant_dlever, antenna_ecef
from .model import BA, BG, PHI, R, SA, SG, V, add_process_noise, f_blocks, propagate, transition_step
from .updates import innovation_covariance, kalman_apply, nis_of, skew_into

# measurement kinds (also the innovation record's type code)
MT_GNSS_POS, MT_GNSS_VEL, MT_ZUPT, MT_ZARU, MT_NHC, MT_ODOM, MT_COURSE = 0, 1, 2, 3, 4, 5, 6
# raw GNSS (tightly coupled): one satellite's pseudorange (z = corrected pseudorange, m; s = sigma) or range
# rate (z = corrected range rate, m/s), aux = (row of the satellite table SAT, system); the epoch's clock row
# (z = its receiver clock from the pseudoranges, m, and drift, m/s; s = sigma): the clock-jump check; one
# satellite's time-differenced carrier phase since the previous epoch (:mod:`sinscli.fusion.tdcp`)
MT_PR, MT_DOP, MT_CLOCK, MT_TDCP = 7, 8, 9, 10
MEAS_NAMES = ("gnss_pos", "gnss_vel", "zupt", "zaru", "nhc", "odom", "course", "pseudorange", "doppler", "clock",
              "tdcp")
AX_LOS = 6                                  # axis code of a line-of-sight measurement

# a measurement row; the course row (heading from the GNSS course) carries z = (course, v_e, v_n) and
# s = (course sigma, horizontal speed sigma, 0)
ROW = Layout("measurement row", [("RW_T", 1), ("RW_KIND", 1), ("RW_Z", 3), ("RW_S", 3), ("RW_AUX", 2)], total=10)
MW = ROW.total
RW_T, RW_KIND, RW_Z, RW_S, RW_AUX = ROW.offsets(*(name for name, _ in ROW.fields))

# the satellite table of the raw rows (one row per satellite and epoch, indexed by a row's aux[0]): position
# and velocity at transmission (ECEF, m, m/s; :mod:`sinscli.gnss.tc`), system, PRN, elevation (rad)
SAT = Layout("satellite table", [("SAT_POS", 3), ("SAT_VEL", 3), ("SAT_SYS", 1), ("SAT_PRN", 1), ("SAT_EL", 1)],
             total=9)
SW = SAT.total
SAT_POS, SAT_VEL, SAT_SYS, SAT_PRN, SAT_EL = SAT.offsets(*(name for name, _ in SAT.fields))

# the kinds whose measurement noise is adapted (index into the FS fields F_RS, F_RA)
NK = 4
K_OF_KIND = (0, 1, -1, -1, 2, 3, -1, -1, -1, -1, -1)   # gnss_pos, gnss_vel, -, -, nhc, odom, -, raw: -
ADAPT_NAMES = ("gnss_pos", "gnss_vel", "nhc", "odom")
NX_MAX = 34                                 # 21 + lever arm (3) + time offset (1) + clock (2) + 3 ISB + 4 TDCP clones,
                                            # or + GNSS error (3)

# configuration vector (read-only in the kernel)
CV = Layout("fusion config", [
    ("C_NX", 1),              # states
    ("C_NCORE", 1),           # 15 or 21 (scale factors): the states F reaches; then the parameter states
    ("C_LA", 1),              # first lever-arm state, or -1
    ("C_TD", 1),              # the GNSS time-offset state, or -1
    ("C_METHOD", 1), ("C_ORDER", 1), ("C_NSUB", 1), ("C_EVERY", 1), ("C_CONV", 1),
    ("C_PROP_DT", 1),         # s between covariance propagations (0: every attitude update)
    ("C_GATE", 3),            # chi-square gate of 1, 2, 3 components
    ("C_ROBUST", 3),          # IGG-III full-weight bound (NIS of 1, 2, 3 components; 0: off)
    ("C_ARW2", 3), ("C_VRW2", 3), ("C_QBG", 3), ("C_QBA", 3), ("C_ITG", 3), ("C_ITA", 3),
    ("C_SFG", 1), ("C_SFA", 1),     # sigma^2 tau_c of the unestimated scale factor + misalignment
    ("C_SF_TAU", 1),              # tau_c, s
    ("C_REJ_RUN", 1),
    ("C_RADAPT_N", 1),        # measurements per R-adaptation window (0: off)
    ("C_RADAPT_MAX", 1),      # largest R variance scale
    ("C_RADAPT_BAND", 2),     # the window's estimate out of [lo, hi] x the scale (chi-square quantiles) moves it
    ("C_RBASE", 3 * NK),      # per kind and axis, the R scale a calibration pass found (the online floor)
    ("C_QB_MAX", 1),          # the drift process-noise scale stays at most qb_max times its base (1: off)
    ("C_QB_TAU", 1),          # s: its decay back to the base
    ("C_QB_THR", 1),          # outage-exit ratio (innovation^2 / predicted variance) that raises it
    ("C_QB_BASE", 1),         # the base drift scale (1, or calibrated by a first pass over the log)
    ("C_OUTAGE_DT", 1),       # s: a gap between GNSS fixes longer than this is an outage
    ("C_SMOOTH_DT", 1),       # > 0: store smoother epochs at least this often
    ("C_ZUPT_MAXV", 1),
    ("C_NHC_AX", 2),
    ("C_FWD", 1),             # the body's forward axis (0 x, 1 y): roll/pitch sigma
    ("C_CLK", 1),             # the receiver clock bias state (m; its drift, m/s, the next), or -1 (raw GNSS)
    ("C_ISB", N_SYS),         # per system the state of its inter-system bias (m), or -1 (the reference system)
    ("C_QCLK", 2),            # clock bias (white frequency noise, m^2/s) and drift (random walk, (m/s)^2/s) densities
    ("C_QISB", 1),            # inter-system bias random walk density, m^2/s
    ("C_CLK_JUMP", 1),        # m: an epoch's clock this far from the filter's (and 10 sigma) is a clock jump
    ("C_CLK_P0", 1),          # m: the clock bias 1-sigma after a jump
    ("C_FADE_ALPHA", 1),      # weight of a fix in the consistency statistics (1 / window); 0: the test off
    ("C_FADE_THR", 1),        # their mean NIS per component over which the filter is too confident
    ("C_FADE_MAX", 1),        # the largest covariance factor of one widening
    ("C_GE", 1),              # the first of the GNSS position error states (E, N, U; Gauss-Markov), or -1
    ("C_GE_RATIO2", 3),       # their steady variance per stated variance of the fix (a float fix's larger sigma
                              # is a larger correlated error)
    ("C_GE_TAU", 3),          # their correlation times, s
    ("C_TDCP", 2),            # TDCP (fusion/tdcp.py): the first of its 4 clone states (-1: none), the slip test's |w|
], total=89)
(C_NX, C_NCORE, C_LA, C_TD, C_METHOD, C_ORDER, C_NSUB, C_EVERY, C_CONV, C_PROP_DT, C_GATE, C_ROBUST,
 C_ARW2, C_VRW2, C_QBG, C_QBA, C_ITG, C_ITA, C_SFG, C_SFA, C_SF_TAU, C_REJ_RUN, C_RADAPT_N,
 C_RADAPT_MAX, C_RADAPT_BAND, C_RBASE, C_QB_MAX, C_QB_TAU, C_QB_THR, C_QB_BASE, C_OUTAGE_DT,
 C_SMOOTH_DT, C_ZUPT_MAXV, C_NHC_AX, C_FWD, C_CLK, C_ISB, C_QCLK, C_QISB, C_CLK_JUMP,
 C_CLK_P0, C_FADE_ALPHA, C_FADE_THR, C_FADE_MAX, C_GE, C_GE_RATIO2, C_GE_TAU,
 C_TDCP) = CV.offsets(*(name for name, _ in CV.fields))
CV_SIZE = CV.total

# the filter's scalars (read and written by the kernel, carried between blocks)
FS = Layout("fusion filter scalars", [
    ("F_BG", 3), ("F_BA", 3), ("F_SG", 3), ("F_SA", 3),   # sensor estimates (SI): the first NBIAS, as output
    ("F_LEVER", 3),           # antenna lever arm estimate (body, m)
    ("F_TD", 1),              # GNSS time-offset estimate (s, added to the GNSS stamps)
    ("F_QS_DRIFT", 1),        # scale of the drift process noise: bias instability, scale factor, misalignment
    ("F_T_QS", 1),            # time of its last decay step
    ("F_RS", 3 * NK),         # R variance scale per adapted kind and axis (>= 1)
    ("F_RP", 4 * NK * 3),     # per kind and axis, the previous measurement: innovation, H P H^T, stated R, time
    ("F_RA", 4 * NK * 3),     # R-adaptation window per kind and axis: sums of dz^2, H P H^T, stated R; count
    ("F_ACC_T", 1), ("F_ACC_DV", 3), ("F_ACC_DTH", 3),  # since the last propagation: time, f^n dt, w^b dt
    ("F_W", 3), ("F_HAVE_W", 1),                      # compensated body rate, low-passed (ANTENNA_TAU)
    ("F_LPW", 3), ("F_LPF", 3),                       # low-passed body rate and f^n - g^n (scale_factor_tau)
    ("F_F", 3),               # specific force (ENU, m/s^2), low-passed (ANTENNA_TAU)
    ("F_HEAD_KNOWN", 1),
    ("F_NREJ", 1), ("F_TREJ0", 1),
    ("F_T_FIX", 1),           # time of the last GNSS position fix (-inf: none yet)
    ("F_T_EPOCH", 1),
    ("F_ERR", 1), ("F_ERR_T", 1),
    ("F_RESET", 1),
    ("F_TPREV", 1),
    ("F_NSAMP_OUT", 1),
    ("F_XACC", NX_MAX),       # correction fed back since the last stored epoch
    ("F_CLK", 2),             # receiver clock bias (m) and drift (m/s) estimates (raw GNSS)
    ("F_ISB", N_SYS),         # inter-system bias estimate per system (m)
    ("F_EP_T", 1),            # the current raw epoch: its time, pseudoranges accepted and rejected
    ("F_EP_ACC", 1), ("F_EP_REJ", 1),
    ("F_EP_NREJ", 1), ("F_EP_T0", 1),   # consecutive epochs whose pseudoranges were all rejected, and the first
    ("F_CL", 1), ("F_CD", 1),           # consistency of the GNSS fixes: weighted means of NIS/m and of the
                                        # consecutive innovations' differences (_consistency)
    ("F_CZ", 3), ("F_CS", 3), ("F_CT", 1),   # the previous fix: innovation, variances, time
    ("F_CJ", 1),              # a jump of the fixes since the last one taken cleanly (no widening then)
    ("F_CN", 1),              # fixes in the statistics since they last restarted
    ("F_GE", 3),              # the GNSS position error estimate (E, N, U, m): the fixes are the antenna plus it
    ("F_GE_V", 3),            # its steady variance now (m^2): the ratio times the last fix's stated variance
    ("F_TDCP", 5),            # TDCP clones' nominal values (fusion/tdcp.py): antenna then (ECEF), clock bias, time
], total=226)
(F_BG, F_BA, F_SG, F_SA, F_LEVER, F_TD, F_QS_DRIFT, F_T_QS, F_RS, F_RP, F_RA, F_ACC_T, F_ACC_DV,
 F_ACC_DTH, F_W, F_HAVE_W, F_LPW, F_LPF, F_F, F_HEAD_KNOWN, F_NREJ, F_TREJ0, F_T_FIX, F_T_EPOCH, F_ERR,
 F_ERR_T, F_RESET, F_TPREV, F_NSAMP_OUT, F_XACC, F_CLK, F_ISB, F_EP_T, F_EP_ACC, F_EP_REJ, F_EP_NREJ,
 F_EP_T0, F_CL, F_CD, F_CZ, F_CS, F_CT, F_CJ, F_CN, F_GE, F_GE_V,
 F_TDCP) = FS.offsets(*(name for name, _ in FS.fields))
FS_SIZE = FS.total

ERR_NONFINITE, ERR_NOT_PD = 1.0, 2.0
# events: (time, code, a, b)
EV_REJECTION_RUN, EV_HEADING_INIT, EV_RSCALE, EV_REACQUIRE, EV_QSCALE, EV_EXIT = 1.0, 2.0, 3.0, 4.0, 5.0, 6.0
EV_CLOCK_JUMP, EV_WIDEN = 7.0, 8.0
EV_SLIP = 9.0               # a cycle slip found by the INS-aided test (a = the satellite-table row, b = its w)
EV_NAMES = {1: "rejection_run", 2: "heading_init", 3: "r_scale", 4: "reacquire", 5: "drift_q_scale", 6: "outage_exit",
            7: "clock_jump", 8: "widen", 9: "cycle_slip"}

# workspace: matrices (nx, nx) and rows (nx,)
WM = Layout("fusion workspace matrices", [("W_F", 1), ("W_W", 1), ("W_PM", 1), ("W_A", 1), ("W_L", 1), ("W_PHI", 1)])
W_F, W_W, W_PM, W_A, W_L, W_PHI = WM.offsets(*(name for name, _ in WM.fields))
WV = Layout("fusion workspace rows", [("V_X", 1), ("V_H", 3), ("V_HP", 3), ("V_KT", 3), ("V_Z", 1), ("V_R", 1)])
V_X, V_H, V_HP, V_KT, V_Z, V_R = WV.offsets(*(name for name, _ in WV.fields))
# the slots of the layouts above that fusion/tdcp.py reads, in the order of its SLOT_NAMES (passed to its kernels:
# it does not import this module)
TDCP_SLOTS = tuple(globals()[name] for name in tdcp.SLOT_NAMES)
TDCP_SLIP = RW_S + 1          # a TDCP row's slot that its slip test sets to the row's w (0: no slip found)
# per-row variances written with every output row
NVAR = 9             # pos E N U, vel E N U, roll, pitch, heading (heading < 0: not yet known)
NREC = 12            # columns of an innovation record (_record)
ANTENNA_TAU = 0.05   # s: low-pass of the rate and specific force in the GNSS models (lever arm, time offset)
NBIAS = 12           # b_g, b_a, s_g, s_a (SI)


def workspace(nx):
    """The kernel's scratch: ``(mats (WM.total, nx, nx), vecs (WV.total, nx), s3 (2, 3, 3))``."""
    mats = np.zeros((WM.total, nx, nx))
    mats[W_PHI] = np.eye(nx)
    return mats, np.zeros((WV.total, nx)), np.zeros((2, 3, 3))


def epoch_width(ncore: int, nx: int, clk: int = -1, clone: int = -1) -> int:
    """Floats of one smoother epoch's transition matrix: its navigation rows over the core states, the
    diagonal of the rest, with a receiver clock (state ``clk``) its bias-drift entry and with TDCP clones (states
    ``clone`` .. ``clone + 3``) their full rows (:func:`_store_epoch`)."""
    return 9 * ncore + (nx - 9) + (1 if clk >= 0 else 0) + (4 * nx if clone >= 0 else 0)


@njit(cache=True)
def _set_attitude(st, c):
    """Write an attitude (tuple matrix) into Cbn and q together; clears their summation residues."""
    ca = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            st[sd.S_CBN + 3 * i + j] = c[i][j]
            ca[i, j] = c[i][j]
    q = dcm_to_quat(ca)
    for i in range(4):
        st[sd.S_Q + i] = q[i]
        st[sd.S_QLO + i] = 0.0
    for i in range(9):
        st[sd.S_CLO + i] = 0.0


@njit(cache=True)
def feedback(st, fs, cv, x, nx, method):
    """Closed loop: remove the estimated errors ``x`` from the mechanization state, the sensor and the
    parameter estimates; the error state is zero afterwards."""
    lat, h = st[sd.S_LAT], st[sd.S_H]
    rm, rn = radii(np.sin(lat))
    st[sd.S_LAT] = lat - x[R + 1] / (rm + h)
    st[sd.S_LON] = st[sd.S_LON] - x[R] / ((rn + h) * np.cos(lat))
    st[sd.S_H] = h - x[R + 2]
    for i in range(3):
        st[sd.S_PLO + i] = 0.0
        st[sd.S_VEL + i] -= x[V + i]
        st[sd.S_VMM2 + i] -= x[V + i]       # the velocity history of the position rule moves with it
        st[sd.S_VMM3 + i] -= x[V + i]
        st[sd.S_VLO + i] = 0.0
    phi = (x[PHI], x[PHI + 1], x[PHI + 2])
    if method == sd.ATT_QUAT:
        q = (st[sd.S_Q], st[sd.S_Q + 1], st[sd.S_Q + 2], st[sd.S_Q + 3])
        q = quat_normalize_t(quat_mul_t(rotvec_to_quat_t(phi), q))
        _set_attitude(st, quat_to_dcm_t(q))
        for i in range(4):
            st[sd.S_Q + i] = q[i]
    else:
        _set_attitude(st, orthonormalize_t(m_mul(rotvec_to_dcm_t(phi), sd._cbn(st))))
    for i in range(3):
        fs[F_BG + i] += x[BG + i]
        fs[F_BA + i] += x[BA + i]
    if int(cv[C_NCORE]) > 15:
        for i in range(3):
            fs[F_SG + i] += x[SG + i]
            fs[F_SA + i] += x[SA + i]
    la, td = int(cv[C_LA]), int(cv[C_TD])
    clk = int(cv[C_CLK])
    if clk >= 0:
        fs[F_CLK] -= x[clk]
        fs[F_CLK + 1] -= x[clk + 1]
        for s in range(N_SYS):
            k = int(cv[C_ISB + s])
            if k >= 0:
                fs[F_ISB + s] -= x[k]
        if int(cv[C_TDCP]) >= 0:
            tdcp.feedback(fs, cv, x, lat, st[sd.S_LON], TDCP_SLOTS)
    if la >= 0:
        for i in range(3):
            fs[F_LEVER + i] -= x[la + i]
    if td >= 0:
        fs[F_TD] -= x[td]
    ge = int(cv[C_GE])
    if ge >= 0:
        for i in range(3):
            fs[F_GE + i] -= x[ge + i]
    for i in range(nx):
        fs[F_XACC + i] += x[i]


@njit(cache=True)
def _fail(fs, t, code):
    fs[F_ERR] = code
    fs[F_ERR_T] = t
    return False


@njit(cache=True)
def _health(P, nx, fs, t, L, full):
    """A finite positive diagonal (after each propagation: a non-finite entry reaches the diagonal
    within one propagation); with ``full``, every entry finite and P positive definite (a Cholesky
    factorization succeeds: after each measurement group).  While the heading is held out of the filter
    its zero row and column are left out of the test."""
    held = fs[F_HEAD_KNOWN] == 0.0             # heading held out: its row and column of P are zero
    for i in range(nx):
        d = P[i, i]
        if not np.isfinite(d):
            return _fail(fs, t, ERR_NONFINITE)
        if not d > 0.0 and not (held and i == PHI + 2 and d == 0.0):
            return _fail(fs, t, ERR_NOT_PD)
    if full:
        s = 0.0
        for i in range(nx):
            for j in range(nx):
                s += P[i, j]
        if not np.isfinite(s):
            return _fail(fs, t, ERR_NONFINITE)
        if held:                                # the zero row/column: a unit variance for the check
            P[PHI + 2, PHI + 2] = 1.0
        ok = cholesky(P, nx, L)
        if held:
            P[PHI + 2, PHI + 2] = 0.0
        if not ok:
            return _fail(fs, t, ERR_NOT_PD)
    return True


@njit(cache=True)
def _do_propagate(st, fs, cv, P, mats, store):
    """Propagate P over the accumulated time with F at the current state and the mean f, w; with
    ``store`` (smoothing) also the transition matrix since the last smoother epoch."""
    T = fs[F_ACC_T]
    if T <= 0.0:
        return
    nx = int(cv[C_NX])
    ncore = int(cv[C_NCORE])
    c = sd._cbn(st)
    f_n = (fs[F_ACC_DV] / T, fs[F_ACC_DV + 1] / T, fs[F_ACC_DV + 2] / T)
    w_b = (fs[F_ACC_DTH] / T, fs[F_ACC_DTH + 1] / T, fs[F_ACC_DTH + 2] / T)
    # the rate and specific force the GNSS models see: low-passed with ANTENNA_TAU, as a receiver's loops
    # smooth its velocity (an engine's vibration of the gyro would otherwise make the lever-arm velocity
    # term a noise the GNSS never shows)
    b = min(T / ANTENNA_TAU, 1.0) if fs[F_HAVE_W] > 0.0 else 1.0
    for i in range(3):
        fs[F_W + i] += b * (w_b[i] - fs[F_W + i])
        fs[F_F + i] += b * (f_n[i] - fs[F_F + i])
    fs[F_HAVE_W] = 1.0
    f_b = m_tvec(c, f_n)
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    lat, h = st[sd.S_LAT], st[sd.S_H]
    fb = f_blocks(c, vel, lat, h, f_n, w_b, f_b)
    itg, ita = cv[C_ITG:C_ITG + 3], cv[C_ITA:C_ITA + 3]
    W = mats[W_W]
    propagate(P, W, fb, T, nx, ncore, itg, ita)
    g = gravity(np.sin(lat), h)
    # the unestimated scale factor and misalignment act on the sustained rate and acceleration: their means
    # over the correlation time (a step, a wobble or a vibration averages out: its error is bounded, not a
    # random walk); first-order low-pass of time constant scale_factor_tau
    a = min(T / max(cv[C_SF_TAU], 1e-9), 1.0)
    for i in range(3):
        fs[F_LPW + i] += a * (w_b[i] - fs[F_LPW + i])
        fs[F_LPF + i] += a * ((f_n[i] - g if i == 2 else f_n[i]) - fs[F_LPF + i])
    w2 = fs[F_LPW] ** 2 + fs[F_LPW + 1] ** 2 + fs[F_LPW + 2] ** 2
    fd2 = fs[F_LPF] ** 2 + fs[F_LPF + 1] ** 2 + fs[F_LPF + 2] ** 2
    add_process_noise(P, c, T, fs[F_QS_DRIFT], cv[C_ARW2:C_ARW2 + 3], cv[C_VRW2:C_VRW2 + 3],
                      cv[C_QBG:C_QBG + 3], cv[C_QBA:C_QBA + 3], cv[C_SFG] * w2, cv[C_SFA] * fd2)
    if store:
        transition_step(mats[W_PHI], W, fb, T, ncore, itg, ita)
    if int(cv[C_CLK]) >= 0:
        _propagate_clock(P, nx, cv, fs, T, mats[W_PHI], store)
    if int(cv[C_GE]) >= 0:
        _propagate_gnss_error(P, nx, cv, fs, T, mats[W_PHI], store)
    fs[F_ACC_T] = 0.0
    for i in range(3):
        fs[F_ACC_DV + i] = 0.0
        fs[F_ACC_DTH + i] = 0.0


@njit(cache=True)
def _propagate_clock(P, nx, cv, fs, T, Phi, store):
    """The receiver clock states over ``T`` s (docs/raw_gnss.md; Brown & Hwang 9.3, Groves 9.4.2): bias ``b`` (m)
    and drift ``d`` (m/s) with ``b' = d + w_f``, ``d' = w_g``, so ``Phi = [[1, T], [0, 1]]`` and
    ``Qd = [[S_f T + S_g T^3/3, S_g T^2/2], [S_g T^2/2, S_g T]]`` (``S_f``, ``S_g`` the densities ``cv.q_clk``);
    each inter-system bias a random walk of density ``cv.q_isb``.  The estimate moves as ``b += d T``.  The
    clock block is uncoupled from the others in F, so ``P <- Phi P Phi^T`` is one row and one column operation
    after :func:`propagate`; with ``store`` the smoother's transition product gets the same ``T``."""
    fs[F_CLK] += fs[F_CLK + 1] * T
    c = int(cv[C_CLK])
    d = c + 1
    for j in range(nx):
        P[c, j] += T * P[d, j]
    for i in range(nx):
        P[i, c] += T * P[i, d]
    sf, sg = cv[C_QCLK], cv[C_QCLK + 1]
    P[c, c] += sf * T + sg * T * T * T / 3.0
    P[c, d] += 0.5 * sg * T * T
    P[d, c] += 0.5 * sg * T * T
    P[d, d] += sg * T
    for s in range(N_SYS):
        k = int(cv[C_ISB + s])
        if k >= 0:
            P[k, k] += cv[C_QISB] * T
    if store:
        Phi[c, d] += T


@njit(cache=True)
def _propagate_gnss_error(P, nx, cv, fs, T, Phi, store):
    """The GNSS position error states over ``T`` s: a first-order Gauss-Markov process per axis (Brown &
    Hwang 2012, "Introduction to Random Signals and Applied Kalman Filtering", 4th ed., sec. 8.x: colored
    measurement noise by state augmentation; Gelb 1974, table 3.8-1), ``e' = -e / tau + w`` with the steady
    variance ``s^2`` (the last fix's, :func:`_gnss_error_level`): ``phi = exp(-T / tau)``,
    ``Qd = s^2 (1 - phi^2)``.  The estimate decays as ``e *= phi``;
    uncoupled from the other states in F, so ``P <- Phi P Phi^T`` scales its rows and columns; with ``store``
    the smoother's transition matrix gets the same ``phi``."""
    g = int(cv[C_GE])
    for a in range(3):
        k = g + a
        d = np.exp(-T / cv[C_GE_TAU + a])
        fs[F_GE + a] *= d
        for j in range(nx):
            P[k, j] *= d
            P[j, k] *= d
        P[k, k] += fs[F_GE_V + a] * (1.0 - d * d)
        if store:
            Phi[k, k] *= d


@njit(cache=True)
def _gnss_error_level(row, fs, cv, P, Pm, store):
    """A fix sets the steady variance of the GNSS error states: its stated variance times the ratio
    ``C_GE_RATIO2`` (a float fix's larger sigma is a larger slowly varying error, a fixed one's smaller).  A
    rise is added to the states' variance at once (a positive increment, given to the smoother's prior too);
    a fall lets the states decay to the new level with their correlation time."""
    g = int(cv[C_GE])
    for a in range(3):
        s = row[RW_S + a]
        v = cv[C_GE_RATIO2 + a] * s * s
        dv = v - fs[F_GE_V + a]
        if dv > 0.0:
            P[g + a, g + a] += dv
            if store:
                Pm[g + a, g + a] += dv
        fs[F_GE_V + a] = v


@njit(cache=True)
def _close(st, fs, sums, order, method, t_end, cflu, events, n_ev):
    """Close the attitude interval at ``t_end`` with the shared mechanization step; accumulate f, w."""
    T = t_end - st[sd.S_TSTART]
    n_ev = sd.interval_update(st, sums, order, method, t_end, cflu, 0, events, n_ev)
    dv_n = m_vec(sd._cbn(st), sums[1])
    alpha = sums[0]
    for i in range(3):
        fs[F_ACC_DV + i] += dv_n[i]
        fs[F_ACC_DTH + i] += alpha[i]
    fs[F_ACC_T] += T
    return n_ev


@njit(cache=True)
def _record(inn, n_inn, t, kind, axis, z, var, nis, acc, hph, r_stated, exit_fix, comp, sat_row):
    """One innovation record (:data:`NREC` columns): time, kind, axis, innovation, its sigma, the NIS of its
    measurement, accepted, then the filter's part of its variance (H P H^T), the stated noise variance
    whether it was an outage exit and the component's index (the calibration pass's statistics,
    :mod:`sinscli.fusion.pipeline`), the row of the satellite table (:data:`SAT`; -1: not a satellite's)."""
    if n_inn < inn.shape[0]:
        inn[n_inn, 0] = t
        inn[n_inn, 1] = kind
        inn[n_inn, 2] = axis
        inn[n_inn, 3] = z
        inn[n_inn, 4] = np.sqrt(var) if var > 0.0 else 0.0
        inn[n_inn, 5] = nis
        inn[n_inn, 6] = 1.0 if acc else 0.0
        inn[n_inn, 7] = hph
        inn[n_inn, 8] = r_stated
        inn[n_inn, 9] = 1.0 if exit_fix else 0.0
        inn[n_inn, 10] = comp
        inn[n_inn, 11] = sat_row
    return n_inn + 1


@njit(cache=True)
def _event(evs, n_evs, t, kind, a, b):
    if n_evs < evs.shape[0]:
        evs[n_evs, 0] = t
        evs[n_evs, 1] = kind
        evs[n_evs, 2] = a
        evs[n_evs, 3] = b
    return n_evs + 1


@njit(cache=True)
def _heading_from_course(row, st, fs, cv, P, nx, evs, n_evs):
    """Set heading and horizontal velocity from the GNSS course (the heading was unknown)."""
    if fs[F_HEAD_KNOWN] > 0.0:
        return n_evs
    conv = int(cv[C_CONV])
    ca = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            ca[i, j] = st[sd.S_CBN + 3 * i + j]
    rpy = dcm_to_euler(ca, conv)
    course, ve, vn, csig, svh = row[RW_Z], row[RW_Z + 1], row[RW_Z + 2], row[RW_S], row[RW_S + 1]
    c_new = euler_to_dcm(rpy[0], rpy[1], course, conv)
    # the antenna stays where the fixes put it: the IMU moves by (C_old - C_new) l
    lever = (fs[F_LEVER], fs[F_LEVER + 1], fs[F_LEVER + 2])
    d = np.zeros(3)
    for i in range(3):
        for j in range(3):
            d[i] += (ca[i, j] - c_new[i, j]) * lever[j]
    lat, h = st[sd.S_LAT], st[sd.S_H]
    rm, rn = radii(np.sin(lat))
    st[sd.S_LAT] = lat + d[1] / (rm + h)
    st[sd.S_LON] = st[sd.S_LON] + d[0] / ((rn + h) * np.cos(lat))
    st[sd.S_H] = h + d[2]
    for i in range(3):
        st[sd.S_PLO + i] = 0.0
    # the tilt error, in navigation axes, turns with the estimate (T = C_new C_old^T, about the vertical):
    # its covariance with the biases was built under the old heading
    T = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                T[i, j] += c_new[i, k] * ca[j, k]
    for b in (PHI, V):
        tmp = np.zeros((3, nx))
        for i in range(3):
            for j in range(nx):
                for k in range(3):
                    tmp[i, j] += T[i, k] * P[b + k, j]
        for i in range(3):
            for j in range(nx):
                P[b + i, j] = tmp[i, j]
        tmp2 = np.zeros((nx, 3))
        for i in range(nx):
            for j in range(3):
                for k in range(3):
                    tmp2[i, j] += P[i, b + k] * T[j, k]
        for i in range(nx):
            for j in range(3):
                P[i, b + j] = tmp2[i, j]
    _set_attitude(st, ((c_new[0, 0], c_new[0, 1], c_new[0, 2]), (c_new[1, 0], c_new[1, 1], c_new[1, 2]),
                       (c_new[2, 0], c_new[2, 1], c_new[2, 2])))
    st[sd.S_VEL] = ve
    st[sd.S_VEL + 1] = vn
    for i in range(3):
        st[sd.S_VLO + i] = 0.0
    for j in (PHI + 2, V, V + 1):
        for i in range(nx):
            P[i, j] = 0.0
            P[j, i] = 0.0
    P[PHI + 2, PHI + 2] = csig * csig
    P[V, V] = svh * svh
    P[V + 1, V + 1] = svh * svh
    fs[F_HEAD_KNOWN] = 1.0
    fs[F_RESET] = 1.0
    return _event(evs, n_evs, row[RW_T], EV_HEADING_INIT, (rpy[2] - course), csig)


@njit(cache=True)
def _raw_model(row, kind, st, fs, cv, nx, H, z, r, sat):
    """One satellite's pseudorange (``MT_PR``) or range rate (``MT_DOP``) at the filter's antenna (docs/raw_gnss.md,
    "Tightly coupled"; IS-GPS-200 20.3.3.3.3 for the range, the clock states of :func:`_propagate_clock`).

    The antenna ``r_a = r(lat, lon, h) + C_n^e (Cbn l + v_ant tau)`` (ECEF; ``tau`` the GNSS time offset), the
    range with the Earth's rotation during the flight and its line of sight ``e``
    (:func:`sinscli.gnss.model.geo_range`), the rate :func:`sinscli.gnss.model.range_rate` at the antenna's
    velocity ``C_n^e v_ant``.  Predicted: ``P_c = rho + b + ISB_sys`` and ``rho' + d``; innovations computed
    minus measured.  Jacobians (``e_n`` the line of sight in ENU): the pseudorange is ``-e_n^T`` times the
    GNSS-position rows of :func:`_model` (``[I, 0, [l_n x]]``, lever arm ``Cbn``, time offset ``v_ant``)
    plus 1 on the bias and on the system's ISB; the range rate ``-e_n^T`` times the GNSS-velocity rows, plus
    the line of sight's turn with the position ``-(u - (e.u) e)^T / rho`` (``u`` the relative velocity), plus 1
    on the drift.  ``r`` the row's sigma squared (the pseudorange's plus the horizontal lever arm's
    ``|l_h|^2/2`` along the line of sight while the heading is unknown).  Returns as :func:`_model`, axis
    :data:`AX_LOS`; 0 components for a range rate while the heading is unknown."""
    clk = int(cv[C_CLK])
    if clk < 0:
        return 0, 0, 0, 1, 2
    head_known = fs[F_HEAD_KNOWN] > 0.0
    if kind == MT_DOP and (not head_known or fs[F_HAVE_W] == 0.0):
        return 0, 0, 0, 1, 2
    k = int(row[RW_AUX])
    sys = int(sat[k, SAT_SYS])
    c = sd._cbn(st)
    lat, lon, h = st[sd.S_LAT], st[sd.S_LON], st[sd.S_H]
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    lever = (fs[F_LEVER], fs[F_LEVER + 1], fs[F_LEVER + 2])
    la, td = int(cv[C_LA]), int(cv[C_TD])
    tau = fs[F_TD]
    w = (fs[F_W], fs[F_W + 1], fs[F_W + 2])
    v_ant, cw, l_n, w_in = _antenna_velocity(c, vel, lat, h, w, lever)
    rx, ry, rz, ue, un, uu = antenna_ecef(lat, lon, h, l_n, v_ant, tau)
    sx, sy, sz = sat[k, SAT_POS], sat[k, SAT_POS + 1], sat[k, SAT_POS + 2]
    omge = earth_rate(sys)
    rho, ex, ey, ez = geo_range(sx, sy, sz, rx, ry, rz, omge)
    e = (ue[0] * ex + ue[1] * ey + ue[2] * ez, un[0] * ex + un[1] * ey + un[2] * ez,
         uu[0] * ex + uu[1] * ey + uu[2] * ez)
    isb = int(cv[C_ISB + sys])
    s0 = row[RW_S]
    r[0] = s0 * s0
    if kind == MT_PR:
        z[0] = rho + fs[F_CLK] + (fs[F_ISB + sys] if isb >= 0 else 0.0) - row[RW_Z]
        # the antenna offset l_n + tau v_ant turns with the attitude error: [l_n x] + tau ([cw x] - [w_in x][l_n x])
        exl = _cross(e, l_n)
        ecw = _cross(e, cw)
        ewl = _cross(_cross(e, w_in), l_n)
        for i in range(3):
            H[0, R + i] = -e[i]
            H[0, V + i] = -e[i] * tau               # the antenna at the stamp + tau
            H[0, PHI + i] = -exl[i] - tau * (ecw[i] - ewl[i])
        if tau != 0.0:                              # and with the gyro bias error through the rate: tau Cbn (w x l)
            gxl = _cross(m_tvec(c, e), lever)
            for i in range(3):
                H[0, BG + i] = tau * gxl[i]
        if la >= 0:                                 # d (l_n + tau v_ant) / d l = Cbn + tau (Cbn [w x] - [w_in x] Cbn)
            dl = _dvant_dlever(c, w, w_in)
            for j in range(3):
                H[0, la + j] = -(e[0] * (c[0][j] + tau * dl[0][j]) + e[1] * (c[1][j] + tau * dl[1][j])
                                 + e[2] * (c[2][j] + tau * dl[2][j]))
        if td >= 0:
            H[0, td] = -(e[0] * v_ant[0] + e[1] * v_ant[1] + e[2] * v_ant[2])
        H[0, clk] = 1.0
        if isb >= 0:
            H[0, isb] = 1.0
        if not head_known:
            r[0] += 0.5 * (lever[0] * lever[0] + lever[1] * lever[1]) * (e[0] * e[0] + e[1] * e[1])
    else:
        g = gravity(np.sin(lat), h)
        acc = (fs[F_F], fs[F_F + 1], fs[F_F + 2] - g)
        va = (v_ant[0] + acc[0] * tau, v_ant[1] + acc[1] * tau, v_ant[2] + acc[2] * tau)
        vx = ue[0] * va[0] + un[0] * va[1] + uu[0] * va[2]
        vy = ue[1] * va[0] + un[1] * va[1] + uu[1] * va[2]
        vz = ue[2] * va[0] + un[2] * va[1] + uu[2] * va[2]
        rate = range_rate(sx, sy, sz, sat[k, SAT_VEL], sat[k, SAT_VEL + 1], sat[k, SAT_VEL + 2], rx, ry, rz,
                          vx, vy, vz, ex, ey, ez, omge)
        z[0] = rate + fs[F_CLK + 1] - row[RW_Z]
        # the line of sight turns with the position: d rate / d r = -(u - (e.u) e)^T / rho (ECEF, u = v_s - v_a)
        ux, uy, uz = sat[k, SAT_VEL] - vx, sat[k, SAT_VEL + 1] - vy, sat[k, SAT_VEL + 2] - vz
        eu = ex * ux + ey * uy + ez * uz
        px, py, pz = -(ux - eu * ex) / rho, -(uy - eu * ey) / rho, -(uz - eu * ez) / rho
        ecw = _cross(e, cw)                         # v_ant turns with the attitude error: [cw x] - [w_in x][l_n x]
        ewl = _cross(_cross(e, w_in), l_n)
        gxl = _cross(m_tvec(c, e), lever)           # -e^T (-Cbn [l x]) = (Cbn^T e) x l on b_g
        # and the ENU axes the velocity is given in turn with the latitude and longitude
        sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
        dlon = (-co * va[0] + sl * so * va[1] - cl * so * va[2], -so * va[0] - sl * co * va[1] + cl * co * va[2], 0.0)
        dlat = (-cl * co * va[1] - sl * co * va[2], -cl * so * va[1] - sl * so * va[2], -sl * va[1] + cl * va[2])
        rm, rn = radii(sl)
        pn = (ue[0] * px + ue[1] * py + ue[2] * pz, un[0] * px + un[1] * py + un[2] * pz,
              uu[0] * px + uu[1] * py + uu[2] * pz)
        H[0, R] = pn[0] - (ex * dlon[0] + ey * dlon[1]) / ((rn + h) * cl)
        H[0, R + 1] = pn[1] - (ex * dlat[0] + ey * dlat[1] + ez * dlat[2]) / (rm + h)
        H[0, R + 2] = pn[2]
        pxl = _cross(pn, l_n)                       # the antenna's position turns with the attitude: [l_n x]
        for i in range(3):
            H[0, V + i] = -e[i]
            H[0, PHI + i] = ewl[i] - ecw[i] + pxl[i]
            H[0, BG + i] = gxl[i]
        if la >= 0:                                 # horizontal lever arm only (see _model's GNSS velocity)
            dl = _dvant_dlever(c, w, w_in)
            for j in range(2):
                H[0, la + j] = -(e[0] * dl[0][j] + e[1] * dl[1][j] + e[2] * dl[2][j]) \
                    + pn[0] * c[0][j] + pn[1] * c[1][j] + pn[2] * c[2][j]
        if td >= 0:                                 # the velocity at stamp + tau, and the position there
            H[0, td] = -(e[0] * acc[0] + e[1] * acc[1] + e[2] * acc[2]) \
                + pn[0] * v_ant[0] + pn[1] * v_ant[1] + pn[2] * v_ant[2]
        H[0, clk + 1] = 1.0
    return 1, AX_LOS, 0, 1, 2


@njit(cache=True)
def _clock_check(row, fs, cv, P, nx, evs, n_evs):
    """A receiver clock jump (a receiver that keeps its clock within a millisecond steps it by one): the epoch's
    clock from its own pseudoranges (``z[0]``, m, 1-sigma ``s[0]``; :mod:`sinscli.fusion.raw`) further than
    ``cv.clk_jump`` and 10 sigma from the filter's resets the bias state there (its correlations dropped, its
    variance ``clk_p0^2 + s^2``), an event; the smoother restarts there."""
    c = int(cv[C_CLK])
    if c < 0:
        return n_evs
    dz = row[RW_Z] - fs[F_CLK]
    lim = max(cv[C_CLK_JUMP], 10.0 * np.sqrt(P[c, c] + row[RW_S] * row[RW_S]))
    if abs(dz) <= lim:
        return n_evs
    fs[F_CLK] = row[RW_Z]
    for i in range(nx):
        P[i, c] = 0.0
        P[c, i] = 0.0
    P[c, c] = cv[C_CLK_P0] * cv[C_CLK_P0] + row[RW_S] * row[RW_S]
    fs[F_RESET] = 1.0
    return _event(evs, n_evs, row[RW_T], EV_CLOCK_JUMP, dz, fs[F_CLK])


@njit(cache=True)
def _widen_state(P, nx, k, ratio):
    """Widen row and column ``k`` of P by ``sqrt(ratio)`` (a congruence, as :func:`_widen_nav`)."""
    f = np.sqrt(max(ratio, 1.0))
    for i in range(nx):
        P[k, i] *= f
        P[i, k] *= f


@njit(cache=True)
def _model(row, kind, st, fs, cv, nx, H, z, r, sat):
    """Innovation ``z``, its Jacobian ``H`` (rows zeroed here) and noise ``r`` of one measurement row
    (``sat``: the satellite table of raw rows, :func:`_raw_model`).

    Returns ``(m, axis0, ax0, ax1, ax2)``: the number of components (0: not applicable now), the
    axis code of the first (0 e, 1 n, 2 u, 3 x, 4 y, 5 z, 6 line of sight) and the axes used.
    """
    for a in range(3):
        for j in range(nx):
            H[a, j] = 0.0
    if kind == MT_PR or kind == MT_DOP:
        return _raw_model(row, kind, st, fs, cv, nx, H, z, r, sat)
    if kind == MT_TDCP:
        return tdcp.model(row, st, fs, cv, nx, H, z, r, sat, TDCP_SLOTS)
    c = sd._cbn(st)
    lat, lon, h = st[sd.S_LAT], st[sd.S_LON], st[sd.S_H]
    vel = (st[sd.S_VEL], st[sd.S_VEL + 1], st[sd.S_VEL + 2])
    head_known = fs[F_HEAD_KNOWN] > 0.0
    lever = (fs[F_LEVER], fs[F_LEVER + 1], fs[F_LEVER + 2])
    la, td = int(cv[C_LA]), int(cv[C_TD])
    tau = fs[F_TD]
    m = 3
    axis0 = 0
    ax = (0, 1, 2)
    if kind == MT_GNSS_POS:
        rm, rn = radii(np.sin(lat))
        w = (fs[F_W], fs[F_W + 1], fs[F_W + 2])
        v_ant, cw, l_n, w_in = _antenna_velocity(c, vel, lat, h, w, lever)
        # the fix is of the antenna at the stamp + tau: r_ant(t) + v_ant tau
        z[0] = dlon_nb(lon, row[RW_Z + 1]) * (rn + h) * np.cos(lat) + l_n[0] + v_ant[0] * tau   # across 180 deg too
        z[1] = (lat - row[RW_Z]) * (rm + h) + l_n[1] + v_ant[1] * tau
        z[2] = h - row[RW_Z + 2] + l_n[2] + v_ant[2] * tau
        for i in range(3):
            H[i, R + i] = 1.0
        skew_into(H, 0, PHI, l_n, 1.0)
        ge = int(cv[C_GE])
        if ge >= 0:                         # the fix is the antenna plus the GNSS error: predicted with its estimate
            for i in range(3):
                z[i] += fs[F_GE + i]
                H[i, ge + i] = 1.0
        if la >= 0:
            for i in range(3):
                for j in range(3):
                    H[i, la + j] = c[i][j]
        if td >= 0:
            for i in range(3):
                H[i, td] = v_ant[i]
    elif kind == MT_GNSS_VEL:
        if not head_known or fs[F_HAVE_W] == 0.0:
            return 0, 0, 0, 1, 2
        if np.isnan(row[RW_Z + 2]):
            m = 2                               # horizontal only (speed and course): east and north rows
        w = (fs[F_W], fs[F_W + 1], fs[F_W + 2])
        v_ant, cw, l_n, w_in = _antenna_velocity(c, vel, lat, h, w, lever)
        g = gravity(np.sin(lat), h)
        acc = (fs[F_F], fs[F_F + 1], fs[F_F + 2] - g)        # d v / dt, Coriolis neglected (tau small)
        for i in range(3):
            z[i] = v_ant[i] + acc[i] * tau - row[RW_Z + i]
            H[i, V + i] = 1.0
        skew_into(H, 0, PHI, cw, 1.0)
        lx = ((0.0, -lever[2], lever[1]), (lever[2], 0.0, -lever[0]), (-lever[1], lever[0], 0.0))
        clx = m_mul(c, lx)                      # -Cbn [l x] on b_g
        for i in range(3):
            for j in range(3):
                H[i, BG + j] = -clx[i][j]
        if la >= 0:                             # d v_ant / d l = Cbn [w x] - [w_in x] Cbn
            # for the horizontal lever arm only (through the yaw rate): the vertical one would be observed
            # through the roll and pitch rates, which on a car are mostly a mount's vibration, not the
            # antenna's; taken for signal it would drag the estimate to zero; the positions observe it
            wx = ((0.0, -w[2], w[1]), (w[2], 0.0, -w[0]), (-w[1], w[0], 0.0))
            wix = ((0.0, -w_in[2], w_in[1]), (w_in[2], 0.0, -w_in[0]), (-w_in[1], w_in[0], 0.0))
            a1 = m_mul(c, wx)
            a2 = m_mul(wix, c)
            for i in range(3):
                for j in range(2):
                    H[i, la + j] = a1[i][j] - a2[i][j]
        if td >= 0:
            for i in range(3):
                H[i, td] = acc[i]
    elif kind == MT_ZUPT or kind == MT_ZARU:
        speed2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
        if speed2 > cv[C_ZUPT_MAXV] ** 2:
            return 0, 0, 0, 1, 2
        if kind == MT_ZUPT:
            for i in range(3):
                z[i] = vel[i]
                H[i, V + i] = 1.0
        else:
            w_exp = m_tvec(c, (0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)))
            axis0 = 3
            for i in range(3):
                wc = (row[RW_Z + i] - fs[F_BG + i]) / (1.0 + fs[F_SG + i])
                z[i] = wc - w_exp[i]
                H[i, BG + i] = 1.0
                if int(cv[C_NCORE]) > 15:
                    H[i, SG + i] = row[RW_Z + i]
    elif kind == MT_NHC or kind == MT_ODOM:
        if not head_known:
            return 0, 0, 0, 1, 2
        v_b = m_tvec(c, vel)
        vx = ((0.0, -vel[2], vel[1]), (vel[2], 0.0, -vel[0]), (-vel[1], vel[0], 0.0))
        cvx = m_mul(m_trans(c), vx)                         # Cbn^T [v x]
        axis0 = 3
        if kind == MT_NHC:
            m = 2
            ax = (int(cv[C_NHC_AX]), int(cv[C_NHC_AX + 1]), 0)
        for a in range(m):
            i = ax[a]
            z[a] = v_b[i] - (row[RW_Z + i] if kind == MT_ODOM else 0.0)
            for j in range(3):
                H[a, V + j] = c[j][i]
                H[a, PHI + j] = -cvx[i][j]
    else:
        return 0, 0, 0, 1, 2
    for a in range(m):
        s = row[RW_S + ax[a]] if kind == MT_NHC else row[RW_S + a]
        r[a] = s * s
    if kind == MT_GNSS_POS and not head_known:
        # the heading is held out of the filter: the horizontal lever arm points anywhere (l_h^2 / 2 per axis)
        lh2 = 0.5 * (lever[0] * lever[0] + lever[1] * lever[1])
        r[0] += lh2
        r[1] += lh2
    return m, axis0, ax[0], ax[1], ax[2]


@njit(cache=True)
def _adapt_r(kind, z, r, S, m, fs, cv, evs, n_evs, t):
    """Measurement-noise adaptation per kind and axis (module docstring), from the differences of
    consecutive innovations: for a consistent filter the innovations are white, so that
    ``E[(z_k - z_k-1)^2] = S_k + S_k-1``; with R too small by a factor ``s``,
    ``s = (mean dz^2 - mean(HPH_k + HPH_k-1)) / mean(R_k + R_k-1)`` (stated R).  A filter error that grows
    slowly (a diverging heading, a wandering bias) cancels in the difference, so it cannot pass for
    measurement noise and make the filter trust the measurements less and diverge more; a time-correlated
    measurement error cancels too (a calibration pass over the whole log measures it and sets the floor
    ``rbase``, :func:`sinscli.fusion.pipeline.calibrated_noise`).  Each ``dz^2`` is
    clipped at 9 times its variance (an outlier counts as a 3-sigma difference).  Over windows of
    ``adapt.window`` differences the scale moves half-way (in the logarithm) to the estimate when the
    estimate leaves the band a consistent filter keeps it in (the chi-square quantiles 1e-4 and 1 - 1e-4
    of the window); never below the calibrated floor (1 without calibration), at most
    ``adapt.max_scale``.  Returns the
    event count."""
    k = K_OF_KIND[kind]
    if k < 0 or cv[C_RADAPT_N] <= 0.0:
        return n_evs
    for a in range(m):
        i = 3 * k + a
        s_r = fs[F_RS + i]
        rn = r[a] / s_r                         # the stated R
        hph = S[a, a] - r[a]
        p = F_RP + 4 * i
        gap = t - fs[p + 3]
        if fs[p + 3] != 0.0 and gap > 0.0 and gap <= max(cv[C_OUTAGE_DT], 0.5):
            dz = z[a] - fs[p]
            q = F_RA + 4 * i
            fs[q] += min(dz * dz, 9.0 * (S[a, a] + fs[p + 1] + s_r * fs[p + 2]))
            fs[q + 1] += hph + fs[p + 1]
            fs[q + 2] += rn + fs[p + 2]
            fs[q + 3] += 1.0
            n = fs[q + 3]
            if n >= cv[C_RADAPT_N]:
                est = (fs[q] - fs[q + 1]) / fs[q + 2]
                for j in range(4):
                    fs[q + j] = 0.0
                new = s_r
                # half-way in the logarithm toward an estimate out of the band a consistent filter keeps it in
                # (chi-square quantiles of the window: a false move once in ten thousand windows)
                if est > s_r * cv[C_RADAPT_BAND + 1]:
                    new = min(np.sqrt(s_r * est), cv[C_RADAPT_MAX])
                elif est < s_r * cv[C_RADAPT_BAND]:
                    new = max(np.sqrt(s_r * max(est, 1e-12)), cv[C_RBASE + i])
                if new != s_r:
                    fs[F_RS + i] = new
                    n_evs = _event(evs, n_evs, t, EV_RSCALE, float(3 * kind + a), new)
        fs[p] = z[a]
        fs[p + 1] = hph
        fs[p + 2] = rn
        fs[p + 3] = t
    return n_evs


@njit(cache=True)
def _decay_drift_scale(fs, cv, t):
    """The drift process-noise scale decays back toward its base (in its logarithm) with time constant
    ``qb_tau``."""
    base = cv[C_QB_BASE]
    if fs[F_QS_DRIFT] != base and t > fs[F_T_QS]:
        fs[F_QS_DRIFT] = base * np.exp(np.log(fs[F_QS_DRIFT] / base) * np.exp(-(t - fs[F_T_QS]) / cv[C_QB_TAU]))
    fs[F_T_QS] = t


@njit(cache=True)
def _exit_drift_scale(ratio, r_share, fs, cv, evs, n_evs, t):
    """An outage exit tests the dead-reckoning prediction: the ratio of its horizontal innovation squared to
    its predicted variance (logged as an event with the measurement's share of S, for the calibration pass
    of :mod:`sinscli.fusion.pipeline`).  Over ``qb_thr`` the drift process noise (bias instability, scale
    factor and misalignment: the terms that make dead reckoning drift) was too small by about the ratio:
    its scale is multiplied by it, at most ``qb_max`` times its base; an event."""
    n_evs = _event(evs, n_evs, t, EV_EXIT, ratio, r_share)
    if cv[C_QB_MAX] <= 1.0:
        return n_evs
    s_old = fs[F_QS_DRIFT]
    if ratio > cv[C_QB_THR]:
        fs[F_QS_DRIFT] = min(s_old * ratio, cv[C_QB_MAX] * cv[C_QB_BASE])
    if fs[F_QS_DRIFT] != s_old:
        n_evs = _event(evs, n_evs, t, EV_QSCALE, ratio, fs[F_QS_DRIFT])
    return n_evs


@njit(cache=True)
def _inflate(P, Pm, nx, ncore, ge, lam, store):
    """Widen the core states' covariance (navigation and sensor errors, and the GNSS error states ``ge..ge+2``
    when carried: the drift may be the fixes') by ``lam`` >= 1: ``P <- P + (lam - 1) E P E^T`` with ``E`` the
    selector of those states, a positive semi-definite increment
    (a principal block of P embedded with zeros), so that the filter stays positive definite; with ``store``
    the smoother's prior ``Pm`` of this epoch gets the same increment, so that ``Q = P^- - Phi P^+ Phi^T``
    stays positive semi-definite (the widening is process noise of the interval, not a break in the
    chain).  The fading-memory widening of Fagin (1964) and Sorenson & Sacks (1971, eq. 9), restricted to
    the states the mechanization drives."""
    f = lam - 1.0
    if f <= 0.0:
        return
    for i in range(nx):
        if not (i < ncore or (ge >= 0 and ge <= i < ge + 3)):
            continue
        for j in range(nx):
            if not (j < ncore or (ge >= 0 and ge <= j < ge + 3)):
                continue
            d = f * P[i, j]
            if store:
                Pm[i, j] += d
            P[i, j] += d


@njit(cache=True)
def _consistency(z, S, m, nis, fs, cv, t):
    """The consistency test of the GNSS fixes (docs/fusion.md, "A filter too sure of itself").

    Two weighted means (weight ``alpha`` per fix, ``1/alpha`` fixes' memory) are kept: of the NIS per
    component ``min(NIS, gate) / m`` (1 for a consistent filter) and of the consecutive innovations'
    differences ``(1/m) sum_i min(dz_i^2 / (S_ii + S_ii,prev), gate_1)`` (also 1: consecutive innovations
    of a consistent filter are independent).  A filter whose covariance is too small while the fixes agree
    with one another shows the first far above 1 and the second not: its innovations drift away smoothly
    (a bias beyond its prior, a process noise too small, a time-correlated GNSS error taken for white).
    Measurement noise too small shows in both (the measurement-noise adaptation's business); a fix that
    jumped shows in the differences (a component beyond ``gate_1``): after a jump, no widening until a fix
    is taken cleanly again (the jumped fixes stay rejected until the covariance grows honestly).

    Returns the factor ``L`` (> 1) by which the innovation covariance was too small when the first mean is
    over ``C_FADE_THR`` (the chi-square quantile 1 - 1e-4 of its equivalent degrees of freedom), the second
    is not and the means hold at least ``1/alpha`` fixes; then they restart.  Else 0."""
    a = cv[C_FADE_ALPHA]
    g1 = cv[C_GATE]
    prev = fs[F_CT] > -np.inf and t - fs[F_CT] <= cv[C_OUTAGE_DT]
    dl = 1.0
    if prev:
        dl = 0.0
        for i in range(m):
            d = z[i] - fs[F_CZ + i]
            v = d * d / (S[i, i] + fs[F_CS + i])
            if v > g1:
                fs[F_CJ] = 1.0
            dl += min(v, g1)
        dl /= m
    for i in range(m):
        fs[F_CZ + i] = z[i]
        fs[F_CS + i] = S[i, i]
    fs[F_CT] = t
    fs[F_CL] += a * (min(nis, cv[C_GATE + m - 1]) / m - fs[F_CL])
    fs[F_CD] += a * (dl - fs[F_CD])
    fs[F_CN] += 1.0
    thr = cv[C_FADE_THR]
    if fs[F_CJ] == 0.0 and fs[F_CN] * a >= 1.0 and fs[F_CL] > thr and fs[F_CD] < thr:
        lam = fs[F_CL]
        fs[F_CL] = 1.0
        fs[F_CD] = 1.0
        fs[F_CN] = 0.0
        return lam
    return 0.0


@njit(cache=True)
def _apply(row, st, fs, cv, P, mats, vecs, s3, inn, n_inn, evs, n_evs, sat):
    """Apply one measurement row at the current time (the state is at its time).  Returns counters."""
    nx = int(cv[C_NX])
    kind = int(row[RW_KIND])
    t = row[RW_T]
    if kind == MT_COURSE:
        return n_inn, _heading_from_course(row, st, fs, cv, P, nx, evs, n_evs)
    if kind == MT_CLOCK:
        return n_inn, _clock_check(row, fs, cv, P, nx, evs, n_evs)
    H = vecs[V_H:V_H + 3]
    z = vecs[V_Z]
    r = vecs[V_R]
    x = vecs[V_X]
    m, axis0, a0, a1, a2 = _model(row, kind, st, fs, cv, nx, H, z, r, sat)
    if m == 0:
        return n_inn, n_evs
    if kind == MT_GNSS_POS and int(cv[C_GE]) >= 0:
        _gnss_error_level(row, fs, cv, P, mats[W_PM], cv[C_SMOOTH_DT] > 0.0)
    k = K_OF_KIND[kind]
    if k >= 0:
        for a in range(m):
            r[a] *= fs[F_RS + 3 * k + a]
    head_known = fs[F_HEAD_KNOWN] > 0.0
    if not head_known:
        for i in range(nx):
            P[i, PHI + 2] = 0.0
            P[PHI + 2, i] = 0.0
    gate = cv[C_GATE + m - 1]
    HP = vecs[V_HP:V_HP + 3]
    KT = vecs[V_KT:V_KT + 3]
    A = mats[W_A]
    S, Si = s3[0], s3[1]
    innovation_covariance(P, nx, H, r, m, HP, S)
    nis = nis_of(S, z, m, Si)
    if not np.isfinite(nis):
        return n_inn, n_evs
    hph = (S[0, 0] - r[0], S[1, 1] - r[1], S[2, 2] - r[2])
    rst = (r[0] / fs[F_RS + 3 * k] if k >= 0 else r[0], r[1] / fs[F_RS + 3 * k + 1] if k >= 0 else r[1],
           r[2] / fs[F_RS + 3 * k + 2] if k >= 0 else r[2])
    acc = nis < gate
    if kind == MT_TDCP and row[TDCP_SLIP] != 0.0:     # a slip (tdcp.screen): left out, an event
        acc = False
        n_evs = _event(evs, n_evs, t, EV_SLIP, row[RW_AUX], row[TDCP_SLIP])
    nis_report = nis
    exit_fix = False
    if kind == MT_GNSS_POS:
        exit_fix = fs[F_T_FIX] > -np.inf and t - fs[F_T_FIX] > cv[C_OUTAGE_DT]
        fs[F_T_FIX] = t
        _decay_drift_scale(fs, cv, t)
    if k >= 0 and not exit_fix:
        n_evs = _adapt_r(kind, z, r, S, m, fs, cv, evs, n_evs, t)
    store = cv[C_SMOOTH_DT] > 0.0
    ncore = int(cv[C_NCORE])
    if kind == MT_GNSS_POS and not exit_fix and cv[C_FADE_ALPHA] > 0.0:
        lam_s = _consistency(z, S, m, nis, fs, cv, t)
        if lam_s > 0.0:
            # the covariance that makes the innovation covariance lam_s times larger: (lam_s tr S - tr R) / tr HPH
            trs, trr = 0.0, 0.0
            for a in range(m):
                trs += S[a, a]
                trr += r[a]
            lam = min(max((lam_s * trs - trr) / max(trs - trr, 1e-300), 1.0), cv[C_FADE_MAX])
            _inflate(P, mats[W_PM], nx, ncore, int(cv[C_GE]), lam, store)
            n_evs = _event(evs, n_evs, t, EV_WIDEN, lam_s, lam)
            innovation_covariance(P, nx, H, r, m, HP, S)
            nis = nis_of(S, z, m, Si)
            nis_report = nis
            hph = (S[0, 0] - r[0], S[1, 1] - r[1], S[2, 2] - r[2])
            acc = nis < gate
    if exit_fix:
        # the dead-reckoning prediction tested: its horizontal innovation against its variance
        ratio = (z[0] * z[0] + z[1] * z[1]) / (S[0, 0] + S[1, 1])
        n_evs = _exit_drift_scale(ratio, (r[0] + r[1]) / (S[0, 0] + S[1, 1]), fs, cv, evs, n_evs, t)
        fs[F_CT] = -np.inf                      # the consistency statistics start again after an outage
        if not acc:
            # reacquisition: the dead reckoning's covariance was too small by about the ratio (_inflate)
            n_evs = _event(evs, n_evs, t, EV_REACQUIRE, nis, ratio)
            _inflate(P, mats[W_PM], nx, ncore, int(cv[C_GE]), ratio, store)
            innovation_covariance(P, nx, H, r, m, HP, S)
            nis_of(S, z, m, Si)
            acc = True                          # a reacquired fix is taken (the widening made room)
    elif kind == MT_GNSS_POS and not acc:
        if fs[F_NREJ] == 0.0:
            fs[F_TREJ0] = t
        fs[F_NREJ] += 1.0
        if fs[F_NREJ] >= cv[C_REJ_RUN]:
            # a run of rejected fixes: the filter diverged (or the GNSS jumped and stays): the navigation
            # block widened by the fix's horizontal innovation against its variance (_inflate), the fix taken
            n_evs = _event(evs, n_evs, t, EV_REJECTION_RUN, fs[F_TREJ0], fs[F_NREJ])
            run_ratio = max((z[0] * z[0] + z[1] * z[1]) / (S[0, 0] + S[1, 1]), nis / m)
            _inflate(P, mats[W_PM], nx, ncore, int(cv[C_GE]), run_ratio, store)
            innovation_covariance(P, nx, H, r, m, HP, S)
            nis_of(S, z, m, Si)
            acc = True
            fs[F_NREJ] = 0.0
            fs[F_CJ] = 0.0
    elif kind == MT_PR and _epoch_rejected(fs, cv, t, acc):
        # every pseudorange of rej_run consecutive epochs rejected: the filter diverged (or the receiver's
        # ranges jumped and stay): the navigation block and the clock bias widened by this satellite's NIS
        # (_widen_nav, _widen_state), the satellite taken
        n_evs = _event(evs, n_evs, t, EV_REJECTION_RUN, fs[F_EP_T0], fs[F_EP_NREJ])
        _widen_nav(P, nx, nis)
        _widen_state(P, nx, int(cv[C_CLK]), nis)
        innovation_covariance(P, nx, H, r, m, HP, S)
        nis_of(S, z, m, Si)
        acc = True
        fs[F_EP_NREJ] = 0.0
        fs[F_RESET] = 1.0
    elif acc and (k >= 0 or kind == MT_PR or kind == MT_DOP or kind == MT_TDCP):
        # IGG-III robust weight: above the full-weight bound the noise is inflated smoothly up to the gate
        k0 = cv[C_ROBUST + m - 1]
        if k0 > 0.0 and nis > k0:
            u, u0, u1 = np.sqrt(nis), np.sqrt(k0), np.sqrt(gate)
            infl = (u / u0) * ((u1 - u0) / (u1 - u)) ** 2
            for a in range(m):
                r[a] *= infl
            innovation_covariance(P, nx, H, r, m, HP, S)
            nis_of(S, z, m, Si)
    if acc and kind == MT_GNSS_POS:
        fs[F_NREJ] = 0.0
        if nis < cv[C_ROBUST + m - 1] or cv[C_ROBUST + m - 1] <= 0.0:
            fs[F_CJ] = 0.0                      # taken cleanly: a jump before it is over
    if kind == MT_PR:
        if acc:
            fs[F_EP_ACC] += 1.0
        else:
            fs[F_EP_REJ] += 1.0
    axes = (a0, a1, a2)
    sat_row = row[RW_AUX] if kind == MT_PR or kind == MT_DOP or kind == MT_TDCP else -1.0
    for a in range(m):
        n_inn = _record(inn, n_inn, t, kind, axis0 + axes[a], z[a], S[a, a], nis_report, acc, hph[a], rst[a],
                        exit_fix, a, sat_row)
    if acc:
        kalman_apply(P, nx, H, z, r, m, x, HP, KT, A, Si)
        if not head_known:
            x[PHI + 2] = 0.0
        feedback(st, fs, cv, x, nx, int(cv[C_METHOD]))
    return n_inn, n_evs


@njit(cache=True)
def _epoch_rejected(fs, cv, t, acc):
    """Book-keeping of the raw epochs (pseudorange rows): at the first row of a new epoch the previous one is
    counted as rejected (all its pseudoranges rejected) or not; True when this row is rejected and
    ``rejection_run`` consecutive epochs before it were."""
    if t != fs[F_EP_T]:
        if fs[F_EP_ACC] == 0.0 and fs[F_EP_REJ] > 0.0:
            if fs[F_EP_NREJ] == 0.0:
                fs[F_EP_T0] = fs[F_EP_T]
            fs[F_EP_NREJ] += 1.0
        elif fs[F_EP_ACC] > 0.0:
            fs[F_EP_NREJ] = 0.0
        fs[F_EP_T] = t
        fs[F_EP_ACC] = 0.0
        fs[F_EP_REJ] = 0.0
    return not acc and fs[F_EP_NREJ] >= cv[C_REJ_RUN]


@njit(cache=True)
def _widen_nav(P, nx, ratio):
    """Widen the navigation rows and columns of P (position, velocity, attitude) by ``sqrt(ratio)``: their
    block by the ratio, their correlations with the sensor states kept (a congruence: P stays positive
    definite).  Where the innovations show the dead reckoning's covariance too small by that ratio."""
    f = np.sqrt(max(ratio, 1.0))
    for i in range(nx):
        for j in range(nx):
            if i < 9:
                P[i, j] *= f
            if j < 9:
                P[i, j] *= f


@njit(cache=True)
def _store_epoch(t, P, Pm, nx, ncore, fs, Phi, ep, n_ep, clk, clone=-1):
    """One smoother epoch: P- and P+ (upper triangles, row by row), the transition matrix since the
    previous epoch (its navigation rows over the core states, then the diagonal of the other rows, then with
    a receiver clock at state ``clk`` its bias-drift entry, then with TDCP clones at ``clone`` their 4 rows), the
    correction fed back since the previous epoch, the reset flag; the transition matrix restarts at I."""
    ep_t, ep_pm, ep_pp, ep_ft, ep_x, ep_reset = ep
    if n_ep < ep_t.shape[0]:
        ep_t[n_ep] = t
        u = 0
        for i in range(nx):
            ep_x[n_ep, i] = fs[F_XACC + i]
            fs[F_XACC + i] = 0.0
            for j in range(i, nx):
                ep_pm[n_ep, u] = Pm[i, j]
                ep_pp[n_ep, u] = P[i, j]
                u += 1
        u = 0
        for i in range(9):
            for j in range(ncore):
                ep_ft[n_ep, u] = Phi[i, j]
                u += 1
        for i in range(9, nx):
            ep_ft[n_ep, u] = Phi[i, i]
            u += 1
        if clk >= 0:
            ep_ft[n_ep, u] = Phi[clk, clk + 1]
            u += 1
        if clone >= 0:
            for i in range(clone, clone + 4):
                for j in range(nx):
                    ep_ft[n_ep, u] = Phi[i, j]
                    u += 1
        ep_reset[n_ep] = fs[F_RESET]
    for i in range(nx):
        for j in range(nx):
            Phi[i, j] = 1.0 if i == j else 0.0
    fs[F_RESET] = 0.0
    fs[F_T_EPOCH] = t
    return n_ep + 1


@njit(cache=True)
def _measure_group(tm, meas, im, st, fs, cv, P, ws, rec, ep, n_ep, tol, sat):
    """Propagate P to ``tm`` and apply every row at that time; store the smoother epoch."""
    mats, vecs, s3 = ws
    inn, n_inn, evs, n_evs = rec
    store = cv[C_SMOOTH_DT] > 0.0
    _do_propagate(st, fs, cv, P, mats, store)
    nx = int(cv[C_NX])
    Pm = mats[W_PM]
    if store:
        for i in range(nx):
            for j in range(nx):
                Pm[i, j] = P[i, j]
    nm = meas.shape[0]
    t_raw = -np.inf                             # the time of this group's raw GNSS rows (TDCP clones them)
    while im < nm and meas[im, RW_T] <= tm + tol:
        kind = int(meas[im, RW_KIND])
        if kind >= MT_PR and meas[im, RW_T] != t_raw:
            t_raw = meas[im, RW_T]
            if int(cv[C_TDCP]) >= 0:            # a new raw epoch: its TDCP rows against the INS prediction
                wide = tdcp.screen(meas, im, st, fs, cv, P, nx, sat, mats, vecs, TDCP_SLOTS)
                if wide < 0.0:                  # the prediction, not the carriers: widened (as a rejection run)
                    _widen_nav(P, nx, -wide)
                    _widen_state(P, nx, int(cv[C_CLK]), -wide)
                    fs[F_RESET] = 1.0
                    n_evs = _event(evs, n_evs, meas[im, RW_T], EV_WIDEN, -wide, -wide)
        n_inn, n_evs = _apply(meas[im], st, fs, cv, P, mats, vecs, s3, inn, n_inn, evs, n_evs, sat)
        im += 1
    if not _health(P, nx, fs, tm, mats[W_L], True):
        return im, n_inn, n_evs, n_ep
    if store:
        n_ep = _store_epoch(tm, P, Pm, nx, int(cv[C_NCORE]), fs, mats[W_PHI], ep, n_ep, int(cv[C_CLK]),
                            int(cv[C_TDCP]))
    if t_raw > -np.inf and int(cv[C_TDCP]) >= 0:
        tdcp.clone(st, fs, cv, P, nx, t_raw, mats, store, TDCP_SLOTS)
    return im, n_inn, n_evs, n_ep


@njit(cache=True, inline="always")
def row_variances(out, n, c, fwd, pe, pn, pu, ve, vn, vu, aee, ann, auu, aen, head_known):
    """The variances of an output row: position, velocity, then roll, pitch (the phi block about the
    body's forward and right axes, levelled) and heading (-1 while the heading is unknown)."""
    ue, un = c[0][fwd], c[1][fwd]
    nrm = np.sqrt(ue * ue + un * un)
    if nrm > 1e-12:
        ue /= nrm
        un /= nrm
    else:
        ue, un = 0.0, 1.0
    out[n, 0] = pe
    out[n, 1] = pn
    out[n, 2] = pu
    out[n, 3] = ve
    out[n, 4] = vn
    out[n, 5] = vu
    out[n, 6] = ue * ue * aee + un * un * ann + 2.0 * ue * un * aen        # about the forward axis
    out[n, 7] = un * un * aee + ue * ue * ann - 2.0 * ue * un * aen        # about the right axis
    out[n, 8] = auu if head_known else -1.0


@njit(cache=True)
def fuse(imu, nav, meas, ws, out, rec, ep, n_ep, sat):
    """Fused navigation of one block of IMU samples with the measurement rows ``meas`` (module docstring) and
    the satellite table ``sat`` of their raw GNSS rows (:data:`SAT`; (0, SW) without).

    ``imu = (time, dtheta_b, dvel_b)``; ``nav = (st, fs, cv, P, cflu)``: the strapdown state
    (:func:`sinscli.nav.strapdown.new_state`), the filter scalars (:data:`FS`), the configuration
    (:data:`CV`), the covariance (nx, nx) and the FLU rotation of the body convention;
    ``ws = (mats, vecs, s3)`` the :func:`workspace`; ``out = (t, pos, vel, cbn, var, bias)`` the output
    rows, written every ``nsub * every`` samples (position, velocity, Cbn, the variances of
    :func:`row_variances`, the sensor estimates); ``rec = (inn, evs)`` innovation records and events;
    ``ep`` the smoother's epoch arrays, written from index ``n_ep``.  Returns ``(rows, measurement rows
    consumed, innovation records, events, n_ep)``; stops early with ``fs[F_ERR]`` set when the
    covariance turns non-finite or loses positive definiteness.
    """
    time, dtheta_b, dvel_b = imu
    st, fs, cv, P, cflu_arr = nav
    mats, vecs, s3 = ws
    out_t, out_pos, out_vel, out_cbn, out_var, out_bias = out
    inn, evs = rec
    nx = int(cv[C_NX])
    method = int(cv[C_METHOD])
    order = int(cv[C_ORDER])
    nsub = int(cv[C_NSUB])
    per_out = nsub * int(cv[C_EVERY])
    fwd = int(cv[C_FWD])
    smooth_dt = cv[C_SMOOTH_DT]
    store = smooth_dt > 0.0
    cflu = ((cflu_arr[0, 0], cflu_arr[0, 1], cflu_arr[0, 2]), (cflu_arr[1, 0], cflu_arr[1, 1], cflu_arr[1, 2]),
            (cflu_arr[2, 0], cflu_arr[2, 1], cflu_arr[2, 2]))
    Pm = mats[W_PM]
    events = np.empty((1, sd.N_EVENT))
    buf_th = np.empty((1, 3))
    buf_dv = np.empty((1, 3))
    n_ev = 0
    n_out = 0
    n_inn = 0
    n_evs = 0
    im = 0
    nm = meas.shape[0]
    prev_dth, prev_dv, n_prev, sums, nsub_now = sd.load_fast(st)
    z3 = (0.0, 0.0, 0.0)
    for k in range(time.shape[0]):
        tk = time[k]
        t0s = fs[F_TPREV]
        dt = tk - t0s
        tol = 1e-6 * dt
        for i in range(3):
            buf_th[0, i] = (dtheta_b[k, i] - fs[F_BG + i] * dt) / (1.0 + fs[F_SG + i])
            buf_dv[0, i] = (dvel_b[k, i] - fs[F_BA + i] * dt) / (1.0 + fs[F_SA + i])
        th_full = (buf_th[0, 0], buf_th[0, 1], buf_th[0, 2])
        dv_full = (buf_dv[0, 0], buf_dv[0, 1], buf_dv[0, 2])
        frac = 0.0
        # measurements strictly inside the interval: split the increments at their time
        while im < nm and meas[im, RW_T] < tk - tol:
            tm = meas[im, RW_T]
            if tm <= t0s + tol:          # before the navigation start: not used
                im += 1
                continue
            a = (tm - t0s) / dt
            for i in range(3):
                buf_th[0, i] = th_full[i] * (a - frac)
                buf_dv[0, i] = dv_full[i] * (a - frac)
            sums, n_prev = sd.fast_sample(buf_th, buf_dv, 0, sums, prev_dth, prev_dv, n_prev, order)
            n_ev = _close(st, fs, sums, order, method, tm, cflu, events, n_ev)
            sums = (z3, z3, z3, z3)
            nsub_now = 0
            frac = a
            im, n_inn, n_evs, n_ep = _measure_group(tm, meas, im, st, fs, cv, P, ws, (inn, n_inn, evs, n_evs), ep,
                                                    n_ep, tol, sat)
            if fs[F_ERR] != 0.0:
                sd.save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
                return n_out, im, n_inn, n_evs, n_ep
        for i in range(3):
            buf_th[0, i] = th_full[i] * (1.0 - frac)
            buf_dv[0, i] = dv_full[i] * (1.0 - frac)
        sums, n_prev = sd.fast_sample(buf_th, buf_dv, 0, sums, prev_dth, prev_dv, n_prev, order)
        nsub_now += 1
        fs[F_TPREV] = tk
        fs[F_NSAMP_OUT] += 1.0
        due = im < nm and meas[im, RW_T] <= tk + tol
        if nsub_now < nsub and not due:
            continue
        n_ev = _close(st, fs, sums, order, method, tk, cflu, events, n_ev)
        sums = (z3, z3, z3, z3)
        nsub_now = 0
        if due:
            im, n_inn, n_evs, n_ep = _measure_group(tk, meas, im, st, fs, cv, P, ws, (inn, n_inn, evs, n_evs), ep,
                                                    n_ep, tol, sat)
            if fs[F_ERR] != 0.0:
                break
        elif fs[F_ACC_T] >= cv[C_PROP_DT] * (1.0 - 1e-9):
            _do_propagate(st, fs, cv, P, mats, store)
            if not _health(P, nx, fs, tk, mats[W_L], False):
                break
            if store and tk - fs[F_T_EPOCH] >= smooth_dt * (1.0 - 1e-9):
                for i in range(nx):
                    for j in range(nx):
                        Pm[i, j] = P[i, j]
                n_ep = _store_epoch(tk, P, Pm, nx, int(cv[C_NCORE]), fs, mats[W_PHI], ep, n_ep, int(cv[C_CLK]),
                                    int(cv[C_TDCP]))
        if fs[F_NSAMP_OUT] >= per_out and n_out < out_t.shape[0]:
            fs[F_NSAMP_OUT] = 0.0
            out_t[n_out] = tk
            out_pos[n_out, 0] = st[sd.S_LAT]
            out_pos[n_out, 1] = st[sd.S_LON]
            out_pos[n_out, 2] = st[sd.S_H]
            for i in range(3):
                out_vel[n_out, i] = st[sd.S_VEL + i]
                for j in range(3):
                    out_cbn[n_out, i, j] = st[sd.S_CBN + 3 * i + j]
            row_variances(out_var, n_out, sd._cbn(st), fwd, P[R, R], P[R + 1, R + 1], P[R + 2, R + 2],
                          P[V, V], P[V + 1, V + 1], P[V + 2, V + 2], P[PHI, PHI], P[PHI + 1, PHI + 1],
                          P[PHI + 2, PHI + 2], P[PHI, PHI + 1], fs[F_HEAD_KNOWN] > 0.0)
            for i in range(NBIAS):
                out_bias[n_out, i] = fs[i]
            n_out += 1
    sd.save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
    return n_out, im, n_inn, n_evs, n_ep

