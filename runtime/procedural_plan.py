"""The procedural plan in the step loop: the XPBD solver of `procedural.py` over the scene's active constraints.

Per epoch (a stretch of time with a fixed set of active rows) the families are cut down to their active
instances once, with a `keep` mask for rows removed by `-` or not yet switched on, and handed to a
`ProceduralSolver`, which is cached. Forces are evaluated once per step (the wind with the step's length, for
its exact drag relaxation); moving nails and self-assembly targets once per substep.

Self-assembly (PHYSICS.md section 4). The dynamics plan lets a row that switches on with error C0 and rate D0
decay along Baumgarte's curve, C'' + kd C' + ks C = 0. A projection would close it in one substep, so here a row
that switches on is projected, from then on, to that very curve instead of to 0: target(s) = C(s) with
C(0) = C0, C'(0) = D0, s the time since the switch, ks and kd the row's (constraint_plan row_ks, row_kd).
Orientation rows are curved in the dynamics plan's C = T . N = sin(angle) and projected to the angle.
Velocity rows (gears, ropes) have no C(x) and hold from the first substep.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from isaac_lang import expr as E

from .constraints import projections as pj
from .constraints.layout import Orientation, PointToNail, PointToPoint
from .forces import apply_forces
from .kinematics import evaluate_paths
from .procedural import ProceduralSolver
from .rotation import quat_to_matrix

# sweep order: the family swept last ends every substep exact, so the gear ratio goes last (procedural.py)
SWEEP_ORDER = ("PointToNail", "PointToPoint", "Orientation", "PointOnPlane", "Element", "GearToWeight", "GearToGear")
# a row that switches on with |C0| and |D0| / omega below this (m or rad) has nothing to assemble
ASSEMBLED = 1e-12
# an assembly curve is dropped once its envelope exp(-decay s) has fallen below exp(-CURVE_SPAN)
CURVE_SPAN = 40.0


class ProceduralStepper:
    def __init__(self, plan, dynamics=None, contacts="auto"):
        self.plan = plan
        self.forces = dataclasses.replace(plan.forces, gyroscopic=None)  # the XPBD integrator has its own
        self.force = np.zeros((plan.n, 3))
        self.torque = np.zeros((plan.n, 3))
        self.R = np.zeros((plan.n, 3, 3))
        self.inertia_world = np.zeros((plan.n, 3, 3))
        self.solvers: dict[int, tuple] = {}  # epoch id -> (solver, moving nails, plan row of each solver row)
        options = plan.scene.solver
        self.substeps = options.substeps
        self.iterations = options.iterations
        self.method = getattr(options, "projection", "auto")
        self.curves = AssemblyCurves(plan.constraints)
        self.epoch = None
        if contacts == "auto":
            from .procedural_sphere import ProceduralSpheres

            contacts = ProceduralSpheres.from_plan(plan) if getattr(plan, "collisions", None) is None else None
        self.contacts = contacts

    def step(self, state, h: float, epoch) -> None:
        solver, nails, rows = self._solver(epoch)
        if epoch is not self.epoch:
            self.curves.switch(solver, rows, state)
            self.epoch = epoch
        quat_to_matrix(state.q, out=self.R)
        if self.forces.wind is not None and hasattr(self.forces.wind, "set_step"):
            self.forces.wind.set_step(h)
        apply_forces(self.forces, state.x, state.v, state.w, self.R, state.t, self.inertia_world, self.force,
                     self.torque)
        curves = self.curves if self.curves.running else None
        solver.target = curves.target if curves is not None else None

        paths = self.plan.kinematics

        def on_substep(tau: float) -> None:
            if paths is not None:
                # kinematic bodies on their paths at the substep's end (the unconstrained move glided them at the
                # start's velocity: a hand shaken at 30 Hz would lag its path by centimetres within a 10 ms step)
                evaluate_paths(paths, state.t + tau, state.x, state.q, state.v, state.w)
            for family, index, nail in nails:
                family.target[index] = E.evaluate(nail.position, {"t": state.t + tau})
            if curves is not None:
                curves.evaluate(state.t + tau)

        moving = paths is not None or nails or curves is not None
        solver.step(state.x, state.q, state.v, state.w, h, self.force, self.torque, on_substep if moving else None)
        if curves is not None:
            curves.expire(state.t + h)

    def _solver(self, epoch):
        key = id(epoch)
        if key not in self.solvers:
            self.solvers[key] = self._build(epoch)
        return self.solvers[key]

    def _build(self, epoch):
        plan, c = self.plan, self.plan.constraints
        families, compliance, keep, nails, rows = [], [], [], [], []
        if c is not None and epoch is not None:
            active = np.zeros(c.total_rows, dtype=bool)
            active[epoch.active] = True
            order = sorted(range(len(c.families)), key=lambda f: SWEEP_ORDER.index(type(c.families[f]).__name__))
            for f in order:
                subset = self._subset(c, f, active)
                if subset is None:
                    continue
                family, chosen, rows_kept = subset
                families.append(family)
                size = type(family).ROWS
                first_rows = c.family_offsets[f] + chosen * size
                rows.append((first_rows[:, None] + np.arange(size)).reshape(-1))
                compliance.append(c.row_compliance[first_rows])
                keep.append(rows_kept)
                nails.extend(self._moving_nails(c, f, chosen, family))
        solver = ProceduralSolver(families, compliance, plan.inv_mass, plan.inv_inertia_body,
                                  substeps=self.substeps, iterations=self.iterations, keep=keep, method=self.method,
                                  contacts=self.contacts)
        return solver, nails, np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)

    @staticmethod
    def _subset(c, f: int, active: np.ndarray):
        """The family's instances with at least one active row, and their (k,3) kept-row mask."""
        family = c.families[f]
        rows = type(family).ROWS
        count = (c.family_offsets[f + 1] if f + 1 < len(c.families) else c.total_rows) - c.family_offsets[f]
        mask = active[c.family_offsets[f]:c.family_offsets[f] + count].reshape(-1, rows)
        chosen = np.flatnonzero(mask.any(axis=1))
        if not chosen.size:
            return None
        fields = {fd.name: getattr(family, fd.name)[chosen] for fd in dataclasses.fields(family)
                  if getattr(family, fd.name) is not None}
        subset = type(family)(**fields)
        kept = mask[chosen] if isinstance(family, (PointToPoint, PointToNail)) else None
        return subset, chosen, kept

    @staticmethod
    def _moving_nails(c, f: int, chosen: np.ndarray, family) -> list:
        out = []
        for nail in c.moving_nails:
            if nail.family == f and nail.instance in chosen:
                out.append((family, int(np.flatnonzero(chosen == nail.instance)[0]), nail))
        return out


class AssemblyCurves:
    """The self-assembly targets of the rows that switched on (module docstring).

    Per constraint-plan row: on (the time it switched on, nan if never), C0, D0 (in curve space: sin(angle) for
    orientation rows), and the curve's constants. For the current solver: live (solver rows on a curve), their
    plan rows, and target (the solver's rows,), written at every substep."""

    def __init__(self, constraints):
        total = constraints.total_rows if constraints is not None else 0
        self.constraints = constraints
        self.on = np.full(total, np.nan)
        self.C0, self.D0 = np.zeros(total), np.zeros(total)
        self.sine = np.zeros(total, dtype=bool)
        self.active = np.zeros(total, dtype=bool)
        self.running = False
        self.target = None

    def switch(self, solver: ProceduralSolver, rows: np.ndarray, state) -> None:
        """A new epoch: rows that were off and are now on record their error and rate; the solver's curves."""
        fresh = np.zeros(len(rows), dtype=bool)
        if len(rows):
            fresh = ~self.active[rows]
            self.active[:] = False
            self.active[rows] = True
        if fresh.any():
            C, D, sine = self._values(solver, state)
            r = rows[fresh]
            self.on[r], self.C0[r], self.D0[r], self.sine[r] = state.t, C[fresh], D[fresh], sine[fresh]
        self.target = np.zeros(len(rows)) if len(rows) else None
        self.rows = rows
        self._select()

    def _values(self, solver, state):
        """C0, D0 of every solver row at the state, in curve space, and whether the row is an orientation row."""
        p = solver.plan
        C, D, sine = np.zeros(p.rows), np.zeros(p.rows), np.zeros(p.rows, dtype=bool)
        for f, fam in enumerate(p.families):
            c, d = row_values(fam, state.x, state.q, state.v, state.w, p.inv_mass, p.inv_inertia_body)
            rows = solver.family_rows(f)
            if isinstance(fam, Orientation):  # the dynamics plan's C = T . N = sin(angle)
                c, d, sine[rows] = np.sin(c), np.cos(c) * d, True
            C[rows], D[rows] = c.reshape(-1), d.reshape(-1)
        return C, D, sine

    def _select(self) -> None:
        """The solver rows on a curve that has not yet died out."""
        c, rows = self.constraints, self.rows
        live = np.zeros(len(rows), dtype=bool)
        if len(rows):
            ks, kd = c.row_ks[rows], c.row_kd[rows]
            omega = np.sqrt(ks)
            size = np.abs(self.C0[rows]) + np.abs(self.D0[rows]) / np.maximum(omega, 1e-300)
            live = ~np.isnan(self.on[rows]) & (size > ASSEMBLED)
        self.live = np.flatnonzero(live)
        plan_rows = rows[self.live]
        self.live_rows = plan_rows
        if len(plan_rows):
            self.curve = Curve(self.C0[plan_rows], self.D0[plan_rows], c.row_ks[plan_rows], c.row_kd[plan_rows])
            self.end = self.on[plan_rows] + self.curve.span
        self.running = len(self.live) > 0
        if self.target is not None:
            self.target.fill(0.0)

    def evaluate(self, t: float) -> None:
        """target of the live rows at time t (the end of the coming substep)."""
        value = self.curve(t - self.on[self.live_rows])
        sine = self.sine[self.live_rows]
        if sine.any():
            value = np.where(sine, np.arcsin(np.clip(value, -1.0, 1.0)), value)
        self.target[self.live] = value

    def expire(self, t: float) -> None:
        """Drop the curves that have died out by time t."""
        if (t >= self.end).any():
            self.on[self.live_rows[t >= self.end]] = np.nan
            self._select()


class Curve:
    """C(s) of C'' + kd C' + ks C = 0 with C(0) = C0, C'(0) = D0, per row (k,): the roots of r^2 + kd r + ks
    decide the form. Critically damped (kd^2 = 4 ks, within 1e-9): C = (C0 + (D0 + a C0) s) exp(-a s), a = kd/2;
    under-damped: exp(-a s) (C0 cos(b s) + (D0 + a C0) sin(b s) / b), b = sqrt(ks - a^2); over-damped:
    A exp(r1 s) + (C0 - A) exp(r2 s), r1,2 = -a +- sqrt(a^2 - ks), A = (D0 - r2 C0) / (r1 - r2).
    span (k,): the time after which the envelope is below exp(-CURVE_SPAN) (inf without damping)."""

    def __init__(self, C0, D0, ks, kd):
        self.C0, self.D0 = C0, D0
        a = 0.5 * kd
        disc = a * a - ks
        self.a = a
        self.critical = np.abs(disc) <= 1e-9 * np.maximum(ks, 1e-300)
        self.under = ~self.critical & (disc < 0.0)
        self.over = ~self.critical & (disc > 0.0)
        self.b = np.sqrt(np.abs(disc))
        self.r1, self.r2 = -a + self.b, -a - self.b
        slowest = np.where(self.over, -self.r1, a)
        self.span = np.divide(CURVE_SPAN, slowest, out=np.full(len(a), np.inf), where=slowest > 0.0)

    def __call__(self, s):
        s = np.maximum(s, 0.0)
        a, b, C0, D0 = self.a, self.b, self.C0, self.D0
        out = (C0 + (D0 + a * C0) * s) * np.exp(-a * s)
        if self.under.any():
            bb = np.where(self.under, b, 1.0)
            out = np.where(self.under, np.exp(-a * s) * (C0 * np.cos(bb * s) + (D0 + a * C0) * np.sin(bb * s) / bb),
                           out)
        if self.over.any():
            gap = np.where(self.over, self.r1 - self.r2, 1.0)
            A = (D0 - self.r2 * C0) / gap
            out = np.where(self.over, A * np.exp(self.r1 * s) + (C0 - A) * np.exp(self.r2 * s), out)
        return out


def row_values(fam, x, q, v, w, inv_mass, inv_inertia_body) -> tuple:
    """(C, dC/dt) of every row of a family at the state (x, q, v, w), in the layout of its multipliers
    ((k,3) for point families, (k,) otherwise), C as the projections define it (the angle asin(T . N) for an
    orientation row). Velocity families give zeros: they have no C(x). Used when rows switch on."""
    shape = pj.lam_shape(fam)
    if isinstance(fam, pj.VELOCITY_FAMILIES):
        return np.zeros(shape), np.zeros(shape)
    body_a, body_b = pj.instance_bodies(fam)
    both = np.concatenate((body_a, body_b))
    vs, ws = _slot_rows(v, both), _slot_rows(w, both)
    if fam.ROWS == 3:
        k = len(body_a)
        pair = pj.gather(body_a, body_b, x, q, inv_mass, inv_inertia_body)
        points = np.concatenate((fam.point, np.zeros_like(fam.point))) if isinstance(fam, PointToNail) else (
            np.concatenate((fam.point_a, fam.point_b)))
        target = fam.target if isinstance(fam, PointToNail) else 0.0
        r = pj.matvec(pair.R, points)
        P, Pdot = pair.x + r, vs + pj.cross(ws, r)
        return P[:k] - P[k:] - target, Pdot[:k] - Pdot[k:]
    C, Cdot = np.zeros(shape), np.zeros(shape)
    for idx, rows in pj.row_groups(fam):
        pair = pj.gather(body_a[idx], body_b[idx], x, q, inv_mass, inv_inertia_body)
        c, l, g = rows(fam, idx, pair, None)
        slots = np.concatenate((idx, idx + len(body_a)))
        rate = pj.dot(l, vs[slots]) + pj.dot(g, ws[slots])
        C[idx], Cdot[idx] = c, rate[: len(idx)] + rate[len(idx):]
    return C, Cdot


def _slot_rows(a, index):
    """Rows of a (n,3) for body indices (WORLD -> a zero row)."""
    return np.vstack((a, np.zeros((1, a.shape[1])))).take(index, axis=0)
