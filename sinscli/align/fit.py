"""The inertial-frame fit with the sensor biases: Gauss-Newton generalized least squares.

The Wahba solution (:mod:`.wahba`) treats ``Cbn(0) alpha_j = beta_j`` (seed 001 eq 16) as exact up to
independent errors.  They are neither: a gyro bias turns ``C_b(t)^b(0)`` and so every later
``alpha``, an accelerometer bias adds to it, and the noise is a random walk.  Here the biases are
parameters with the budget's prior, the noise has its true correlation, and the fit's own residual
says whether the model holds.  Per epoch j (``t_j`` since the start, ``b_j = C alpha_j``)

    r_j = beta_j - C alpha_j = -[b_j x] phi - C B_j nabla - C G_j eps - C G^E_j e + d + e_j
    B_j = int_0^tj C_b^b(0) dt,     G_j = -int_0^tj [f^b(0) x] B dt
    P^E_j = int_0^tj C_b^b(0) E w dt (as columns for the 9 elements of E),  G^E_j = -int [f^b(0) x] P^E dt

(``alpha_meas = alpha + B nabla + G eps + G^E e`` to first order: an accelerometer bias integrates
through ``C_b^b(0)``, a gyro bias turns the frame by ``psi = B eps`` and so the force by ``psi x f``;
the gyro scale factor and misalignment ``E`` (``w_meas = (I + E) w + eps``, ``e`` its 9 elements) turn
it by ``psi = P^E e`` in turns), with
``phi`` the attitude error of ``C = Cbn(0)`` (``C_true = exp([phi x]) C``), ``d`` the initial-velocity
error (with GNSS) and the noise covariance between epochs (each axis)

    E e_j e_k = s_v^2 delta_jk + VRW^2 min(t_j, t_k) + g^2 ARW^2 K(t_j, t_k),  K(s, t) = s^2 (3t - s) / 6

(GNSS velocity white noise; velocity random walk; the angle random walk turning gravity, integrated).
Each iteration re-integrates the increments with the estimated errors removed (so large biases are
handled exactly, not to first order), and the parameters ``[phi, nabla, eps, e, d]`` are solved with
the prior ``nabla ~ N(0, s_a^2)``, ``eps ~ N(0, s_g^2)``, scale factors ``~ N(0, s_sf^2)`` and
misalignments ``~ N(0, s_m^2)`` on the totals.

**Residual statistic.**  ``chi^2`` (whitened residual plus prior terms) against its degrees of
freedom ``3n - p_eff``.  When it is significantly above (more than 3 standard deviations of
chi-square), the model or the description is wrong, and the fit finds which, as a variance-component
estimate: the factors widening the accelerometer prior and the gyro prior (bias and matrix), and an
unmodelled white velocity noise ``s_w`` (a swaying base's heave, GNSS noise larger than stated,
lever-arm effects), that maximize the marginal likelihood of the residuals (type-II maximum
likelihood, ``-2 log L = chi^2_min + log det S + log det N - log det Lambda`` of the linearized
model; coordinate-wise golden-section search, the fit repeated).  A widened prior is reported at
the Student t of its redundancy ``r_p = sum (1 - [N^-1]_ii / s_i^2)`` (the caller widens the budget by
the returned factors); should ``chi^2`` still be significantly above its degrees of freedom, ``s_w``
grows until it is not.  The attitude covariance carries both.

**Outliers.**  GNSS epochs whose whitened innovation (one step ahead, from the Cholesky factor) is
beyond 30 times the robust (median) scale (chi-square with 3 degrees of freedom: p ~ 1e-6) are
dropped one at a time and the fit is repeated.  No I/O here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..nav.linalg import cholesky_inverse
from ..nav.rotation import rotvec_to_dcm, skew
from . import inertial
from .budget import Z995, t995

P_PHI, P_NAB, P_EPS, P_E, P_D = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 18), slice(18, 21)
DIAG_E = np.array([0, 4, 8])          # scale factors among the 9 elements of E (row-major)
OUTLIER_Q = 30.0          # whitened squared innovation / robust scale: an outlier beyond this
MAX_EPOCHS = 400          # epochs used (evenly thinned beyond; the last is kept)
NUMERIC_V = 1e-9          # m/s: white noise floor of the observation vectors (double-precision sums)
CONVERGED = 1e-6          # rad: a Gauss-Newton step whose attitude effect is below this has converged
                          # (what the next linearization would change is of its square)
MAX_HALVINGS = 12         # a step that raises the objective is halved at most this often (2^-12 of it)
RISE_TOL = 1e-9           # relative rise of the objective taken as rounding, not as an overshoot


@njit(cache=True)
def corrected_increments(dtheta_b, dvel_b, dt, gyro_bias, accel_bias, E, out_dtheta, out_dvel):
    """The increments with the estimated errors removed: ``dtheta - eps dt - E dtheta``,
    ``dvel - nabla dt`` (first order in E: ``w = (I + E)^-1 (w_meas - eps)``)."""
    for k in range(dt.shape[0]):
        for a in range(3):
            acc = dtheta_b[k, a] - gyro_bias[a] * dt[k]
            for b in range(3):
                acc -= E[a, b] * dtheta_b[k, b]
            out_dtheta[k, a] = acc
            out_dvel[k, a] = dvel_b[k, a] - accel_bias[a] * dt[k]


@njit(cache=True, inline="always")
def _sub_cross_mid(acc, old, new, da0, da1, da2):
    """``acc[:, b] -= [da x] (old[:, b] + new[:, b]) / 2`` for every column ``b`` (trapezoidal step)."""
    for b in range(acc.shape[1]):
        m0 = 0.5 * (old[0, b] + new[0, b])
        m1 = 0.5 * (old[1, b] + new[1, b])
        m2 = 0.5 * (old[2, b] + new[2, b])
        acc[0, b] -= da1 * m2 - da2 * m1
        acc[1, b] -= da2 * m0 - da0 * m2
        acc[2, b] -= da0 * m1 - da1 * m0


@njit(cache=True)
def bias_sensitivities(cbb0, alpha, dtheta_b, dt, rows, out_b, out_g, out_pe, out_ge):
    """``B_j``, ``G_j`` (3, 3) and ``P^E_j``, ``G^E_j`` (3, 9) of the module docstring at the sample
    rows ``rows`` (0 = start), trapezoidal in the attitude, the increment ``dtheta_b`` over each step."""
    m = dt.shape[0]
    n = rows.shape[0]
    B = np.zeros((3, 3))
    G = np.zeros((3, 3))
    PE = np.zeros((3, 9))
    GE = np.zeros((3, 9))
    Bn = np.zeros((3, 3))
    PEn = np.zeros((3, 9))
    cm = np.zeros((3, 3))
    j = 0
    while j < n and rows[j] == 0:
        out_b[j] = B
        out_g[j] = G
        out_pe[j] = PE
        out_ge[j] = GE
        j += 1
    for k in range(m):
        for a in range(3):
            for b in range(3):
                cm[a, b] = 0.5 * (cbb0[k, a, b] + cbb0[k + 1, a, b])
                Bn[a, b] = B[a, b] + cm[a, b] * dt[k]
        for a in range(3):
            for i in range(3):
                for jj in range(3):
                    PEn[a, 3 * i + jj] = PE[a, 3 * i + jj] + cm[a, i] * dtheta_b[k, jj]
        da0 = alpha[k + 1, 0] - alpha[k, 0]
        da1 = alpha[k + 1, 1] - alpha[k, 1]
        da2 = alpha[k + 1, 2] - alpha[k, 2]
        _sub_cross_mid(G, B, Bn, da0, da1, da2)
        _sub_cross_mid(GE, PE, PEn, da0, da1, da2)
        for a in range(3):
            for b in range(3):
                B[a, b] = Bn[a, b]
            for b in range(9):
                PE[a, b] = PEn[a, b]
        while j < n and rows[j] == k + 1:
            out_b[j] = B
            out_g[j] = G
            out_pe[j] = PE
            out_ge[j] = GE
            j += 1


def noise_covariance(t, s_white, vrw, arw, g, s_common=0.0, gyro_rw=0.0, accel_rw=0.0):
    """Epoch covariance (n, n) of one axis of the residual (module docstring); ``s_white`` (n,) or
    a number; ``s_common`` a 1-sigma common to all epochs (one GNSS velocity subtracted from all);
    ``gyro_rw`` (rad/s/sqrt(s)), ``accel_rw`` (m/s^2/sqrt(s)): the bias instability as a random walk."""
    t = np.asarray(t, dtype=float)
    lo = np.minimum.outer(t, t)
    hi = np.maximum.outer(t, t)
    once = lo ** 2 * (3.0 * hi - lo) / 6.0            # integrated Wiener process
    S = vrw ** 2 * lo + ((g * arw) ** 2 + accel_rw ** 2) * once
    if gyro_rw:
        d = hi - lo                                   # twice-integrated Wiener process
        S += (g * gyro_rw) ** 2 * (d * d * lo ** 3 / 3.0 + d * lo ** 4 / 2.0 + lo ** 5 / 5.0) / 4.0
    # white noise, and the rounding of the integrated vectors (1e-9 m/s): never singular
    S[np.diag_indices_from(S)] += np.broadcast_to(np.asarray(s_white, dtype=float) ** 2, t.shape) + NUMERIC_V ** 2
    if s_common:
        S += s_common ** 2
    return S


@dataclass
class FitResult:
    cbn0: np.ndarray            # (3, 3) at the start
    cov: np.ndarray             # (p, p) parameters [phi, nabla, eps, e, (d)], rad / m/s^2 / rad/s / - / m/s
    gyro_bias: np.ndarray       # (3,) rad/s, body, estimated (total)
    accel_bias: np.ndarray      # (3,) m/s^2
    gyro_matrix: np.ndarray     # (3, 3) E: gyro scale factor (diagonal) and misalignment, estimated
    d: np.ndarray               # (3,) initial-velocity offset (m/s), zero without it
    chi2: float                 # before the unmodelled noise was added
    dof: float
    s_white: float              # m/s, unmodelled white noise added (0 when the model held)
    dropped: list               # epoch indices (into the rows given) dropped as outliers
    kept: np.ndarray            # bool (n,) epochs used
    resid: np.ndarray           # (n, 3) residual velocity after the fit at every epoch (n0 frame)
    cbb0: np.ndarray            # (M+1, 3, 3) of the bias-corrected increments
    alpha: np.ndarray           # (M+1, 3)
    B_end: np.ndarray           # (3, 3) B at the last sample
    PE_end: np.ndarray          # (3, 9) P^E at the last sample
    cov_floor: np.ndarray       # (3, 3) attitude covariance of the noise alone (biases known, no s_w)
    iterations: int = 0
    widen: dict = None          # {"accel": k, "gyro": k}: the estimation priors were too narrow by these factors
    report_widen: dict = None   # the same for the reported 1-sigma (with the Student t of the prior statistic)

    def end_cov(self, cnn0_end, arw, T, gyro_rw=0.0):
        """Attitude covariance (ENU at the end, rad^2): ``phi - C (B_T eps + P^E_T e)`` rotated by
        ``C_n(T)^n(0)^T``, plus the angle random walk over ``T`` and the turn of a bias that walks
        (``gyro_rw``, rad/s/sqrt(s): ``gyro_rw^2 T^3 / 3``, the integrated Wiener process)."""
        p = self.cov.shape[0]
        J = np.zeros((3, p))
        J[:, P_PHI] = np.eye(3)
        J[:, P_EPS] = -self.cbn0 @ self.B_end
        J[:, P_E] = -self.cbn0 @ self.PE_end
        c = J @ self.cov @ J.T + np.eye(3) * (arw ** 2 * T + gyro_rw ** 2 * T ** 3 / 3.0)
        R = np.asarray(cnn0_end).T
        return psd(R @ c @ R.T)


def psd(c):
    """The nearest positive semi-definite matrix (symmetrized, negative eigenvalues from rounding to 0)."""
    c = 0.5 * (c + c.T)
    vals, vecs = np.linalg.eigh(c)
    return (vecs * np.maximum(vals, 0.0)) @ vecs.T


def inv_psd(N, floor=1e-13):
    """Inverse of a symmetric positive semi-definite matrix: Jacobi-scaled, eigenvalues below
    ``floor`` x the largest raised to it, so that an undetermined direction gets a huge variance
    (a pseudo-inverse would give it zero, claiming it known)."""
    d = np.sqrt(np.maximum(np.diag(N), 1e-300))
    Ns = N / np.outer(d, d)
    vals, vecs = np.linalg.eigh(0.5 * (Ns + Ns.T))
    vals = np.maximum(vals, floor * max(float(vals.max()), 1e-300))
    return (vecs / vals) @ vecs.T / np.outer(d, d)


class Whitener:
    """``L^-1`` of the Cholesky factor of an epoch covariance ``S`` (computed once, applied by products)
    and ``log det S``."""

    def __init__(self, S):
        self.Li, self.logdet = cholesky_inverse(np.ascontiguousarray(S, dtype=np.float64))


def _whitener(t, s_white, vrw, arw, g, s_common, gyro_rw=0.0, accel_rw=0.0):
    return Whitener(noise_covariance(t, s_white, vrw, arw, g, s_common, gyro_rw, accel_rw))


def _solve(H, r, W, lam, mu):
    """GLS with prior, whitened per axis by ``W`` (:class:`Whitener`); returns
    ``(delta, N^-1, chi2, p_eff, z, N)`` (``z`` the whitened residuals, (n, 3))."""
    n, _, p = H.shape
    Hw = np.einsum("ij,jap->aip", W.Li, H)                                  # (3, n, p)
    rw = np.einsum("ij,ja->ai", W.Li, r)                                    # (3, n)
    N = np.einsum("anp,anq->pq", Hw, Hw) + np.diag(lam)
    rhs = np.einsum("anp,an->p", Hw, rw) + lam * mu
    Ni = inv_psd(N)
    delta = Ni @ rhs
    z = rw - np.einsum("anp,p->an", Hw, delta)
    chi2 = float((z ** 2).sum() + (lam * (delta - mu) ** 2).sum())
    p_eff = float(p - np.trace(Ni * lam[None, :]))
    return delta, Ni, chi2, p_eff, z.T, N


def _golden(f, a, b, tol=0.02, maxit=30):
    """Minimum of a unimodal ``f`` on ``[a, b]`` by golden-section search (to ``tol``)."""
    gr = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - gr * (b - a), a + gr * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(maxit):
        if b - a < tol:
            break
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - gr * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + gr * (b - a)
            fd = f(d)
    return 0.5 * (a + b)


def fit(dtheta_b, dvel_b, dt, rows, beta_ep, cbn0, t_ep, *, g, vrw, arw, s_v=0.0, prior_accel=None,
        prior_gyro=None, prior_sf=None, prior_mis=None, centered=False, s_common=0.0, order=2,
        alpha_adjust=None, robust=False, max_iter=8, report_accel=None, report_gyro=None, report_sf=None,
        report_mis=None, widen_priors=True, accel_axes=None, start=None, statistics=True,
        halving=False, gyro_rw=0.0, accel_rw=0.0) -> FitResult:
    """Fit ``Cbn(0)`` and the sensor errors to the epochs ``rows`` (sample rows, 1..M) of one window.

    ``beta_ep`` (n, 3) the navigation-side vectors at the epochs; ``t_ep`` (n,) s since the start;
    ``prior_accel``/``prior_gyro`` the bias 1-sigma, ``prior_sf``/``prior_mis`` the gyro scale factor
    and misalignment 1-sigma (None or 0: not a parameter);
    ``report_*`` (default: the same) the 1-sigma the covariance is reported for: the covariance is then
    the error covariance of the estimate made with the prior when the errors follow the reported
    1-sigma, ``N^-1 (H^T W H + L S L) N^-1`` (L the prior information, S the reported variance);
    ``s_v`` (n,) or a number: the GNSS velocity 1-sigma; ``alpha_adjust(alpha_ep, cbb0_ep)`` moves the
    GNSS lever arm to the body side; ``widen_priors``: whether a misfit may widen the priors (else
    only the white noise grows); ``accel_axes`` (3, 3): body axes (columns) in which the accelerometer
    bias is parametrized, with ``prior_accel``/``report_accel`` then a 3-vector (one 1-sigma per axis;
    a tiny estimation prior holds that component at zero).  See the module docstring.
    """
    rows = np.asarray(rows, dtype=np.int64)
    n_all = rows.shape[0]
    keep = np.ones(n_all, dtype=bool)
    if n_all > MAX_EPOCHS:
        keep[:] = False
        keep[np.unique(np.linspace(0, n_all - 1, MAX_EPOCHS).round().astype(int))] = True
    s_v = np.broadcast_to(np.asarray(s_v, dtype=float), (n_all,)).copy()
    p = 21 if centered else 18
    est = np.zeros(p)                 # prior 1-sigma of each parameter (0: fixed at zero; inf: free)
    rep = np.zeros(p)
    est[P_PHI] = rep[P_PHI] = np.inf
    if centered:
        est[P_D] = rep[P_D] = np.inf
    mis_mask = np.ones(9, dtype=bool)
    mis_mask[DIAG_E] = False
    for sl, pe, pr in ((P_NAB, prior_accel, report_accel), (P_EPS, prior_gyro, report_gyro)):
        pe = 0.0 if pe is None else np.asarray(pe, dtype=float)
        est[sl] = pe
        rep[sl] = pe if pr is None else np.asarray(pr, dtype=float)
    Ra = np.eye(3) if accel_axes is None else np.asarray(accel_axes, dtype=float)
    e_est = np.where(mis_mask, prior_mis or 0.0, prior_sf or 0.0)
    e_rep = np.where(mis_mask, report_mis if report_mis is not None else (prior_mis or 0.0),
                     report_sf if report_sf is not None else (prior_sf or 0.0))
    est[P_E], rep[P_E] = e_est, e_rep
    free = est > 0.0
    # prior information: 0 for free parameters, 1/s^2 with a prior, 1 for fixed ones (their columns are 0)
    lam = np.where(np.isinf(est), 0.0, np.where(free, 1.0 / np.where(free, est, 1.0) ** 2, 1.0))
    ba = np.zeros(3)
    bg = np.zeros(3)
    E = np.zeros((3, 3))
    if start is not None:                # the linearization point of the sensor errors (a shorter window's fit)
        bg, ba, E = (np.array(x, dtype=float) for x in start)
    C = np.array(cbn0, dtype=float)
    dropped = []
    M = dtheta_b.shape[0]
    rows_b = np.concatenate([rows, [M]])
    dth_all = np.ascontiguousarray(dtheta_b, dtype=np.float64)

    dth = np.empty_like(dth_all)
    dvc = np.empty_like(dth_all)
    dv_all = np.ascontiguousarray(dvel_b, dtype=np.float64)
    dt_c = np.ascontiguousarray(dt, dtype=np.float64)

    def linearize():
        corrected_increments(dth_all, dv_all, dt_c, bg, ba, E, dth, dvc)
        cbb0, alpha = _integrate(dth, dvc, dt, order)
        Bs = np.empty((n_all + 1, 3, 3))
        Gs = np.empty((n_all + 1, 3, 3))
        PEs = np.empty((n_all + 1, 3, 9))
        GEs = np.empty((n_all + 1, 3, 9))
        bias_sensitivities(cbb0, alpha, np.ascontiguousarray(dth), np.ascontiguousarray(dt), rows_b, Bs, Gs,
                           PEs, GEs)
        a_ep = alpha[rows]
        if alpha_adjust is not None:
            a_ep = alpha_adjust(a_ep, cbb0[rows])
        return cbb0, alpha, a_ep, (Bs, Gs, PEs, GEs)

    def system(a_ep, sens, mask):
        Bs, Gs, PEs, GEs = sens
        b = a_ep[mask] @ C.T
        r = beta_ep[mask] - b
        H = np.zeros((b.shape[0], 3, p))
        H[:, :, P_PHI] = -np.stack([skew(x) for x in b])
        H[:, :, P_NAB] = -np.einsum("ij,njk->nik", C, Bs[:-1][mask] @ Ra)
        H[:, :, P_EPS] = -np.einsum("ij,njk->nik", C, Gs[:-1][mask])
        H[:, :, P_E] = -np.einsum("ij,njk->nik", C, GEs[:-1][mask])
        H[:, :, ~free] = 0.0
        if centered:
            H[:, :, P_D] = np.eye(3)
        return H, r

    def prior_mean():
        mu = np.zeros(p)
        mu[P_NAB] = -Ra.T @ ba
        mu[P_EPS] = -bg
        mu[P_E] = -E.ravel()
        return mu

    def step(delta):
        """Apply a Gauss-Newton step; returns its size as an attitude (rad): the start attitude's change
        and the turn of the frame by the bias and gyro-matrix changes at the end."""
        nonlocal C, ba, bg, E
        C = rotvec_to_dcm(delta[P_PHI]) @ C
        ba = ba + Ra @ delta[P_NAB]
        bg = bg + delta[P_EPS]
        E = E + delta[P_E].reshape(3, 3)
        Bs, _, PEs, _ = sens
        turn = Bs[-1] @ delta[P_EPS] + PEs[-1] @ delta[P_E]
        return max(float(np.abs(delta[P_PHI]).max()), float(np.abs(turn).max()),
                   float(np.abs(delta[P_NAB]).max()) * t_ep[-1] / max(float(np.abs(beta_ep).max()), 1e-9))

    def cost(H, r, W, mu):
        """The objective at the current point: whitened residual and prior terms (the step's start)."""
        rw = np.einsum("ij,ja->ai", W.Li, r)
        return float((rw ** 2).sum() + (lam * mu ** 2).sum())

    def gauss_newton(W, iters):
        """Gauss-Newton on the epochs ``keep`` with the whitener ``W``; a step that raises the objective (the
        model far from linear there: a large gyro bias turns the frame by tens of degrees) is taken again at
        half its length from where it started, up to ``MAX_HALVINGS`` times.  Returns the last solve's
        ``(delta, Ni, chi2, p_eff, z, N, H, r, iterations, converged)``."""
        nonlocal C, ba, bg, E, cbb0, alpha, a_ep, sens
        last = None              # (C, ba, bg, E, objective, delta) where the last step started
        halved = 0
        k = 0
        while True:
            cbb0, alpha, a_ep, sens = linearize()
            H, r = system(a_ep, sens, keep)
            mu = prior_mean()
            f = cost(H, r, W, mu)
            if halving and last is not None and f > last[4] * (1.0 + RISE_TOL) and halved < MAX_HALVINGS:
                C, ba, bg, E = (x.copy() for x in last[:4])
                last = (*last[:5], 0.5 * last[5])
                halved += 1
                step(last[5])
                continue
            halved = 0
            k += 1
            delta, Ni, chi2, p_eff, z, N = _solve(H, r, W, lam, mu)
            last = (C.copy(), ba.copy(), bg.copy(), E.copy(), f, delta)
            done = step(delta) < CONVERGED
            out = (delta, Ni, chi2, p_eff, z, N, H, r, k, done)
            if done or k >= iters:
                break
        return out

    it = 0
    s_w = 0.0
    cbb0 = alpha = a_ep = sens = None
    while True:
        L = _whitener(t_ep[keep], np.hypot(s_v[keep], s_w), vrw, arw, g, s_common, gyro_rw, accel_rw)
        delta, Ni, chi2, p_eff, z, N, H, r, it, converged = gauss_newton(L, max_iter)
        if not robust or keep.sum() <= 6 or not converged:     # outliers of a fit at its minimum only
            break
        q = (z ** 2).sum(axis=1)
        scale = max(float(np.median(q)) / 2.366, 1.0)
        worst = int(np.argmax(q))
        if q[worst] / scale <= OUTLIER_Q or len(dropped) >= max(1, keep.sum() // 5):
            break
        idx = np.nonzero(keep)[0][worst]
        keep[idx] = False
        dropped.append(int(idx))
    # the residual statistics (module docstring): when the data do not fit, the widening of each
    # sensor's prior and the unmodelled white noise that make them most likely
    n_used = int(keep.sum())
    dof = max(3.0 * n_used - p_eff, 1.0)
    chi2_0 = chi2
    groups = {"accel": np.r_[3:6], "gyro": np.r_[6:18]}
    widen = {"accel": 1.0, "gyro": 1.0}
    lam0, est0, rep0 = lam.copy(), est.copy(), rep.copy()
    if statistics and not consistent(chi2, dof):
        gidx = {k: v[free[v] & np.isfinite(est[v])] for k, v in groups.items()}
        for _ in range(2):
            H, r = system(a_ep, sens, keep)
            mu = prior_mean()
            s_ref = max(float(np.sqrt(np.mean(r ** 2))), 1e-9)
            wcache = {}

            def neg2ll(ka, kg, sw, _H=H, _r=r, _mu=mu):
                lt = lam0.copy()
                lt[gidx["accel"]] /= ka ** 2
                lt[gidx["gyro"]] /= kg ** 2
                key = round(sw, 12)
                if key not in wcache:
                    wcache[key] = _whitener(t_ep[keep], np.hypot(s_v[keep], sw), vrw, arw, g, s_common, gyro_rw, accel_rw)
                Wt = wcache[key]
                _, _, c2, _, _, Nt = _solve(_H, _r, Wt, lt, _mu)
                pri = np.concatenate([gidx["accel"], gidx["gyro"]])
                return c2 + 3.0 * Wt.logdet + np.linalg.slogdet(Nt)[1] - float(np.log(lt[pri]).sum())
            hyp = [widen["accel"], widen["gyro"], s_w]
            bounds = [(0.0, math.log(1e4)) if gidx["accel"].size and widen_priors else None,
                      (0.0, math.log(1e4)) if gidx["gyro"].size and widen_priors else None,
                      (math.log(1e-4 * s_ref), math.log(10.0 * s_ref))]
            # the white noise first (a base's own motion, e.g. heave, is what the model leaves out
            # most often), then each prior, twice over
            for _sweep in range(2):
                for i in (2, 0, 1):
                    bd = bounds[i]
                    if bd is None:
                        continue

                    def fcoord(u, _i=i):
                        h = list(hyp)
                        h[_i] = math.exp(u)
                        return neg2ll(*h)
                    u = _golden(fcoord, *bd)
                    cand = math.exp(u)
                    h0 = list(hyp)
                    h0[i] = 0.0 if i == 2 else 1.0      # the white noise absent, the prior as it was
                    h1 = list(hyp)
                    h1[i] = cand
                    hyp[i] = cand if neg2ll(*h1) < neg2ll(*h0) else h0[i]
            widen["accel"], widen["gyro"], s_w = hyp
            lam = lam0.copy()
            est, rep = est0.copy(), rep0.copy()
            for name, k in widen.items():
                lam[gidx[name]] /= k ** 2
                est[groups[name]] *= k
                rep[groups[name]] *= k
            L = _whitener(t_ep[keep], np.hypot(s_v[keep], s_w), vrw, arw, g, s_common, gyro_rw, accel_rw)
            delta, Ni, chi2, p_eff, z, N, H, r, it, _ = gauss_newton(L, max_iter)
        # a widened prior is the data's figure from r_p components: reported at its Student t (as the
        # bias components at rest, :mod:`.budget`)
        for name in groups:
            fi = gidx[name]
            if widen[name] > 1.0 + 1e-6 and fi.size:
                r_p = float((1.0 - lam[fi] * np.diag(Ni)[fi]).sum())
                rep[groups[name]] *= t995(max(r_p, 1.0)) / Z995
        # the data's statistic: if it is still significantly above its degrees of freedom, more
        # white noise until it is not
        dof = max(3.0 * n_used - p_eff, 1.0)
        if not consistent(chi2, dof):
            lo, hi = s_w, max(s_w, max(float(np.sqrt(np.mean(r ** 2))), 1e-9)) * 10.0 + 1.0
            for _ in range(60):                  # chi2(s_w) decreases with s_w: bisect on chi2 = dof
                mid = math.sqrt(lo * hi) if lo > 0 else hi / 1e6
                L = _whitener(t_ep[keep], np.hypot(s_v[keep], mid), vrw, arw, g, s_common, gyro_rw, accel_rw)
                _, _, c2, pe, _, _ = _solve(H, r, L, lam, prior_mean())
                if c2 > 3.0 * n_used - pe:
                    lo = mid
                else:
                    hi = mid
                if lo > 0 and hi / lo < 1.01:
                    break
            s_w = hi
            L = _whitener(t_ep[keep], np.hypot(s_v[keep], s_w), vrw, arw, g, s_common, gyro_rw, accel_rw)
            for _ in range(3):
                cbb0, alpha, a_ep, sens = linearize()
                H, r = system(a_ep, sens, keep)
                delta, Ni, _, _, _, N = _solve(H, r, L, lam, prior_mean())
                step(delta)
    report_widen = {name: float(np.max(rep[groups[name]] / np.where(rep0[groups[name]] > 0, rep0[groups[name]], 1.0)))
                    if widen[name] > 1.0 + 1e-6 else 1.0 for name in groups}
    # the error covariance under the reported 1-sigma (the sandwich of the docstring)
    fin = free & np.isfinite(est)
    if np.any(rep[fin] != est[fin]):
        info = np.zeros(p)
        info[fin] = lam[fin] ** 2 * rep[fin] ** 2
        M_data = N - np.diag(lam)
        Ni = Ni @ (M_data + np.diag(info)) @ Ni
    Ni[~free, :] = 0.0
    Ni[:, ~free] = 0.0
    Ni = psd(Ni)
    # final linearization at the solution: residuals at every epoch, noise-only floor
    cbb0, alpha, a_ep, sens = linearize()
    Hall, rall = system(a_ep, sens, np.ones(n_all, dtype=bool))
    d = delta[P_D] if centered else np.zeros(3)
    resid = rall - d
    W0 = _whitener(t_ep[keep], s_v[keep], vrw, arw, g, s_common)
    cols = [0, 1, 2] + ([18, 19, 20] if centered else [])
    Hf = Hall[keep][:, :, cols]
    Hw = np.einsum("ij,jap->aip", W0.Li, Hf)
    Nf = np.einsum("anp,anq->pq", Hw, Hw)
    cov_floor = psd(inv_psd(Nf)[:3, :3])
    if accel_axes is not None:                   # the covariance with the accelerometer bias in body axes
        Tr = np.eye(p)
        Tr[P_NAB, P_NAB] = Ra
        Ni = Tr @ Ni @ Tr.T
    return FitResult(C, Ni, bg, ba, E, d, chi2_0, dof, s_w, dropped, keep, resid, cbb0, alpha, sens[0][-1],
                     sens[2][-1], cov_floor, it, widen, report_widen)


def consistent(chi2: float, dof: float) -> bool:
    """Is a residual chi-square within 3 standard deviations (``sqrt(2 dof)``) of its degrees of freedom?"""
    return chi2 <= dof + 3.0 * math.sqrt(2.0 * dof)


def _integrate(dtheta_b, dvel_b, dt, order):
    """Body side only (``C_b^b(0)``, ``alpha``), of :func:`sinscli.align.inertial.body_side`."""
    m = dtheta_b.shape[0]
    cbb0 = np.empty((m + 1, 3, 3))
    alpha = np.empty((m + 1, 3))
    inertial.body_side(np.ascontiguousarray(dtheta_b, dtype=np.float64),
                       np.ascontiguousarray(dvel_b, dtype=np.float64), int(order), cbb0, alpha)
    return cbb0, alpha


def observed_components(x, cov, prior, ratio=0.3):
    """Bias components the fit determined (posterior 1-sigma below ``ratio`` x the prior): their
    values and 1-sigma, along the eigenvectors of the 3x3 posterior covariance ``cov``."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    ok = np.sqrt(np.maximum(vals, 0.0)) < ratio * prior
    return vecs[:, ok].T @ np.asarray(x, dtype=float), np.sqrt(np.maximum(vals[ok], 0.0))
