"""Wahba's problem: the rotation that best maps body vectors onto navigation vectors.

Seed 001 determines ``Cbn(0)`` from ``beta_j = Cbn(0) alpha_j`` over all
observation epochs j (eq 16).  The optimal solution in the least-squares sense,

    min_C  sum_j w_j |beta_j - C alpha_j|^2,     B = sum_j w_j beta_j alpha_j^T,

is ``C = U diag(1, 1, det U det V) V^T`` from the SVD ``B = U S V^T``
(Markley's SVD method); Davenport's q-method (the eigenvector of the largest
eigenvalue of the 4x4 K matrix) gives the same rotation and is kept as an
independent check.  Vectors are used as they are (not normalized): the
integral vectors grow with time, so later epochs, whose directions are the
better known, weigh more.
"""
from __future__ import annotations

import numpy as np

from ..nav.rotation import quat_to_dcm


def attitude_profile(alpha, beta, weights=None):
    """``B = sum_j w_j beta_j alpha_j^T`` (3, 3) from (n, 3) vector pairs."""
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    w = np.ones(alpha.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    return np.einsum("n,ni,nj->ij", w, beta, alpha)


def svd_rotation(B):
    """Optimal rotation(s) for attitude profile matrices ``B`` (3, 3) or (n, 3, 3) (SVD method)."""
    B = np.asarray(B, dtype=float)
    u, _, vt = np.linalg.svd(B)
    d = np.linalg.det(u) * np.linalg.det(vt)
    u = u.copy()
    u[..., :, 2] *= d[..., None] if np.ndim(d) else d
    return np.matmul(u, vt)


def solve(alpha, beta, weights=None):
    """``Cbn`` minimizing ``sum w |beta - C alpha|^2`` (SVD method)."""
    return svd_rotation(attitude_profile(alpha, beta, weights))


def solve_cumulative(alpha, beta, weights=None, centered: bool = False):
    """The solution over epochs 0..j for every j: (n, 3, 3) (alignment against time).

    ``centered``: fit ``beta_j = C alpha_j + d`` with an unknown constant ``d``
    as well (the vectors less their weighted means, as in point-set
    registration); ``d`` takes up an error common to all ``beta_j``, such as
    the noise of the one initial velocity that eq 18 subtracts.
    """
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    w = np.ones(alpha.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    B = np.cumsum(w[:, None, None] * beta[:, :, None] * alpha[:, None, :], axis=0)
    if centered:
        sw = np.cumsum(w)
        ma = np.cumsum(w[:, None] * alpha, axis=0) / sw[:, None]
        mb = np.cumsum(w[:, None] * beta, axis=0) / sw[:, None]
        B = B - sw[:, None, None] * mb[:, :, None] * ma[:, None, :]
    # scale each B (the rotation does not depend on it) so that the SVD sees numbers near 1
    s = np.abs(B).max(axis=(1, 2))
    s[s == 0.0] = 1.0
    return svd_rotation(B / s[:, None, None])


def q_method(alpha, beta, weights=None):
    """Davenport's q-method: the same optimum from the 4x4 K matrix (independent check of :func:`solve`)."""
    B = attitude_profile(alpha, beta, weights)
    S = B + B.T
    sigma = np.trace(B)
    z = np.array([B[1, 2] - B[2, 1], B[2, 0] - B[0, 2], B[0, 1] - B[1, 0]])
    K = np.empty((4, 4))
    K[0, 0] = sigma
    K[0, 1:] = z
    K[1:, 0] = z
    K[1:, 1:] = S - sigma * np.eye(3)
    vals, vecs = np.linalg.eigh(K)
    q = vecs[:, np.argmax(vals)]
    # K's eigenvector is the quaternion of the rotation from n to b in this sign convention:
    # B = sum beta alpha^T maps alpha (b) to beta (n), so the optimum is C = A^T with A(q) the
    # attitude matrix of Shuster's convention (vector part negated relative to q_b^n).
    q_bn = np.array([q[0], -q[1], -q[2], -q[3]])
    if q_bn[0] < 0:
        q_bn = -q_bn
    return quat_to_dcm(q_bn / np.linalg.norm(q_bn))
