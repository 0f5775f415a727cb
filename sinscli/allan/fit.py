"""Noise terms from an Allan variance curve (IEEE Std 952-1997 annex C), with the sensor model's bias.

The model fitted to each axis, in rate units squared (rad/s or m/s^2):

    AVAR(tau) = 3 Q^2 / tau^2             quantization (slope -1 of the deviation), Q = q / sqrt(12)
              + N^2 / tau                 angle / velocity random walk (slope -1/2)
              + sigma^2 G(tau / T)        first-order Gauss-Markov bias (steady-state sigma, correlation T)
              + K^2 tau / 3               rate random walk (slope +1/2)

with the Gauss-Markov Allan variance ``G(x) = (2 / x^2) (x - 3/2 + 2 e^-x - e^-2x / 2)``
(continuous process of autocorrelation ``sigma^2 e^{-|t|/T}``).  ``G`` rises as
``2 x / 3`` (a rate random walk ``K^2 = 2 sigma^2 / T``) for ``tau << T``, falls as
``2 / x`` (white) for ``tau >> T``, and peaks at ``tau = 1.8926 T`` with
``sqrt(G) = 0.61736``: **the bias-instability hump of the curve is mapped to the
simulator's model by its peak**, ``bias_tau = tau_peak / 1.8926``,
``bias_instability = ADEV_peak / 0.61736`` (the fit uses the whole shape).  The
classic flicker "bias instability" ``B = min ADEV / 0.664`` is reported beside it.

For logs whose increments came from rate samples by the trapezoidal rule, the
white term is ``N^2 / tau (1 - 3 / (4 m))`` (the rule correlates neighbouring
increments; exact for white rate noise) and the quantization term is not fitted.

Fit: nonnegative weighted least squares on the relative residuals (weights from
the deviation's 1-sigma), the four linear coefficients exactly by enumerating the
active sets, ``T`` by a log-spaced search refined around the best value, twice
reweighted with the model in place of the noisy curve.  A term is *identified*
when it makes at least half the model variance at two or more cluster times with
at least 9 clusters each; the Gauss-Markov term also needs its peak inside that
range (so a log of about 17 T or more).  No I/O.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

GM_PEAK_X = 1.8926178594521157        # tau_peak / T of the Gauss-Markov Allan deviation
GM_PEAK_RATIO = 0.6173642831444414    # its peak ADEV / sigma
FLICKER_RATIO = float(np.sqrt(2.0 * np.log(2.0) / np.pi))   # 0.664: flicker floor ADEV / B
MIN_CLUSTERS = 9.0                    # cluster times used to decide what is identified
TERMS = ("quantization", "white", "gauss_markov", "rate_random_walk")


@dataclass
class AxisFit:
    """Fitted terms of one axis, SI (rad and rad/s for a gyro, m/s and m/s^2 for an accelerometer)."""
    quantization: float        # Q (rad or m/s); the count size is q = sqrt(12) Q
    white: float               # N: ARW rad/sqrt(s) or VRW m/s/sqrt(s)
    gm_sigma: float            # Gauss-Markov steady-state sigma (rad/s or m/s^2)
    gm_tau: float              # its correlation time T, s (nan when there is no such term)
    rrw: float                 # K (rad/s/sqrt(s) or m/s^2/sqrt(s))
    identified: dict           # term -> bool
    flicker_b: float           # classic bias instability: min ADEV / 0.664
    tau_min_adev: float        # where the deviation is lowest, s
    model_avar: np.ndarray     # the fitted curve at the cluster times

    @property
    def gm_peak(self) -> tuple[float, float]:
        """``(tau_peak s, ADEV_peak)`` of the Gauss-Markov term alone."""
        return GM_PEAK_X * self.gm_tau, GM_PEAK_RATIO * self.gm_sigma


def gm_avar(tau: np.ndarray, T: float) -> np.ndarray:
    """Allan variance of a unit-sigma first-order Gauss-Markov process with correlation time ``T``."""
    x = np.asarray(tau, dtype=np.float64) / T
    small = x < 1e-2                                # the closed form cancels there: its series
    xs = np.where(small, 1.0, x)
    g = np.where(small, x ** 3 / 3.0 - x ** 4 / 4.0 + 7.0 * x ** 5 / 60.0 - x ** 6 / 24.0,
                 xs - 1.5 + 2.0 * np.exp(-xs) - 0.5 * np.exp(-2.0 * xs))
    return 2.0 * g / x ** 2


def basis(tau: np.ndarray, m: np.ndarray, T: float, trapezoid: bool) -> np.ndarray:
    """Columns of the model for unit coefficients ``(Q^2, N^2, sigma^2, K^2)``: (n_tau, 4)."""
    white = 1.0 / tau * ((1.0 - 0.75 / m) if trapezoid else 1.0)
    quant = np.zeros_like(tau) if trapezoid else 3.0 / tau ** 2
    return np.column_stack([quant, white, gm_avar(tau, T), tau / 3.0])


def _nnls_small(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Nonnegative least squares for a few columns: the best of every active set's unconstrained solution."""
    best, best_r = np.zeros(A.shape[1]), float(b @ b)
    cols = [j for j in range(A.shape[1]) if np.any(A[:, j] != 0.0)]
    for k in range(1, len(cols) + 1):
        for sub in itertools.combinations(cols, k):
            sub = list(sub)
            c, *_ = np.linalg.lstsq(A[:, sub], b, rcond=None)
            if np.all(c >= 0.0):
                r = b - A[:, sub] @ c
                rr = float(r @ r)
                if rr < best_r:
                    best_r = rr
                    best = np.zeros(A.shape[1])
                    best[sub] = c
    return best, best_r


def _solve(tau, m, avar, scale, T, trapezoid):
    B = basis(tau, m, T, trapezoid)
    A = B / scale[:, None]
    coef, r = _nnls_small(A, avar / scale)
    return coef, r, B


def fit_axis(tau: np.ndarray, m: np.ndarray, avar: np.ndarray, rel_sigma: np.ndarray, n: int,
             trapezoid: bool = False) -> AxisFit:
    """Fit the model to one axis' Allan variance at cluster times ``tau`` (sizes ``m``) of an ``n``-sample log."""
    good = np.isfinite(avar) & (avar > 0)
    tau, m, avar, rel_sigma = tau[good], m[good], avar[good], rel_sigma[good]
    rel_var = 2.0 * rel_sigma                       # relative 1-sigma of the variance
    grid = np.logspace(np.log10(tau[0] / 2.0), np.log10(tau[-1] * 2.0), 40)
    ref = avar.copy()
    for _ in range(3):                              # reweight with the model instead of the noisy curve
        scale = ref * rel_var
        res = [_solve(tau, m, avar, scale, T, trapezoid)[1] for T in grid]
        k = int(np.argmin(res))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        fine = np.logspace(np.log10(lo), np.log10(hi), 25)
        res_f = [_solve(tau, m, avar, scale, T, trapezoid)[1] for T in fine]
        T = float(fine[int(np.argmin(res_f))])
        coef, _, B = _solve(tau, m, avar, scale, T, trapezoid)
        model = B @ coef
        ref = np.where(model > 0, model, avar)
    parts = B * coef[None, :]
    reliable = (n / m) >= MIN_CLUSTERS
    frac = parts / np.where(model > 0, model, 1.0)[:, None]
    identified = {name: bool(np.count_nonzero((frac[:, j] >= 0.5) & reliable) >= 2 and coef[j] > 0)
                  for j, name in enumerate(TERMS)}
    if identified["gauss_markov"]:
        identified["gauss_markov"] = bool(GM_PEAK_X * T <= tau[reliable][-1]) if reliable.any() else False
    adev = np.sqrt(avar)
    i_min = int(np.argmin(adev))
    return AxisFit(quantization=float(np.sqrt(coef[0])), white=float(np.sqrt(coef[1])),
                   gm_sigma=float(np.sqrt(coef[2])), gm_tau=T if coef[2] > 0 else float("nan"),
                   rrw=float(np.sqrt(coef[3])), identified=identified,
                   flicker_b=float(adev[i_min] / FLICKER_RATIO), tau_min_adev=float(tau[i_min]),
                   model_avar=np.interp(np.arange(good.size), np.nonzero(good)[0], model))
