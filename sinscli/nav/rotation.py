"""Rotation kernels: DCM, quaternion, rotation vector, Euler angles.

Conventions (``docs/formats.md``): ``Cbn`` turns a body vector into ENU; the
quaternion ``q_b^n`` is scalar first and means the same rotation; Euler angles
are physical (heading clockwise from north, pitch nose up, roll right side
down) whatever the body convention.  Body conventions are coded as integers:
``FLU = 0``, ``RFU = 1``, ``FRD = 2``.

All kernels are numba ``njit(cache=True)`` functions over plain float64
arrays, with no I/O.  Trigonometric coefficients near zero angle use the
Taylor series of Savage (seed 004) eqs 26 and 60, so they are exact to double
precision for every angle.
"""
import numpy as np
from numba import njit

from ..conventions import BODY_CONVENTIONS, FLU, FRD, RFU  # noqa: F401  (re-exported)

# C_{conv}^{flu}: turns a vector given in the named body axes into FLU axes.
_CONV_TO_FLU = np.array([
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],      # FLU
    [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],     # RFU: F = y, L = -x, U = z
    [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],    # FRD: F = x, L = -y, U = -z
])


@njit(cache=True)
def conv_to_flu(conv):
    """``C_{conv}^{FLU}`` for body convention code ``conv`` (3x3)."""
    return _CONV_TO_FLU[conv].copy()


# ---------------------------------------------------------------------------
# Tuple cores: the one implementation of each formula.  3-vectors are 3-tuples,
# matrices 3-tuples of row 3-tuples, quaternions 4-tuples; they live on the
# stack, so the navigation loop allocates nothing per sample.  The array
# functions further down wrap them for non-hot callers.
# ---------------------------------------------------------------------------

@njit(cache=True, inline="always")
def v_add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, inline="always")
def v_sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, inline="always")
def v_scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(cache=True, inline="always")
def v_cross(a, b):
    """Cross product ``a x b``."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def m_vec(m, v):
    """``M v``."""
    return (m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2])


@njit(cache=True)
def m_tvec(m, v):
    """``M^T v``."""
    return (m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
            m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
            m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2])


@njit(cache=True)
def m_mul(a, b):
    """``A B``."""
    return (m_tvec(b, a[0]), m_tvec(b, a[1]), m_tvec(b, a[2]))


@njit(cache=True)
def m_trans(a):
    return ((a[0][0], a[1][0], a[2][0]), (a[0][1], a[1][1], a[2][1]), (a[0][2], a[1][2], a[2][2]))


@njit(cache=True)
def rotvec_coeffs(phi2):
    """``(sin p / p, (1 - cos p) / p^2)`` for ``p^2 = phi2`` (Savage eq 26).

    The series are used below p = 1e-2, where 5 terms reach 1 ulp.
    """
    if phi2 < 1e-4:
        a = 1.0 - phi2 / 6.0 * (1.0 - phi2 / 20.0 * (1.0 - phi2 / 42.0 * (1.0 - phi2 / 72.0)))
        b = 0.5 * (1.0 - phi2 / 12.0 * (1.0 - phi2 / 30.0 * (1.0 - phi2 / 56.0 * (1.0 - phi2 / 90.0))))
        return a, b
    p = np.sqrt(phi2)
    return np.sin(p) / p, (1.0 - np.cos(p)) / phi2


@njit(cache=True)
def exp_so3_delta(phi, a, b):
    """``a [phi x] + b [phi x]^2``: the rotation matrix minus I (the shared body of eqs 8, 13, 26).

    Kept apart from I so that small rotations add to a state without rounding
    the increment against O(1) elements first.
    """
    x, y, z = phi[0], phi[1], phi[2]
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return ((-b * (yy + zz), -a * z + b * xy, a * y + b * xz),
            (a * z + b * xy, -b * (xx + zz), -a * x + b * yz),
            (-a * y + b * xz, a * x + b * yz, -b * (xx + yy)))


@njit(cache=True)
def rotvec_to_dcm_delta_t(phi):
    """``exp([phi x]) - I`` (Savage eq 26 without the identity)."""
    a, b = rotvec_coeffs(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    return exp_so3_delta(phi, a, b)


@njit(cache=True)
def rotvec_to_dcm_t(phi):
    """``C = I + (sin p/p)[phi x] + ((1-cos p)/p^2)[phi x]^2`` (Savage eq 26, seed 000 eq 8)."""
    d = rotvec_to_dcm_delta_t(phi)
    return ((1.0 + d[0][0], d[0][1], d[0][2]), (d[1][0], 1.0 + d[1][1], d[1][2]),
            (d[2][0], d[2][1], 1.0 + d[2][2]))


@njit(cache=True)
def rotvec_to_quat_delta_t(phi):
    """``q(phi) - (1, 0, 0, 0) = (cos(p/2) - 1, (sin(p/2)/p) phi)`` (Savage eq 60 without the unit)."""
    phi2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    if phi2 < 1e-4:
        h2 = 0.25 * phi2
        cm1 = -h2 / 2.0 * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0 * (1.0 - h2 / 56.0)))
        s = 0.5 * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0 * (1.0 - h2 / 72.0))))
    else:
        p = np.sqrt(phi2)
        sq = np.sin(0.25 * p)
        cm1 = -2.0 * sq * sq
        s = np.sin(0.5 * p) / p
    return (cm1, s * phi[0], s * phi[1], s * phi[2])


@njit(cache=True)
def rotvec_to_quat_t(phi):
    """``q = [cos(p/2), (sin(p/2)/p) phi]`` (Savage eq 60, seed 000 eq 3)."""
    d = rotvec_to_quat_delta_t(phi)
    return (1.0 + d[0], d[1], d[2], d[3])


@njit(cache=True)
def quat_mul_t(p, q):
    """Hamilton product ``p o q`` (seed 000 eq 3 in matrix form)."""
    return (p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
            p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
            p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
            p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0])


@njit(cache=True)
def quat_normalize_t(q):
    """``q / |q|`` (Savage 4.2.3, seed 000 eq 4), sign chosen with ``q0 >= 0``."""
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if q[0] < 0.0:
        n = -n
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@njit(cache=True)
def quat_to_dcm_t(q):
    """``Cbn`` from ``q_b^n`` (seed 000 eq 1)."""
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    return ((q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2.0 * (q1 * q2 - q0 * q3), 2.0 * (q1 * q3 + q0 * q2)),
            (2.0 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2.0 * (q2 * q3 - q0 * q1)),
            (2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3))


@njit(cache=True)
def orthonormalize_t(c):
    """Orthonormalize a DCM (Savage 4.1.3): twice ``C <- C - 0.5 C (C^T C - I)``.

    Exact to second order in the orthogonality error, so to the last bit for the
    errors one step's rounding leaves.
    """
    for _ in range(2):
        e = m_mul(m_trans(c), c)
        e = ((e[0][0] - 1.0, e[0][1], e[0][2]), (e[1][0], e[1][1] - 1.0, e[1][2]),
             (e[2][0], e[2][1], e[2][2] - 1.0))
        ce = m_mul(c, e)
        c = ((c[0][0] - 0.5 * ce[0][0], c[0][1] - 0.5 * ce[0][1], c[0][2] - 0.5 * ce[0][2]),
             (c[1][0] - 0.5 * ce[1][0], c[1][1] - 0.5 * ce[1][1], c[1][2] - 0.5 * ce[1][2]),
             (c[2][0] - 0.5 * ce[2][0], c[2][1] - 0.5 * ce[2][1], c[2][2] - 0.5 * ce[2][2]))
    return c


@njit(cache=True)
def m_from_array(a):
    return ((a[0, 0], a[0, 1], a[0, 2]), (a[1, 0], a[1, 1], a[1, 2]), (a[2, 0], a[2, 1], a[2, 2]))


@njit(cache=True)
def m_to_array(m):
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = m[i][j]
    return out


# ---------------------------------------------------------------------------
# Array wrappers (for readers, writers, alignment and tests; not for hot loops).
# ---------------------------------------------------------------------------

@njit(cache=True)
def mm3(a, b):
    """3x3 matrix product ``a b`` (no BLAS)."""
    return m_to_array(m_mul(m_from_array(a), m_from_array(b)))


@njit(cache=True)
def mtv3(a, v):
    """Transposed 3x3 matrix times 3-vector ``a^T v``."""
    return np.array(m_tvec(m_from_array(a), (v[0], v[1], v[2])))


@njit(cache=True)
def skew(v):
    """``[v x]``: the matrix with ``skew(v) u == cross(v, u)``."""
    m = np.zeros((3, 3))
    m[0, 1] = -v[2]
    m[0, 2] = v[1]
    m[1, 0] = v[2]
    m[1, 2] = -v[0]
    m[2, 0] = -v[1]
    m[2, 1] = v[0]
    return m


@njit(cache=True)
def cross(a, b):
    """Cross product of two 3-vectors (arrays)."""
    return np.array(v_cross((a[0], a[1], a[2]), (b[0], b[1], b[2])))


@njit(cache=True)
def rotvec_to_dcm(phi):
    """Array form of :func:`rotvec_to_dcm_t` (Savage eq 26)."""
    return m_to_array(rotvec_to_dcm_t((phi[0], phi[1], phi[2])))


@njit(cache=True)
def quat_to_dcm(q):
    """Array form of :func:`quat_to_dcm_t` (seed 000 eq 1)."""
    return m_to_array(quat_to_dcm_t((q[0], q[1], q[2], q[3])))


@njit(cache=True)
def dcm_to_quat_t(c):
    """``q_b^n`` from a tuple ``Cbn`` (Shepperd's method, largest pivot), ``q0 >= 0``."""
    tr = c[0][0] + c[1][1] + c[2][2]
    if tr >= c[0][0] and tr >= c[1][1] and tr >= c[2][2]:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = (0.25 * s, (c[2][1] - c[1][2]) / s, (c[0][2] - c[2][0]) / s, (c[1][0] - c[0][1]) / s)
    elif c[0][0] >= c[1][1] and c[0][0] >= c[2][2]:
        s = 2.0 * np.sqrt(1.0 + c[0][0] - c[1][1] - c[2][2])
        q = ((c[2][1] - c[1][2]) / s, 0.25 * s, (c[0][1] + c[1][0]) / s, (c[0][2] + c[2][0]) / s)
    elif c[1][1] >= c[2][2]:
        s = 2.0 * np.sqrt(1.0 + c[1][1] - c[0][0] - c[2][2])
        q = ((c[0][2] - c[2][0]) / s, (c[0][1] + c[1][0]) / s, 0.25 * s, (c[1][2] + c[2][1]) / s)
    else:
        s = 2.0 * np.sqrt(1.0 + c[2][2] - c[0][0] - c[1][1])
        q = ((c[1][0] - c[0][1]) / s, (c[0][2] + c[2][0]) / s, (c[1][2] + c[2][1]) / s, 0.25 * s)
    return quat_normalize_t(q)


@njit(cache=True)
def dcm_to_quat(c):
    """Array form of :func:`dcm_to_quat_t`."""
    return np.array(dcm_to_quat_t(m_from_array(c)))


@njit(cache=True)
def dcm_to_rotvec(c):
    """Rotation vector of a DCM (inverse of eq 26), accurate at every angle."""
    q = dcm_to_quat(c)
    sn = np.sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    ang = 2.0 * np.arctan2(sn, q[0])
    out = np.empty(3)
    if sn < 1e-300:
        out[:] = 0.0
        return out
    k = ang / sn
    out[0] = k * q[1]
    out[1] = k * q[2]
    out[2] = k * q[3]
    return out


@njit(cache=True)
def orthonormalize(c):
    """Array form of :func:`orthonormalize_t` (Savage 4.1.3)."""
    return m_to_array(orthonormalize_t(m_from_array(c)))


@njit(cache=True)
def _rx(a):
    """Rotation about x by ``a`` radians (tuple matrix)."""
    ca, sa = np.cos(a), np.sin(a)
    return ((1.0, 0.0, 0.0), (0.0, ca, -sa), (0.0, sa, ca))


@njit(cache=True)
def _ry(a):
    """Rotation about y by ``a`` radians (tuple matrix)."""
    ca, sa = np.cos(a), np.sin(a)
    return ((ca, 0.0, sa), (0.0, 1.0, 0.0), (-sa, 0.0, ca))


@njit(cache=True)
def _rz(a):
    """Rotation about z by ``a`` radians (tuple matrix)."""
    ca, sa = np.cos(a), np.sin(a)
    return ((ca, -sa, 0.0), (sa, ca, 0.0), (0.0, 0.0, 1.0))


@njit(cache=True)
def euler_to_dcm(roll, pitch, heading, conv):
    """``Cbn`` from physical Euler angles in radians (docs/formats.md).

    For RFU axes ``Cbn = Rz(-heading) Rx(pitch) Ry(roll)``; other conventions
    follow through ``C_{conv}^{RFU}``.
    """
    c_rfu = m_mul(m_mul(_rz(-heading), _rx(pitch)), _ry(roll))
    # C_conv^RFU = C_FLU^RFU C_conv^FLU, and C_FLU^RFU = (C_RFU^FLU)^T.
    c_conv_rfu = m_mul(m_trans(m_from_array(_CONV_TO_FLU[RFU])), m_from_array(_CONV_TO_FLU[conv]))
    return m_to_array(m_mul(c_rfu, c_conv_rfu))


@njit(cache=True)
def dcm_to_euler_t(cbn, conv):
    """Physical ``(roll, pitch, heading)`` in radians from a tuple ``Cbn``.

    heading in [0, 2 pi), pitch in [-pi/2, pi/2], roll in (-pi, pi].  At
    pitch +-90 deg (gimbal lock) roll is set to 0 and heading takes the whole
    rotation about the vertical.
    """
    c_rfu_conv = m_mul(m_trans(m_from_array(_CONV_TO_FLU[conv])), m_from_array(_CONV_TO_FLU[RFU]))
    c = m_mul(cbn, c_rfu_conv)  # C_RFU^n
    s_pitch = c[2][1]
    if s_pitch > 1.0:
        s_pitch = 1.0
    elif s_pitch < -1.0:
        s_pitch = -1.0
    horiz = np.sqrt(c[0][1] * c[0][1] + c[1][1] * c[1][1])
    pitch = np.arctan2(s_pitch, horiz)
    if horiz > 1e-12:
        roll = np.arctan2(-c[2][0], c[2][2])
        yaw = np.arctan2(-c[0][1], c[1][1])
    else:
        roll = 0.0
        yaw = np.arctan2(c[1][0], c[0][0])
    if roll <= -np.pi:
        roll += 2.0 * np.pi
    heading = -yaw
    if heading < 0.0:
        heading += 2.0 * np.pi
    if heading >= 2.0 * np.pi:
        heading -= 2.0 * np.pi
    return roll, pitch, heading


@njit(cache=True)
def dcm_to_euler(cbn, conv):
    """Array form of :func:`dcm_to_euler_t`."""
    return dcm_to_euler_t(m_from_array(cbn), conv)


@njit(cache=True)
def put_row(out, k, a):
    """``out[k] = a`` element by element, for ``out`` of shape (N, m) or (N, m, m).

    The slice assignment would compile numba's shape-checked broadcast with its error-message
    formatting (str, repr, concatenation: 4-8 s of a first compile on the 2-core machine).
    """
    row = out[k].reshape(a.size)
    flat = a.reshape(a.size)
    for i in range(a.size):
        row[i] = flat[i]


@njit(cache=True)
def euler_to_dcm_many(roll, pitch, heading, conv):
    """Vectorized :func:`euler_to_dcm` over arrays of angles (radians) -> (N, 3, 3)."""
    n = roll.shape[0]
    out = np.empty((n, 3, 3))
    for k in range(n):
        put_row(out, k, euler_to_dcm(roll[k], pitch[k], heading[k], conv))
    return out


@njit(cache=True)
def dcm_to_euler_many(cbn, conv):
    """Vectorized :func:`dcm_to_euler` over (N, 3, 3) -> (N, 3) roll, pitch, heading (radians)."""
    n = cbn.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        r, p, h = dcm_to_euler_t(m_from_array(cbn[k]), conv)
        out[k, 0] = r
        out[k, 1] = p
        out[k, 2] = h
    return out


@njit(cache=True)
def dcm_to_quat_many(cbn):
    """Vectorized :func:`dcm_to_quat` over (N, 3, 3) -> (N, 4)."""
    n = cbn.shape[0]
    out = np.empty((n, 4))
    for k in range(n):
        q = dcm_to_quat_t(m_from_array(cbn[k]))
        for i in range(4):
            out[k, i] = q[i]
    return out


@njit(cache=True)
def quat_to_dcm_many(q):
    """Vectorized :func:`quat_to_dcm` over (N, 4) -> (N, 3, 3)."""
    n = q.shape[0]
    out = np.empty((n, 3, 3))
    for k in range(n):
        put_row(out, k, quat_to_dcm(q[k]))
    return out


@njit(cache=True)
def attitude_error_many(cbn_true, cbn_est):
    """Small-angle attitude error vectors in the navigation frame, radians, (N, 3).

    ``phi`` with ``Cbn_true = exp([phi x]) Cbn_est``: computed from the DCM
    difference ``Cbn_true Cbn_est^T``, never from Euler differences.
    """
    n = cbn_true.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        put_row(out, k, dcm_to_rotvec(mm3(cbn_true[k], cbn_est[k].T.copy())))
    return out


# ---------------------------------------------------------------------------
# Body-convention changes of DCM stacks: plain numpy (einsum), not kernels.
# ---------------------------------------------------------------------------

def body_flu_in_enu(cbn: np.ndarray, conv: int) -> np.ndarray:
    """``C_FLU^n = Cbn C_{conv}^{FLU T}`` (N, 3, 3): the attitude of the FLU body axes."""
    return np.einsum("nij,kj->nik", np.asarray(cbn, dtype=np.float64), conv_to_flu(conv))


def cbn_from_flu(c_flu_n: np.ndarray, conv: int) -> np.ndarray:
    """Inverse of :func:`body_flu_in_enu`: ``Cbn = C_FLU^n C_{conv}^{FLU}``."""
    return np.einsum("nij,jk->nik", np.asarray(c_flu_n, dtype=np.float64), conv_to_flu(conv))


def level_heading_frame(heading: np.ndarray) -> np.ndarray:
    """``M`` (N, 3, 3) with ``(roll, pitch, heading components) = M phi_n`` for ENU small angles ``phi_n``.

    The level heading frame of a physical heading ``H`` (rad): roll about the
    horizontal forward axis ``(sin H, cos H, 0)``, pitch about the horizontal
    right axis ``(cos H, -sin H, 0)``, heading about the down axis (clockwise
    positive).  ``M`` is symmetric and orthogonal, so ``phi_n = M (r, p, h)``
    as well, and a covariance maps as ``M P M``.
    """
    h = np.asarray(heading, dtype=np.float64)
    sh, ch = np.sin(h), np.cos(h)
    m = np.zeros(h.shape + (3, 3))
    m[..., 0, 0], m[..., 0, 1] = sh, ch
    m[..., 1, 0], m[..., 1, 1] = ch, -sh
    m[..., 2, 2] = -1.0
    return m
