"""The constraint stage of the procedural plan done at once: every row of the epoch projected together.

Gauss-Seidel (constraints/projections.py, one colour after another) is what XPBD engines do, and it is cheap per
sweep, but along a chain of n links it removes a stretch by only ~1/n^2 of itself per sweep: a 10-link chain
whipping at 50 rad/s keeps its joints open by 1.4 mm at 20 substeps of 0.5 ms. The direct projection solves the
linearized projection of all rows as one system instead (the "direct position-based solver" of Deul, Kugelstadt,
Weiler, Bender 2018, and SHAKE's matrix form): with the rows' gradients J now, their correction directions Jd
(the gradients at the start of the substep, as in projections.py) and W = diag(1/m, I^-1) of the start of the
substep,

    (J W Jd^T + alpha~) dlam = -(C - target) - alpha~ lam          dx = W Jd^T dlam  (per body: 1/m l, I^-1 g)

which is one Newton step of the projection: what is left is second order in the correction. Each row touches at
most two bodies, so J W Jd^T is assembled from the pairs of row slots that share a body (the couplings, fixed
for the epoch): K[i, j] = sum over shared bodies of  l_i . ld_j / m + g_i . I^-1 gd_j.
Small systems are solved dense (LU), larger ones sparse (SuperLU); either way a tree of constraints costs about
linear time. A relative diagonal shift of REGULARIZATION keeps redundant rows (a closed loop, a repeated
orientation) finite: the extra multiplier lies in the null space and moves nothing.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg
from scipy.linalg.lapack import dgesv

from .constraints import projections as pj
from .constraints.layout import WORLD, PointToNail, PointToPoint

# above this many rows the system is solved sparse (dense LU costs ~R^3: 0.3 ms at 150 rows on a laptop)
DENSE_MAX_ROWS = 150
# the largest turn of a body in one projection, rad (a trust region: beyond, a linearized step is unreliable)
MAX_TURN = 0.2
# the 0/1 matrix that sums row entries into bodies is dense up to this many elements, sparse beyond
SPREAD_DENSE_MAX = 20000
# relative diagonal shift: keeps a singular (redundant) system finite, changes a regular one by ~1e-10
REGULARIZATION = 1e-10


class PointBlock:
    """Every point-to-point and point-to-nail instance as one block of 3 rows each (row 3 i + c is component c
    of instance i; nails have body b = WORLD and point b = 0, joints target 0).

    slots (2k,) body per slot, a over b; points (2k,3,1) body-frame points; minus_sign (2k,1) -1 for a, +1 for b;
    nails: [(family, first instance)] whose targets (P(t), refreshed by the caller) are copied in per call;
    l (2, 3k, 3) the linear gradient, constant: l_a = e_c, l_b = -e_c."""

    def __init__(self, families, offsets):
        a, b, pa, pb, rows, self.nails = [], [], [], [], [], []
        k = 0
        for fam, offset in zip(families, offsets):
            count = len(pj.instance_bodies(fam)[0])
            if isinstance(fam, PointToNail):
                a.append(fam.body), b.append(np.full(count, WORLD)), pa.append(fam.point)
                pb.append(np.zeros((count, 3)))
                self.nails.append((fam, k))
            else:
                a.append(fam.body_a), b.append(fam.body_b), pa.append(fam.point_a), pb.append(fam.point_b)
            rows.append(offset + np.arange(3 * count))
            k += count
        self.k = k
        self.slots = np.concatenate(a + b).astype(np.int64)
        self.points = np.concatenate(pa + pb)[:, :, None]
        self.minus_sign = np.repeat([-1.0, 1.0], k)[:, None]
        self.rows = np.concatenate(rows)  # global row of each block row
        self.target = np.zeros((k, 3))
        self.row_bodies = np.repeat(self.slots.reshape(2, k), 3, axis=1)  # (2, 3k) body of each row slot
        eye = np.tile(np.eye(3), (k, 1))
        self.l = np.stack((eye, -eye))

    def _gradient(self, R):
        """g (2, 3k, 3): row c of slot s is sign_s (r_s x e_c) = row c of [-sign_s r_s]x, r = R p."""
        r = (R @ self.points)[:, :, 0]
        return r, pj.skew(self.minus_sign * r).reshape(2, -1, 3)

    def directions(self, before: pj.Frame):
        """ld, gd (2, 3k, 3) at the start of the substep."""
        return self.l, self._gradient(before.R.take(self.slots, axis=0))[1]

    def current(self, now: pj.Frame):
        """C (3k,), l, g (2, 3k, 3) at the pose of `now`."""
        k = self.k
        for fam, first in self.nails:
            self.target[first:first + len(fam.body)] = fam.target
        r, g = self._gradient(now.R.take(self.slots, axis=0))
        P = now.x.take(self.slots, axis=0) + r
        return (P[:k] - P[k:] - self.target).reshape(-1), self.l, g


class FamilyBlock:
    """The instances idx of a 1-row family, with their row function (projections.ROW_FUNCTIONS)."""

    def __init__(self, fam, idx, rows, offset):
        self.fam, self.idx, self.rows_of = fam, idx, rows
        body_a, body_b = pj.instance_bodies(fam)
        self.slots = np.concatenate((body_a[idx], body_b[idx])).astype(np.int64)
        self.rows = offset + idx
        self.row_bodies = self.slots.reshape(2, len(idx))

    def directions(self, before: pj.Frame):
        _, ld, gd = self.rows_of(self.fam, self.idx, before.pose(self.slots), before)
        return ld.reshape(2, -1, 3), gd.reshape(2, -1, 3)

    def current(self, now: pj.Frame):
        C, l, g = self.rows_of(self.fam, self.idx, now.pose(self.slots), self.before)
        return C, l.reshape(2, -1, 3), g.reshape(2, -1, 3)


class DirectProjection:
    """The direct projection of a fixed set of families (one epoch). Rows are numbered globally as in
    ProceduralSolver (family after family, instance after instance, 3 per point instance); the system holds the
    live ones: kept (not subtracted) and movable by at least one body.

    Built once: blocks; rows (R,) global row of each system row; entry_body (2R,) body of each row slot
    (slot-major: entry s R + i) and entry_inv_mass (2R,); the couplings: pairs (first, second) of entries on one
    moving body and their position in K^T (flat, row-major); bodies: the moving bodies the rows touch (a slice
    when they are 0..b-1) and spread (b, 2R), the 0/1 matrix that sums entries into bodies; reach, the longest
    lever of a turn (for the error estimate)."""

    def __init__(self, families, offsets, keep, inv_mass):
        inv_mass = np.asarray(inv_mass, dtype=float)
        points = [(f, o) for f, o in zip(families, offsets) if isinstance(f, (PointToPoint, PointToNail))]
        self.blocks = [PointBlock(*zip(*points))] if points else []
        for fam, offset in zip(families, offsets):
            if not isinstance(fam, (PointToPoint, PointToNail)):
                self.blocks += [FamilyBlock(fam, idx, rows, offset) for idx, rows in pj.row_groups(fam)]
        all_rows = np.concatenate([b.rows for b in self.blocks]) if self.blocks else np.zeros(0, np.int64)
        bodies = np.concatenate([b.row_bodies for b in self.blocks], axis=1) if self.blocks else np.zeros((2, 0))
        kept = np.ones(len(all_rows), dtype=bool)
        for offset, kp in zip(offsets, keep):
            if kp is not None:
                mask = np.isin(all_rows, offset + np.arange(kp.size))
                kept[mask] = np.asarray(kp, dtype=bool).reshape(-1)[all_rows[mask] - offset]
        mobile_of = np.append(inv_mass > 0.0, False)  # index -1 (WORLD) -> False
        live = kept & mobile_of[bodies.astype(np.int64)].any(axis=0)
        self.select = None if live.all() else np.flatnonzero(live)
        self.rows = all_rows[live]
        R = self.size = len(self.rows)
        self.entry_body = bodies[:, live].reshape(-1).astype(np.int64)
        self.entry_inv_mass = np.append(inv_mass, 0.0)[self.entry_body][:, None]
        self._couplings(mobile_of)
        moving = np.unique(self.entry_body[mobile_of[self.entry_body]])
        spread = (moving[:, None] == self.entry_body[None, :]).astype(float)
        self.spread = spread if spread.size <= SPREAD_DENSE_MAX else sparse.csr_matrix(spread)
        self.bodies = slice(0, len(moving)) if np.array_equal(moving, np.arange(len(moving))) else moving
        self.dense = R <= DENSE_MAX_ROWS
        self.lam = np.zeros(R)
        self.diagonal = np.arange(R) * (R + 1)
        # the longest lever a turn acts through: body points of point rows; 1 m for angle rows (rad ~ m)
        arms = [np.linalg.norm(b.points[:, :, 0], axis=1).max(initial=0.0) for b in self.blocks
                if isinstance(b, PointBlock)]
        self.reach = max(arms + [1.0 if len(self.blocks) > len(arms) else 0.0])

    def _couplings(self, mobile_of) -> None:
        R, body = self.size, self.entry_body
        first, second = [], []
        for b in np.unique(body[mobile_of[body]]):
            on = np.flatnonzero(body == b)
            first.append(np.repeat(on, len(on)))
            second.append(np.tile(on, len(on)))
        self.first = np.concatenate(first) if first else np.zeros(0, np.int64)
        self.second = np.concatenate(second) if second else np.zeros(0, np.int64)
        # K[i, j] sits at K^T[j, i]: flat j R + i (K^T row-major is K column-major, what LAPACK takes)
        self.row_of, self.column_of = self.first % R if R else self.first, self.second % R if R else self.second
        self.flat = self.column_of * R + self.row_of
        self.on_diagonal = np.flatnonzero(self.row_of == self.column_of)

    # ------------------------------------------------------------ per substep

    def start(self, before: pj.Frame) -> None:
        """Once per substep: the correction directions W Jd^T of the start of the substep (when before says to
        use them), the entries' world inverse inertia; zero multipliers."""
        self.before = before
        self.lam.fill(0.0)
        if self.size == 0:
            return
        for b in self.blocks:
            b.before = before
        self.inv_I = before.inv_I.take(self.entry_body, axis=0)
        if before.use_directions:
            ld, gd = self._stack([b.directions(before) for b in self.blocks])
            self.moves_per_lam = np.concatenate((self.entry_inv_mass * ld, pj.matvec(self.inv_I, gd)), axis=1)

    def _stack(self, parts):
        """Concatenate per-block (2, r, 3) arrays along rows, keep the live rows, flatten to (2R, 3)."""
        out = []
        for i in range(len(parts[0])):
            a = parts[0][i] if len(parts) == 1 else np.concatenate([p[i] for p in parts], axis=1)
            if self.select is not None:
                a = a.take(self.select, axis=1)
            out.append(a.reshape(-1, 3))
        return out

    def project(self, x, q, now: pj.Frame, alpha, target) -> float:
        """One Newton step of the projection of every live row (x (n,3), q (n,4) in place). alpha (R,) the
        compliance over hs^2, target (R,) the value each row is projected to (None: 0). Returns an estimate of
        the largest error the step leaves, m (or rad)."""
        R = self.size
        if R == 0:
            return 0.0
        now.set_pose(x, q)
        parts = [b.current(now) for b in self.blocks]
        C = parts[0][0] if len(parts) == 1 else np.concatenate([p[0] for p in parts])
        if self.select is not None:
            C = C.take(self.select)
        l, g = self._stack([p[1:] for p in parts])
        if target is not None:
            C = C - target
        J = np.concatenate((l, g), axis=1)  # (2R, 6) gradient blocks now
        # W Jd^T: the correction of each entry per unit multiplier (the gradient now: a closest-point projection,
        # dissipative but stable at any step)
        Wd = self.moves_per_lam if self.before.use_directions else np.concatenate(
            (self.entry_inv_mass * l, pj.matvec(self.inv_I, g)), axis=1)
        # K = J W Jd^T: K[i, j] = sum over shared bodies of l_i . ld_j / m + g_i . I^-1 gd_j
        values = pj.dot(J.take(self.first, axis=0), Wd.take(self.second, axis=0))
        dlam = self._solve(values, alpha, -C - alpha * self.lam)
        # dx, dphi of each body: the sum over its entries of dlam W Jd^T
        moves = self.spread @ (np.concatenate((dlam, dlam))[:, None] * Wd)
        # a trust region: the rows are linear in translation, not in rotation, so a step that turns a body by
        # more than MAX_TURN is shortened to MAX_TURN (the rest is left to the next iteration or substep)
        turn = np.sqrt(pj.dot(moves[:, 3:], moves[:, 3:]).max())
        if turn > MAX_TURN:
            dlam, moves, turn = MAX_TURN / turn * dlam, MAX_TURN / turn * moves, MAX_TURN
        self.lam += dlam
        b = self.bodies
        x[b] += moves[:, :3]
        q[b] = pj.turn_by(q[b], moves[:, 3:])
        # what the step leaves: second order in the turn, times the longest arm
        return 0.5 * turn * turn * self.reach

    def _solve(self, values, alpha, rhs):
        """dlam of (K + alpha) dlam = rhs, K assembled from the coupling values (dense: as K^T in one array for
        LAPACK; sparse: the couplings as triplets, duplicates summed)."""
        R = self.size
        if self.dense:
            KT = np.bincount(self.flat, values, minlength=R * R)
            diag = KT[self.diagonal]
        else:
            diag = np.bincount(self.row_of[self.on_diagonal], values[self.on_diagonal], minlength=R)
        shift = diag * REGULARIZATION + alpha
        if not diag.all():  # a row no body can move at this pose (a degenerate gradient): left alone
            shift = np.where(diag == 0.0, 1.0, shift)
            rhs = np.where(diag == 0.0, 0.0, rhs)
        if self.dense:
            KT[self.diagonal] += shift
            dlam, info = dgesv(KT.reshape(R, R).T, rhs)[2:]
            return dlam if info == 0 else np.linalg.lstsq(KT.reshape(R, R).T, rhs, rcond=None)[0]
        every = np.arange(R)
        K = sparse.csc_matrix((np.concatenate((values, shift)), (np.concatenate((self.row_of, every)),
                                                                 np.concatenate((self.column_of, every)))),
                              shape=(R, R))
        return sparse_linalg.spsolve(K, rhs)
