"""The model: the plan as plain arrays, read-only during a run (MuJoCo's mjModel).

Every body array has n + 1 rows: the last one is the world (static, at rest, identity pose), so that a kernel
reads a WORLD = -1 slot as that row, with no branch. Constraint instances of every family are one table: a
family code, two body slots and a fixed-width parameter row whose meaning depends on the family (the `*_P` slot
names below); their rows are numbered as the plan numbers them (family after family, instance after instance,
ROWS each), so the plan's row metadata (windows, gains, `-` removals) indexes the same rows.

    bodies       inv_mass (n+1,), mass (n+1,), inertia, inv_inertia (n+1,3,3) body frame, dynamic (n+1,),
                 isotropic (n+1,) inertia a multiple of I, principal (n+1,) inertia diagonal in the body frame,
                 inv_moments (n+1,3) the diagonal of inv_inertia, weight (n+1,3) m g, gyroscopic (n+1,)
    kinematic    body (k,), column (k,): the body's 19 columns in the time table (x, v, a, q, w, alpha)
    springs      body (s,2), point (s,2,3) body frame (world point for WORLD), stiffness, rest, damping (s,)
    loads        body (l,), point (l,3) body frame, column (l,): force (3) and torque (3) in the time table
    constraints  family (K,), body (K,2), first_row (K,), rows (K,), param (K, PARAMS); drivers: instance, slot,
                 column, size (d,): param[instance, slot:slot+size] <- table[:, column:column+size] (moving
                 nails: P, dP/dt, d2P/dt2); row_instance, row_component (M,), velocity_only (M,), ks, kd (M,) Baumgarte gains,
                 compliance (M,) the procedural plan's softness, settles (M,) a row may be held (projected)
                 once assembled (not under `stabilization baumgarte`), soft (M,) a relative regularization of
                 the row's diagonal (contacts: core/contact.py)
    wind         runtime/wind/kernels.WindModel; its winds' speeds s(t) are table columns wind_column ..
                 wind_column + wind_count, followed by their source points and directions when one moves
                 (wind/kernels.wind_table's layout; without, the kernels read the model's constants)
    shapes, pairs, margin   collision shapes and the pairs the collision stage watches between its calls
                 (below); the contact instances are the last ones of `constraints` (contact.py)
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from isaac_runtime.constraints import layout as L

# constraint families (codes of constraints.family); the contact families are written by the collision stage
NAIL, POINT, ORIENT, PLANE, GEAR, ROPE, ELEMENT, CONTACT, CONTACT_SPHERES = range(9)
FAMILY_OF_LAYOUT = {L.PointToNail: NAIL, L.PointToPoint: POINT, L.Orientation: ORIENT, L.PointOnPlane: PLANE,
                    L.GearToGear: GEAR, L.GearToWeight: ROPE, L.Element: ELEMENT}
ROWS_OF_FAMILY = (3, 3, 1, 1, 1, 1, 1, 3, 1)  # (a contact without friction has 1 row: cons.rows says)
VELOCITY_FAMILIES = (GEAR, ROPE)
PARAMS = 24  # width of a parameter row

# parameter slots (offsets into a parameter row); world-frame time derivatives are written by drivers
NAIL_POINT, NAIL_TARGET, NAIL_TARGET_RATE, NAIL_TARGET_ACCEL = 0, 3, 6, 9
POINT_A, POINT_B = 0, 3
ORIENT_AXIS_A, ORIENT_AXIS_B, ORIENT_AXIS_B_RATE, ORIENT_AXIS_B_ACCEL = 0, 3, 6, 9
PLANE_POINT, PLANE_ORIGIN, PLANE_NORMAL = 0, 3, 6
PLANE_ORIGIN_RATE, PLANE_ORIGIN_ACCEL, PLANE_NORMAL_RATE, PLANE_NORMAL_ACCEL = 9, 12, 15, 18
GEAR_AXIS_A, GEAR_AXIS_B, GEAR_RADIUS_A, GEAR_RADIUS_B, GEAR_RADIUS_A_RATE, GEAR_RADIUS_B_RATE = 0, 3, 6, 7, 8, 9
ROPE_ARM, ROPE_DIRECTION = 0, 3
ELEMENT_AXIS, ELEMENT_ROTATIONAL, ELEMENT_OFFSET, ELEMENT_REFERENCE = 0, 3, 4, 5
# a contact of body a's point (or a sphere's centre and radius) with a face of b (or a plane): the point in a's
# frame, the face's origin, normal and tangents in b's frame (b's face axes: friction rows and the face's
# bounds), the anchor of sticking friction in b's frame, the radius (0 for a point), the face's half extents
# along the tangents (inf: no edge), the friction coefficient of sliding (0: not sliding) and of the cone
CONTACT_POINT, CONTACT_ORIGIN, CONTACT_NORMAL, CONTACT_T1, CONTACT_T2, CONTACT_ANCHOR = 0, 3, 6, 9, 12, 15
CONTACT_RADIUS, CONTACT_HALF1, CONTACT_HALF2, CONTACT_SLIDE_MU, CONTACT_MU = 18, 19, 20, 21, 22
# a contact of two spheres: their centres in their frames, the sum of their radii
SPHERES_A, SPHERES_B, SPHERES_REACH = 0, 3, 6

# the parameters that may be functions of time: (family, layout field) -> ((value, rate, acceleration) slots, size);
# a slot of None is not written (a gear's row needs no radius acceleration)
MOVING_SLOTS = {
    (NAIL, "target"): ((NAIL_TARGET, NAIL_TARGET_RATE, NAIL_TARGET_ACCEL), 3),
    (PLANE, "plane_point"): ((PLANE_ORIGIN, PLANE_ORIGIN_RATE, PLANE_ORIGIN_ACCEL), 3),
    (PLANE, "plane_normal"): ((PLANE_NORMAL, PLANE_NORMAL_RATE, PLANE_NORMAL_ACCEL), 3),
    (ORIENT, "axis_b"): ((ORIENT_AXIS_B, ORIENT_AXIS_B_RATE, ORIENT_AXIS_B_ACCEL), 3),
    (GEAR, "radius_a"): ((GEAR_RADIUS_A, GEAR_RADIUS_A_RATE), 1),
    (GEAR, "radius_b"): ((GEAR_RADIUS_B, GEAR_RADIUS_B_RATE), 1),
}

# columns of a kinematic body in the time table
KIN_X, KIN_V, KIN_A, KIN_Q, KIN_W, KIN_ALPHA, KIN_WIDTH = 0, 3, 6, 9, 13, 16, 19

Bodies = namedtuple("Bodies", "inv_mass mass inertia inv_inertia dynamic isotropic principal inv_moments weight "
                               "gyroscopic")
Kinematic = namedtuple("Kinematic", "body column on")  # on (k,): on its path now (a body may leave it: `kinematic A .. B`)
Springs = namedtuple("Springs", "body point stiffness rest damping")
Loads = namedtuple("Loads", "body point column")
Constraints = namedtuple("Constraints", "family body first_row rows param driver_instance driver_slot "
                                        "driver_column driver_size row_instance row_component velocity_only ks kd "
                                        "compliance settles soft")
# collision shapes (the codes of runtime/collide/shapes.py): kind (n+1,), radius (n+1,), half (n+1,3) half edges or
# bounding half-extents, half_length (n+1,) of a capsule's or cylinder's straight part, normal (n+1,3) a plane's,
# centre (n+1,3) of the bounding box, all in the body frame
SHAPE_NONE, SHAPE_SPHERE, SHAPE_BOX, SHAPE_CAPSULE, SHAPE_CYLINDER, SHAPE_PLANE, SHAPE_MESH = range(7)
Shapes = namedtuple("Shapes", "kind radius half half_length normal centre")
# the pairs that may collide: a, b (P,); state (P,) 0 apart (the broad phase watches it), 1 in contact (its rows
# hold it; it is watched for turning), 2 excluded now; relative (P,4) conj(q_b) q_a when its contacts were found
# (or, apart, at the look that set its clearance); turn (P,) how far it may turn before they are looked for again
# (rad); an apart pair's clearance at its last look (core/contact.py `kept_clear`): clear (P,) its distance less
# the margin (m; 0: none, the swept boxes decide), side (P,) whose point ref (P,3) is, in that body's frame (0: a's,
# 1: b's), seen (P,3) where that point was in the other body's frame, lever (P,) the arm its turning acts through
# (m); written by the collision stage
Pairs = namedtuple("Pairs", "a b state relative turn clear side ref seen lever")
Model = namedtuple("Model", "n bodies kinematic springs loads constraints wind wind_column wind_count shapes pairs "
                            "margin")


def no_shapes(n: int) -> Shapes:
    return Shapes(np.zeros(n + 1, np.int64), _f(n + 1), _f((n + 1, 3)), _f(n + 1), _f((n + 1, 3)), _f((n + 1, 3)))


def no_pairs() -> Pairs:
    z = np.zeros(0, np.int64)
    return Pairs(z, z.copy(), z.copy(), _f((0, 4)), _f(0), _f(0), z.copy(), _f((0, 3)), _f((0, 3)), _f(0))


def _f(shape) -> np.ndarray:
    return np.zeros(shape, dtype=np.float64)


def _i(values) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values, dtype=np.int64).reshape(-1))


def build_bodies(plan) -> Bodies:
    """The body arrays of the plan, padded with the world row."""
    n = plan.n
    inv_mass, mass = _f(n + 1), _f(n + 1)
    inv_mass[:n], mass[:n] = plan.inv_mass, plan.mass
    inertia, inv_inertia = np.tile(np.eye(3), (n + 1, 1, 1)), _f((n + 1, 3, 3))
    inertia[:n], inv_inertia[:n] = plan.inertia_body, plan.inv_inertia_body
    dynamic = np.zeros(n + 1, dtype=np.bool_)
    dynamic[:n] = plan.dynamic
    moments = np.einsum("nii->ni", inertia)
    isotropic = np.array([np.array_equal(inertia[i], moments[i, 0] * np.eye(3)) for i in range(n + 1)], np.bool_)
    principal = np.array([np.array_equal(inv_inertia[i], np.diag(np.diag(inv_inertia[i]))) for i in range(n + 1)],
                         np.bool_)
    inv_moments = np.ascontiguousarray(np.einsum("nii->ni", inv_inertia))
    weight = _f((n + 1, 3))
    if plan.forces.weight is not None:
        weight[:n] = plan.forces.weight
    gyroscopic = np.zeros(n + 1, dtype=np.bool_)
    if plan.forces.gyroscopic is not None:
        gyroscopic[np.asarray(plan.forces.gyroscopic, int)] = True
    return Bodies(inv_mass, mass, inertia, inv_inertia, dynamic, isotropic, principal, inv_moments, weight, gyroscopic)


def build_springs(plan) -> Springs:
    s = plan.forces.springs
    if s is None:
        return Springs(np.zeros((0, 2), np.int64), _f((0, 2, 3)), _f(0), _f(0), _f(0))
    body = np.ascontiguousarray(np.stack([s.body_a, s.body_b], axis=1).astype(np.int64))
    point = np.ascontiguousarray(np.stack([s.point_a, s.point_b], axis=1).astype(np.float64))
    return Springs(body, point, np.asarray(s.stiffness, float), np.asarray(s.rest, float),
                   np.asarray(s.damping, float))


def pack_constraints(cplan, drivers) -> Constraints:
    """The constraint families of a ConstraintPlan as one instance table (module docstring). drivers: list of
    (instance, slot, column, size) from the time table."""
    family, body, first, rows, params = [], [], [], [], []
    for fam, offset in zip(cplan.families, cplan.family_offsets):
        code = FAMILY_OF_LAYOUT[type(fam)]
        for i, (a, b, p) in enumerate(_instances(code, fam)):
            family.append(code)
            body.append((a, b))
            first.append(offset + ROWS_OF_FAMILY[code] * i)
            rows.append(ROWS_OF_FAMILY[code])
            row = np.zeros(PARAMS)
            row[:len(p)] = p
            params.append(row)
    K, M = len(family), cplan.total_rows
    row_instance, row_component = np.zeros(M, np.int64), np.zeros(M, np.int64)
    for k in range(K):
        row_instance[first[k]:first[k] + rows[k]] = k
        row_component[first[k]:first[k] + rows[k]] = np.arange(rows[k])
    velocity_only = np.isin(np.asarray(family, np.int64)[row_instance], VELOCITY_FAMILIES) if M else \
        np.zeros(0, np.bool_)
    d = np.asarray(drivers, dtype=np.int64).reshape(-1, 4)
    return Constraints(_i(family), np.ascontiguousarray(np.asarray(body, np.int64).reshape(-1, 2)), _i(first),
                       _i(rows), np.ascontiguousarray(np.asarray(params, np.float64).reshape(-1, PARAMS)),
                       _i(d[:, 0]), _i(d[:, 1]), _i(d[:, 2]), _i(d[:, 3]), row_instance, row_component,
                       np.ascontiguousarray(velocity_only, dtype=np.bool_), np.asarray(cplan.row_ks, float).copy(),
                       np.asarray(cplan.row_kd, float).copy(), np.asarray(cplan.row_compliance, float).copy(),
                       np.full(M, getattr(cplan, "stabilization", "projection") != "baumgarte", np.bool_), _f(M))


def with_capacity(cons: Constraints, instances: int, rows: int) -> Constraints:
    """The same table with room for `instances` more instances and `rows` more rows after its own (zero-filled;
    the collision stage writes its contacts there)."""
    def grow(array, extra):
        shape = (array.shape[0] + extra,) + array.shape[1:]
        out = np.zeros(shape, array.dtype)
        out[:len(array)] = array
        return out

    fields = {}
    for name, array in cons._asdict().items():
        if name.startswith("driver_"):
            fields[name] = array
        elif name in ("family", "body", "first_row", "rows", "param"):
            fields[name] = grow(array, instances)
        else:
            fields[name] = grow(array, rows)
    return Constraints(**fields)


def empty_constraints() -> Constraints:
    z = np.zeros(0, np.int64)
    return Constraints(z, np.zeros((0, 2), np.int64), z, z, _f((0, PARAMS)), z, z, z, z, z, z,
                       np.zeros(0, np.bool_), _f(0), _f(0), _f(0), np.zeros(0, np.bool_), _f(0))


def instance_count(fam) -> int:
    """Instances of a layout family."""
    return len(fam.body if isinstance(fam, L.PointToNail) else fam.gear if isinstance(fam, L.GearToWeight)
               else fam.body_a)


def _instances(code, fam):
    """(body a, body b, parameters) of every instance of a layout family."""
    if code == NAIL:
        for i in range(len(fam.body)):
            yield fam.body[i], L.WORLD, np.concatenate((fam.point[i], fam.target[i], fam.target_velocity[i],
                                                       fam.target_acceleration[i]))
    elif code == POINT:
        for i in range(len(fam.body_a)):
            yield fam.body_a[i], fam.body_b[i], np.concatenate((fam.point_a[i], fam.point_b[i]))
    elif code == ORIENT:
        for i in range(len(fam.body_a)):
            yield fam.body_a[i], fam.body_b[i], np.concatenate((fam.axis_a[i], fam.axis_b[i]))
    elif code == PLANE:
        for i in range(len(fam.body_a)):
            yield fam.body_a[i], fam.body_b[i], np.concatenate((fam.point_a[i], fam.plane_point[i],
                                                               fam.plane_normal[i]))
    elif code == GEAR:
        for i in range(len(fam.body_a)):
            yield fam.body_a[i], fam.body_b[i], np.concatenate((fam.axis_a[i], fam.axis_b[i],
                                                               [fam.radius_a[i], fam.radius_b[i]]))
    elif code == ROPE:
        for i in range(len(fam.gear)):
            yield fam.gear[i], fam.weight[i], np.concatenate((fam.arm[i], fam.direction[i]))
    else:
        for i in range(len(fam.body_a)):
            yield fam.body_a[i], fam.body_b[i], np.concatenate((fam.axis[i], [float(fam.rotational[i]),
                                                               fam.offset[i]], fam.reference_rotation[i]))
