"""Constraint rows (acceleration level): C, J, ct and bias of every family, vectorized over its instances.

Conventions are those of layout.py: dC/dt = J v + ct, d2C/dt2 = J a + bias, with J acting on (v, w) per body
slot, w the world angular velocity and r = R p the world arm of a body point p. Each kernel
`<family>_rows(fam, frame, rows)` writes C, J, ct and bias of all k instances of its family into `rows`, the
views of a RowBlock where they go (`FamilyRows`: instance i's rows at start + ROWS i ...). A WORLD slot is read
as identity pose and zero velocity, gets a zero J block and row_bodies -1. "bias" below means the value of
d2C/dt2 when every body has zero linear and angular acceleration (a = 0, alpha = 0).

`write_rows(fam, frame, out, start)` writes everything: the structure (row_bodies, velocity_only, and the
entries that never change: zeros, constant J blocks), then the kernel, which writes only what changes with the
frame. The runtime writes the structure once and then calls the kernels on views built once (`FamilyRows`),
four times per RK4 step on a handful of instances: numpy's per-call cost is what they spend. They read a
`WorldPaddedFrame` (a plain BodyFrame is padded on entry), whose extra last row is the world, and gather both
slots of a family with one index, with no masks; rows_reference.py is the slow, obvious oracle.
`position_kernel_for` gives the kernel of C alone, for the constraint error, where it splits off cheaply.
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
    """r = R p for stacks (...,3,3) x (...,3): r_i = R_i . p, one vecdot (a gufunc, cheaper than matmul's)."""
    return np.vecdot(R, p[..., None, :])


def _rot_t(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """R^T p for stacks (k,3,3) x (k,3)."""
    return np.matmul(p[:, None, :], R)[:, 0, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (k,3) stacks (np.vecdot: one gufunc call, no temporary)."""
    return np.vecdot(a, b)


def _centripetal(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """w x (w x r): the acceleration of a body-fixed vector r under constant angular velocity w."""
    # w x (w x r) = w (w . r) - r (w . w)
    return w * np.vecdot(w, r)[..., None] - r * np.vecdot(w, w)[..., None]


def _pair(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(2, ...) stack of a and b (np.stack without its argument checks)."""
    return np.concatenate((a[None], b[None]))


class FamilyRows:
    """Where one family's rows go in a RowBlock (rows start .. start + ROWS k), as views shaped per instance:
    C, ct, bias (k, ROWS) and J (k, ROWS, 2, 6), or (k,) and (k, 2, 6) for one-row families; live (k[, ROWS],
    2, 1) is 1.0 where the slot names a body and 0.0 for the world (its J block is written as zero); body_a,
    body_b (k,) the bodies of the slots (body_b may be WORLD)."""

    def __init__(self, fam, out: RowBlock, start: int):
        self.fam, self.out, self.start = fam, out, start
        self.body_a, self.body_b = _slot_bodies(fam)
        k, per = len(self.body_a), type(fam).ROWS
        self.count = per * k
        end = start + self.count
        if end > len(out.C):
            raise ValueError(f"write_rows: out has {len(out.C)} rows, {end} needed")
        shape = (k, per) if per > 1 else (k,)
        self.C, self.ct, self.bias = (column[start:end].reshape(shape) for column in (out.C, out.ct, out.bias))
        self.J = out.J[start:end].reshape(shape + (2, 6))
        body = np.stack(np.broadcast_arrays(self.body_a, self.body_b), axis=-1)  # (k,2)
        live = (body != WORLD).astype(float)[:, None, :, None]  # (k,1,2,1)
        self.live = np.broadcast_to(live, (k, per, 2, 1)).reshape(shape + (2, 1))

    def write_structure(self) -> None:
        """What never changes: row_bodies, velocity_only, and every entry of C, J, ct and bias the kernel does
        not write (zero, or the family's constant J blocks, _CONSTANT_J)."""
        out, per = self.out, type(self.fam).ROWS
        rows = slice(self.start, self.start + self.count)
        out.row_bodies[rows, 0] = self.body_a.repeat(per)
        out.row_bodies[rows, 1] = np.broadcast_to(self.body_b, self.body_a.shape).repeat(per)
        out.velocity_only[rows] = isinstance(self.fam, (GearToGear, GearToWeight))
        for column in (out.C, out.J, out.ct, out.bias):
            column[rows] = 0.0
        constant = _CONSTANT_J.get(type(self.fam))
        if constant is not None:
            constant(self)

    def write_J(self, J: np.ndarray) -> None:
        """J (k[, ROWS], 2, 6) with its world slots zeroed."""
        np.multiply(J, self.live, out=self.J)


def _slot_bodies(fam) -> tuple:
    """(body_a, body_b) of a family's rows: the bodies of slot 0 and slot 1 (WORLD for a nail)."""
    if isinstance(fam, PointToNail):
        return fam.body, WORLD
    if isinstance(fam, GearToWeight):
        return fam.gear, fam.weight
    return fam.body_a, fam.body_b


# J_a = [I, -[r_a]x] and J_b = -[I, -[r_b]x]: the sign of each slot of a point row, and its linear block
_SLOT_SIGN = np.array([1.0, -1.0])
_SLOT_LINEAR = _SLOT_SIGN[:, None, None, None] * _EYE  # (2,1,3,3)


def point_to_point_rows(fam: PointToPoint, frame: BodyFrame, rows: FamilyRows) -> None:
    """Ball joint, 3 world-axis rows per instance. Both slots are evaluated at once: arrays (2,k,...)."""
    ab, r = point_to_point_position(fam, frame, rows)
    # dC/dt = v_a + w_a x r_a - v_b - w_b x r_b = sign_s (v_s - [r_s]x w_s) summed over the slots s:
    #   J_s = sign_s [I, -[r_s]x]   (rows: world axes)
    #   (the linear blocks are constant: written with the structure)
    per_slot = rows.J.transpose(2, 0, 1, 3)  # (2,k,3,6) view
    per_slot[..., 3:] = skew(-_SLOT_SIGN[:, None, None] * r)
    rows.J[..., 3:] *= rows.live
    # bias = w_a x (w_a x r_a) - w_b x (w_b x r_b)
    centripetal = _centripetal(ab.w, r)
    np.subtract(centripetal[0], centripetal[1], out=rows.bias)


def point_to_point_position(fam: PointToPoint, frame: BodyFrame, rows: FamilyRows) -> tuple:
    """C of the ball joints (written), and the slots and arms r (2,k,3) the rest of the rows use."""
    ab = _slots(frame, fam.body_a, fam.body_b)
    # r = R p (for a WORLD b: R = I, x = 0, so x_b + r_b is the world point point_b)
    r = _rot(ab.R, _pair(fam.point_a, fam.point_b))
    # C = x_a + R_a p_a - x_b - R_b p_b
    P = ab.x + r
    np.subtract(P[0], P[1], out=rows.C)
    return ab, r


def point_to_nail_rows(fam: PointToNail, frame: BodyFrame, rows: FamilyRows) -> None:
    """Body point held at the world point P(t), 3 world-axis rows per instance; second slot is WORLD."""
    r = point_to_nail_position(fam, frame, rows)
    # dC/dt = v + w x r - dP/dt  =>  J = [I, -[r]x] (I and the world slot's 0 written with the structure),
    #   ct = -dP/dt
    #   (-[r]x = [r]x^T)
    rows.J[:, :, 0, 3:] = skew(r).swapaxes(-1, -2)
    np.negative(fam.target_velocity, out=rows.ct)
    # bias = w x (w x r) - d2P/dt2
    np.subtract(_centripetal(frame.w.take(fam.body, axis=0), r), fam.target_acceleration, out=rows.bias)


def point_to_nail_position(fam: PointToNail, frame: BodyFrame, rows: FamilyRows) -> np.ndarray:
    """C of the nails (written), and the arms r = R p (k,3) the rest of the rows use."""
    body = fam.body
    r = _rot(frame.R.take(body, axis=0), fam.point)
    # C = x + R p - P(t)
    np.add(frame.x.take(body, axis=0), r, out=rows.C)
    rows.C -= fam.target
    return r


def orientation_rows(fam: Orientation, frame: BodyFrame, rows: FamilyRows) -> None:
    """T = R_a axis_a kept perpendicular to N = R_b axis_b (R_b = I for a WORLD b), 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    T, N = _rot(a.R, fam.axis_a), _rot(b.R, fam.axis_b)
    # C = T . N
    rows.C[...] = _dot(T, N)
    # dC/dt = (w_a x T) . N + T . (w_b x N) = w_a . (T x N) + w_b . (N x T)  =>  J_a = [0, T x N], J_b = [0, N x T]
    TxN = cross(T, N)
    J = np.zeros((len(T), 2, 6))
    J[:, 0, 3:] = TxN
    J[:, 1, 3:] = -TxN
    rows.write_J(J)
    # bias (Tdot = w_a x T, Ndot = w_b x N, Tddot = w_a x (w_a x T) at alpha = 0):
    #   d2C/dt2 = Tddot . N + 2 Tdot . Ndot + T . Nddot
    rows.bias[...] = _dot(_centripetal(a.w, T), N) + 2.0 * _dot(cross(a.w, T), cross(b.w, N)) + _dot(
        T, _centripetal(b.w, N)
    )


def point_on_plane_rows(fam: PointOnPlane, frame: BodyFrame, rows: FamilyRows) -> None:
    """P = x_a + R_a p_a on the plane through S = x_b + R_b s with normal N = R_b n, 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    r_a, r_s, N = _rot(a.R, fam.point_a), _rot(b.R, fam.plane_point), _rot(b.R, fam.plane_normal)
    P = a.x + r_a
    d = P - (b.x + r_s)
    # C = N . (P - S) = N . d
    rows.C[...] = _dot(N, d)
    # dC/dt = Ndot . d + N . ddot, Ndot = w_b x N, ddot = v_a + w_a x r_a - v_b - w_b x r_s; collecting w_b:
    #   w_b . (N x d) - w_b . (r_s x N) = w_b . (N x (P - x_b)), i.e. b's material point at P:
    #   J_a = [N, r_a x N], J_b = [-N, -(P - x_b) x N]
    J = np.empty((len(N), 2, 6))
    J[:, 0, :3], J[:, 0, 3:] = N, cross(r_a, N)
    J[:, 1, :3], J[:, 1, 3:] = -N, -cross(P - b.x, N)
    rows.write_J(J)
    # bias = Nddot . d + 2 Ndot . ddot + N . dddot, with Nddot = w_b x (w_b x N) and
    #   dddot = w_a x (w_a x r_a) - w_b x (w_b x r_s)  (all at a = 0, alpha = 0)
    d_dot = a.v + cross(a.w, r_a) - b.v - cross(b.w, r_s)
    d_ddot = _centripetal(a.w, r_a) - _centripetal(b.w, r_s)
    rows.bias[...] = _dot(_centripetal(b.w, N), d) + 2.0 * _dot(cross(b.w, N), d_dot) + _dot(N, d_ddot)


def gear_to_gear_rows(fam: GearToGear, frame: BodyFrame, rows: FamilyRows) -> None:
    """Velocity row r_a (w_a . A_a) + r_b (w_b . A_b) = 0 with A = R axis (world), 1 row per instance."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    A_a, A_b = _rot(a.R, fam.axis_a), _rot(b.R, fam.axis_b)
    # Cv = J v with J_a = [0, r_a A_a], J_b = [0, r_b A_b]
    J = np.zeros((len(A_a), 2, 6))
    J[:, 0, 3:] = fam.radius_a[:, None] * A_a
    J[:, 1, 3:] = fam.radius_b[:, None] * A_b
    rows.write_J(J)
    # C = ct = 0, and bias = Jdot v = r_a w_a . (w_a x A_a) + r_b w_b . (w_b x A_b) = 0 (w . (w x A) vanishes
    # identically): all three stay as the structure wrote them


def gear_to_weight_rows(fam: GearToWeight, frame: BodyFrame, rows: FamilyRows) -> None:
    """Velocity row (w_gear x arm) . d - v_weight . d = 0 with arm, d world-fixed, 1 row per instance."""
    # Cv = w_gear . (arm x d) - v_weight . d  =>  J_gear = [0, arm x d], J_weight = [-d, 0]
    J = np.zeros((len(fam.gear), 2, 6))
    J[:, 0, 3:] = cross(fam.arm, fam.direction)
    J[:, 1, :3] = -fam.direction
    rows.write_J(J)
    # C = ct = 0, and bias = Jdot v = 0 (arm and d are fixed in the world, so J does not change): all three stay
    # as the structure wrote them


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


def element_rows(fam: Element, frame: BodyFrame, rows: FamilyRows) -> None:
    """One fixed translational or rotational DOF of body_a relative to body_b (or the world), 1 row each."""
    a, b = _slot(frame, fam.body_a), _slot(frame, fam.body_b)
    C_t, J_t, bias_t = _element_translational(fam, a, b)
    C_r, J_r, bias_r = _element_rotational(fam, a, b)
    rot = fam.rotational
    rows.C[...] = np.where(rot, C_r, C_t)
    rows.write_J(np.where(rot[:, None, None], J_r, J_t))
    rows.bias[...] = np.where(rot, bias_r, bias_t)


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


def _point_to_point_constant_J(rows: FamilyRows) -> None:
    # J_s = sign_s [I, -[r_s]x]: the linear blocks are +-I (0 in a world slot)
    rows.J.transpose(2, 0, 1, 3)[..., :3] = _SLOT_LINEAR * rows.live.transpose(2, 0, 1, 3)


def _point_to_nail_constant_J(rows: FamilyRows) -> None:
    # J = [I, -[r]x] in the body's slot: the linear block is I (the world slot's is 0)
    rows.J[:, :, 0, :3] = _EYE


# the constant entries of J, written once with the structure (entries not named here are 0 or the kernel's)
_CONSTANT_J = {PointToPoint: _point_to_point_constant_J, PointToNail: _point_to_nail_constant_J}

_KERNELS = {
    PointToPoint: point_to_point_rows,
    PointToNail: point_to_nail_rows,
    Orientation: orientation_rows,
    PointOnPlane: point_on_plane_rows,
    GearToGear: gear_to_gear_rows,
    GearToWeight: gear_to_weight_rows,
    Element: element_rows,
}


def _velocity_rows_position(fam, frame: BodyFrame, rows: FamilyRows) -> None:
    """Velocity rows have C = 0, written with the structure: nothing to evaluate."""


# C alone, for the constraint error: the families whose position level splits off cheaply have their own
# function, the others evaluate all their rows
_POSITION_KERNELS = {
    **_KERNELS,
    PointToPoint: point_to_point_position,
    PointToNail: point_to_nail_position,
    GearToGear: _velocity_rows_position,
    GearToWeight: _velocity_rows_position,
}


def position_kernel_for(fam):
    """The kernel that writes (at least) C of a family's rows, for callers that need only the position error."""
    kernel_for(fam)  # the same check
    return _POSITION_KERNELS[type(fam)]


def row_count(fam) -> int:
    """Number of rows the family writes: ROWS per instance."""
    return type(fam).ROWS * len(_slot_bodies(fam)[0])


def kernel_for(fam):
    """The row kernel of a family (TypeError for anything else): callers that write the same families every
    evaluation resolve it once, with the family's `FamilyRows`, and call it directly."""
    try:
        return _KERNELS[type(fam)]
    except KeyError:
        raise TypeError(f"write_rows: fam is a {type(fam).__name__}, not a constraint family") from None


def write_rows(fam, frame: BodyFrame, out: RowBlock, start: int) -> int:
    """Write the rows of any family at `start`, structure and values; returns the number of rows written."""
    kernel = kernel_for(fam)
    rows = FamilyRows(fam, out, start)
    rows.write_structure()
    kernel(fam, pad_world(frame), rows)
    return rows.count
