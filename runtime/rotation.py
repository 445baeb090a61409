"""Rotation kernels: unit quaternions (w, x, y, z), rotation matrices, cross-product matrices.

Every function works on stacks: a quaternion argument is (..., 4), a vector (..., 3), a matrix (..., 3, 3).
Angular velocity is in the world frame throughout the runtime, so dq/dt = 0.5 (0, w) * q.
"""
from __future__ import annotations

import numpy as np


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q for stacks of quaternions (..., 4)."""
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        (
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ),
        axis=-1,
    )


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """q* = (w, -x, -y, -z): the inverse of a unit quaternion."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Scale quaternions to unit length (in place when out is q)."""
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    return np.divide(q, norm, out=out)


def quat_to_matrix(q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    if out is None:
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


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R(q) v for stacks of quaternions and vectors."""
    qv = q[..., 1:]
    # v' = v + 2 w (qv x v) + 2 qv x (qv x v)
    t = 2.0 * np.cross(qv, v)
    return v + q[..., :1] * t + np.cross(qv, t)


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit quaternion of a rotation by angle (radians) about axis (need not be unit)."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)
    unit = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * angle[..., None]
    return np.concatenate((np.cos(half), np.sin(half) * unit), axis=-1)


def quat_derivative(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """dq/dt = 0.5 (0, w) * q, with w the world-frame angular velocity."""
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
    """Cross-product matrices [v]x (..., 3, 3) with [v]x u = v x u."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def world_inverse_inertia(R: np.ndarray, inv_inertia_body: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """I^-1 = R I_b^-1 R^T for every body: (n, 3, 3)."""
    return np.matmul(np.matmul(R, inv_inertia_body), np.swapaxes(R, -1, -2), out=out)
