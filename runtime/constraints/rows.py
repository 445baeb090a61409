"""Constraint rows (acceleration level): C, J, ct and bias of every family, vectorized over its instances.

Conventions are those of layout.py: dC/dt = J v + ct, d2C/dt2 = J a + bias, with J acting on (v, w) per body
slot, w the world angular velocity and r = R p the world arm of a body point p. Each kernel
`<family>_rows(fam, frame, out, start) -> int` writes all k instances of its family at rows
start .. start + ROWS k (instance i's rows at start + ROWS i ...) and returns ROWS k. A WORLD slot is read as
identity pose and zero velocity, gets a zero J block and row_bodies -1. "bias" below means the value of
d2C/dt2 when every body has zero linear and angular acceleration (a = 0, alpha = 0).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from isaac_runtime.constraints.layout import (
    WORLD,
    BodyFrame,
    Element,
    GearToGear,
    GearToWeight,
    Orientation,
    PointOnPlane,
    PointToNail,
    PointToPoint,
    RowBlock,
)
from isaac_runtime.rotation import quat_conjugate, quat_multiply, quat_to_matrix, skew

_IDENTITY_QUAT = np.array([1.0, 0.0, 0.0, 0.0])


class _Slot(NamedTuple):
    """Pose and velocity of the body in one slot of every instance (k,...); WORLD rows are identity / zero."""

    x: np.ndarray  # (k,3)
    q: np.ndarray  # (k,4)
    R: np.ndarray  # (k,3,3)
    v: np.ndarray  # (k,3)
    w: np.ndarray  # (k,3)


def _slot(frame: BodyFrame, body: np.ndarray) -> _Slot:
    """Gather the state of `body` (k,) from the frame; WORLD (-1) entries become the fixed world frame."""
    k = len(body)
    live = body != WORLD
    idx = body[live]
    x, v, w = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3))
    q, R = np.tile(_IDENTITY_QUAT, (k, 1)), np.tile(np.eye(3), (k, 1, 1))
    x[live], q[live], R[live] = frame.x[idx], frame.q[idx], frame.R[idx]
    v[live], w[live] = frame.v[idx], frame.w[idx]
    return _Slot(x, q, R, v, w)


def _rot(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """r = R p for stacks (k,3,3) x (k,3)."""
    return np.einsum("kij,kj->ki", R, p)


def _rot_t(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """R^T p for stacks (k,3,3) x (k,3)."""
    return np.einsum("kji,kj->ki", R, p)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (k,3) stacks."""
    return np.einsum("ki,ki->k", a, b)


def _centripetal(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """w x (w x r): the acceleration of a body-fixed vector r under constant angular velocity w."""
    return np.cross(w, np.cross(w, r))


def _emit(out: RowBlock, start: int, rows: int, body_a, body_b, C, J, ct, bias, velocity_only: bool) -> int:
    """Write k instances of `rows` rows each: C, ct, bias (k, rows) or (k,); J (k, rows, 2, 6) or (k, 2, 6)."""
    m = rows * len(body_a)
    end = start + m
    bodies = np.repeat(np.stack((body_a, body_b), axis=-1), rows, axis=0)
    J = np.asarray(J, dtype=float).reshape(m, 2, 6)  # a fresh array in every kernel: masked in place
    # a WORLD slot has no degrees of freedom: zero block
    J[bodies == WORLD] = 0.0
    out.row_bodies[start:end] = bodies
    out.J[start:end] = J
    out.C[start:end] = np.reshape(C, m)
    out.ct[start:end] = np.reshape(ct, m)
    out.bias[start:end] = np.reshape(bias, m)
    out.velocity_only[start:end] = velocity_only
    return m


def _point_jacobian(r: np.ndarray, sign: float) -> np.ndarray:
    """sign * d(x + r)/d(v, w) per world axis: [I, -[r]x] (k,3,6), since d(x + r)/dt = v + w x r = v - [r]x w."""
    k = len(r)
    block = np.empty((k, 3, 6))
    block[:, :, :3] = np.eye(3)
    block[:, :, 3:] = -skew(r)
    return sign * block


def point_to_point_rows(fam: PointToPoint, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Ball joint, 3 world-axis rows per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    # r = R p (for a WORLD b: R = I, x = 0, so x_b + r_b is the world point point_b)
    r_a, r_b = _rot(a.R, fam.point_a), _rot(b.R, fam.point_b)
    # C = x_a + R_a p_a - x_b - R_b p_b
    C = a.x + r_a - b.x - r_b
    # dC/dt = v_a + w_a x r_a - v_b - w_b x r_b  =>  J_a = [I, -[r_a]x], J_b = [-I, [r_b]x]
    J = np.stack((_point_jacobian(r_a, 1.0), _point_jacobian(r_b, -1.0)), axis=2)
    # bias = w_a x (w_a x r_a) - w_b x (w_b x r_b)
    bias = _centripetal(a.w, r_a) - _centripetal(b.w, r_b)
    return _emit(out, start, 3, fam.body_a, fam.body_b, C, J, np.zeros_like(C), bias, False)


def point_to_nail_rows(fam: PointToNail, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Body point held at the world point P(t), 3 world-axis rows per instance; second slot is WORLD."""
    a = _slot(frame, fam.body)
    world = np.full_like(fam.body, WORLD)
    r = _rot(a.R, fam.point)
    # C = x + R p - P(t)
    C = a.x + r - fam.target
    # dC/dt = v + w x r - dP/dt  =>  J = [I, -[r]x], ct = -dP/dt
    J = np.stack((_point_jacobian(r, 1.0), np.zeros((len(r), 3, 6))), axis=2)
    ct = -fam.target_velocity
    # bias = w x (w x r) - d2P/dt2
    bias = _centripetal(a.w, r) - fam.target_acceleration
    return _emit(out, start, 3, fam.body, world, C, J, ct, bias, False)


def orientation_rows(fam: Orientation, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """T = R_a axis_a kept perpendicular to N = R_b axis_b (R_b = I for a WORLD b), 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    T, N = _rot(a.R, fam.axis_a), _rot(b.R, fam.axis_b)
    # C = T . N
    C = _dot(T, N)
    # dC/dt = (w_a x T) . N + T . (w_b x N) = w_a . (T x N) + w_b . (N x T)  =>  J_a = [0, T x N], J_b = [0, N x T]
    TxN = np.cross(T, N)
    J = np.zeros((len(C), 2, 6))
    J[:, 0, 3:] = TxN
    J[:, 1, 3:] = -TxN
    # bias (Tdot = w_a x T, Ndot = w_b x N, Tddot = w_a x (w_a x T) at alpha = 0):
    #   d2C/dt2 = Tddot . N + 2 Tdot . Ndot + T . Nddot
    bias = _dot(_centripetal(a.w, T), N) + 2.0 * _dot(np.cross(a.w, T), np.cross(b.w, N)) + _dot(
        T, _centripetal(b.w, N)
    )
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, np.zeros_like(C), bias, False)


def point_on_plane_rows(fam: PointOnPlane, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """P = x_a + R_a p_a on the plane through S = x_b + R_b s with normal N = R_b n, 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    r_a, r_s, N = _rot(a.R, fam.point_a), _rot(b.R, fam.plane_point), _rot(b.R, fam.plane_normal)
    P = a.x + r_a
    d = P - (b.x + r_s)
    # C = N . (P - S) = N . d
    C = _dot(N, d)
    # dC/dt = Ndot . d + N . ddot, Ndot = w_b x N, ddot = v_a + w_a x r_a - v_b - w_b x r_s; collecting w_b:
    #   w_b . (N x d) - w_b . (r_s x N) = w_b . (N x (P - x_b)), i.e. b's material point at P:
    #   J_a = [N, r_a x N], J_b = [-N, -(P - x_b) x N]
    J = np.empty((len(C), 2, 6))
    J[:, 0, :3], J[:, 0, 3:] = N, np.cross(r_a, N)
    J[:, 1, :3], J[:, 1, 3:] = -N, -np.cross(P - b.x, N)
    # bias = Nddot . d + 2 Ndot . ddot + N . dddot, with Nddot = w_b x (w_b x N) and
    #   dddot = w_a x (w_a x r_a) - w_b x (w_b x r_s)  (all at a = 0, alpha = 0)
    d_dot = a.v + np.cross(a.w, r_a) - b.v - np.cross(b.w, r_s)
    d_ddot = _centripetal(a.w, r_a) - _centripetal(b.w, r_s)
    bias = _dot(_centripetal(b.w, N), d) + 2.0 * _dot(np.cross(b.w, N), d_dot) + _dot(N, d_ddot)
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, np.zeros_like(C), bias, False)


def gear_to_gear_rows(fam: GearToGear, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Velocity row r_a (w_a . A_a) + r_b (w_b . A_b) = 0 with A = R axis (world), 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    A_a, A_b = _rot(a.R, fam.axis_a), _rot(b.R, fam.axis_b)
    # Cv = J v with J_a = [0, r_a A_a], J_b = [0, r_b A_b]
    J = np.zeros((len(A_a), 2, 6))
    J[:, 0, 3:] = fam.radius_a[:, None] * A_a
    J[:, 1, 3:] = fam.radius_b[:, None] * A_b
    # bias = Jdot v = r_a w_a . (w_a x A_a) + r_b w_b . (w_b x A_b) = 0 (w . (w x A) vanishes identically)
    zero = np.zeros(len(A_a))
    return _emit(out, start, 1, fam.body_a, fam.body_b, zero, J, zero, zero, True)


def gear_to_weight_rows(fam: GearToWeight, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Velocity row (w_gear x arm) . d - v_weight . d = 0 with arm, d world-fixed, 1 row per instance."""
    # Cv = w_gear . (arm x d) - v_weight . d  =>  J_gear = [0, arm x d], J_weight = [-d, 0]
    J = np.zeros((len(fam.gear), 2, 6))
    J[:, 0, 3:] = np.cross(fam.arm, fam.direction)
    J[:, 1, :3] = -fam.direction
    # bias = Jdot v = 0: arm and d are fixed in the world, so J does not change
    zero = np.zeros(len(fam.gear))
    return _emit(out, start, 1, fam.gear, fam.weight, zero, J, zero, zero, True)


def _element_translational(fam: Element, a: _Slot, b: _Slot):
    """C, J (k,2,6), bias of C = e . (x_a - x_b) - offset with e = R_b axis."""
    e, dx, dv = _rot(b.R, fam.axis), a.x - b.x, a.v - b.v
    # C = e . (x_a - x_b) - offset
    C = _dot(e, dx) - fam.offset
    # dC/dt = (w_b x e) . dx + e . dv = e . (v_a - v_b) + w_b . (e x dx)  =>  J_a = [e, 0], J_b = [-e, e x dx]
    J = np.zeros((len(C), 2, 6))
    J[:, 0, :3], J[:, 1, :3], J[:, 1, 3:] = e, -e, np.cross(e, dx)
    # bias = (w_b x (w_b x e)) . dx + 2 (w_b x e) . dv
    bias = _dot(_centripetal(b.w, e), dx) + 2.0 * _dot(np.cross(b.w, e), dv)
    return C, J, bias


def _element_rotational(fam: Element, a: _Slot, b: _Slot):
    """C, J (k,2,6), bias of C = 2 vec(q_err) . axis, q_err = conj(q_b) q_a conj(q_ref) = (s, u)."""
    q_err = quat_multiply(quat_multiply(quat_conjugate(b.q), a.q), quat_conjugate(fam.reference_rotation))
    s, u, axis = q_err[:, 0], q_err[:, 1:], fam.axis
    # C = 2 u . axis
    C = 2.0 * _dot(u, axis)
    # with qdot = 0.5 (0, w) q: q_err' = 0.5 (0, om) q_err, om = R_b^T (w_a - w_b) (relative, in b's frame), so
    #   u' = 0.5 (s om + om x u), s' = -0.5 om . u, and dC/dt = axis . (s om + om x u) = om . g,
    #   g = s axis + u x axis  =>  J_a = [0, R_b g], J_b = [0, -R_b g]
    g = s[:, None] * axis + np.cross(u, axis)
    G = _rot(b.R, g)
    J = np.zeros((len(C), 2, 6))
    J[:, 0, 3:], J[:, 1, 3:] = G, -G
    # bias = om' . g + om . g' with (at alpha = 0, R_b' = [w_b]x R_b) om' = -R_b^T (w_b x (w_a - w_b))
    #   = R_b^T (w_a x w_b), and g' = s' axis + u' x axis
    om = _rot_t(b.R, a.w - b.w)
    om_dot = _rot_t(b.R, np.cross(a.w, b.w))
    s_dot = -0.5 * _dot(om, u)
    u_dot = 0.5 * (s[:, None] * om + np.cross(om, u))
    g_dot = s_dot[:, None] * axis + np.cross(u_dot, axis)
    bias = _dot(om_dot, g) + _dot(om, g_dot)
    return C, J, bias


def element_rows(fam: Element, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """One fixed translational or rotational DOF of body_a relative to body_b (or the world), 1 row each."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    C_t, J_t, bias_t = _element_translational(fam, a, b)
    C_r, J_r, bias_r = _element_rotational(fam, a, b)
    rot = fam.rotational
    C = np.where(rot, C_r, C_t)
    J = np.where(rot[:, None, None], J_r, J_t)
    bias = np.where(rot, bias_r, bias_t)
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, np.zeros_like(C), bias, False)


def capture_element_references(fam: Element, x0: np.ndarray, q0: np.ndarray) -> None:
    """Fill fam.offset and fam.reference_rotation from the initial poses x0 (n,3), q0 (n,4) so that C = 0.

    Both fields are filled for every instance (each row reads only the one its kind uses).
    """
    x0, q0 = np.asarray(x0, dtype=float).reshape(-1, 3), np.asarray(q0, dtype=float).reshape(-1, 4)
    frame0 = BodyFrame(x=x0, q=q0, v=np.zeros_like(x0), w=np.zeros_like(x0), R=quat_to_matrix(q0))
    a, b = _slot(frame0, fam.body_a), _slot(frame0, fam.body_b)
    # offset = e_0 . (x_a0 - x_b0), e_0 = R_b0 axis
    fam.offset[:] = _dot(_rot(b.R, fam.axis), a.x - b.x)
    # reference_rotation = conj(q_b0) q_a0, so that q_err = 1 at the start
    fam.reference_rotation[:] = quat_multiply(quat_conjugate(b.q), a.q)


_KERNELS = {
    PointToPoint: point_to_point_rows,
    PointToNail: point_to_nail_rows,
    Orientation: orientation_rows,
    PointOnPlane: point_on_plane_rows,
    GearToGear: gear_to_gear_rows,
    GearToWeight: gear_to_weight_rows,
    Element: element_rows,
}


def row_count(fam) -> int:
    """Number of rows the family writes: ROWS per instance."""
    return type(fam).ROWS * len(_first_body(fam))


def _first_body(fam) -> np.ndarray:
    return fam.body if isinstance(fam, PointToNail) else fam.gear if isinstance(fam, GearToWeight) else fam.body_a


def write_rows(fam, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Write the rows of any family at `start`; returns the number of rows written."""
    try:
        kernel = _KERNELS[type(fam)]
    except KeyError:
        raise TypeError(f"write_rows: fam is a {type(fam).__name__}, not a constraint family") from None
    if start + row_count(fam) > len(out.C):
        raise ValueError(f"write_rows: out has {len(out.C)} rows, {start + row_count(fam)} needed")
    return kernel(fam, frame, out, start)
