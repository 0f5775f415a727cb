"""Strapdown navigation in the launch-centred inertial frame (seed 000's frame): a numba kernel.

The frame ``i`` (docs/inertial.md, :mod:`sinscli.nav.earth`): origin at the launch
point at the launch time t_L, x_i horizontal along the launch azimuth, y_i up along the
ellipsoid normal, z_i = x_i x y_i; frozen in inertial space.  In it the strapdown
equations have no frame rotation, no Coriolis and no transport terms:

    C_b^i(t_m) = C_b^i(t_{m-1}) exp([phi_m x])                      (seed 000 eqs 3-4, 12-14)
    v^i_m     = v^i_{m-1} + C_b^i(t_{m-1}) dv^{b(m-1)} + G(r_mid) T
    r^i_m     = r^i_{m-1} + int v^i dt                               (fourth-order rule)

``phi_m`` and ``dv^{b(m-1)}`` (rotation-compensated, sculling-corrected) are the
interval's body increments of :mod:`sinscli.nav.coning`, exactly as in the ENU loop;
``G`` is the WGS-84 gravitation with J2 (:func:`sinscli.nav.earth.gravitation`) at
the interval midpoint; the position is the fourth-order Adams-Moulton rule of
:func:`sinscli.nav.mechanization.displacement`.  The attitude update is the ENU loop's
own (:func:`sinscli.nav.strapdown._attitude_update`, dcm / seed000 / quat) with a zero
navigation-frame rotation; the state vector extends the ENU loop's layout (``S_CBN``
holds ``C_b^i``, ``S_VEL`` holds ``v^i``).

Outputs are converted back to the earth: position ``R^e = C_i^e(t) (R_0^i + r^i)`` to
latitude, longitude, height; velocity relative to the earth in ENU,
``v^n = C_e^n (C_i^e v^i - W x R^e)``; attitude ``Cbn = C_e^n C_i^e(t) C_b^i``; plus the
inertial columns ``x_i, y_i, z_i, vx_i, vy_i, vz_i``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import SinsError
from ..types import NavState, Trajectory
from .earth import (OMEGA_IE, ecef_to_lla, ecef_to_launch_axes_py, enu_rotation, gravitation,
                    launch_axes, launch_to_ecef_axes_py, lla_to_ecef)
from .mechanization import displacement
from .rotation import m_tvec, m_vec, v_add, v_scale
from .strapdown import (S_HAVE_MM2, S_NOUT, S_TMM2, S_TMM3, S_TSTART,
                        S_VEL, S_VMM2, S_VMM3, STATE, STATE_SIZE, _acc, _attitude_update, _cbn, _vec,
                        close_interval, fast_sample, load_fast, save_fast, store_interval)
from .strapdown import new_state as _enu_new_state

# Extra trajectory columns of the launch-inertial frame (m, m/s).
COLUMNS = ("x_i", "y_i", "z_i", "vx_i", "vy_i", "vz_i")

# --- state vector: the ENU loop's layout plus these slots ------------------
I_STATE = STATE.extend("launch-inertial state", [
    ("S_R", 3),                # r^i, position from the launch point, m
    ("S_RLO", 3),              # compensated-summation residues of r^i
    ("S_CEI", 9),              # C_e^i at launch (row-major), constant
    ("S_R0E", 3),              # launch point in ECEF, m, constant
], total=STATE_SIZE + 18)
S_R, S_RLO, S_CEI, S_R0E = I_STATE.offsets("S_R", "S_RLO", "S_CEI", "S_R0E")
I_STATE_SIZE = I_STATE.total

_ZERO3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class LaunchFrame:
    """The launch-inertial frame: launch point and azimuth (radians, m), launch time (s)."""
    time: float
    lat: float
    lon: float
    height: float
    azimuth: float

    @property
    def c_ei(self) -> np.ndarray:
        """``C_e^i`` at launch (3, 3)."""
        return launch_axes(self.lat, self.lon, self.azimuth)

    @property
    def r0_e(self) -> np.ndarray:
        """The launch point in ECEF (3,), m."""
        return lla_to_ecef(self.lat, self.lon, self.height)


def launch_frame(launch, t_default: float, src: str = "navigation.launch") -> LaunchFrame:
    """A :class:`LaunchFrame` from a mapping ``{lat, lon (deg), height (m), azimuth (deg), [time (s)]}``.

    ``time`` defaults to ``t_default`` (the initial state's time).  Raises ``SinsError``
    naming ``src`` and the key when a key is missing or not a finite number.
    """
    if launch is None:
        raise SinsError(f"{src}: frame launch-inertial needs the launch point {{lat, lon, height, azimuth}} "
                        f"(deg, m): give navigation.launch in the config, or a 'launch:' mapping in the "
                        f"init YAML (sins simulate writes one)")
    if not isinstance(launch, dict):
        raise SinsError(f"{src}: expected a mapping with keys lat, lon, height, azimuth, got {launch!r}")
    vals = {}
    for k in ("lat", "lon", "height", "azimuth", "time"):
        if k not in launch:
            if k == "time":
                vals[k] = float(t_default)
                continue
            raise SinsError(f"{src}.{k}: missing; the launch point needs lat, lon, height, azimuth")
        v = launch[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise SinsError(f"{src}.{k}: expected a finite number, got {v!r}")
        vals[k] = float(v)
    if not -90.0 <= vals["lat"] <= 90.0:
        raise SinsError(f"{src}.lat: {vals['lat']!r} deg is outside [-90, 90]")
    r = math.radians
    return LaunchFrame(vals["time"], r(vals["lat"]), r(vals["lon"]), vals["height"], r(vals["azimuth"]))


def _to_launch(v_e, dt, c):
    """ECEF vectors (..., 3) at ``t_L + dt`` in launch-inertial axes (..., 3)."""
    return np.stack(ecef_to_launch_axes_py(v_e[..., 0], v_e[..., 1], v_e[..., 2], dt, c), axis=-1)


def _to_ecef(v_i, dt, c):
    """Launch-inertial vectors (..., 3) in ECEF axes at ``t_L + dt`` (..., 3)."""
    return np.stack(launch_to_ecef_axes_py(v_i[..., 0], v_i[..., 1], v_i[..., 2], dt, c), axis=-1)


def inertial_state(frame: LaunchFrame, init: NavState):
    """``(r^i, v^i, C_b^i)`` of an earth-referenced state (lat/lon/h, ENU velocity, Cbn)."""
    c = frame.c_ei
    dt = init.time - frame.time
    r_e = lla_to_ecef(init.lat, init.lon, init.height)
    # r^i = C_e(t)^i R^e - C_e(tL)^i R_0^e: exactly 0 at the launch point and time
    r_i = _to_launch(r_e, dt, c) - _to_launch(frame.r0_e, 0.0, c)
    c_ne = enu_rotation(init.lat, init.lon).T
    w_x_r = np.array([-OMEGA_IE * r_e[1], OMEGA_IE * r_e[0], 0.0])
    v_i = _to_launch(c_ne @ np.asarray(init.vel_n, dtype=float) + w_x_r, dt, c)
    cbi = _to_launch((c_ne @ np.asarray(init.Cbn, dtype=float)).T, dt, c).T   # column by column
    return r_i, v_i, cbi


def earth_state(frame: LaunchFrame, t, r_i, v_i, cbi):
    """Earth-referenced ``(lat, lon, h, vel_n, Cbn)`` of launch-inertial states (n rows).

    ``R^e = C_i^e(t) r^i + Rz(-W dt) R_0^e``, ``v^e = C_i^e v^i - W x R^e``,
    ``v^n = C_e^n v^e``, ``Cbn = C_e^n C_i^e(t) C_b^i``.
    """
    c = frame.c_ei
    dt = np.asarray(t, dtype=float) - frame.time
    r_e = _to_ecef(r_i, dt, c) + _to_ecef(np.broadcast_to(frame.r0_e, r_i.shape), dt, np.eye(3))
    lat, lon, h = ecef_to_lla(r_e)
    c_en = enu_rotation(lat, lon)
    w_x_r = np.stack([-OMEGA_IE * r_e[..., 1], OMEGA_IE * r_e[..., 0], np.zeros_like(dt)], axis=-1)
    v_e = _to_ecef(v_i, dt, c) - w_x_r
    vel_n = np.einsum("nij,nj->ni", c_en, v_e)
    cbe = np.swapaxes(_to_ecef(np.swapaxes(cbi, -1, -2), dt[:, None], c), -1, -2)   # C_i^e C_b^i by columns
    cbn = np.einsum("nij,njk->nik", c_en, cbe)
    return lat, lon, h, vel_n, cbn


def new_state(frame: LaunchFrame, init: NavState) -> np.ndarray:
    """A fresh launch-inertial state vector at the initial time."""
    r_i, v_i, cbi = inertial_state(frame, init)
    st = np.zeros(I_STATE_SIZE)
    st[:STATE_SIZE] = _enu_new_state(init.time, 0.0, 0.0, 0.0, v_i, cbi)
    st[S_R:S_R + 3] = r_i
    st[S_CEI:S_CEI + 9] = frame.c_ei.ravel()
    st[S_R0E:S_R0E + 3] = frame.r0_e
    return st


@njit(cache=True, inline="always")
def _gravitation_i(st, r):
    """``G^i`` (m/s^2) at ``r`` (from the launch point, launch-inertial axes).

    The J2 field is symmetric about the polar axis, so it is evaluated in ECEF axes frozen at
    the launch time, ``R = R_0^e + C_i^e r``, and turned back with ``C_e^i``: no time enters.
    """
    c = ((st[S_CEI], st[S_CEI + 1], st[S_CEI + 2]), (st[S_CEI + 3], st[S_CEI + 4], st[S_CEI + 5]),
         (st[S_CEI + 6], st[S_CEI + 7], st[S_CEI + 8]))
    re = v_add(_vec(st, S_R0E), m_tvec(c, r))
    return m_vec(c, gravitation(re[0], re[1], re[2]))


@njit(cache=True)
def run(time, dtheta_b, dvel_b, st, method, order, nsub, every, out_t, out_r, out_v, out_cbi):
    """Navigate the samples ``time[k]`` (end of each increment interval) in the launch-inertial frame.

    Same arguments and chunking contract as :func:`sinscli.nav.strapdown.run`; writes
    ``r^i`` (m), ``v^i`` (m/s) and ``C_b^i`` of every ``every``-th attitude update and
    returns the number of rows written; ``st`` (:func:`new_state`) is updated in place.
    """
    n_out = 0
    prev_dth, prev_dv, n_prev, sums, nsub_now = load_fast(st)
    for k in range(time.shape[0]):
        sums, n_prev = fast_sample(dtheta_b, dvel_b, k, sums, prev_dth, prev_dv, n_prev, order)
        nsub_now += 1
        if nsub_now < nsub:
            continue
        # ---- attitude interval closes ----
        t_end = time[k]
        T = t_end - st[S_TSTART]
        phi, dv_b, _ = close_interval(st, sums, order)
        dv_i = m_vec(_cbn(st), dv_b)                  # C_b^i(t_{m-1}) dv^{b(m-1)}
        vel = _vec(st, S_VEL)
        r = _vec(st, S_R)
        # gravitation at the midpoint r + int_0^{T/2} v = r + T/8 (3 v_{m-1} + v_m), iterated
        dvel = v_add(dv_i, v_scale(_gravitation_i(st, r), T))
        for _ in range(2):
            r_mid = v_add(r, v_scale(v_add(v_scale(vel, 3.0), v_add(vel, dvel)), 0.125 * T))
            dvel = v_add(dv_i, v_scale(_gravitation_i(st, r_mid), T))
        v_new = v_add(vel, dvel)
        nhist = int(st[S_HAVE_MM2])
        dR = displacement(_vec(st, S_VMM3), _vec(st, S_VMM2), vel, v_new,
                          st[S_TMM2] - st[S_TMM3], st[S_TSTART] - st[S_TMM2], T, nhist)
        _attitude_update(st, method, phi, _ZERO3)
        store_interval(st, vel, dvel, nhist, t_end)         # the strapdown store step, then r^i
        for i in range(3):
            _acc(st, S_R + i, S_RLO + i, dR[i])
        sums = (_ZERO3, _ZERO3, _ZERO3, _ZERO3)
        nsub_now = 0
        st[S_NOUT] += 1.0
        if st[S_NOUT] >= every:
            st[S_NOUT] = 0.0
            out_t[n_out] = t_end
            for i in range(3):
                out_r[n_out, i] = st[S_R + i]
                out_v[n_out, i] = st[S_VEL + i]
            c = _cbn(st)
            for i in range(3):
                for j in range(3):
                    out_cbi[n_out, i, j] = c[i][j]
            n_out += 1
    save_fast(st, prev_dth, prev_dv, n_prev, sums, nsub_now)
    return n_out


class LaunchInertial:
    """The launch-inertial navigator's state and block runner (driven by ``pipeline.Navigator``).

    ``launch`` is the mapping of :func:`launch_frame`; when None, the init's own
    ``launch`` entry (an init YAML written by ``sins simulate``) is used.
    """

    def __init__(self, init: NavState, launch, method: int, order: int, nsub: int, every: int):
        src = "navigation.launch" if launch is not None or "launch" not in init.extra else "init launch"
        if launch is None:
            launch = init.extra.get("launch")
        self.frame = launch_frame(launch, init.time, src)
        self.init = init
        self.method, self.order, self.nsub, self.every = method, order, nsub, every
        self.state = new_state(self.frame, init)

    def initial_row(self) -> Trajectory:
        """The initial state as given, with its inertial columns."""
        s = self.init
        st = self.state
        ri, vi = st[S_R:S_R + 3], st[S_VEL:S_VEL + 3]
        extra = {name: np.array([x]) for name, x in zip(COLUMNS, np.concatenate([ri, vi]))}
        return Trajectory(np.array([s.time]), np.array([s.lat]), np.array([s.lon]), np.array([s.height]),
                          np.asarray(s.vel_n, dtype=float)[None, :].copy(),
                          np.asarray(s.Cbn, dtype=float)[None, :, :].copy(), extra)

    def run(self, time, dth, dv) -> Trajectory:
        """Navigate one block (contiguous arrays); the rows it closes, earth-referenced plus inertial columns."""
        cap = time.shape[0] // (self.nsub * self.every) + 2
        out_t = np.empty(cap)
        out_r = np.empty((cap, 3))
        out_v = np.empty((cap, 3))
        out_cbi = np.empty((cap, 3, 3))
        n = run(time, dth, dv, self.state, self.method, self.order, self.nsub, self.every,
                out_t, out_r, out_v, out_cbi)
        t, r_i, v_i, cbi = out_t[:n], out_r[:n], out_v[:n], out_cbi[:n]
        lat, lon, h, vel_n, cbn = earth_state(self.frame, t, r_i, v_i, cbi)
        extra = {name: col for name, col in zip(COLUMNS, np.concatenate([r_i, v_i], axis=1).T.copy())}
        return Trajectory(t, lat, lon, h, vel_n, cbn, extra)
