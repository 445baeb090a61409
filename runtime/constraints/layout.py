"""Data layout shared by every constraint family: instance arrays, the body frame they read, the rows they write.

A family holds k instances as parallel arrays (struct of arrays). Body indices point into the state arrays;
-1 means "the world" (a fixed frame: identity pose, zero velocity). Vectors marked "body frame" are expressed
in the local frame of that body (origin at its centre of mass); "world" vectors in world coordinates.

Row convention (acceleration level, docs/design/physics.md section 2). Each row r touches at most two bodies,
`row_bodies[r] = (i, j)` (-1 for an unused slot), with a 1x6 Jacobian block per slot acting on (v, w):

    dC/dt     = J v + ct                       (ct: explicit time derivative, e.g. -dP/dt of a moving nail)
    d2C/dt2   = J a + bias                     (bias = Jdot v + the explicit second time derivative)

so the solver enforces `J a = -bias - kd (J v + ct) - ks C`. Velocity-only rows (gears) have no C: they
set `velocity_only[r] = True`, `C[r] = 0`, and the solver uses `J a = -bias - kd (J v + ct)`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

WORLD = -1


@dataclass
class BodyFrame:
    """What the row kernels read: the pose and velocity of every body at one instant, plus derived matrices.

    x (n,3) centre of mass, q (n,4) orientation (w,x,y,z), v (n,3) linear velocity, w (n,3) world angular
    velocity, R (n,3,3) rotation matrices of q. Index -1 is never used to index these arrays: kernels treat a
    WORLD slot as identity pose and zero velocity themselves.
    """

    x: np.ndarray
    q: np.ndarray
    v: np.ndarray
    w: np.ndarray
    R: np.ndarray
    t: float = 0.0


@dataclass
class RowBlock:
    """Preallocated output of the row kernels, m rows in all (m = the largest number of rows ever active).

    C (m,) position error; row_bodies (m,2) body indices; J (m,2,6) Jacobian blocks [linear(3), angular(3)]
    per slot; ct (m,) explicit time derivative of C; bias (m,) Jdot v + explicit d2C/dt2;
    velocity_only (m,) rows that have no position-level C. values (3,m): C, ct and bias are its rows, so that
    a solver reads all three of a row range at once.
    """

    C: np.ndarray
    row_bodies: np.ndarray
    J: np.ndarray
    ct: np.ndarray
    bias: np.ndarray
    velocity_only: np.ndarray
    values: np.ndarray | None = None

    @classmethod
    def empty(cls, m: int) -> "RowBlock":
        values = np.zeros((3, m))
        return cls(
            C=values[0],
            row_bodies=np.full((m, 2), WORLD, dtype=np.int64),
            J=np.zeros((m, 2, 6)),
            ct=values[1],
            bias=values[2],
            velocity_only=np.zeros(m, dtype=bool),
            values=values,
        )


def _ints(values) -> np.ndarray:
    return np.asarray(values, dtype=np.int64).reshape(-1)


def _vecs(values) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(-1, 3)


@dataclass
class PointToPoint:
    """Ball joint: body_a's point_a coincides with body_b's point_b. 3 rows per instance (world x, y, z).

    C = x_a + R_a p_a - x_b - R_b p_b.
    """

    ROWS = 3
    body_a: np.ndarray  # (k,) int
    point_a: np.ndarray  # (k,3) body frame of a
    body_b: np.ndarray  # (k,) int, may be WORLD (then point_b is a world point)
    point_b: np.ndarray  # (k,3) body frame of b

    def __post_init__(self):
        self.body_a, self.body_b = _ints(self.body_a), _ints(self.body_b)
        self.point_a, self.point_b = _vecs(self.point_a), _vecs(self.point_b)


@dataclass
class PointToNail:
    """Body point held at a world point P(t) (a fixed nail, or a moving one: "point on path"). 3 rows.

    C = x + R p - P(t). The runtime refreshes target, target_velocity, target_acceleration before each
    evaluation when the nail moves (dP/dt and d2P/dt2 come from the scene's expression of t).
    """

    ROWS = 3
    body: np.ndarray  # (k,) int
    point: np.ndarray  # (k,3) body frame
    target: np.ndarray  # (k,3) world P(t)
    target_velocity: np.ndarray = None  # (k,3) dP/dt
    target_acceleration: np.ndarray = None  # (k,3) d2P/dt2

    def __post_init__(self):
        self.body = _ints(self.body)
        self.point, self.target = _vecs(self.point), _vecs(self.target)
        k = len(self.body)
        self.target_velocity = np.zeros((k, 3)) if self.target_velocity is None else _vecs(self.target_velocity)
        self.target_acceleration = (
            np.zeros((k, 3)) if self.target_acceleration is None else _vecs(self.target_acceleration)
        )


@dataclass
class Orientation:
    """Body-fixed direction T of body_a kept perpendicular to N (world-fixed, or fixed in body_b). 1 row.

    C = T . N with T = R_a axis_a, N = axis_b (world) or R_b axis_b.
    """

    ROWS = 1
    body_a: np.ndarray  # (k,) int
    axis_a: np.ndarray  # (k,3) body frame of a (unit)
    body_b: np.ndarray  # (k,) int or WORLD
    axis_b: np.ndarray  # (k,3) world (if WORLD) or body frame of b (unit)

    def __post_init__(self):
        self.body_a, self.body_b = _ints(self.body_a), _ints(self.body_b)
        self.axis_a, self.axis_b = _vecs(self.axis_a), _vecs(self.axis_b)


@dataclass
class PointOnPlane:
    """Body point P of body_a stays on the plane through S with normal N. 1 row.

    C = N . (P - S); S and N are world-fixed (body_b WORLD) or fixed in body_b.
    """

    ROWS = 1
    body_a: np.ndarray  # (k,) int
    point_a: np.ndarray  # (k,3) body frame of a
    body_b: np.ndarray  # (k,) int or WORLD
    plane_point: np.ndarray  # (k,3) S, world or body frame of b
    plane_normal: np.ndarray  # (k,3) N (unit), world or body frame of b

    def __post_init__(self):
        self.body_a, self.body_b = _ints(self.body_a), _ints(self.body_b)
        self.point_a = _vecs(self.point_a)
        self.plane_point, self.plane_normal = _vecs(self.plane_point), _vecs(self.plane_normal)


@dataclass
class GearToGear:
    """Velocity constraint r_a (w_a . A_a) + r_b (w_b . A_b) = 0, A = gear axes (body frame, unit). 1 row."""

    ROWS = 1
    body_a: np.ndarray
    axis_a: np.ndarray  # (k,3) body frame of a
    radius_a: np.ndarray  # (k,)
    body_b: np.ndarray
    axis_b: np.ndarray  # (k,3) body frame of b
    radius_b: np.ndarray  # (k,)

    def __post_init__(self):
        self.body_a, self.body_b = _ints(self.body_a), _ints(self.body_b)
        self.axis_a, self.axis_b = _vecs(self.axis_a), _vecs(self.axis_b)
        self.radius_a = np.asarray(self.radius_a, dtype=float).reshape(-1)
        self.radius_b = np.asarray(self.radius_b, dtype=float).reshape(-1)


@dataclass
class GearToWeight:
    """Velocity constraint: the rope's speed equals the gear's rim speed. 1 row.

    (w_gear x arm) . d - v_weight . d = 0, with arm the world vector from the gear's centre to where the rope
    leaves the rim (a point fixed in the world, not on the turning gear) and d the rope's world direction
    toward the weight (unit).
    """

    ROWS = 1
    gear: np.ndarray  # (k,) int
    arm: np.ndarray  # (k,3) world
    weight: np.ndarray  # (k,) int
    direction: np.ndarray  # (k,3) world unit

    def __post_init__(self):
        self.gear, self.weight = _ints(self.gear), _ints(self.weight)
        self.arm, self.direction = _vecs(self.arm), _vecs(self.direction)


@dataclass
class Element:
    """One of the six element constraints: fix translation along, or rotation about, an axis. 1 row.

    The axis is world-fixed (body_b WORLD) or fixed in body_b. The reference pose is taken at the start:
    translational: C = e_w . (x_a - x_b) - offset, e_w = R_b axis (x_b = 0, R_b = I for WORLD);
    rotational:    C = 2 vec(q_err) . axis with q_err = conj(q_b) q_a conj(reference_rotation) (q_b = 1 for
    WORLD), i.e. the small rotation of a relative to b since the start, about the axis (in b's frame).
    """

    ROWS = 1
    body_a: np.ndarray
    body_b: np.ndarray  # or WORLD
    axis: np.ndarray  # (k,3) unit, world or body frame of b
    rotational: np.ndarray  # (k,) bool
    offset: np.ndarray = None  # (k,) translational reference
    reference_rotation: np.ndarray = None  # (k,4) conj(q_b0) q_a0

    def __post_init__(self):
        self.body_a, self.body_b = _ints(self.body_a), _ints(self.body_b)
        self.axis = _vecs(self.axis)
        self.rotational = np.asarray(self.rotational, dtype=bool).reshape(-1)
        k = len(self.body_a)
        self.offset = np.zeros(k) if self.offset is None else np.asarray(self.offset, float).reshape(-1)
        if self.reference_rotation is None:
            self.reference_rotation = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
        self.reference_rotation = np.asarray(self.reference_rotation, float).reshape(-1, 4)


FAMILIES = (PointToPoint, PointToNail, Orientation, PointOnPlane, GearToGear, GearToWeight, Element)
