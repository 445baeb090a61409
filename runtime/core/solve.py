"""The multiplier system, compiled: assemble A = J M^-1 J^T, factor A = L L^T, solve (docs/design/physics.md section 2).

The pattern of L and the couplings come from structure.py (once per epoch); here only arithmetic, in the
order of the Active rows:

    MJ_r,s  = M_b^-1 J_r,s^T = (J_lin / m_b, I_b^-1 J_ang)    (b the body of slot s of row r; 0 without mass)
    A_ij    = sum over the slots of i and j on one dynamic body of J_i,si . MJ_j,sj
    L       left-looking sparse Cholesky: column j = (A_:j - sum_k L_:k L_jk) / sqrt(pivot), its diagonal entry
            stored as 1 / sqrt(pivot) (the substitutions multiply by it: a division on their chain of dependent
            rows cost a third of their time)

Redundant rows (two constraints that say the same thing, a closed loop) make A singular. A pivot that falls
below RANK_RTOL of its row's diagonal marks the row dependent on the rows before it: its column of L is dropped
and its multiplier is 0, so the other rows are solved exactly (for consistent constraints the result satisfies
every row; the multipliers are one of the many that do). `factor` returns how many rows it dropped.

A row left out of a solve (`include` False: a row still assembling, in the projection) gets an identity row:
multiplier 0, no coupling.

A factorization is kept for the evaluations after it (`solve_again`): where J M^-1 J^T has barely changed since
(bodies at rest on each other, slow motion), the old factor L_0 solves the new A by iterative refinement,

    x_0 = A_0^-1 b,   r_k = b - A x_k  (matrix-free: J (M^-1 J^T x_k)),   x_k+1 = x_k + A_0^-1 r_k

converging by the factor |I - A_0^-1 A| per step; it is used when |r| falls below REFINE_RTOL |b| within the
corrections that cost less than factoring afresh (structure.py affordable_corrections, at most REFINE_STEPS; a
small system, a pendulum's, never keeps one), else the caller factors afresh. A matrix-free product and a
substitution cost a fraction of an assembly and a factorization (a tower of ten boxes, 120 rows: 2 and 4 us
against 35 us).
"""
from __future__ import annotations

import math

from .bodies import turn
from .jit import kernel
from .rows import row_motion
from .vec import quat_to_matrix

# a pivot below this fraction of its diagonal marks a row dependent on the ones before it
RANK_RTOL = 1e-10
# a kept factorization serves a new A when refinement brings max |b - A x| below this fraction of max |b|, within
# this many corrections; a first residual above REFINE_GIVE_UP of it says A moved too far: factor afresh at once
REFINE_RTOL = 1e-13
REFINE_STEPS = 2
REFINE_GIVE_UP = 1e-4


@kernel
def inverse_mass_times_J(act, cons, bodies, inv_inertia, J, MJ):
    """MJ (M,2,6) <- M^-1 J^T per slot of the active rows: (J_lin / m, I^-1 J_ang), 0 for bodies without mass;
    inv_inertia (n+1,3,3) the world inverse inertias."""
    for i in range(len(act.rows)):
        r = act.rows[i]
        k = cons.row_instance[r]
        for s in range(2):
            b = cons.body[k, s]
            im = bodies.inv_mass[b]  # (the world row, b = -1, has none)
            if im == 0.0:
                for c in range(6):
                    MJ[r, s, c] = 0.0
                continue
            # (the block read before MJ is written: the compiler cannot know that the two arrays never overlap)
            lx, ly, lz, ax, ay, az = J[r, s, 0], J[r, s, 1], J[r, s, 2], J[r, s, 3], J[r, s, 4], J[r, s, 5]
            I = inv_inertia
            MJ[r, s, 0], MJ[r, s, 1], MJ[r, s, 2] = im * lx, im * ly, im * lz
            MJ[r, s, 3] = I[b, 0, 0] * ax + I[b, 0, 1] * ay + I[b, 0, 2] * az
            MJ[r, s, 4] = I[b, 1, 0] * ax + I[b, 1, 1] * ay + I[b, 1, 2] * az
            MJ[r, s, 5] = I[b, 2, 0] * ax + I[b, 2, 1] * ay + I[b, 2, 2] * az


@kernel
def assemble(act, J, MJ, include, everything, soft, Lx, diagonal):
    """Lx <- the lower triangle of A = J M^-1 J^T in L's pattern (fill entries 0), each diagonal entry times
    (1 + soft) (soft (M,) per global row), diagonal (m,) <- that diagonal; rows not included (unless `everything`)
    get an identity row and column."""
    for p in range(len(Lx)):
        Lx[p] = 0.0
    for c in range(len(act.cp_dest)):
        if not everything and not (include[act.cp_i[c]] and include[act.cp_j[c]]):
            continue
        ri, rj, si, sj = act.cp_ri[c], act.cp_rj[c], act.cp_si[c], act.cp_sj[c]
        # A_ij += J_i,si . (M^-1 J^T)_j,sj
        Lx[act.cp_dest[c]] += (J[ri, si, 0] * MJ[rj, sj, 0] + J[ri, si, 1] * MJ[rj, sj, 1]
                               + J[ri, si, 2] * MJ[rj, sj, 2] + J[ri, si, 3] * MJ[rj, sj, 3]
                               + J[ri, si, 4] * MJ[rj, sj, 4] + J[ri, si, 5] * MJ[rj, sj, 5])
    for j in range(len(act.rows)):
        if not everything and not include[j]:
            Lx[act.Lp[j]] = 1.0
        else:
            Lx[act.Lp[j]] *= 1.0 + soft[act.rows[j]]
        diagonal[j] = Lx[act.Lp[j]]


@kernel
def factor(act, Lx, diagonal, work, dropped):
    """L L^T = A in place (Lx holds A's lower triangle on entry, L on return, each diagonal entry L_jj kept as
    1 / L_jj), left-looking, column by column;
    dropped (m,) <- rows found dependent (module docstring); returns their number. diagonal (m,): A's, from
    `assemble`; work (m,) must be zero on entry and is left zero."""
    count = 0
    for j in range(len(act.rows)):
        start, end = act.Lp[j], act.Lp[j + 1]
        for p in range(start + 1, end):
            work[act.Li[p]] = Lx[p]
        pivot = Lx[start]
        # column j of A minus the columns k < j that reach row j: A_:j - sum_k L_jk L_:k (rows >= j)
        for e in range(act.Rp[j], act.Rp[j + 1]):
            k, at = act.Rk[e], act.Rpos[e]
            l_jk = Lx[at]
            if l_jk != 0.0:
                pivot -= l_jk * l_jk
                for p in range(at + 1, act.Lp[k + 1]):
                    work[act.Li[p]] -= Lx[p] * l_jk
        if pivot > RANK_RTOL * diagonal[j] and diagonal[j] > 0.0:
            # (L_jj's reciprocal, and the column below it scaled by it as the work array is cleared)
            dropped[j] = False
            inverse = 1.0 / math.sqrt(pivot)
            Lx[start] = inverse
            for p in range(start + 1, end):
                Lx[p] = work[act.Li[p]] * inverse
                work[act.Li[p]] = 0.0
        else:
            dropped[j] = True
            count += 1
            Lx[start] = 1.0
            for p in range(start + 1, end):
                Lx[p] = 0.0
                work[act.Li[p]] = 0.0
    return count


@kernel
def substitute(act, Lx, dropped, b, x):
    """x (m,) <- A^-1 b (m,) with A = L L^T from `factor` (dropped rows: x = 0). b is overwritten."""
    m = len(act.rows)
    # forward: L z = b, column by column
    for j in range(m):
        if dropped[j]:
            b[j] = 0.0
            continue
        z = b[j] * Lx[act.Lp[j]]
        b[j] = z
        for p in range(act.Lp[j] + 1, act.Lp[j + 1]):
            b[act.Li[p]] -= Lx[p] * z
    # backward: L^T x = z
    for j in range(m - 1, -1, -1):
        if dropped[j]:
            x[j] = 0.0
            continue
        total = b[j]
        for p in range(act.Lp[j] + 1, act.Lp[j + 1]):
            total -= Lx[p] * x[act.Li[p]]
        x[j] = total * Lx[act.Lp[j]]


@kernel
def apply_impulses(act, cons, MJ, lam, scale, out):
    """out (n+1,6) += scale M^-1 J^T lam: each active row's multiplier pushes the bodies of its slots."""
    for i in range(len(act.rows)):
        l = lam[i] * scale
        if l == 0.0:
            continue
        r = act.rows[i]
        k = cons.row_instance[r]
        for s in range(2):
            b = cons.body[k, s]
            if b < 0:
                continue
            for c in range(6):
                out[b, c] += MJ[r, s, c] * l


@kernel
def move_along(act, cons, bodies, MJ, lam, delta, y, R):
    """y moved by dx = M^-1 J^T lam (a position projection's step): x += dx_lin, q turned by dx_ang, R (n+1,3,3)
    kept current; delta (n+1,6) scratch."""
    for b in range(len(y)):
        for c in range(6):
            delta[b, c] = 0.0
    apply_impulses(act, cons, MJ, lam, 1.0, delta)
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        for c in range(3):
            y[b, c] += delta[b, c]
        turn(y, b, delta[b, 3], delta[b, 4], delta[b, 5])
        quat_to_matrix(y[b, 3], y[b, 4], y[b, 5], y[b, 6], R, b)


@kernel
def multiply(act, cons, J, MJ, soft, x, delta, out):
    """out (m,) <- A x, A = J M^-1 J^T with each diagonal entry times (1 + soft) as `assemble` makes it, without
    forming A: delta (n+1,6) <- M^-1 J^T x, then out_i = J_i . delta + soft_i A_ii x_i."""
    for b in range(len(delta)):
        for c in range(6):
            delta[b, c] = 0.0
    apply_impulses(act, cons, MJ, x, 1.0, delta)
    for i in range(len(act.rows)):
        r = act.rows[i]
        k = cons.row_instance[r]
        total = row_motion(cons, r, delta, delta, J, 0)
        if soft[r] != 0.0:
            own = 0.0  # A_ii: the products of the row's slots on one body
            for s in range(2):
                for t in range(2):
                    if cons.body[k, s] >= 0 and cons.body[k, s] == cons.body[k, t]:
                        for c in range(6):
                            own += J[r, s, c] * MJ[r, t, c]
            total += soft[r] * own * x[i]
        out[i] = total


@kernel
def solve_again(act, cons, J, MJ, soft, Lx, dropped, b, x, target, correction, delta):
    """x (m,) <- A^-1 b for the current A (J, MJ) from the factor Lx of an earlier A, by iterative refinement
    (module docstring) of at most act.refine corrections (what costs less than factoring afresh: structure.py);
    whether it converged (if not, x is not the solution: factor afresh). b is overwritten;
    target, correction (m,) and delta (n+1,6) are scratch. Rows the factor dropped keep x = 0."""
    m = len(act.rows)
    scale = 0.0
    for i in range(m):
        target[i] = b[i]
        scale = max(scale, abs(b[i]))
    substitute(act, Lx, dropped, b, x)
    steps = act.refine[0]
    for step in range(steps + 1):
        multiply(act, cons, J, MJ, soft, x, delta, correction)
        worst = 0.0
        for i in range(m):
            correction[i] = target[i] - correction[i]  # r = b - A x
            worst = max(worst, abs(correction[i]))
        if worst <= REFINE_RTOL * scale:
            return True
        if step == steps or (step == 0 and not worst <= REFINE_GIVE_UP * scale):
            return False
        # x += A_0^-1 r  (substitute may solve in place: it reads each b_j before it writes x_j)
        substitute(act, Lx, dropped, correction, correction)
        for i in range(m):
            x[i] += correction[i]
    return False
