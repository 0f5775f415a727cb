"""Small dense linear algebra for the filter kernels without BLAS (numba's ``@`` and ``np.linalg``
need SciPy, which the project does not depend on)."""
import numpy as np
from numba import njit


@njit(cache=True)
def rows_times(A, m, P, n, out):
    """``out[:m] = A[:m, :n] P[:n, :n]`` (the zero entries of A skipped: A sparse, e.g. H or Phi)."""
    for a in range(m):
        for j in range(n):
            out[a, j] = 0.0
        for k in range(n):
            h = A[a, k]
            if h != 0.0:
                for j in range(n):
                    out[a, j] += h * P[k, j]


@njit(cache=True)
def inv_small(S, m, out):
    """Inverse of the leading ``m`` x ``m`` block of ``S`` (m = 1, 2, 3) in closed form, into ``out``."""
    if m == 1:
        out[0, 0] = 1.0 / S[0, 0]
    elif m == 2:
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        out[0, 0] = S[1, 1] / det
        out[1, 1] = S[0, 0] / det
        out[0, 1] = -S[0, 1] / det
        out[1, 0] = -S[1, 0] / det
    else:
        a, b, c = S[0, 0], S[0, 1], S[0, 2]
        d, e, f = S[1, 0], S[1, 1], S[1, 2]
        g, h, k = S[2, 0], S[2, 1], S[2, 2]
        A = e * k - f * h
        B = -(d * k - f * g)
        C = d * h - e * g
        det = a * A + b * B + c * C
        out[0, 0] = A / det
        out[1, 0] = B / det
        out[2, 0] = C / det
        out[0, 1] = -(b * k - c * h) / det
        out[1, 1] = (a * k - c * g) / det
        out[2, 1] = -(a * h - b * g) / det
        out[0, 2] = (b * f - c * e) / det
        out[1, 2] = -(a * f - c * d) / det
        out[2, 2] = (a * e - b * d) / det


@njit(cache=True)
def cholesky(A, n, L):
    """Lower Cholesky factor of the leading ``n`` x ``n`` block of ``A`` into ``L``; False when that
    block is not (numerically) positive definite.  The one factorization of the filter's health
    check and of the smoother's gain."""
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
    return True


@njit(cache=True)
def chol_solve_into(L, n, X):
    """``X <- A^-1 X`` in place for ``A = L L^T`` (``X`` (n, m))."""
    m = X.shape[1]
    for c in range(m):
        for i in range(n):
            t = X[i, c]
            for k in range(i):
                t -= L[i, k] * X[k, c]
            X[i, c] = t / L[i, i]
        for i in range(n - 1, -1, -1):
            t = X[i, c]
            for k in range(i + 1, n):
                t -= L[k, i] * X[k, c]
            X[i, c] = t / L[i, i]
