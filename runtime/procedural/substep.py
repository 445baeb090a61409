"""One substep of the procedural plan, compiled: move, project, put the inertia back (docs/design/physics.md section 6).

1. move (`predict`): every dynamic body unconstrained by its forces over hs. Linear: v += hs F / m, x += hs v.
   Angular, the free rigid body's own motion, conserving what it conserves: with L the body-frame angular
   momentum I_b u (u = R^T w) plus the torque's impulse hs R^T tau, the implicit midpoint rule on Euler's
   equations with the Cayley map for the turn,

       Q = cay(hs I_b^-1 (L + L') / 2),    L' = Q^T L,    R' = R Q,    w' = R' I_b^-1 L'

   keeps |L|^2, the energy L . I_b^-1 L / 2 and the world angular momentum R L exactly (both invariants are
   quadratic, and the implicit midpoint rule keeps quadratic invariants; the Cayley map is the rotation that
   the midpoint rule of dR/dt = R [u]x gives). Solved by fixed-point iteration. An explicit update
   w += hs I^-1 (tau - w x I w) gains energy whenever a body tumbles near its intermediate axis.
2. project (`sweep`): every active constraint instance, one after another (Gauss-Seidel), its rows at once,
   mass-weighted (XPBD, Mueller et al. 2020):

       (J W Jd^T + alpha~) dlam = -(C - target) - alpha~ lam,     dx_b = W_b Jd_b^T dlam

   with W = diag(1/m, I^-1) of the start of the substep, J the rows' gradient now and Jd their gradient at the
   start of the substep: the correction goes along the constraint normal of the start of the step, as in SHAKE
   (Ryckaert, Ciccotti, Berendsen 1977), which makes a substep a Verlet step and keeps energy instead of
   damping it; while a body turns fast (|w| hs > SHAKE_MAX_TURN), or where the two gradients disagree (the
   effective mass along Jd below MIN_ALIGNMENT of J's), the gradient now is used (plain XPBD: a closest-point
   projection, dissipative but stable). alpha~ = compliance / hs^2. A velocity row (gear, rope) has no C(x);
   over a substep it relates the increments: C = J (x - x0, theta), theta the turn since the substep began.
   A row still assembling is projected to its self-assembly curve (target), not to 0.
3. velocities (`put_back`): v = v' + (x - x')/hs and w = w' + theta(q q'^-1)/hs, the move's velocities plus the
   projection's correction over the substep: exactly the move's for a free body (so it keeps its energy), and
   v = (x - x0)/hs as in position-based dynamics for translation.
"""
from __future__ import annotations

from ..core.bodies import copy_state, turn_since
from ..core.free_rotation import free_rotation
from ..core.jit import kernel

# SHAKE's direction only while no body turns by more than this in a substep, rad
SHAKE_MAX_TURN = 0.25
# use the start-of-substep direction only while its effective mass is at least this fraction of the current one
MIN_ALIGNMENT = 0.5


@kernel
def predict(m, s, y, hs):
    """Stage 1 for every dynamic body (forces in s.force, s.torque; R current): y moves, s.ys <- the result."""
    bodies = m.bodies
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        im = bodies.inv_mass[b]
        for c in range(3):
            # v += hs F / m, x += hs v
            y[b, 7 + c] += hs * im * s.force[b, c]
            y[b, c] += hs * y[b, 7 + c]
        free_rotation(bodies, b, y, s.R, s.torque, hs)
    copy_state(y, s.ys)


@kernel
def put_back(m, s, y, hs):
    """Stage 3: v = v' + (x - x')/hs, w = w' + theta(q q'^-1)/hs for dynamic bodies (s.ys holds the move's y')."""
    for b in range(len(y) - 1):
        if not m.bodies.dynamic[b]:
            continue
        for c in range(3):
            y[b, 7 + c] = s.ys[b, 7 + c] + (y[b, c] - s.ys[b, c]) / hs
        t0, t1, t2 = turn_since(y, s.ys, b)
        y[b, 10] = s.ys[b, 10] + t0 / hs
        y[b, 11] = s.ys[b, 11] + t1 / hs
        y[b, 12] = s.ys[b, 12] + t2 / hs


@kernel
def velocity_row_error(cons, bodies, r, y, ys, J, hs):
    """A velocity row's C over the substep: hs J v_new, v_new the velocities stage 3 will give (y' in ys, the
    move's pose and velocities): v' + (x - x')/hs and w' + theta(q q'^-1)/hs for a dynamic body, its path's
    velocity for a kinematic one. Projecting it to 0 makes the row hold for the velocities themselves."""
    k = cons.row_instance[r]
    total = 0.0
    for slot in range(2):
        b = cons.body[k, slot]
        if b < 0:
            continue
        if bodies.dynamic[b]:
            t0, t1, t2 = turn_since(y, ys, b)
            d = (y[b, 0] - ys[b, 0] + hs * ys[b, 7], y[b, 1] - ys[b, 1] + hs * ys[b, 8],
                 y[b, 2] - ys[b, 2] + hs * ys[b, 9], t0 + hs * ys[b, 10], t1 + hs * ys[b, 11], t2 + hs * ys[b, 12])
        else:
            d = (hs * y[b, 7], hs * y[b, 8], hs * y[b, 9], hs * y[b, 10], hs * y[b, 11], hs * y[b, 12])
        for c in range(6):
            total += J[r, slot, c] * d[c]
    return total


@kernel
def solve_small(K, rhs, n, out):
    """out <- K^-1 rhs for n <= 3 by Gaussian elimination with partial pivoting (K, rhs overwritten); a pivot of 0
    leaves that unknown 0."""
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(K[i, c]) > abs(K[p, c]):
                p = i
        if p != c:
            for e in range(n):
                K[c, e], K[p, e] = K[p, e], K[c, e]
            rhs[c], rhs[p] = rhs[p], rhs[c]
        if K[c, c] == 0.0:
            continue
        for i in range(c + 1, n):
            f = K[i, c] / K[c, c]
            for e in range(c, n):
                K[i, e] -= f * K[c, e]
            rhs[i] -= f * rhs[c]
    for c in range(n - 1, -1, -1):
        total = rhs[c]
        for e in range(c + 1, n):
            total -= K[c, e] * out[e]
        out[c] = total / K[c, c] if K[c, c] != 0.0 else 0.0


@kernel
def effective_mass(cons, bodies, inv_inertia, r, J, i, D, e):
    """J_i,r W D_e^T: row i of J against row e of D, through the inverse masses of the slots' bodies."""
    k = cons.row_instance[r]
    total = 0.0
    for slot in range(2):
        b = cons.body[k, slot]
        if b < 0 or not bodies.dynamic[b]:
            continue
        im = bodies.inv_mass[b]
        for c in range(3):
            total += im * J[i, slot, c] * D[e, slot, c]
            total += J[i, slot, 3 + c] * (inv_inertia[b, c, 0] * D[e, slot, 3] + inv_inertia[b, c, 1] * D[e, slot, 4]
                                          + inv_inertia[b, c, 2] * D[e, slot, 5])
    return total
