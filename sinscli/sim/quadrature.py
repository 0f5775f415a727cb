"""Gauss-Legendre quadrature on [-1, 1] with its collocation integration matrix."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import pinned as pm


def legendre_nodes(n: int):
    """Gauss-Legendre nodes (ascending) and weights: Newton's iteration on ``P_n`` (three-term recurrence)
    from ``cos(pi (i - 1/4) / (n + 1/2))``, symmetrized as numpy's ``leggauss`` does; in the pinned
    arithmetic (``leggauss`` solves an eigenproblem with LAPACK, whose last bits follow the CPU)."""
    i = np.arange(1, n + 1, dtype=np.float64)
    x = pm.cos(np.pi * (i - 0.25) / (n + 0.5))[::-1].copy()
    for it in range(100):
        p0, p1 = np.ones_like(x), x.copy()
        for k in range(2, n + 1):
            p0, p1 = p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k
        dp = n * (x * p1 - p0) / (x * x - 1.0)
        dx = p1 / dp
        x = x - dx
        if it >= 3 and np.all(np.abs(dx) <= 4e-16 * np.maximum(np.abs(x), 1e-300)):
            break
    p0, p1 = np.ones_like(x), x.copy()
    for k in range(2, n + 1):
        p0, p1 = p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k
    dp = n * (x * p1 - p0) / (x * x - 1.0)
    w = 2.0 / ((1.0 - x * x) * dp * dp)
    return 0.5 * (x - x[::-1]), 0.5 * (w + w[::-1])


@lru_cache(maxsize=8)
def gauss_legendre(n: int):
    """Nodes ``x`` (n,), weights ``w`` (n,) and the integration matrix ``A`` (n, n).

    ``sum_k w_k f(x_k)`` integrates polynomials of degree <= 2n-1 exactly over
    [-1, 1]; ``sum_k A_ik f(x_k) = int_{-1}^{x_i} p(x) dx`` for the degree n-1
    interpolant ``p`` of ``f`` at the nodes (the Gauss collocation method,
    order 2n at the interval end).  ``A`` is built in the Legendre basis,
    ``int_{-1}^x P_j = (P_{j+1} - P_{j-1}) / (2j + 1)``, which is well
    conditioned for any ``n``.
    """
    leg = np.polynomial.legendre
    x, w = legendre_nodes(n)
    # Discrete Legendre coefficients: c_j = (2j+1)/2 sum_k w_k P_j(x_k) f_k  (exact for deg <= n-1).
    P = np.stack([leg.legval(x, np.eye(n + 1)[j]) for j in range(n + 1)], axis=0)   # (n+1, n)
    to_coef = ((2.0 * np.arange(n) + 1.0) / 2.0)[:, None] * P[:n] * w[None, :]      # (n, n): c = to_coef f
    integ = np.empty((n, n))                                   # integ[i, j] = int_{-1}^{x_i} P_j
    integ[:, 0] = x + 1.0
    for j in range(1, n):
        integ[:, j] = (P[j + 1] - P[j - 1]) / (2.0 * j + 1.0)
    A = pm.matmul(integ, to_coef)
    for arr in (x, w, A):
        arr.setflags(write=False)
    return x, w, A
