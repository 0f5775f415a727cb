"""Small dense linear algebra for the kernels (fusion filter and smoother, alignment fit, SPP) without
BLAS: plain loops over a few dozen states, no LAPACK threads waking up on a loaded machine."""
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


@njit(cache=True)
def ldl_psd(A, n, L, D, tol):
    """``A ~ L diag(D) L^T`` (unit lower ``L``) of the symmetric leading ``n`` x ``n`` block of ``A``, with
    every pivot ``D_j >= 0``: the nearest factored positive semi-definite matrix, no pivoting.

    A pivot at or under ``tol * A_jj`` (relative to its own diagonal: rounding of a semi-definite
    matrix, e.g. a zero row, or a state the chain does not reach) is set to 0 and its column of ``L``
    dropped.  Returns ``(clipped, worst)``: the number of pivots that were negative beyond the
    tolerance (a matrix that is not PSD) and the most negative pivot relative to its diagonal (0 when
    none): the guard's measure (docs/fusion.md)."""
    clipped = 0
    worst = 0.0
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k] * D[k]
        a = abs(A[j, j])
        for i in range(j):
            L[i, j] = 0.0
        L[j, j] = 1.0
        if s <= tol * a:
            if s < -tol * a:
                clipped += 1
                r = s / a if a > 0.0 else -1.0
                if r < worst:
                    worst = r
            D[j] = 0.0
            for i in range(j + 1, n):
                L[i, j] = 0.0
            continue
        D[j] = s
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k] * D[k]
            L[i, j] = t / s
    return clipped, worst


@njit(cache=True)
def gram_add(G, D, n, out, init):
    """``out (+)= G diag(D) G^T`` (``init``: overwrite), upper triangle computed and mirrored: with every
    ``D_k >= 0`` each diagonal entry is a sum of non-negative terms, exactly, in floating point."""
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for k in range(n):
                d = D[k]
                if d != 0.0:
                    s += G[i, k] * d * G[j, k]
            v = s if init else out[i, j] + s
            out[i, j] = v
            out[j, i] = v


@njit(cache=True)
def times_lower(A, L, n, out):
    """``out = A L`` for a unit lower-triangular ``L`` (the zero upper part skipped)."""
    for i in range(n):
        for j in range(n):
            s = A[i, j]
            for k in range(j + 1, n):
                s += A[i, k] * L[k, j]
            out[i, j] = s


@njit(cache=True)
def scaled_solve(A, n, X, M, L, s):
    """``X <- A^+ X`` for a symmetric PSD ``A`` whose zero-variance states (``A_jj = 0``: a state held
    out of the filter) are excluded (their rows of the result are 0), through the Cholesky factor of the
    Jacobi-scaled ``M = S A S`` (``S = diag(A)^-1/2``, unit diagonal: its condition number is that of
    the correlations, not of the units).  If ``M`` is not numerically positive definite, a ridge of
    1e-12, 1e-10 ... 1e-6 is added.  Returns the ridge used (0: none).  ``M``, ``L`` (n, n), ``s`` (n,)
    scratch."""
    for j in range(n):
        s[j] = 1.0 / np.sqrt(A[j, j]) if A[j, j] > 0.0 else 0.0
    for i in range(n):
        for j in range(n):
            M[i, j] = A[i, j] * s[i] * s[j]
        if s[i] == 0.0:
            M[i, i] = 1.0
    ridge = 0.0
    while not cholesky(M, n, L):
        ridge = 1e-12 if ridge == 0.0 else ridge * 100.0
        if ridge > 1e-6:
            return -1.0
        for i in range(n):
            M[i, i] = 1.0 + ridge
    m = X.shape[1]
    for i in range(n):
        for c in range(m):
            X[i, c] *= s[i]
    chol_solve_into(L, n, X)
    for i in range(n):
        for c in range(m):
            X[i, c] *= s[i]
    return ridge


@njit(cache=True)
def cholesky_inverse(S):
    """``(L^-1, log det S)`` with ``S = L L^T`` (Cholesky-Banachiewicz, then forward substitution).

    A plain kernel for the few-hundred-epoch covariances here: LAPACK's threaded routines can take
    hundreds of times longer on a loaded 2-core machine (threads waking up), this does not."""
    n = S.shape[0]
    L = np.zeros((n, n))
    logdet = 0.0
    for i in range(n):
        for j in range(i + 1):
            acc = S[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            if i == j:
                if acc <= 0.0:
                    acc = 1e-300
                L[i, i] = np.sqrt(acc)
                logdet += 2.0 * np.log(L[i, i])
            else:
                L[i, j] = acc / L[j, j]
    Li = np.zeros((n, n))
    for c in range(n):
        Li[c, c] = 1.0 / L[c, c]
        for i in range(c + 1, n):
            acc = 0.0
            for k in range(c, i):
                acc -= L[i, k] * Li[k, c]
            Li[i, c] = acc / L[i, i]
    return Li, logdet
