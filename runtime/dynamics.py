"""Constraint-force stage: accelerations of all bodies with Lagrange multipliers (PHYSICS.md section 2).

    (J M^-1 J^T) lambda = -Jdot v - J M^-1 F - kd (J v + ct) - ks C          (Baumgarte-stabilized)
    a = M^-1 (F + J^T lambda)

`Dynamics.accelerations` is the right-hand side the integrators call; all its buffers live in `DynamicsScratch`.
It runs four times per RK4 step on arrays of a few rows, so it is written for few numpy calls: the state is
copied once into world-padded buffers (an extra last row that index WORLD = -1 reads as the fixed world), the
accelerations are summed in a padded buffer and copied out once, the rows' structure is written once (the
kernels then write only what changes), and everything that depends only on the active row set is found once per
epoch (`ActiveRows`). With a dense solve and few bodies the stage works in body space (`BodySpace`): J as one
(m, 6 nb) matrix, every product one BLAS call; beyond, by slot pairs (per-slot gathers, `DensePattern`, sparse
or tree solvers).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import as_strided

from isaac_lang import expr as E

from . import linsolve
from .constraint_plan import ConstraintPlan, Epoch, prepare_epoch
from .constraints.layout import WORLD, BodyFrame, RowBlock
from .constraints.rows import FamilyRows, WorldPaddedFrame, kernel_for, position_kernel_for
from .forces import apply_forces
from .kinematics import evaluate_paths
from .rotation import quat_to_matrix_rows, world_inverse_inertia

# Up to this many bodies touched by the active rows (and a dense solve), the constraint stage works in body space
# (BodySpace): J M^-1 J^T there costs O(m^2 nb) flops in a few BLAS calls, against the slot pairs' O(m^2) in many
# small numpy calls. Measured on chains (3 rows per body, RK4 step): body space 0.40 / 0.46 / 0.58 ms at 5 / 10 /
# 15 links against 0.51 / 0.56 / 0.65 ms, but 1.6 ms against 0.76 ms at 20 links.
BODY_SPACE_MAX_BODIES = 12


@dataclass
class DynamicsScratch:
    """Buffers of one evaluation. The padded arrays have n+1 rows, the last one the world's (zero position,
    velocity and acceleration, identity rotation): row kernels and the constraint stage index both slots of a
    row with it, no masks. R is a view of the body rows; so are x_bodies, q_bodies, v_bodies, w_bodies,
    a_bodies, alpha_bodies (n,3 or 4) and R_rows (n,9), made once."""

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

    def __post_init__(self):
        n = len(self.R)
        # (n,3) and (n,4) views of the body rows of the padded arrays, where each evaluation copies its state
        self.x_bodies, self.q_bodies = self.x_pad[:n], self.q_pad[:n]
        self.v_bodies, self.w_bodies = self.motion_pad[0, :n, :3], self.motion_pad[0, :n, 3:]
        self.a_bodies, self.alpha_bodies = self.motion_pad[1, :n, :3], self.motion_pad[1, :n, 3:]
        self.R_rows = self.R_pad[:n].reshape(n, 9)  # (n,9) view of R: each matrix as one row

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

    rows: a slice or index array into the RowBlock; families: (kernel, family, FamilyRows) of the families with
    an active row; row_bodies (m,2) with WORLD = -1; slots (2m,) the same flattened, WORLD -> n (the padded world
    row); ks, kd (m,) Baumgarte gains; scatter (12m,) flat index 6 body + k of every J entry into an (n+1, 6)
    array; body_space: the rows in body space (BodySpace) when they touch few bodies and the solve is dense;
    terms (5,m) the terms of the right-hand side per row, (C, ct, bias, J v, J a_free), and coefficients (5,m)
    their weights in it (-ks, -kd, -1, -kd, -1).
    """

    def __init__(self, c: ConstraintPlan, epoch: Epoch, n: int, inv_mass: np.ndarray, kernels: list):
        active = epoch.active
        self.rows = contiguous_slice(active)
        ends = list(c.family_offsets[1:]) + [c.total_rows]
        self.families = [(kernel, f, rows) for (kernel, f, rows), end in zip(kernels, ends)
                         if np.any((active >= rows.start) & (active < end))]
        self.row_bodies = c.row_bodies[active]
        self.ks, self.kd = c.row_ks[active], c.row_kd[active]
        body = np.where(self.row_bodies == WORLD, n, self.row_bodies)
        self.slots = body.reshape(-1)
        self.scatter = (6 * body[:, :, None] + np.arange(6)).reshape(-1)
        self.body_space = BodySpace.of(active, self.row_bodies, inv_mass) if epoch.solver == "dense" else None
        self.terms = np.zeros((5, len(active)))
        one = np.ones(len(active))
        self.coefficients = -np.array([self.ks, self.kd, one, self.kd, one])


def contiguous_slice(index: np.ndarray):
    """A slice equal to the sorted index array when its entries are consecutive, else the array itself (a slice
    indexes with views, no copies)."""
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index


class BodySpace:
    """The active rows' J as one dense matrix over the nb bodies they touch, for systems of a few bodies: then
    J v and J a, J M^-1 J^T and M^-1 J^T lambda are each one small matrix product, with no per-slot gathers.

    bodies: slice or (nb,) indices of the bodies the rows touch (not the world); source, target (6e,): flat
    index of every entry of a non-world slot in the RowBlock's J (M,2,6), and where it lands in J (m, 6 nb)
    (every other entry of J stays 0); inverse_mass (6 nb, 6 nb): M^-1 of the bodies, block diagonal with
    diag(m^-1 I3, I^-1) per body, the linear blocks fixed and the angular ones (`angular`, a (nb,3,3) view)
    refreshed per evaluation. All products are 2-D `ndarray.dot`s: one BLAS call each, no gufunc machinery.
    """

    def __init__(self, active: np.ndarray, row_bodies: np.ndarray, bodies: np.ndarray, inv_mass: np.ndarray):
        m, nb, k = len(row_bodies), len(bodies), np.arange(6)
        rows, slots = np.nonzero(row_bodies != WORLD)
        column = np.searchsorted(bodies, row_bodies[rows, slots])
        self.source = ((2 * active[rows] + slots)[:, None] * 6 + k).reshape(-1)
        self.target = ((nb * rows + column)[:, None] * 6 + k).reshape(-1)
        self.J = np.zeros((m, 6 * nb))
        self._J_flat = self.J.reshape(-1)
        self.inverse_mass = np.zeros((6 * nb, 6 * nb))
        blocks = self.inverse_mass.reshape(nb, 6, nb, 6)
        for i, body in enumerate(bodies):
            blocks[i, :3, i, :3] = inv_mass[body] * np.eye(3)
        # body i's angular block starts at row and column 6 i + 3: one stride of 6 rows and 6 columns per body
        row, column = self.inverse_mass.strides
        self.angular = as_strided(self.inverse_mass[3:, 3:], shape=(nb, 3, 3),
                                  strides=(6 * (row + column), row, column))
        self.bodies = contiguous_slice(bodies)

    @classmethod
    def of(cls, active, row_bodies, inv_mass) -> "BodySpace | None":
        """The body space of these rows; None beyond BODY_SPACE_MAX_BODIES bodies, or when a row names one body
        in both slots (its two blocks would share columns)."""
        bodies = np.unique(row_bodies[row_bodies != WORLD])
        if len(bodies) > BODY_SPACE_MAX_BODIES or np.any(row_bodies[:, 0] == row_bodies[:, 1]):
            return None
        return cls(active, row_bodies, bodies, inv_mass)

    def jacobian(self, block_J: np.ndarray) -> np.ndarray:
        """J (m, 6 nb) of the active rows, from the RowBlock's J (M,2,6)."""
        self._J_flat[self.target] = block_J.take(self.source)
        return self.J


class Dynamics:
    """The acceleration function of the dynamics plan: forces, then the constraint solve."""

    def __init__(self, plan):
        self.plan = plan
        self.n = plan.n
        c = plan.constraints
        self.scratch = DynamicsScratch.allocate(self.n, c.total_rows if c is not None else 0)
        # (kernel, family, rows) of every constraint family: its kernel and the views of its rows in the
        # scratch RowBlock, resolved once, with the rows' structure (bodies, velocity-only) written once
        self._kernels = [] if c is None else [(kernel_for(f), f, FamilyRows(f, self.scratch.rows, offset))
                                              for f, offset in zip(c.families, c.family_offsets)]
        for _, _, rows in self._kernels:
            rows.write_structure()
        self._position_kernels = [(position_kernel_for(f), f, rows) for _, f, rows in self._kernels]
        # every body's inertia the same about every axis (spheres, cubes; static and kinematic bodies: 0): the world
        # inverse inertia is the body's, whatever the rotation
        Ib = plan.inv_inertia_body
        self._isotropic = bool(np.array_equal(Ib, Ib[:, :1, :1] * np.eye(3)))
        if self._isotropic:
            self.scratch.inv_inertia_world[...] = Ib
        self._dynamic = contiguous_slice(np.flatnonzero(plan.dynamic))
        self._inv_mass = plan.inv_mass[:, None]  # (n,1)
        self._active: dict[int, tuple] = {}  # id(epoch) -> (epoch, ActiveRows)
        s, velocity = self.scratch, self.scratch.motion_pad[0]
        self._frame = WorldPaddedFrame(s.x_pad, s.q_pad, velocity[:, :3], velocity[:, 3:], s.R_pad, 0.0)

    def frame(self, x, q, v, w, t) -> BodyFrame:
        """The world-padded frame of state (x, q, v, w) at time t. It is one object whose arrays are this
        object's buffers: valid until the next call."""
        s, frame = self.scratch, self._frame
        s.x_bodies[...], s.q_bodies[...], s.v_bodies[...], s.w_bodies[...] = x, q, v, w
        quat_to_matrix_rows(q, s.R_rows)
        frame.t = t
        return frame

    def accelerations(self, t, x, q, v, w, a, alpha, epoch: Epoch | None) -> None:
        """a, alpha (n,3) <- linear and angular accelerations at state (x, q, v, w) and time t.

        They are found in the scratch's padded accelerations (a_bodies, alpha_bodies: kinematic paths, then the
        unconstrained accelerations, then the constraint stage's increments) and copied out once."""
        plan, s = self.plan, self.scratch
        if plan.kinematics is not None:
            evaluate_paths(plan.kinematics, t, x, q, v, w, s.a_bodies, s.alpha_bodies)
        frame = self.frame(x, q, v, w, t)
        if not self._isotropic:  # else I^-1 = R (c 1) R^T = c 1: the body's, copied once
            world_inverse_inertia(s.R, plan.inv_inertia_body, out=s.inv_inertia_world)
        if plan.forces.gyroscopic is not None:
            world_inverse_inertia(s.R, plan.inertia_body, out=s.inertia_world)
        apply_forces(plan.forces, x, v, w, s.R, t, s.inertia_world, s.force, s.torque)
        self._unconstrained()
        if epoch is not None and epoch.active.size:
            self._constrain(frame, epoch)
        a[...], alpha[...] = s.a_bodies, s.alpha_bodies

    def _unconstrained(self) -> None:
        """a = F / m, alpha = I^-1 tau for dynamic bodies (kinematic bodies keep their path's accelerations,
        static ones 0)."""
        s, d = self.scratch, self._dynamic
        if isinstance(d, slice):  # a run of bodies (often all of them): written in place through views
            np.multiply(self._inv_mass[d], s.force[d], out=s.a_bodies[d])
            np.matmul(s.inv_inertia_world[d], s.torque[d, :, None], out=s.alpha_bodies[d, :, None])
            return
        s.a_bodies[d] = self._inv_mass[d] * s.force[d]
        s.alpha_bodies[d] = np.matmul(s.inv_inertia_world[d], s.torque[d, :, None])[:, :, 0]

    def rows_at(self, frame: BodyFrame) -> RowBlock:
        """Evaluate every row of every family at this frame (moving nails first move to time frame.t)."""
        return self._write_rows(frame, self._kernels)

    def positions_at(self, frame: BodyFrame) -> RowBlock:
        """The rows' block with C evaluated at this frame (for the constraint error): J, ct and bias may be left
        from an earlier evaluation."""
        return self._write_rows(frame, self._position_kernels)

    def _write_rows(self, frame: BodyFrame, families) -> RowBlock:
        c = self.plan.constraints
        for nail in c.moving_nails:
            family = c.families[nail.family]
            env = {"t": frame.t}
            family.target[nail.instance] = E.evaluate(nail.position, env)
            family.target_velocity[nail.instance] = E.evaluate(nail.velocity, env)
            family.target_acceleration[nail.instance] = E.evaluate(nail.acceleration, env)
        for kernel, family, rows in families:
            kernel(family, frame, rows)
        return self.scratch.rows

    def _active_rows(self, epoch: Epoch) -> ActiveRows:
        entry = self._active.get(id(epoch))
        if entry is None or entry[0] is not epoch:
            rows = ActiveRows(self.plan.constraints, epoch, self.n, self.plan.inv_mass, self._kernels)
            entry = self._active[id(epoch)] = (epoch, rows)
        return entry[1]

    def _constrain(self, frame: BodyFrame, epoch: Epoch) -> None:
        """The padded accelerations (n+1, 6) += M^-1 J^T lambda, lambda from the multiplier equation."""
        plan = self.plan
        prepare_epoch(plan.constraints, epoch, plan.dynamic)
        act = self._active_rows(epoch)
        block = self._write_rows(frame, act.families)
        if act.body_space is not None:
            self._constrain_in_body_space(act, block)
        else:
            self._constrain_by_slots(epoch, act, block)

    def _constrain_in_body_space(self, act: ActiveRows, block: RowBlock) -> None:
        s, space = self.scratch, act.body_space
        J = space.jacobian(block.J)
        # J v and J a_free at once, from the (v, w) and (a, alpha) rows of the bodies
        s.motion_pad[:, space.bodies].reshape(2, -1).dot(J.T, out=act.terms[3:])
        rhs = _right_hand_side(act, block)
        # M^-1 J^T (6 nb, m), with the bodies' world inverse inertias in M^-1
        space.angular[...] = s.inv_inertia_world[space.bodies]
        MJt = space.inverse_mass.dot(J.T)
        # (J M^-1 J^T) lambda = rhs
        lam = self._record(linsolve.solve_dense(J.dot(MJt), rhs))
        # (a, alpha) += M^-1 J^T lambda
        s.motion_pad[1, space.bodies] += MJt.dot(lam).reshape(-1, 6)

    def _constrain_by_slots(self, epoch: Epoch, act: ActiveRows, block: RowBlock) -> None:
        plan, s, n = self.plan, self.scratch, self.n
        J = block.J[act.rows]
        m = len(J)
        # J v and J a_free for every row: both slots of J (12 entries) dotted with the (v, w) and (a, alpha)
        # of their bodies, gathered per slot
        motion = s.motion_pad.take(act.slots, axis=1).reshape(2, m, 12)
        np.einsum("rk,urk->ur", J.reshape(m, 12), motion, out=act.terms[3:])
        rhs = _right_hand_side(act, block)
        lam = self._solve(epoch, J, rhs)
        # Fc = J^T lambda per body (world slots land in the padded row n), then a += M^-1 Fc
        Fc = np.bincount(act.scatter, weights=(J * lam[:, None, None]).reshape(-1), minlength=6 * (n + 1))
        Fc = Fc.reshape(n + 1, 6)[:n]
        s.a_bodies += self._inv_mass * Fc[:, :3]
        s.alpha_bodies += np.matmul(s.inv_inertia_world, Fc[:, 3:, None])[:, :, 0]

    def _solve(self, epoch: Epoch, J, rhs) -> np.ndarray:
        plan, s = self.plan, self.scratch
        if epoch.solver == "sparse":
            solved = linsolve.solve_sparse(epoch.pattern, J, plan.inv_mass, s.inv_inertia_world, rhs)
        else:  # dense or tree: the pattern solves
            solved = epoch.pattern.solve(J, plan.inv_mass, s.inv_inertia_world, rhs)
        return self._record(solved)

    def _record(self, solved: tuple) -> np.ndarray:
        """lambda of a (lambda, SolveInfo) pair, the info kept in the scratch."""
        lam, info = solved
        s = self.scratch
        s.last_solve = info
        if info.rank_deficient:
            s.rank_deficient_seen = True
        return lam


def _right_hand_side(act: ActiveRows, block: RowBlock) -> np.ndarray:
    """rhs (m,) of the active rows, with J v and J a_free already in act.terms[3:]."""
    if isinstance(act.rows, slice):
        act.terms[:3] = block.values[:, act.rows]
    else:
        np.take(block.values, act.rows, axis=1, out=act.terms[:3])
    # rhs = -(Jdot v + C_tt) - J a_free - kd (J v + ct) - ks C   (velocity-only rows have C = 0): the terms
    #   (C, ct, bias, J v, J a_free) times (-ks, -kd, -1, -kd, -1), summed over the terms by one vecdot
    return np.vecdot(act.coefficients, act.terms, axis=0)
