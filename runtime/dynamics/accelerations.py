"""The dynamics plan's right-hand side, compiled: accelerations of every body with Lagrange multipliers
(docs/design/physics.md section 2).

    M a = F + J^T lambda,   (J M^-1 J^T) lambda = -bias - J M^-1 F - [kd (J v + ct) + ks C]

F includes the friction of sliding contacts, which depends on their lambda_n (core/contact.py).

The bracket (Baumgarte's stabilization) acts only on rows that are still assembling (a constraint that switched on
with its points apart, pulling them together along C'' + kd C' + ks C = 0 at the constraint's own frequency and
damping ratio). Rows on their manifold ("held") are kept there by the projection after each step
(projection.py), which leaves the integrator's order intact: RK4 stays fourth order.

`accelerations(model, active, scratch, y, table, j, acc)`: the state y (n+1,13) at grid row j of the time table;
acc (n+1,6) <- (a, alpha) per body.
"""
from __future__ import annotations

from ..core import model as M
from ..core.bodies import place_kinematic, rotations, world_inverse_inertia
from ..core.data import (COUNTER_BACKOFF, COUNTER_KEPT, COUNTER_KEPT_DROPPED, COUNTER_RANK, COUNTER_REUSED,
                         COUNTER_TURNED_BACK, COUNTER_WAIT)
from ..core.contact import FRICTION_ITERATIONS, FRICTION_TOL, sliding_forces
from ..core.forces import add_gyroscopic, add_loads, add_springs, weights
from ..core.jit import entry, inlined, kernel
from ..core.rows import evaluate_rows, row_motion
from ..core.timetable import TIME
from ..core.solve import apply_impulses, assemble, factor, inverse_mass_times_J, solve_again, substitute
from ..wind.kernels import wind_drag


@inlined
def body_forces(m, s, y, table, j):
    """force, torque (n+1,3) <- every force stage of the model at grid row j (R and inverse inertias current)."""
    weights(m.bodies, s.force, s.torque)
    add_springs(m.springs, y, s.R, s.force, s.torque)
    add_loads(m.loads, table, j, s.R, s.force, s.torque)
    if len(m.wind.body):
        speeds = table[j, m.wind_column:m.wind_column + m.wind_count]
        wind_drag(m.wind, y, s.R, speeds, table[j, TIME], s.force, s.torque, s.air)
    add_gyroscopic(m.bodies, y, s.R, s.torque)


@inlined
def unconstrained(m, s, table, j, acc):
    """acc <- F / m and I^-1 tau for dynamic bodies, the path's accelerations for kinematic ones, 0 otherwise."""
    bodies = m.bodies
    for b in range(len(bodies.inv_mass)):
        if bodies.dynamic[b]:
            im, I = bodies.inv_mass[b], s.inv_inertia
            for c in range(3):
                acc[b, c] = im * s.force[b, c]
                acc[b, 3 + c] = I[b, c, 0] * s.torque[b, 0] + I[b, c, 1] * s.torque[b, 1] + I[b, c, 2] * s.torque[b, 2]
        else:
            for c in range(6):
                acc[b, c] = 0.0
    kin = m.kinematic
    for i in range(len(kin.body)):
        if not kin.on[i]:
            continue
        b, c = kin.body[i], kin.column[i]
        for e in range(3):
            acc[b, e] = table[j, c + M.KIN_A + e]
            acc[b, 3 + e] = table[j, c + M.KIN_ALPHA + e]


@kernel
def _right_hand_side(m, act, s, y, acc):
    """rhs (m,) of the active rows for the accelerations acc (the free ones, with any friction):
    rhs = -bias - J acc  [- kd (J v + ct) - ks C while the row assembles]."""
    cons = m.constraints
    for i in range(len(act.rows)):
        r = act.rows[i]
        rhs = -s.bias[r] - row_motion(cons, r, y, acc, s.J, 0)
        if not act.held[i]:
            rhs -= cons.kd[r] * (row_motion(cons, r, y, y, s.J, 7) + s.ct[r]) + cons.ks[r] * s.C[r]
        s.rhs[i] = rhs


@kernel
def _sliding(m, act, s):
    """Whether any active contact slides (its friction depends on lambda_n)."""
    cons = m.constraints
    for i in range(len(act.instances)):
        k = act.instances[i]
        if cons.family[k] == M.CONTACT and s.param[k, M.CONTACT_SLIDE_MU] > 0.0:
            return True
    return False


@kernel
def _add_friction(m, act, s, y, acc):
    """acc += M^-1 (the sliding contacts' friction for the current s.lam); whether any contact slides (its
    friction depends on lambda_n: the solve must be repeated, even where this lambda_n gave none). Without a
    sliding contact there is nothing to add (joints only, or contacts that stick)."""
    if not _sliding(m, act, s):
        return False
    turned_back = sliding_forces(act, m.constraints, s.param, y, s.R, s.lam, act.local, s.friction)
    if turned_back >= 0 and s.counters[COUNTER_TURNED_BACK] == 0:
        s.counters[COUNTER_TURNED_BACK] = turned_back + 1
    _friction_accelerations(m, s, y, acc, 1.0)
    return True


@kernel
def _friction_accelerations(m, s, y, acc, sign):
    """acc += sign M^-1 s.friction for the dynamic bodies (sign -1: _add_friction undone)."""
    bodies = m.bodies
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        im, I = bodies.inv_mass[b], s.inv_inertia
        for c in range(3):
            acc[b, c] += sign * (im * s.friction[b, c])
            acc[b, 3 + c] += sign * (I[b, c, 0] * s.friction[b, 3] + I[b, c, 1] * s.friction[b, 4]
                                     + I[b, c, 2] * s.friction[b, 5])


# after a kept factorization failed to serve (core/solve.py solve_again), evaluations factor afresh for this many
# before it is tried again; the wait doubles with every failure in a row (a moving chain: a try in 256), up to
KEPT_WAIT_FIRST, KEPT_WAIT_MOST = 4, 256


@inlined
def _factor_afresh(m, act, s):
    """Lx <- the factor of the active rows' whole J M^-1 J^T at the evaluated rows, kept for the evaluations after."""
    cons = m.constraints
    assemble(act, s.J, s.MJ, s.include, True, cons.soft, s.Lx, s.diag)
    dropped = factor(act, s.Lx, s.diag, s.work, s.dropped)
    s.counters[COUNTER_KEPT], s.counters[COUNTER_KEPT_DROPPED] = 1, dropped
    if dropped:
        s.counters[COUNTER_RANK] += 1


@inlined
def _may_keep(act, s):
    """Whether the factor in Lx may be tried for this evaluation (there is one, trying it can cost less than a
    fresh one, and no failure is being waited out)."""
    if s.counters[COUNTER_KEPT] == 0 or act.refine[0] < 0:
        return False
    if s.counters[COUNTER_WAIT] > 0:
        s.counters[COUNTER_WAIT] -= 1
        return False
    return True


@inlined
def _solve(m, act, s, kept):
    """s.lam <- A^-1 s.rhs: by the kept factor while it serves (its failure: factored afresh, and the wait before
    the next try doubled); returns whether the factor in Lx is still the kept one (not refactored)."""
    cons = m.constraints
    if kept:
        if solve_again(act, cons, s.J, s.MJ, cons.soft, s.Lx, s.dropped, s.rhs, s.lam, s.target, s.correction,
                       s.delta):
            s.counters[COUNTER_BACKOFF] = 0
            s.counters[COUNTER_REUSED] += 1
            return True
        wait = min(KEPT_WAIT_MOST, max(KEPT_WAIT_FIRST, 2 * s.counters[COUNTER_BACKOFF]))
        s.counters[COUNTER_BACKOFF], s.counters[COUNTER_WAIT] = wait, wait
        _factor_afresh(m, act, s)
        for i in range(len(act.rows)):
            s.rhs[i] = s.target[i]  # (solve_again kept the right-hand side there)
    substitute(act, s.Lx, s.dropped, s.rhs, s.lam)
    return False


@inlined
def constrain(m, act, s, y, table, j, acc):
    """acc += M^-1 (J^T lambda + sliding friction), lambda from the multiplier equation (module docstring); with
    sliding contacts the solve is repeated with the friction of the last lambda_n until lambda no longer changes
    (core/contact.py; the factorization stays). The factorization of an earlier evaluation is kept while it
    serves this one's J M^-1 J^T (core/solve.py solve_again: bodies at rest on each other)."""
    cons = m.constraints
    evaluate_rows(m, act, s, y, table, j)
    inverse_mass_times_J(act, cons, m.bodies, s.inv_inertia, s.J, s.MJ)
    kept = _may_keep(act, s)
    if kept and s.counters[COUNTER_KEPT_DROPPED]:
        s.counters[COUNTER_RANK] += 1  # (the kept factor dropped dependent rows: so does this solve)
    if not kept:
        _factor_afresh(m, act, s)
    for iteration in range(FRICTION_ITERATIONS):
        friction = _add_friction(m, act, s, y, acc)
        _right_hand_side(m, act, s, y, acc)
        for i in range(len(act.rows)):
            s.dlam[i] = s.lam[i]
        kept = _solve(m, act, s, kept)
        if not friction:
            break
        change, size = 0.0, 0.0
        for i in range(len(act.rows)):
            change = max(change, abs(s.lam[i] - s.dlam[i]))
            size = max(size, abs(s.lam[i]))
        if change <= FRICTION_TOL * size or iteration == FRICTION_ITERATIONS - 1:
            break
        _friction_accelerations(m, s, y, acc, -1.0)
    apply_impulses(act, cons, s.MJ, s.lam, 1.0, acc)


@inlined
def accelerations(m, act, s, y, table, j, acc):
    """acc (n+1,6) <- (a, alpha) of every body at state y, grid row j (module docstring)."""
    place_kinematic(m.kinematic, table, j, y)
    rotations(y, s.R)
    world_inverse_inertia(m.bodies, s.R, s.inv_inertia)
    body_forces(m, s, y, table, j)
    unconstrained(m, s, table, j, acc)
    if len(act.rows):
        constrain(m, act, s, y, table, j, acc)


@entry
def evaluate_accelerations(m, act, s, y, table, acc):
    """acc (n+1,6) <- (a, alpha) at state y and time table row 0 (for tests and for callers that need the
    accelerations of one state, not a run)."""
    s.counters[COUNTER_KEPT] = 0  # (a factor in Lx may be of another state's rows)
    accelerations(m, act, s, y, table, 0, acc)
