"""Constraint-force stage: accelerations of all bodies with Lagrange multipliers (PHYSICS.md section 2).

    (J M^-1 J^T) lambda = -Jdot v - J M^-1 F - kd (J v + ct) - ks C          (Baumgarte-stabilized)
    a = M^-1 (F + J^T lambda)

`Dynamics.accelerations` is the right-hand side the integrators call; all its buffers live in `DynamicsScratch`.
It runs four times per RK4 step on arrays of a few rows, so it is written for few numpy calls: the state is
copied once into world-padded buffers (an extra last row that index WORLD = -1 reads as the fixed world), and
everything that depends only on the active row set is found once per epoch (`ActiveRows`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isaac_lang import expr as E

from . import linsolve
from .constraint_plan import ConstraintPlan, Epoch, prepare_epoch
from .constraints.layout import WORLD, BodyFrame, RowBlock
from .constraints.rows import WorldPaddedFrame, write_rows
from .forces import apply_forces
from .kinematics import evaluate_paths
from .rotation import quat_to_matrix, world_inverse_inertia


@dataclass
class DynamicsScratch:
    """Buffers of one evaluation. The padded arrays have n+1 rows, the last one the world's (zero position,
    velocity and acceleration, identity rotation): row kernels and the constraint stage index both slots of a
    row with it, no masks. R and inv_inertia_world are views of the body rows."""

    x_pad: np.ndarray  # (n+1,3)
    q_pad: np.ndarray  # (n+1,4)
    R_pad: np.ndarray  # (n+1,3,3)
    motion_pad: np.ndarray  # (2,n+1,6): [0] velocities (v, w), [1] accelerations (a, alpha), per body
    R: np.ndarray  # (n,3,3) view of R_pad
    inv_inertia_world: np.ndarray  # (n,3,3)
    inertia_world: np.ndarray  # (n,3,3)
    force: np.ndarray  # (n,3)
    torque: np.ndarray  # (n,3)
    rows: RowBlock | None  # every row of every family
    last_solve: linsolve.SolveInfo | None = None
    rank_deficient_seen: bool = False

    @classmethod
    def allocate(cls, n: int, total_rows: int) -> "DynamicsScratch":
        q_pad = np.zeros((n + 1, 4))
        q_pad[n, 0] = 1.0  # the world: identity rotation
        R_pad = np.zeros((n + 1, 3, 3))
        R_pad[n] = np.eye(3)
        return cls(np.zeros((n + 1, 3)), q_pad, R_pad, np.zeros((2, n + 1, 6)), R_pad[:n], np.zeros((n, 3, 3)),
                   np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                   RowBlock.empty(total_rows) if total_rows else None)


class ActiveRows:
    """What the constraint stage needs about one epoch's active rows, found once per epoch.

    rows: a slice or index array into the RowBlock; families: (family, offset) pairs with an active row;
    row_bodies (m,2) with WORLD = -1; slots (2m,) the same flattened, WORLD -> n (the padded world row);
    ks, kd (m,) Baumgarte gains; scatter (12m,) flat index 6 body + k of every J entry into an (n+1, 6) array.
    """

    def __init__(self, c: ConstraintPlan, epoch: Epoch, n: int):
        active = epoch.active
        contiguous = active.size and np.array_equal(active, np.arange(active[0], active[0] + active.size))
        self.rows = slice(int(active[0]), int(active[0]) + active.size) if contiguous else active
        ends = list(c.family_offsets[1:]) + [c.total_rows]
        self.families = [(f, offset) for f, offset, end in zip(c.families, c.family_offsets, ends)
                         if np.any((active >= offset) & (active < end))]
        self.row_bodies = c.row_bodies[active]
        self.ks, self.kd = c.row_ks[active], c.row_kd[active]
        body = np.where(self.row_bodies == WORLD, n, self.row_bodies)
        self.slots = body.reshape(-1)
        self.scatter = (6 * body[:, :, None] + np.arange(6)).reshape(-1)


class Dynamics:
    """The acceleration function of the dynamics plan: forces, then the constraint solve."""

    def __init__(self, plan):
        self.plan = plan
        total = plan.constraints.total_rows if plan.constraints is not None else 0
        self.scratch = DynamicsScratch.allocate(plan.n, total)
        self._dynamic = np.flatnonzero(plan.dynamic)
        self._all_dynamic = bool(np.all(plan.dynamic))
        self._active: dict[int, tuple] = {}  # id(epoch) -> (epoch, ActiveRows)
        s, velocity = self.scratch, self.scratch.motion_pad[0]
        self._frame = WorldPaddedFrame(s.x_pad, s.q_pad, velocity[:, :3], velocity[:, 3:], s.R_pad, 0.0)

    def frame(self, x, q, v, w, t) -> BodyFrame:
        """The world-padded frame of state (x, q, v, w) at time t. It is one object whose arrays are this
        object's buffers: valid until the next call."""
        s, n, frame = self.scratch, self.plan.n, self._frame
        s.x_pad[:n], s.q_pad[:n] = x, q
        s.motion_pad[0, :n, :3], s.motion_pad[0, :n, 3:] = v, w
        quat_to_matrix(q, out=s.R)
        frame.t = t
        return frame

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
        self._unconstrained(a, alpha)
        if epoch is not None and epoch.active.size:
            self._constrain(frame, epoch, a, alpha)

    def _unconstrained(self, a, alpha) -> None:
        """a = F / m, alpha = I^-1 tau for dynamic bodies (kinematic bodies keep their path's accelerations)."""
        plan, s = self.plan, self.scratch
        if self._all_dynamic:
            np.multiply(plan.inv_mass[:, None], s.force, out=a)
            alpha[...] = np.matmul(s.inv_inertia_world, s.torque[:, :, None])[:, :, 0]
            return
        d = self._dynamic
        a[d] = plan.inv_mass[d, None] * s.force[d]
        alpha[d] = np.matmul(s.inv_inertia_world[d], s.torque[d, :, None])[:, :, 0]

    def rows_at(self, frame: BodyFrame) -> RowBlock:
        """Evaluate every row of every family at this frame (moving nails first move to time frame.t)."""
        c = self.plan.constraints
        return self._write_rows(frame, zip(c.families, c.family_offsets))

    def _write_rows(self, frame: BodyFrame, families) -> RowBlock:
        c, block = self.plan.constraints, self.scratch.rows
        for nail in c.moving_nails:
            family = c.families[nail.family]
            env = {"t": frame.t}
            family.target[nail.instance] = E.evaluate(nail.position, env)
            family.target_velocity[nail.instance] = E.evaluate(nail.velocity, env)
            family.target_acceleration[nail.instance] = E.evaluate(nail.acceleration, env)
        for family, offset in families:
            write_rows(family, frame, block, offset)
        return block

    def _active_rows(self, epoch: Epoch) -> ActiveRows:
        entry = self._active.get(id(epoch))
        if entry is None or entry[0] is not epoch:
            entry = self._active[id(epoch)] = (epoch, ActiveRows(self.plan.constraints, epoch, self.plan.n))
        return entry[1]

    def _constrain(self, frame: BodyFrame, epoch: Epoch, a, alpha) -> None:
        plan, s, n = self.plan, self.scratch, self.plan.n
        prepare_epoch(plan.constraints, epoch, plan.dynamic)
        act = self._active_rows(epoch)
        block = self._write_rows(frame, act.families)
        rows = act.rows
        J = block.J[rows]
        m = len(J)
        s.motion_pad[1, :n, :3], s.motion_pad[1, :n, 3:] = a, alpha
        # J v and J a_free for every row: both slots of J (12 entries) dotted with the (v, w) and (a, alpha)
        # of their bodies, gathered per slot
        motion = s.motion_pad.take(act.slots, axis=1).reshape(2, m, 12)
        Jv, Ja = np.einsum("rk,urk->ur", J.reshape(m, 12), motion)
        # rhs = -(Jdot v + C_tt) - J a_free - kd (J v + ct) - ks C   (velocity-only rows have C = 0)
        rhs = -block.bias[rows] - Ja - act.kd * (Jv + block.ct[rows]) - act.ks * block.C[rows]
        lam = self._solve(epoch, J, rhs)
        # Fc = J^T lambda per body (world slots land in the padded row n), then a += M^-1 Fc
        Fc = np.bincount(act.scatter, weights=(J * lam[:, None, None]).reshape(-1), minlength=6 * (n + 1))
        Fc = Fc.reshape(n + 1, 6)[:n]
        a += plan.inv_mass[:, None] * Fc[:, :3]
        alpha += np.matmul(s.inv_inertia_world, Fc[:, 3:, None])[:, :, 0]

    def _solve(self, epoch: Epoch, J, rhs) -> np.ndarray:
        plan, s = self.plan, self.scratch
        if epoch.solver == "sparse":
            lam, info = linsolve.solve_sparse(epoch.pattern, J, plan.inv_mass, s.inv_inertia_world, rhs)
        else:  # dense or tree: the pattern solves
            lam, info = epoch.pattern.solve(J, plan.inv_mass, s.inv_inertia_world, rhs)
        s.last_solve = info
        s.rank_deficient_seen |= bool(getattr(info, "rank_deficient", False))
        return lam
