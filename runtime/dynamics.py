"""Constraint-force stage: accelerations of all bodies with Lagrange multipliers (PHYSICS.md section 2).

    (J M^-1 J^T) lambda = -Jdot v - J M^-1 F - kd (J v + ct) - ks C          (Baumgarte-stabilized)
    a = M^-1 (F + J^T lambda)

`Dynamics.accelerations` is the right-hand side the integrators call; all its buffers live in `DynamicsScratch`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from isaac_lang import expr as E

from . import linsolve
from .constraint_plan import Epoch, prepare_epoch
from .constraints.layout import BodyFrame, RowBlock
from .constraints.rows import write_rows
from .forces import apply_forces
from .kinematics import evaluate_paths
from .rotation import quat_to_matrix, world_inverse_inertia


@dataclass
class DynamicsScratch:
    R: np.ndarray  # (n,3,3)
    inv_inertia_world: np.ndarray  # (n,3,3)
    inertia_world: np.ndarray  # (n,3,3)
    force: np.ndarray  # (n,3)
    torque: np.ndarray  # (n,3)
    rows: RowBlock | None  # every row of every family
    last_solve: linsolve.SolveInfo | None = None
    rank_deficient_seen: bool = False

    @classmethod
    def allocate(cls, n: int, total_rows: int) -> "DynamicsScratch":
        return cls(np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3)),
                   np.zeros((n, 3)), RowBlock.empty(total_rows) if total_rows else None)


class Dynamics:
    """The acceleration function of the dynamics plan: forces, then the constraint solve."""

    def __init__(self, plan):
        self.plan = plan
        total = plan.constraints.total_rows if plan.constraints is not None else 0
        self.scratch = DynamicsScratch.allocate(plan.n, total)

    def frame(self, x, q, v, w, t) -> BodyFrame:
        s = self.scratch
        quat_to_matrix(q, out=s.R)
        return BodyFrame(x, q, v, w, s.R, t)

    def accelerations(self, t, x, q, v, w, a, alpha, epoch: Epoch | None) -> None:
        """a, alpha (n,3) <- linear and angular accelerations at state (x, q, v, w) and time t."""
        plan, s = self.plan, self.scratch
        if plan.kinematics is not None:
            evaluate_paths(plan.kinematics, t, x, q, v, w, a, alpha)
        frame = self.frame(x, q, v, w, t)
        world_inverse_inertia(s.R, plan.inv_inertia_body, out=s.inv_inertia_world)
        if plan.forces.gyroscopic is not None:
            world_inverse_inertia(s.R, plan.inertia_body, out=s.inertia_world)
        apply_forces(plan.forces, x, v, w, s.R, t, s.inertia_world, s.force, s.torque)
        dynamic = plan.dynamic
        # unconstrained: a = F / m, alpha = I^-1 tau (kinematic bodies keep their path's accelerations)
        a[dynamic] = plan.inv_mass[dynamic, None] * s.force[dynamic]
        alpha[dynamic] = np.einsum("nij,nj->ni", s.inv_inertia_world[dynamic], s.torque[dynamic])
        if epoch is not None and epoch.active.size:
            self._constrain(frame, epoch, a, alpha)

    def rows_at(self, frame: BodyFrame) -> RowBlock:
        """Evaluate every row of every family at this frame (moving nails first move to time frame.t)."""
        c, block = self.plan.constraints, self.scratch.rows
        for nail in c.moving_nails:
            family = c.families[nail.family]
            env = {"t": frame.t}
            family.target[nail.instance] = E.evaluate(nail.position, env)
            family.target_velocity[nail.instance] = E.evaluate(nail.velocity, env)
            family.target_acceleration[nail.instance] = E.evaluate(nail.acceleration, env)
        for family, offset in zip(c.families, c.family_offsets):
            write_rows(family, frame, block, offset)
        return block

    def _constrain(self, frame: BodyFrame, epoch: Epoch, a, alpha) -> None:
        plan, s = self.plan, self.scratch
        c = plan.constraints
        prepare_epoch(c, epoch, plan.dynamic)
        block = self.rows_at(frame)
        active = epoch.active
        J = block.J[active]
        rb = c.row_bodies[active]
        ks, kd = c.row_ks[active], c.row_kd[active]
        Jv = _apply_rows(J, rb, frame.v, frame.w)
        Ja = _apply_rows(J, rb, a, alpha)
        # rhs = -(Jdot v + C_tt) - J a_free - kd (J v + ct) - ks C   (velocity-only rows have C = 0)
        rhs = -block.bias[active] - Ja - kd * (Jv + block.ct[active]) - ks * block.C[active]
        lam = self._solve(epoch, J, rb, rhs)
        # a += M^-1 J^T lambda
        MJ = linsolve.apply_inverse_mass(J, rb, plan.inv_mass, s.inv_inertia_world)
        _scatter_add(MJ, rb, lam, a, alpha)

    def _solve(self, epoch: Epoch, J, rb, rhs) -> np.ndarray:
        plan, s = self.plan, self.scratch
        if epoch.solver == "tree":
            lam, info = epoch.pattern.solve(J, plan.inv_mass, s.inv_inertia_world, rhs)
        elif epoch.solver == "sparse":
            lam, info = linsolve.solve_sparse(epoch.pattern, J, plan.inv_mass, s.inv_inertia_world, rhs)
        else:
            A = linsolve.assemble_dense(J, rb, plan.inv_mass, s.inv_inertia_world)
            lam, info = linsolve.solve_dense(A, rhs)
        s.last_solve = info
        s.rank_deficient_seen |= bool(getattr(info, "rank_deficient", False))
        return lam


def _apply_rows(J, rb, lin, ang) -> np.ndarray:
    """J x for a stacked velocity-like x = (lin, ang) per body: sum over the two slots of each row."""
    out = np.zeros(len(J))
    for slot in range(2):
        body = rb[:, slot]
        inside = body >= 0
        safe = np.where(inside, body, 0)
        contribution = np.einsum("ri,ri->r", J[:, slot, :3], lin[safe]) + np.einsum("ri,ri->r", J[:, slot, 3:], ang[safe])
        out += np.where(inside, contribution, 0.0)
    return out


def _scatter_add(MJ, rb, lam, a, alpha) -> None:
    """a, alpha += sum over rows of M^-1 J^T lambda, per body (world slots dropped)."""
    n = len(a)
    for slot in range(2):
        body = rb[:, slot]
        inside = body >= 0
        if not inside.any():
            continue
        impulse = MJ[inside, slot, :] * lam[inside, None]
        index = body[inside]
        for k in range(3):
            a[:, k] += np.bincount(index, weights=impulse[:, k], minlength=n)
            alpha[:, k] += np.bincount(index, weights=impulse[:, 3 + k], minlength=n)
