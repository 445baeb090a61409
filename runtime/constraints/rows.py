"""Constraint rows (acceleration level): C, J, ct and bias of every family, vectorized over its instances.

Conventions are those of layout.py: dC/dt = J v + ct, d2C/dt2 = J a + bias, with J acting on (v, w) per body
slot, w the world angular velocity and r = R p the world arm of a body point p. Each kernel
`<family>_rows(fam, frame, out, start) -> int` writes all k instances of its family at rows
start .. start + ROWS k (instance i's rows at start + ROWS i ...) and returns ROWS k. A WORLD slot is read as
identity pose and zero velocity, gets a zero J block and row_bodies -1. "bias" below means the value of
d2C/dt2 when every body has zero linear and angular acceleration (a = 0, alpha = 0).

The kernels run four times per RK4 step on a handful of instances, so numpy's per-call cost is what they spend:
they read a `WorldPaddedFrame` (a plain BodyFrame is padded on entry), whose extra last row is the world, and
gather both slots of a family with one index, with no masks; rows_reference.py is the slow, obvious oracle.
"""
from __future__ import annotations

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
from isaac_runtime.rotation import cross, quat_conjugate, quat_multiply, quat_to_matrix, skew

_EYE = np.eye(3)
_IDENTITY_QUAT = np.array([1.0, 0.0, 0.0, 0.0])


class WorldPaddedFrame(BodyFrame):
    """A BodyFrame whose arrays (n+1, ...) end with one extra row for the world: x, v, w zero, q = (1, 0, 0, 0),
    R = I. Index WORLD = -1 then reads that row, so the kernels gather both slots of every instance with plain
    indexing and no masks. `Dynamics` builds one per evaluation; `pad_world` makes one from any frame."""


def pad_world(frame: BodyFrame) -> WorldPaddedFrame:
    """The frame itself if it is world-padded already, else a copy with the world row appended."""
    if isinstance(frame, WorldPaddedFrame):
        return frame
    zero = np.zeros((1, 3))
    return WorldPaddedFrame(
        np.concatenate((frame.x, zero)), np.concatenate((frame.q, _IDENTITY_QUAT[None])),
        np.concatenate((frame.v, zero)), np.concatenate((frame.w, zero)),
        np.concatenate((frame.R, _EYE[None])), frame.t,
    )


class _Slot:
    """Pose and velocity of the body in one slot of every instance, gathered from a world-padded frame on first
    use (a kernel reads only what it needs); WORLD entries read identity pose and zero velocity. `body` is (k,)
    for one slot, or (2,k) for both slots of a family at once: every array then gains that leading axis."""

    __slots__ = ("_frame", "_body", "_x", "_q", "_R", "_v", "_w")

    def __init__(self, frame: BodyFrame, body: np.ndarray):
        self._frame, self._body = pad_world(frame), body
        self._x = self._q = self._R = self._v = self._w = None

    @property
    def x(self) -> np.ndarray:  # (k,3)
        if self._x is None:
            self._x = self._frame.x.take(self._body, axis=0)
        return self._x

    @property
    def q(self) -> np.ndarray:  # (k,4)
        if self._q is None:
            self._q = self._frame.q.take(self._body, axis=0)
        return self._q

    @property
    def R(self) -> np.ndarray:  # (k,3,3)
        if self._R is None:
            self._R = self._frame.R.take(self._body, axis=0)
        return self._R

    @property
    def v(self) -> np.ndarray:  # (k,3)
        if self._v is None:
            self._v = self._frame.v.take(self._body, axis=0)
        return self._v

    @property
    def w(self) -> np.ndarray:  # (k,3)
        if self._w is None:
            self._w = self._frame.w.take(self._body, axis=0)
        return self._w


def _slot(frame: BodyFrame, body: np.ndarray) -> _Slot:
    """The state of `body` (k,) in the frame; WORLD (-1) entries are the fixed world frame."""
    return _Slot(frame, body)


def _slots(frame: BodyFrame, body_a: np.ndarray, body_b: np.ndarray) -> _Slot:
    """The state of both slots at once: arrays (2,k,...), index 0 for body_a, 1 for body_b."""
    return _Slot(frame, _pair(body_a, body_b))


def _rot(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """r = R p for stacks (...,3,3) x (...,3)."""
    return np.matmul(R, p[..., None])[..., 0]


def _rot_t(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """R^T p for stacks (k,3,3) x (k,3)."""
    return np.matmul(p[:, None, :], R)[:, 0, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (k,3) stacks."""
    return np.add.reduce(a * b, axis=-1)


def _centripetal(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """w x (w x r): the acceleration of a body-fixed vector r under constant angular velocity w."""
    # w x (w x r) = w (w . r) - r (w . w)
    return w * np.add.reduce(w * r, axis=-1, keepdims=True) - r * np.add.reduce(w * w, axis=-1, keepdims=True)


def _pair(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(2, ...) stack of a and b (np.stack without its argument checks)."""
    return np.concatenate((a[None], b[None]))


def _emit(out: RowBlock, start: int, rows: int, body_a, body_b, C, J, ct, bias, velocity_only: bool) -> int:
    """Write k instances of `rows` rows each: body_a (k,), body_b (k,) or WORLD for all; C, ct, bias (k, rows)
    or (k,) or a scalar; J (k, rows, 2, 6) or (k, 2, 6)."""
    m = rows * len(body_a)
    end = start + m
    bodies = out.row_bodies[start:end]
    bodies[:, 0] = body_a.repeat(rows)
    bodies[:, 1] = body_b.repeat(rows) if isinstance(body_b, np.ndarray) else body_b
    # a WORLD slot has no degrees of freedom: zero block (the kernels' world blocks are finite)
    np.multiply(J.reshape(m, 2, 6), (bodies != WORLD)[:, :, None], out=out.J[start:end])
    out.C[start:end] = _flat(C)
    out.ct[start:end] = _flat(ct)
    out.bias[start:end] = _flat(bias)
    out.velocity_only[start:end] = velocity_only
    return m


def _flat(value):
    """Row values in row order: (k, rows) arrays flattened, scalars as they are."""
    return value.reshape(-1) if isinstance(value, np.ndarray) else value


# J_a = [I, -[r_a]x] and J_b = -[I, -[r_b]x]: the sign of each slot of a point row, and its linear block
_SLOT_SIGN = np.array([1.0, -1.0])
_SLOT_LINEAR = _SLOT_SIGN[:, None, None, None] * _EYE  # (2,1,3,3)


def point_to_point_rows(fam: PointToPoint, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Ball joint, 3 world-axis rows per instance. Both slots are evaluated at once: arrays (2,k,...)."""
    ab = _slots(frame, fam.body_a, fam.body_b)
    # r = R p (for a WORLD b: R = I, x = 0, so x_b + r_b is the world point point_b)
    r = _rot(ab.R, _pair(fam.point_a, fam.point_b))
    # C = x_a + R_a p_a - x_b - R_b p_b
    P = ab.x + r
    C = P[0] - P[1]
    # dC/dt = v_a + w_a x r_a - v_b - w_b x r_b = sign_s (v_s - [r_s]x w_s) summed over the slots s:
    #   J_s = sign_s [I, -[r_s]x]   (rows: world axes)
    J = np.empty((len(C), 3, 2, 6))
    per_slot = J.transpose(2, 0, 1, 3)  # (2,k,3,6) view
    per_slot[..., :3] = _SLOT_LINEAR
    per_slot[..., 3:] = skew(-_SLOT_SIGN[:, None, None] * r)
    # bias = w_a x (w_a x r_a) - w_b x (w_b x r_b)
    centripetal = _centripetal(ab.w, r)
    bias = centripetal[0] - centripetal[1]
    return _emit(out, start, 3, fam.body_a, fam.body_b, C, J, 0.0, bias, False)


def point_to_nail_rows(fam: PointToNail, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Body point held at the world point P(t), 3 world-axis rows per instance; second slot is WORLD."""
    a = _slot(frame, fam.body)
    r = _rot(a.R, fam.point)
    # C = x + R p - P(t)
    C = a.x + r - fam.target
    # dC/dt = v + w x r - dP/dt  =>  J = [I, -[r]x], ct = -dP/dt
    J = np.zeros((len(r), 3, 2, 6))
    J[:, :, 0, :3] = _EYE
    J[:, :, 0, 3:] = skew(-r)
    ct = -fam.target_velocity
    # bias = w x (w x r) - d2P/dt2
    bias = _centripetal(a.w, r) - fam.target_acceleration
    return _emit(out, start, 3, fam.body, WORLD, C, J, ct, bias, False)


def orientation_rows(fam: Orientation, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """T = R_a axis_a kept perpendicular to N = R_b axis_b (R_b = I for a WORLD b), 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    T, N = _rot(a.R, fam.axis_a), _rot(b.R, fam.axis_b)
    # C = T . N
    C = _dot(T, N)
    # dC/dt = (w_a x T) . N + T . (w_b x N) = w_a . (T x N) + w_b . (N x T)  =>  J_a = [0, T x N], J_b = [0, N x T]
    TxN = cross(T, N)
    J = np.zeros((len(C), 2, 6))
    J[:, 0, 3:] = TxN
    J[:, 1, 3:] = -TxN
    # bias (Tdot = w_a x T, Ndot = w_b x N, Tddot = w_a x (w_a x T) at alpha = 0):
    #   d2C/dt2 = Tddot . N + 2 Tdot . Ndot + T . Nddot
    bias = _dot(_centripetal(a.w, T), N) + 2.0 * _dot(cross(a.w, T), cross(b.w, N)) + _dot(
        T, _centripetal(b.w, N)
    )
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, 0.0, bias, False)


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
    J[:, 0, :3], J[:, 0, 3:] = N, cross(r_a, N)
    J[:, 1, :3], J[:, 1, 3:] = -N, -cross(P - b.x, N)
    # bias = Nddot . d + 2 Ndot . ddot + N . dddot, with Nddot = w_b x (w_b x N) and
    #   dddot = w_a x (w_a x r_a) - w_b x (w_b x r_s)  (all at a = 0, alpha = 0)
    d_dot = a.v + cross(a.w, r_a) - b.v - cross(b.w, r_s)
    d_ddot = _centripetal(a.w, r_a) - _centripetal(b.w, r_s)
    bias = _dot(_centripetal(b.w, N), d) + 2.0 * _dot(cross(b.w, N), d_dot) + _dot(N, d_ddot)
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, 0.0, bias, False)


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
    J[:, 0, 3:] = cross(fam.arm, fam.direction)
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
    J[:, 0, :3], J[:, 1, :3], J[:, 1, 3:] = e, -e, cross(e, dx)
    # bias = (w_b x (w_b x e)) . dx + 2 (w_b x e) . dv
    bias = _dot(_centripetal(b.w, e), dx) + 2.0 * _dot(cross(b.w, e), dv)
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
    g = s[:, None] * axis + cross(u, axis)
    G = _rot(b.R, g)
    J = np.zeros((len(C), 2, 6))
    J[:, 0, 3:], J[:, 1, 3:] = G, -G
    # bias = om' . g + om . g' with (at alpha = 0, R_b' = [w_b]x R_b) om' = -R_b^T (w_b x (w_a - w_b))
    #   = R_b^T (w_a x w_b), and g' = s' axis + u' x axis
    om = _rot_t(b.R, a.w - b.w)
    om_dot = _rot_t(b.R, cross(a.w, b.w))
    s_dot = -0.5 * _dot(om, u)
    u_dot = 0.5 * (s[:, None] * om + cross(om, u))
    g_dot = s_dot[:, None] * axis + cross(u_dot, axis)
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
    return _emit(out, start, 1, fam.body_a, fam.body_b, C, J, 0.0, bias, False)


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
