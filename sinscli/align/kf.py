"""Kalman-filter fine alignment: attitude error, velocity error, gyro and accelerometer biases.

State (12): ``x = [phi (3, ENU), dv (3, ENU m/s), eps (3, body rad/s), nabla (3, body m/s^2)]``
with the computed attitude ``Cbn_c = (I - [phi x]) Cbn`` and ``dv = v_c - v``.
Error model of the ENU strapdown equations over an alignment (position
errors left out: they change gravity and the earth rate negligibly in
minutes):

    phi'   = -w_in^n x phi - Cbn eps               - Cbn w_g      (w_g: ARW)
    dv'    =  f^n x phi - (2 w_ie^n + w_en^n) x dv + Cbn nabla + Cbn w_a      (w_a: VRW)
    eps'   = 0,    nabla' = 0

The gyro scale factor and misalignment ``E`` (``w_meas = (I + E) w + eps``) are not states; with
``E_cov`` given they enter the error covariance ``P_true`` as consider parameters (``phi' = ... - Cbn E
w``, no gain on them), so the reported covariance carries what the 12 states leave out.

Measurements: ``z = v_c - v_ref`` (zero at rest, the GNSS velocity moved to
the IMU by the lever arm when moving), ``H = [0 I 0 0]``.  The filter runs
closed loop: after each update the attitude and velocity are corrected, the
bias estimates are added to the ones that compensate the following IMU
increments, and the state is reset to zero.  The navigation between updates
is the project's (:func:`sinscli.nav.pipeline.navigate`).  No I/O here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..nav.earth import OMEGA_IE, transport_rate_n
from ..nav.pipeline import NavOptions, navigate
from ..nav.rotation import orthonormalize, rotvec_to_dcm, skew
from ..types import ImuLog, NavState

NX = 12
PHI, DV, EPS, NAB = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
GATE = 30.7      # normalized innovation squared beyond which an update is an outlier (chi-square 3, p = 1e-6)


def error_dynamics(cbn, f_n, lat, h, vel_n):
    """Continuous-time error matrix ``F`` (12, 12) at one instant (module docstring)."""
    w_ie = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    w_en = transport_rate_n(lat, h, np.asarray(vel_n, dtype=float))
    F = np.zeros((NX, NX))
    F[PHI, PHI] = -skew(w_ie + w_en)
    F[PHI, EPS] = -cbn
    F[DV, PHI] = skew(np.asarray(f_n, dtype=float))
    F[DV, DV] = -skew(2.0 * w_ie + w_en)
    F[DV, NAB] = cbn
    return F


def discretize(F, T, q_gyro, q_accel, q_bias_g=0.0, q_bias_a=0.0):
    """``(Phi, Qd)`` over ``T`` s: ``Phi = I + F T + (F T)^2/2``, white-noise densities on the attitude
    (``q_gyro`` rad^2/s) and velocity (``q_accel`` (m/s)^2/s) errors and bias random walks, with the
    trapezoidal ``Qd = (Phi Q Phi^T + Q) T / 2``."""
    FT = F * T
    Phi = np.eye(NX) + FT + 0.5 * FT @ FT
    q = np.zeros(NX)
    q[PHI] = q_gyro
    q[DV] = q_accel
    q[EPS] = q_bias_g
    q[NAB] = q_bias_a
    Q = np.diag(q)
    return Phi, 0.5 * T * (Phi @ Q @ Phi.T + Q)


def predict(x, P, Phi, Qd):
    return Phi @ x, Phi @ P @ Phi.T + Qd


def _pad(A, n):
    """``A`` (k, k) in the top-left corner of a (k + n, k + n) zero matrix."""
    out = np.zeros((A.shape[0] + n, A.shape[1] + n))
    out[:A.shape[0], :A.shape[1]] = A
    return out


def update_velocity(x, P, z, r_var, gate=None, P_true=None):
    """Measurement update with ``H = [0 I 0 0]`` and ``R = diag(r_var)`` (Joseph form).

    Returns ``(x, P, nis, P_true)``: the normalized innovation squared ``nu^T S^-1 nu``; above
    ``gate`` the update is skipped (an outlier) and ``x``, ``P`` are returned as they were.
    ``P_true``: a second covariance updated with this filter's gain (the error covariance of this
    filter when the truth follows another prior; Joseph form holds for any gain)."""
    H = np.zeros((3, NX))
    H[:, DV] = np.eye(3)
    R = np.diag(np.broadcast_to(r_var, (3,)))
    S = H @ P @ H.T + R
    nu = z - H @ x
    nis = float(nu @ np.linalg.solve(S, nu))
    if gate is not None and nis > gate:
        return x, P, nis, P_true
    K = np.linalg.solve(S, H @ P).T
    x = x + K @ nu
    IKH = np.eye(NX) - K @ H
    P = IKH @ P @ IKH.T + K @ R @ K.T
    if P_true is not None:
        nc = P_true.shape[0] - NX
        Ka = np.vstack([K, np.zeros((nc, 3))])               # no gain on consider parameters
        Ha = np.hstack([H, np.zeros((3, nc))])
        IKHa = np.eye(NX + nc) - Ka @ Ha
        P_true = IKHa @ P_true @ IKHa.T + Ka @ R @ Ka.T
        P_true = 0.5 * (P_true + P_true.T)
    return x, 0.5 * (P + P.T), nis, P_true


@dataclass
class FineResult:
    state: NavState                 # corrected state at the last update
    P: np.ndarray                   # (12, 12) covariance after the last update (biases in body axes)
    gyro_bias: np.ndarray           # (3,) rad/s, estimated
    accel_bias: np.ndarray          # (3,) m/s^2, estimated
    times: np.ndarray               # (n,) update epochs
    cbn: np.ndarray                 # (n, 3, 3) corrected attitude at each update
    sigma_phi: np.ndarray           # (n, 3) attitude 1-sigma (rad, ENU) after each update
    P_true: np.ndarray | None = None    # (12, 12) error covariance for the other prior (``P0_true``)
    nis_sum: float = 0.0            # sum of the normalized innovations squared of the updates used
    n_updates: int = 0
    n_rejected: int = 0             # updates skipped by the gate (outliers)


def fine_align(imu: ImuLog, k_updates, init: NavState, v_ref, r_var, P0, q_gyro, q_accel,
               position=None, lever_b=None, w_ib_b=None, nav_opts: NavOptions | None = None,
               progress=None, q_bias_g=0.0, q_bias_a=0.0, gate=GATE, P0_true=None, E_cov=None) -> FineResult:
    """Run the filter over ``imu`` (increments after ``init.time``) with updates after samples ``k_updates``.

    ``v_ref`` (n, 3): reference velocity at each update (the antenna's when
    ``lever_b`` is given, then ``w_ib_b`` (n, 3) is the body rate there);
    ``r_var`` (n, 3) its variance; ``position(t) -> (lat, lon, h)`` resets the
    position at each update (the known position at rest, GNSS when moving;
    None keeps the navigated one).  ``P0`` (12, 12) initial covariance;
    ``q_gyro``, ``q_accel`` noise densities, ``q_bias_g``, ``q_bias_a`` the bias random walks'.
    Updates whose normalized innovation squared exceeds ``gate`` are skipped and counted.
    ``P0_true``: carry the error covariance of this filter for that initial covariance as well
    (``FineResult.P_true``; default: ``P``); ``E_cov`` (9, 9): the gyro matrix ``E`` (row-major) as
    consider parameters of that covariance (module docstring).
    """
    opts = nav_opts or NavOptions(attitude="quat", coning=2)
    # navigate in time relative to the start (large epochs such as UNIX time keep their precision)
    t_ref = float(init.time)
    rel_time = imu.time - t_ref
    init = NavState(0.0, init.lat, init.lon, init.height, np.asarray(init.vel_n, dtype=float), init.Cbn)
    x = np.zeros(NX)
    P = np.array(P0, dtype=float)
    Pt = None if P0_true is None else np.array(P0_true, dtype=float)
    nc = 0
    if E_cov is not None:
        nc = 9
        Pt = np.zeros((NX + nc, NX + nc)) if Pt is None else _pad(Pt, nc)
        if P0_true is None:
            Pt[:NX, :NX] = P
        Pt[NX:, NX:] = E_cov
    bg = np.zeros(3)
    ba = np.zeros(3)
    state = init
    k_prev = -1
    t_prev = init.time
    times, cbns, sig = [], [], []
    nis_sum, n_rej = 0.0, 0
    for j, k in enumerate(k_updates):
        sl = slice(k_prev + 1, k + 1)
        t_seg = rel_time[sl]
        dt = np.diff(np.concatenate([[t_prev], t_seg]))
        dth = imu.dtheta_b[sl] - bg[None, :] * dt[:, None]
        dv = imu.dvel_b[sl] - ba[None, :] * dt[:, None]
        traj = navigate(ImuLog(t_seg, dth, dv, t0=t_prev, source=imu.source), state, opts)
        T = float(t_seg[-1] - t_prev)
        c_end = traj.Cbn[-1]
        c_mid = orthonormalize(0.5 * (state.Cbn + c_end))
        f_n = c_mid @ (dv.sum(axis=0) / T)
        F = error_dynamics(c_mid, f_n, state.lat, state.height, 0.5 * (state.vel_n + traj.vel_n[-1]))
        Phi, Qd = discretize(F, T, q_gyro, q_accel, q_bias_g, q_bias_a)
        x, P = predict(x, P, Phi, Qd)
        if Pt is not None and nc:
            w_b = dth.sum(axis=0) / T                       # mean body rate over the step
            Fa = _pad(F, nc)
            Fa[PHI, NX:] = -np.einsum("ai,j->aij", c_mid, w_b).reshape(3, 9)
            FT = Fa * T
            Phia = np.eye(NX + nc) + FT + 0.5 * FT @ FT
            Pt = Phia @ Pt @ Phia.T + _pad(Qd, nc)
        elif Pt is not None:
            Pt = Phi @ Pt @ Phi.T + Qd
        v_c = traj.vel_n[-1].copy()
        if lever_b is not None:
            v_c = v_c + c_end @ np.cross(w_ib_b[j], lever_b)
        x, P, nis, Pt = update_velocity(x, P, v_c - v_ref[j], r_var[j], gate, Pt)
        if gate is not None and nis > gate:
            n_rej += 1
        else:
            nis_sum += nis
        # closed loop: correct, accumulate the biases, reset
        cbn = orthonormalize(rotvec_to_dcm(x[PHI]) @ c_end)
        vel = traj.vel_n[-1] - x[DV]
        bg = bg + x[EPS]
        ba = ba + x[NAB]
        x = np.zeros(NX)
        if position is not None:
            lat, lon, h = position(float(t_seg[-1]) + t_ref)
        else:
            lat, lon, h = float(traj.lat[-1]), float(traj.lon[-1]), float(traj.height[-1])
        state = NavState(float(t_seg[-1]), lat, lon, h, vel, cbn)
        times.append(state.time)
        cbns.append(cbn)
        sig.append(np.sqrt(np.maximum(np.diag(P)[PHI], 0.0)))
        k_prev = k
        t_prev = float(t_seg[-1])
        if progress is not None:
            progress(1)
    state = NavState(state.time + t_ref, state.lat, state.lon, state.height, state.vel_n, state.Cbn)
    return FineResult(state, P, bg, ba, np.array(times) + t_ref, np.array(cbns), np.array(sig),
                      P if Pt is None else Pt[:NX, :NX], nis_sum, len(k_updates), n_rej)
