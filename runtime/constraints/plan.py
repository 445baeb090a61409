"""Stage 4 (constraints part): IR constraints -> the families of the library, row metadata, time-window epochs.

Every declared constraint is compiled once into instances of the library's families (one numpy struct of
arrays per family). Each row knows its constraint, its time window, whether `-` removed it, and its
Baumgarte gains. The run is cut into epochs at the switch times; within an epoch the active row set, and so
the structure of J M^-1 J^T, is fixed, which lets the solver's sparsity pattern be built once per epoch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isaac_ir import expr as E
from isaac_ir.derivative import derivative
from isaac_ir import ir

from ..core.rotation import quat_conjugate, quat_multiply, quat_to_matrix
from . import layout as L

# rows of each family, in the order the kernels write them, and the element tag of each
ROW_TAGS = {"nail": ("tx", "ty", "tz"), "point": ("tx", "ty", "tz")}

# default stabilization of a row that assembles: a constraint that switches on apart closes along a critically
# damped curve at this frequency (about 0.1 s), whatever the step; stable for RK4 up to steps of 44 ms
# (omega h < 2.78)
DEFAULT_STABILIZE = 10.0  # Hz
# under `stabilization baumgarte` (every row stabilized for the whole run, the dissertation's formulation) the
# default is tied to the step instead: f = 1 / (STABILIZE_STEPS h), omega h = 2 pi / STABILIZE_STEPS ~ 0.31
STABILIZE_STEPS = 20


@dataclass
class MovingParameter:
    """A constraint parameter that is a function of time (a nail's target, a world plane's point or normal, a
    world axis of `orient`, a gear's radius): its expression and two derivatives, for the time table, and the
    parameter slots (core/model.py) they are written to at every grid row."""

    family: int  # index into ConstraintPlan.families (a family name until the families are laid out)
    instance: int
    name: str  # the layout field (target, plane_point, plane_normal, axis_b, radius_a, radius_b)
    value: E.Expr  # P(t)
    rate: E.Expr  # dP/dt
    acceleration: E.Expr  # d2P/dt2


@dataclass
class Epoch:
    """A stretch of time with a fixed set of active rows (the structure of their solve is built when the run enters
    it: core/structure.py)."""

    start: float
    end: float
    active: np.ndarray  # (m,) global row indices
    solver: str  # "sparse" or "dense" Cholesky (the scene's `linear`), "none" without active rows


@dataclass
class ConstraintPlan:
    names: list  # constraint names, indexed by row_constraint
    families: list  # layout family objects
    family_offsets: list  # first global row of each family
    total_rows: int
    row_constraint: np.ndarray  # (M,) int
    row_kept: np.ndarray  # (M,) bool: not removed by `-`
    row_group: np.ndarray  # (M,) int: rows of one instance share a group
    row_start: np.ndarray  # (M,) s
    row_end: np.ndarray  # (M,) s
    row_ks: np.ndarray  # (M,) 1/s2, Baumgarte position gain
    row_kd: np.ndarray  # (M,) 1/s, Baumgarte velocity gain
    row_compliance: np.ndarray  # (M,) procedural softness
    row_bodies: np.ndarray  # (M, 2) int, fixed for the whole run
    moving: list  # [MovingParameter]
    epochs: list = field(default_factory=list)
    linear_solver: str = "sparse"  # "dense": every pair of rows coupled (a full Cholesky), else minimum degree
    stabilization: str = "projection"  # "baumgarte": no row is ever held (projected); all assemble, always

    def epoch_at(self, t: float) -> Epoch:
        for epoch in self.epochs:
            if epoch.start <= t < epoch.end:
                return epoch
        return self.epochs[-1]

    def switch_times(self) -> list:
        return [e.start for e in self.epochs[1:]]


def stabilization_gains(frequency: float, damping_ratio: float) -> tuple:
    """Baumgarte gains from a frequency (Hz) and a damping ratio: C'' + kd C' + ks C = 0.

    omega = 2 pi f;  ks = omega^2;  kd = 2 zeta omega  (zeta = 1: critically damped, no overshoot)
    """
    omega = 2.0 * math.pi * frequency
    return omega * omega, 2.0 * damping_ratio * omega


def default_stabilization_frequency(step: float, stabilization: str = "projection") -> float:
    return 1.0 / (STABILIZE_STEPS * step) if stabilization == "baumgarte" else DEFAULT_STABILIZE


class _FamilyBuilder:
    """Collects the instances of one family, then builds its struct of arrays."""

    def __init__(self, cls):
        self.cls = cls
        self.columns: dict[str, list] = {}
        self.count = 0

    def add(self, **values) -> int:
        for key, value in values.items():
            self.columns.setdefault(key, []).append(value)
        self.count += 1
        return self.count - 1

    def build(self):
        return self.cls(**{key: np.asarray(values) for key, values in self.columns.items()})


def compile_constraints(scene: ir.Scene, step: float, x0, q0) -> ConstraintPlan:
    index = scene.body_index()
    builders: dict[str, _FamilyBuilder] = {}
    rows_meta: dict[str, list] = {}  # family -> per-row (constraint, kept, group) in instance order
    moving: list = []
    order = ("nail", "point", "orient", "plane", "gear", "rope", "element")
    classes = {"nail": L.PointToNail, "point": L.PointToPoint, "orient": L.Orientation, "plane": L.PointOnPlane,
               "gear": L.GearToGear, "rope": L.GearToWeight, "element": L.Element}
    group = 0
    for c_index, constraint in enumerate(scene.constraints):
        for term in constraint.terms:
            builder = builders.setdefault(term.family, _FamilyBuilder(classes[term.family]))
            instance = _add_instance(builder, term, index, moving)
            # an element term has the one row its name says; other one-row families are tagged by family
            tags = ROW_TAGS.get(term.family, term.rows if term.family == "element" else (term.family,))
            for tag in tags:
                rows_meta.setdefault(term.family, []).append((c_index, tag in term.rows, group))
            group += 1
    families, offsets, meta, total = [], [], [], 0
    for name in order:
        if name not in builders:
            continue
        family = builders[name].build()
        if name == "element":
            capture_element_references(family, x0, q0)
        for m in moving:
            if m.family == name:
                m.family = len(families)
        families.append(family)
        offsets.append(total)
        total += row_count(family)
        meta.extend(rows_meta[name])
    return _finish(scene, step, families, offsets, total, meta, moving, x0, q0)


def _add_instance(builder, term: ir.ConstraintTerm, index: dict, moving: list) -> int:
    b = [index[name] for name in term.bodies] + [L.WORLD]
    family = term.family
    values = {}

    def p(name):
        """The parameter at t = 0; a function of time is noted for the time table (MovingParameter)."""
        value = term.param(name)
        if isinstance(value, E.Expr) and not isinstance(value, E.Const):
            values[name] = value
            return np.asarray(E.evaluate(value, {"t": 0.0}), float)
        return value.value if isinstance(value, E.Const) else value

    if family == "nail":
        instance = builder.add(body=b[0], point=p("point"), target=p("target"))
    elif family == "point":
        instance = builder.add(body_a=b[0], point_a=p("point_a"), body_b=b[1], point_b=p("point_b"))
    elif family == "orient":
        instance = builder.add(body_a=b[0], axis_a=p("axis_a"), body_b=b[1], axis_b=p("axis_b"))
    elif family == "plane":
        instance = builder.add(body_a=b[0], point_a=p("point_a"), body_b=b[1], plane_point=p("plane_point"),
                               plane_normal=p("normal"))
    elif family == "gear":
        instance = builder.add(body_a=b[0], axis_a=p("axis_a"), radius_a=p("radius_a"), body_b=b[1],
                               axis_b=p("axis_b"), radius_b=p("radius_b"))
    elif family == "rope":
        instance = builder.add(gear=b[0], arm=p("arm"), weight=b[1], direction=p("direction"))
    elif family == "element":
        instance = builder.add(body_a=b[0], body_b=b[1], axis=p("axis"), rotational=p("rotational"))
    else:
        raise ValueError(f"unknown constraint family {family}")
    for name, value in values.items():
        rate = derivative(value)
        moving.append(MovingParameter(family, instance, LAYOUT_NAME.get((family, name), name), value, rate,
                                      derivative(rate)))
    return instance


# the term's parameter name -> the layout's field, where they differ
LAYOUT_NAME = {("plane", "normal"): "plane_normal"}


def _finish(scene, step, families, offsets, total, meta, moving, x0, q0) -> ConstraintPlan:
    constraints = scene.constraints
    row_constraint = np.array([m[0] for m in meta], dtype=np.int64).reshape(-1)
    ks, kd, compliance = np.zeros(total), np.zeros(total), np.zeros(total)
    for c_index, constraint in enumerate(constraints):
        frequency = (constraint.stabilize_frequency or scene.solver.stabilize_frequency
                     or default_stabilization_frequency(step, scene.solver.stabilization))
        ratio = constraint.damping_ratio if constraint.damping_ratio is not None else scene.solver.damping_ratio
        mask = row_constraint == c_index
        ks[mask], kd[mask] = stabilization_gains(frequency, ratio)
        compliance[mask] = constraint.compliance if constraint.compliance is not None else scene.solver.compliance
    plan = ConstraintPlan(
        names=[c.name for c in constraints], families=families, family_offsets=offsets, total_rows=total,
        row_constraint=row_constraint, row_kept=np.array([m[1] for m in meta], dtype=bool).reshape(-1),
        row_group=np.array([m[2] for m in meta], dtype=np.int64).reshape(-1),
        row_start=np.array([constraints[c].start for c in row_constraint]).reshape(-1),
        row_end=np.array([constraints[c].end for c in row_constraint]).reshape(-1),
        row_ks=ks, row_kd=kd, row_compliance=compliance,
        row_bodies=_row_bodies(families, offsets, total, x0, q0), moving=moving,
        linear_solver="dense" if scene.solver.linear_solver == "dense" else "sparse",
        stabilization=scene.solver.stabilization,
    )
    plan.epochs = _epochs(plan, scene.time.start, scene.time.end)
    return plan


def _row_bodies(families, offsets, total, x0, q0) -> np.ndarray:
    """(M,2) the bodies of each row's two slots (WORLD = -1), fixed for the run."""
    out = np.full((total, 2), L.WORLD, dtype=np.int64)
    for family, offset in zip(families, offsets):
        a, b = slot_bodies(family)
        rows = type(family).ROWS
        out[offset:offset + rows * len(a), 0] = np.repeat(a, rows)
        out[offset:offset + rows * len(a), 1] = np.repeat(np.broadcast_to(b, np.shape(a)), rows)
    return out


def slot_bodies(fam) -> tuple:
    """(body_a, body_b) of a family's instances: the bodies of slot 0 and slot 1 (WORLD for a nail)."""
    if isinstance(fam, L.PointToNail):
        return fam.body, L.WORLD
    if isinstance(fam, L.GearToWeight):
        return fam.gear, fam.weight
    return fam.body_a, fam.body_b


def row_count(fam) -> int:
    """Number of rows of a family: ROWS per instance."""
    return type(fam).ROWS * len(slot_bodies(fam)[0])


def capture_element_references(fam: L.Element, x0: np.ndarray, q0: np.ndarray) -> None:
    """Fill fam.offset and fam.reference_rotation from the initial poses x0 (n,3), q0 (n,4) so that C = 0 at the
    start (each row reads only the one its kind uses)."""
    x0, q0 = np.asarray(x0, dtype=float).reshape(-1, 3), np.asarray(q0, dtype=float).reshape(-1, 4)
    # the world: at the origin, unturned
    x = np.vstack((x0, np.zeros((1, 3))))
    q = np.vstack((q0, [[1.0, 0.0, 0.0, 0.0]]))
    R = quat_to_matrix(q)
    a, b = fam.body_a, fam.body_b
    # offset = e_0 . (x_a0 - x_b0), e_0 = R_b0 axis
    fam.offset[:] = np.einsum("ki,ki->k", np.einsum("kij,kj->ki", R[b], fam.axis), x[a] - x[b])
    # reference_rotation = conj(q_b0) q_a0, so that q_err = 1 at the start
    fam.reference_rotation[:] = quat_multiply(quat_conjugate(q[b]), q[a])


def _epochs(plan: ConstraintPlan, start: float, end: float) -> list:
    times = {start, end}
    for t in np.concatenate((plan.row_start, plan.row_end)):
        if start < t < end:
            times.add(float(t))
    bounds = sorted(times)
    epochs = []
    for t0, t1 in zip(bounds[:-1], bounds[1:]):
        active = np.flatnonzero(plan.row_kept & (plan.row_start <= t0) & (plan.row_end > t0))
        epochs.append(Epoch(t0, t1, active, "none" if active.size == 0 else plan.linear_solver))
    if not epochs:
        epochs.append(Epoch(start, end, np.zeros(0, dtype=np.int64), "none"))
    return epochs
