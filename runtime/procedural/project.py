"""Stage 2 of a procedural substep, compiled: the active constraints projected back, one instance after another
(Gauss-Seidel), or all rows at once (`direct`: Newton iterations of the linearized projection with the sparse
Cholesky of the dynamics plan, Deul et al. 2018's direct position-based solver). substep.py states the method.

Self-assembly (docs/design/physics.md section 4). The dynamics plan lets a row that switches on apart close along
Baumgarte's curve C'' + kd C' + ks C = 0; a projection would close it in one substep, so a row still assembling
is projected to that very curve: target(s) = C(s) with C(0) = C0, C'(0) = D0 (at the switch), s the time since.
Once the curve's envelope is below exp(-CURVE_SPAN) of its start the row is held (target 0).

Sweep (a named tuple): first, last (g,) the ranges of Active rows of each instance, in sweep order (the gears
last, so that their ratio is what a substep ends with). Curves: on (m,) the time a row began to assemble,
C0, D0 (m,).
"""
from __future__ import annotations

import math
from collections import namedtuple

from ..core.bodies import rotations, turn, world_inverse_inertia
from ..core.data import COUNTER_KEPT
from ..core.jit import kernel
from ..core.rows import apply_drivers, instance_rows, row_motion, write_rows
from ..core.solve import apply_impulses, assemble, factor, inverse_mass_times_J, move_along, substitute
from ..core.vec import quat_to_matrix, rotate
from .substep import MIN_ALIGNMENT, effective_mass, solve_small, velocity_row_error

Sweep = namedtuple("Sweep", "first last")
Curves = namedtuple("Curves", "on C0 D0")
# how far out an assembly curve is followed: its envelope below exp(-CURVE_SPAN)
CURVE_SPAN = 40.0
# an instance's rows are projected again (a Newton iteration) while they are off by more than this (m or rad),
# at most BLOCK_ITERATIONS times per sweep
BLOCK_TOLERANCE = 1e-10
BLOCK_ITERATIONS = 4


@kernel
def curve(C0, D0, ks, kd, s):
    """C(s) of C'' + kd C' + ks C = 0 with C(0) = C0, C'(0) = D0 (critically, under- or over-damped), and whether
    it has died out (its envelope below exp(-CURVE_SPAN) of its start)."""
    a = 0.5 * kd
    disc = a * a - ks
    if abs(disc) <= 1e-9 * max(ks, 1e-300):
        # critically damped: (C0 + (D0 + a C0) s) exp(-a s)
        value = (C0 + (D0 + a * C0) * s) * math.exp(-a * s)
        slowest = a
    elif disc < 0.0:
        b = math.sqrt(-disc)
        value = math.exp(-a * s) * (C0 * math.cos(b * s) + (D0 + a * C0) * math.sin(b * s) / b)
        slowest = a
    else:
        b = math.sqrt(disc)
        r1, r2 = -a + b, -a - b
        A = (D0 - r2 * C0) / (r1 - r2)
        value = A * math.exp(r1 * s) + (C0 - A) * math.exp(r2 * s)
        slowest = -r1
    done = slowest > 0.0 and s * slowest > CURVE_SPAN
    return value, done


@kernel
def _target(cons, act, curves, i, r, t):
    """What row i (global row r) is projected to at time t: 0 when held, else its assembly curve."""
    if act.held[i]:
        return 0.0
    value, done = curve(curves.C0[i], curves.D0[i], cons.ks[r], cons.kd[r], t - curves.on[i])
    if done:
        act.held[i] = True
        return 0.0
    return value


@kernel
def _row_error(m, r, s, y, hs):
    """C of global row r at the current pose: its position error, or for a velocity row hs J v_new."""
    if m.constraints.velocity_only[r]:
        return velocity_row_error(m.constraints, m.bodies, r, y, s.ys, s.J, hs)
    return s.C[r]


@kernel
def _project_instance(m, act, curves, s, y, first, last, t, hs, shake, lam):
    """The rows first..last-1 of the Active rows (one instance) projected together (substep.py, stage 2), a few
    Newton iterations until they hold to BLOCK_TOLERANCE."""
    for iteration in range(BLOCK_ITERATIONS):
        left = _project_block_once(m, act, curves, s, y, first, last, t, hs, shake and iteration == 0, lam)
        if left <= BLOCK_TOLERANCE:
            break


@kernel
def _project_block_once(m, act, curves, s, y, first, last, t, hs, shake, lam):
    """One linearized projection of the instance's rows; returns the largest |C - target| it started from (0 when
    nothing can move)."""
    cons, bodies = m.constraints, m.bodies
    k = cons.row_instance[act.rows[first]]
    instance_rows(k, cons, s.param, y, s.R, s.C, s.J, s.ct, s.bias)
    n = last - first
    K, rhs, dlam, J, D = s.block.K, s.block.rhs, s.block.x, s.block.J, s.block.D
    for i in range(n):
        r = act.rows[first + i]
        for slot in range(2):
            for c in range(6):
                J[i, slot, c] = s.J[r, slot, c]
                D[i, slot, c] = s.Jd[r, slot, c]
    # SHAKE's direction where it agrees with the gradient now, else the gradient now
    use_start = shake
    for i in range(n):
        r = act.rows[first + i]
        now = effective_mass(cons, bodies, s.inv_inertia, r, J, i, J, i)
        start = effective_mass(cons, bodies, s.inv_inertia, r, J, i, D, i)
        if not start > MIN_ALIGNMENT * now:
            use_start = False
    if not use_start:
        for i in range(n):
            for slot in range(2):
                for c in range(6):
                    D[i, slot, c] = J[i, slot, c]
    any_mass = False
    largest = 0.0
    for i in range(n):
        r = act.rows[first + i]
        alpha = cons.compliance[r] / (hs * hs)
        for e in range(n):
            K[i, e] = effective_mass(cons, bodies, s.inv_inertia, r, J, i, D, e)
        if K[i, i] > 0.0:
            any_mass = True
        K[i, i] += alpha
        # rhs = -(C - target) - alpha~ lam
        error = _row_error(m, r, s, y, hs) - _target(cons, act, curves, first + i, r, t)
        largest = max(largest, abs(error))
        rhs[i] = -error - alpha * lam[first + i]
    if not any_mass:
        return 0.0
    solve_small(K, rhs, n, dlam)
    for i in range(n):
        lam[first + i] += dlam[i]
    # dx_b = W_b D_b^T dlam for each slot
    for slot in range(2):
        b = cons.body[k, slot]
        if b < 0 or not bodies.dynamic[b]:
            continue
        im, I = bodies.inv_mass[b], s.inv_inertia
        dx = s.block.dx
        for c in range(6):
            dx[c] = 0.0
        for i in range(n):
            for c in range(6):
                dx[c] += D[i, slot, c] * dlam[i]
        for c in range(3):
            y[b, c] += im * dx[c]
        p = rotate(I, b, (dx[3], dx[4], dx[5]))
        turn(y, b, p[0], p[1], p[2])
        quat_to_matrix(y[b, 3], y[b, 4], y[b, 5], y[b, 6], s.R, b)
    return largest


@kernel
def sweep(m, act, sw, curves, s, y, t, hs, shake, iterations):
    """Gauss-Seidel: `iterations` passes over the instances in sweep order; multipliers in s.lam."""
    for i in range(len(act.rows)):
        s.lam[i] = 0.0
    for _ in range(iterations):
        for g in range(len(sw.first)):
            _project_instance(m, act, curves, s, y, sw.first[g], sw.last[g], t, hs, shake, s.lam)


@kernel
def direct(m, act, curves, s, y, t, hs, iterations, shake):
    """All rows at once: (Jd W Jd^T + alpha~) dlam = -(C - target) - alpha~ lam, dx = W Jd^T dlam, with Jd the
    gradients of the start of the substep (SHAKE's matrix form; the gradients now when a body turns fast), W of
    the start of the substep: one factorization, then Newton iterations on C until it holds to BLOCK_TOLERANCE
    (at least `iterations`, at most `iterations` + BLOCK_ITERATIONS)."""
    cons = m.constraints
    if not shake:  # the gradients now serve as directions
        write_rows(act.instances, cons, s.param, y, s.R, s.C, s.Jd, s.ct, s.bias)
    inverse_mass_times_J(act, cons, m.bodies, s.inv_inertia, s.Jd, s.MJ)
    assemble(act, s.Jd, s.MJ, s.include, True, cons.soft, s.Lx, s.diag)
    for i in range(len(act.rows)):
        alpha = cons.compliance[act.rows[i]] / (hs * hs)
        s.Lx[act.Lp[i]] += alpha
        s.diag[i] += alpha
        s.lam[i] = 0.0
    s.counters[COUNTER_KEPT] = 0  # (Lx holds a shifted matrix: not one the dynamics evaluations may keep)
    if factor(act, s.Lx, s.diag, s.work, s.dropped):
        s.counters[0] += 1
    for iteration in range(iterations + BLOCK_ITERATIONS):
        write_rows(act.instances, cons, s.param, y, s.R, s.C, s.J, s.ct, s.bias)
        largest = 0.0
        for i in range(len(act.rows)):
            r = act.rows[i]
            alpha = cons.compliance[r] / (hs * hs)
            # rhs = -(C - target) - alpha~ lam
            error = _row_error(m, r, s, y, hs) - _target(cons, act, curves, i, r, t)
            largest = max(largest, abs(error))
            s.rhs[i] = -error - alpha * s.lam[i]
        if iteration >= iterations and largest <= BLOCK_TOLERANCE:
            break
        substitute(act, s.Lx, s.dropped, s.rhs, s.dlam)
        for i in range(len(act.rows)):
            s.lam[i] += s.dlam[i]
        move_along(act, m.constraints, m.bodies, s.MJ, s.dlam, s.delta, y, s.R)


@kernel
def keep_rows(m, act, s, y, hs):
    """After the sliding contacts' friction impulses dv (s.friction (n+1,6), already in y's velocities): the rows'
    answer to them, with the factor of this substep's `direct` projection: (Jd W Jd^T + alpha~) dlam = -hs Jd dv,
    v += W Jd^T dlam / hs, lam += dlam. So the impulses move nothing along the rows: a box sliding on its four
    corners is not left turning about them (its trailing corners rising at the step's end, where a look of the
    collision stage would see them part and drop them), the rows' multipliers carry the torque (its trailing
    corners press less: they lift once it tips) and a joint takes its share of a friction on its body."""
    cons = m.constraints
    n = len(act.rows)
    if n == 0:
        return
    for i in range(n):
        s.rhs[i] = -hs * row_motion(cons, act.rows[i], s.friction, s.friction, s.Jd, 0)
    substitute(act, s.Lx, s.dropped, s.rhs, s.dlam)
    for b in range(len(y)):
        for c in range(6):
            s.delta[b, c] = 0.0
    apply_impulses(act, cons, s.MJ, s.dlam, 1.0 / hs, s.delta)
    for b in range(len(y) - 1):
        if not m.bodies.dynamic[b]:
            continue
        for c in range(3):
            y[b, 7 + c] += s.delta[b, c]
            y[b, 10 + c] += s.delta[b, 3 + c]
    for i in range(n):
        s.lam[i] += s.dlam[i]


@kernel
def start_directions(m, act, s, y, table, j):
    """At the start of a substep: R, W (world inverse inertias) and the rows' gradients Jd of this pose."""
    rotations(y, s.R)
    world_inverse_inertia(m.bodies, s.R, s.inv_inertia)
    if len(act.rows):
        apply_drivers(m.constraints, s.param, table, j)
        write_rows(act.instances, m.constraints, s.param, y, s.R, s.C, s.Jd, s.ct, s.bias)
