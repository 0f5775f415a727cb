"""Small dense linear algebra for the filter kernels without BLAS (numba's ``@`` and ``np.linalg``
need SciPy, which the project does not depend on)."""
import numpy as np
from numba import njit


@njit(cache=True)
def matmul(a, b):
    """``a b`` for 2-D arrays."""
    n, k = a.shape
    m = b.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for p in range(k):
            x = a[i, p]
            if x != 0.0:
                for j in range(m):
                    out[i, j] += x * b[p, j]
    return out


@njit(cache=True)
def matvec(a, v):
    """``a v``."""
    n, k = a.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for p in range(k):
            s += a[i, p] * v[p]
        out[i] = s
    return out


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


@njit(cache=True)
def spd_solve(A, B):
    """``A^-1 B`` for a symmetric positive definite ``A`` (Cholesky); NaN when A is not SPD."""
    n = A.shape[0]
    L = np.zeros((n, n))
    if not cholesky(A, n, L):
        return np.full(B.shape, np.nan)
    X = B.copy()
    chol_solve_into(L, n, X)
    return X
