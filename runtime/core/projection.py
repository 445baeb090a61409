"""After each step: the held rows back on their manifold, positions then velocities (mass-weighted, with the same
J and the same factorization of J M^-1 J^T as the step itself).

    positions   solve A dlam = -C, move dx = M^-1 J^T dlam (x += dx_lin, q turned by dx_ang); repeat while |C|
                is above PROJECT_POSITION (a Newton iteration on C(x) = 0; one usually suffices, C being the
                integrator's local error)
    velocities  solve A lam = -(J v + ct), v += M^-1 J^T lam

This is the standard projection method (Hairer, Lubich, Wanner, "Geometric Numerical Integration", IV.4): a
projection onto the constraint manifold after every step keeps the order of the integrator, and the constraints
hold to round-off over any length of run, with no stabilization term tied to the step. Rows still assembling
(Baumgarte, accelerations.py) are left out; velocity-only rows (gears) take part with C = 0, so a position
correction does not turn a gear train against itself.

`settle_rows` moves rows that have finished assembling (|C| and |dC/dt| / omega below HOLD) to the held set.
"""
from __future__ import annotations

import math

from .bodies import rotations, world_inverse_inertia
from .data import COUNTER_KEPT, COUNTER_KEPT_DROPPED, COUNTER_RANK
from .jit import inlined
from .rows import evaluate_rows, row_motion
from .solve import apply_impulses, assemble, factor, inverse_mass_times_J, move_along, substitute

# a held row whose |C| (m or rad) or |dC/dt| (per second) is above this after a step is projected
PROJECT_POSITION = 1e-14
PROJECT_VELOCITY = 1e-13
# Newton iterations of the position projection, at most
PROJECT_ITERATIONS = 3
# a row that switched on apart joins the held rows once |C| and |dC/dt| / omega fall below this (m or rad)
HOLD = 1e-10


@inlined
def _largest_errors(m, act, s, y):
    """(max |C| over held position rows, max |J v + ct| over held rows); s.target <- J v + ct of the held rows
    (0 for the others): the right-hand side of the velocity projection, negated."""
    cons = m.constraints
    worst_c, worst_v = 0.0, 0.0
    for i in range(len(act.rows)):
        s.target[i] = 0.0
        if not act.held[i]:
            continue
        r = act.rows[i]
        if not cons.velocity_only[r]:
            worst_c = max(worst_c, abs(s.C[r]))
        s.target[i] = row_motion(cons, r, y, y, s.J, 7) + s.ct[r]
        worst_v = max(worst_v, abs(s.target[i]))
    return worst_c, worst_v


@inlined
def _factor_held(m, act, s, every):
    """M^-1 J^T and the factor of the held rows' J M^-1 J^T at the current evaluation (R, J current; s.include
    the held rows)."""
    cons = m.constraints
    world_inverse_inertia(m.bodies, s.R, s.inv_inertia)
    inverse_mass_times_J(act, cons, m.bodies, s.inv_inertia, s.J, s.MJ)
    assemble(act, s.J, s.MJ, s.include, every, cons.soft, s.Lx, s.diag)
    dropped = factor(act, s.Lx, s.diag, s.work, s.dropped)
    if dropped:
        s.counters[COUNTER_RANK] += 1
    # (the factor of the whole J M^-1 J^T when every row took part: the next evaluations may keep it)
    s.counters[COUNTER_KEPT], s.counters[COUNTER_KEPT_DROPPED] = (1 if every else 0), dropped


@inlined
def project(m, act, s, y, table, j, fresh, h):
    """The held rows back on C = 0 and J v + ct = 0 at grid row j (module docstring). Returns whether it moved.

    With `fresh` False the factorization of J M^-1 J^T and M^-1 J^T of the step's last solve are reused when every
    row is held (a quasi-Newton step: they were evaluated O(h) from the end of the step, so the projection leaves
    O(h |C|) of C where a fresh one leaves O(|C|^2), both far below PROJECT_POSITION after one iteration).

    h > 0: the step was semi-implicit Euler's, of h, whose end is O(h^2) off the manifold (RK4's and the midpoint
    rule's: O(h^5), O(h^3)). The position correction dx is then the constraint impulse it takes, as SHAKE has it
    (v += dx / h, w += dtheta / h: the force that puts the step's end on the manifold acts over the step), and
    the velocities are projected with M^-1 J^T and the factor at the corrected positions. Without the first, the
    multipliers of the step's start leave a whirling body O(h^2 w^2) of extra speed along its new tangent; without
    the second, the projection is oblique by the body's turn over the step, and can add kinetic energy: a rod
    spinning at 20 rad/s about a nail gained 8 % of its energy in 0.25 s at 1 ms, and the 10-link chain blew up."""
    if not len(act.rows):
        return False
    cons = m.constraints
    rotations(y, s.R)
    evaluate_rows(m, act, s, y, table, j)
    worst_c, worst_v = _largest_errors(m, act, s, y)
    if worst_c <= PROJECT_POSITION and worst_v <= PROJECT_VELOCITY:
        return False
    s.counters[1] += 1
    every = True
    for i in range(len(act.rows)):
        s.include[i] = act.held[i]
        every = every and act.held[i]
    if fresh or not every:
        _factor_held(m, act, s, every)
    moved = False
    for _ in range(PROJECT_ITERATIONS):
        if worst_c <= PROJECT_POSITION:
            break
        for i in range(len(act.rows)):
            r = act.rows[i]
            s.rhs[i] = -s.C[r] if act.held[i] and not cons.velocity_only[r] else 0.0
        substitute(act, s.Lx, s.dropped, s.rhs, s.dlam)  # (s.lam keeps the step's forces: contacts read them)
        move_along(act, cons, m.bodies, s.MJ, s.dlam, s.delta, y, s.R)
        if h > 0.0:
            _impulse_of_move(m, s, y, h)
        moved = True
        evaluate_rows(m, act, s, y, table, j)
        worst_c, worst_v = _largest_errors(m, act, s, y)
    if moved and h > 0.0:
        _factor_held(m, act, s, every)
    if worst_v > PROJECT_VELOCITY:
        for i in range(len(act.rows)):
            s.rhs[i] = -s.target[i]
        substitute(act, s.Lx, s.dropped, s.rhs, s.dlam)
        for b in range(len(y)):
            for c in range(6):
                s.delta[b, c] = 0.0
        apply_impulses(act, cons, s.MJ, s.dlam, 1.0, s.delta)
        for b in range(len(y) - 1):
            if m.bodies.dynamic[b]:
                for c in range(6):
                    y[b, 7 + c] += s.delta[b, c]
    return True


@inlined
def _impulse_of_move(m, s, y, h):
    """v += dx / h, w += dtheta / h for the move (dx, dtheta) in s.delta just made (project, h > 0)."""
    for b in range(len(y) - 1):
        if m.bodies.dynamic[b]:
            for c in range(6):
                y[b, 7 + c] += s.delta[b, c] / h


@inlined
def settle_rows(m, act, s, y):
    """Rows that were assembling and have arrived (|C|, |dC/dt| / omega <= HOLD) join the held rows. C, J, ct
    must be current (after `project`'s evaluation)."""
    cons = m.constraints
    for i in range(len(act.rows)):
        r = act.rows[i]
        if act.held[i] or not cons.settles[r]:
            continue
        omega = math.sqrt(max(cons.ks[r], 1.0))
        rate = abs(row_motion(cons, r, y, y, s.J, 7) + s.ct[r])
        position = 0.0 if cons.velocity_only[r] else abs(s.C[r])
        if position <= HOLD and rate <= HOLD * omega:
            act.held[i] = True
