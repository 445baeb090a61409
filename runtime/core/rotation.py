"""Rotation kernels: unit quaternions (w, x, y, z), rotation matrices, cross-product matrices.

Every function works on stacks: a quaternion argument is (..., 4), a vector (..., 3), a matrix (..., 3, 3).
Angular velocity is in the world frame throughout the runtime, so dq/dt = 0.5 (0, w) * q.

The step calls these on stacks of a few rows, where numpy's cost per call is all there is: cross, skew,
quat_to_matrix and quat_derivative are each one outer product and one product with a constant coefficient
matrix (two or three calls whatever the formula), built below from the plain formulas, which stay as references
(np.cross, quat_to_matrix_reference, quat_derivative_reference).
"""
from __future__ import annotations

import numpy as np


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q for stacks of quaternions (..., 4)."""
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(np.shape(p), np.shape(q)))
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """q* = (w, -x, -y, -z): the inverse of a unit quaternion."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Scale quaternions to unit length (in place when out is q)."""
    # |q| = sqrt(sum q_i^2): one vecdot (a single gufunc call, no temporary), cheaper than a reduction
    norm = np.sqrt(np.vecdot(q, q))[..., None]
    return np.divide(q, norm, out=out)


def _quadratic_form_of_matrix() -> np.ndarray:
    """Q (16, 9) with R_ij = delta_ij + sum_ab Q[4a + b, 3i + j] q_a q_b (quaternion index w, x, y, z = 0..3)."""
    w, x, y, z = range(4)
    # R = I + 2 w [v]x + 2 [v]x^2, written out per entry as (coefficient, a, b) terms
    entries = {
        (0, 0): ((-2.0, y, y), (-2.0, z, z)),  # 1 - 2 (y y + z z)
        (0, 1): ((2.0, x, y), (-2.0, w, z)),  # 2 (x y - w z)
        (0, 2): ((2.0, x, z), (2.0, w, y)),  # 2 (x z + w y)
        (1, 0): ((2.0, x, y), (2.0, w, z)),  # 2 (x y + w z)
        (1, 1): ((-2.0, x, x), (-2.0, z, z)),  # 1 - 2 (x x + z z)
        (1, 2): ((2.0, y, z), (-2.0, w, x)),  # 2 (y z - w x)
        (2, 0): ((2.0, x, z), (-2.0, w, y)),  # 2 (x z - w y)
        (2, 1): ((2.0, y, z), (2.0, w, x)),  # 2 (y z + w x)
        (2, 2): ((-2.0, x, x), (-2.0, y, y)),  # 1 - 2 (x x + y y)
    }
    Q = np.zeros((16, 9))
    for (i, j), terms in entries.items():
        for coefficient, a, b in terms:
            Q[4 * a + b, 3 * i + j] = coefficient
    return Q


# every entry of R has two products q_a q_b with coefficients +-2: summed in any order, the result is exactly
# the per-entry formula's (scaling by 2 is exact, the zero terms add nothing)
_MATRIX_OF_QUAT = _quadratic_form_of_matrix()
_EYE_FLAT = np.eye(3).reshape(9)


def quat_to_matrix(q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    q = np.asarray(q, dtype=float)
    stack = q.shape[:-1]
    if out is None:
        out = np.empty(stack + (3, 3))
    # write straight into out when it is one block of memory, else through a temporary
    contiguous = out.flags.c_contiguous
    rows = out.reshape(-1, 9) if contiguous else np.empty((q.size // 4, 9))
    quat_to_matrix_rows(q.reshape(-1, 4), rows)
    if not contiguous:
        out[...] = rows.reshape(stack + (3, 3))
    return out


def quat_to_matrix_rows(q: np.ndarray, out: np.ndarray) -> np.ndarray:
    """The rotation matrices of unit quaternions q (n,4) as rows of 9 entries, written into out (n,9), which must
    be C-contiguous."""
    # R_ij = delta_ij + sum_ab Q_ab,ij q_a q_b: one outer product and one matrix product for the whole stack
    # (ndarray.dot: the same BLAS product as matmul for 2-D operands, without the gufunc machinery)
    qq = q[:, :, None] * q[:, None, :]
    qq.reshape(len(q), 16).dot(_MATRIX_OF_QUAT, out=out)
    out += _EYE_FLAT
    return out


def quat_to_matrix_reference(q: np.ndarray) -> np.ndarray:
    """quat_to_matrix entry by entry: the plain formula, kept as the test oracle."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    # R = I + 2 w [v]x + 2 [v]x^2, written out per entry
    out[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    out[..., 0, 1] = 2.0 * (x * y - w * z)
    out[..., 0, 2] = 2.0 * (x * z + w * y)
    out[..., 1, 0] = 2.0 * (x * y + w * z)
    out[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    out[..., 1, 2] = 2.0 * (y * z - w * x)
    out[..., 2, 0] = 2.0 * (x * z - w * y)
    out[..., 2, 1] = 2.0 * (y * z + w * x)
    out[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return out


def _levi_civita() -> np.ndarray:
    """eps (3,3,3): eps_ijk = +1 for even permutations of (0,1,2), -1 for odd ones, 0 otherwise."""
    eps = np.zeros((3, 3, 3))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[i, j, k], eps[i, k, j] = 1.0, -1.0
    return eps


_EPS = _levi_civita()
# (a x b)_i = sum_jk eps_ijk a_j b_k: rows 3 j + k of the outer product a_j b_k, column i
_CROSS_OF_OUTER = _EPS.transpose(1, 2, 0).reshape(9, 3)
# ([v]x)_ik = sum_j eps_ijk v_j: row j, column 3 i + k
_SKEW_OF_VECTOR = _EPS.transpose(1, 0, 2).reshape(3, 9)


# Above this many vectors the matrix product loses to plain component arithmetic (measured: 1000 vectors
# 70 us vs 26 us, 100 vectors 12 us vs 14 us).
CROSS_MATMUL_MAX = 300


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for stacks of 3-vectors (..., 3), broadcasting like np.cross on the last axis, at a fraction of
    np.cross's cost on small stacks.

    Every component is two products of the outer product a_j b_k with coefficients +-1, so the result is
    exactly np.cross's: (a x b)_i = sum_jk eps_ijk a_j b_k.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    outer = a[..., :, None] * b[..., None, :]
    if outer.size > 9 * CROSS_MATMUL_MAX:
        return _cross_components(a, b, outer.shape[:-1])
    return np.matmul(outer.reshape(outer.shape[:-2] + (9,)), _CROSS_OF_OUTER)


def _cross_components(a, b, shape) -> np.ndarray:
    """a x b one component at a time, as np.cross computes it (for long stacks)."""
    out = np.empty(shape)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R(q) v for stacks of quaternions and vectors."""
    qv = q[..., 1:]
    # v' = v + 2 w (qv x v) + 2 qv x (qv x v)
    t = 2.0 * cross(qv, v)
    return v + q[..., :1] * t + cross(qv, t)


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation by angle (radians) about axis (need not be unit)."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)
    unit = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * angle[..., None]
    return np.concatenate((np.cos(half), np.sin(half) * unit), axis=-1)


def _bilinear_form_of_derivative() -> np.ndarray:
    """D (12, 4) with 0.5 (0, w) * q = sum_ab D[4a + b] w_a q_b (w index x, y, z = 0..2; q index w, x, y, z)."""
    D = np.zeros((3, 4, 4))
    for a in range(3):
        unit = np.zeros(4)
        unit[1 + a] = 1.0
        # row b: 0.5 (0, e_a) * e_b, with e_b the b-th unit quaternion
        D[a] = 0.5 * quat_multiply(unit, np.eye(4))
    return D.reshape(12, 4)


_DERIVATIVE_OF_WQ = _bilinear_form_of_derivative()


def quat_derivative(q: np.ndarray, w: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """dq/dt = 0.5 (0, w) * q, with w the world-frame angular velocity (written into out if given)."""
    # bilinear in (w, q): one outer product and one matrix product for the whole stack
    wq = w[..., :, None] * q[..., None, :]
    return np.matmul(wq.reshape(wq.shape[:-2] + (12,)), _DERIVATIVE_OF_WQ, out=out)


def quat_derivative_reference(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """quat_derivative as the plain Hamilton product: the test oracle."""
    wq = np.concatenate((np.zeros(w.shape[:-1] + (1,)), w), axis=-1)
    return 0.5 * quat_multiply(wq, q)


def quat_integrate(q: np.ndarray, w: np.ndarray, h: float) -> np.ndarray:
    """Rotate q by the world angular velocity w held for time h (exact for constant w), then renormalize."""
    speed = np.linalg.norm(w, axis=-1, keepdims=True)
    half = 0.5 * h * speed
    # sinc form avoids 0/0 for bodies at rest: sin(half)/speed -> h/2 as speed -> 0
    scale = np.where(speed > 1e-12, np.sin(half) / np.where(speed > 1e-12, speed, 1.0), 0.5 * h)
    dq = np.concatenate((np.cos(half), scale * w), axis=-1)
    return quat_normalize(quat_multiply(dq, q))


def quat_from_euler_xyz(angles: np.ndarray) -> np.ndarray:
    """Quaternion of extrinsic x, then y, then z rotations (radians): R = Rz Ry Rx."""
    angles = np.asarray(angles, dtype=float)
    ex = np.array([1.0, 0.0, 0.0])
    ey = np.array([0.0, 1.0, 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    qx = quat_from_axis_angle(np.broadcast_to(ex, angles.shape), angles[..., 0])
    qy = quat_from_axis_angle(np.broadcast_to(ey, angles.shape), angles[..., 1])
    qz = quat_from_axis_angle(np.broadcast_to(ez, angles.shape), angles[..., 2])
    return quat_multiply(qz, quat_multiply(qy, qx))


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices [v]x (..., 3, 3) with [v]x u = v x u: ([v]x)_ik = sum_j eps_ijk v_j."""
    v = np.asarray(v, dtype=float)
    # every entry is one term +-v_j: exact whatever the product sums (ndarray.dot: no gufunc machinery)
    return v.dot(_SKEW_OF_VECTOR).reshape(v.shape[:-1] + (3, 3))


def world_inverse_inertia(R: np.ndarray, inv_inertia_body: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """I^-1 = R I_b^-1 R^T for every body: (n, 3, 3)."""
    return np.matmul(np.matmul(R, inv_inertia_body), R.swapaxes(-1, -2), out=out)
