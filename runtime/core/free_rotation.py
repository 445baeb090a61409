"""A rigid body's free rotation over a step, compiled: the motion it has of itself, keeping what it keeps.

With L the body-frame angular momentum I_b u (u = R^T w) plus the torque's impulse h R^T tau, the implicit midpoint
rule on Euler's equations with the Cayley map for the turn,

    Q = cay(h I_b^-1 (L + L') / 2),    L' = Q^T L,    R' = R Q,    w' = R' I_b^-1 L'

keeps |L|^2, the energy L . I_b^-1 L / 2 and the world angular momentum R L exactly (both invariants are quadratic,
and the implicit midpoint rule keeps quadratic invariants; the Cayley map is the rotation the midpoint rule of
dR/dt = R [u]x gives), solved by fixed-point iteration. An explicit update w += h I^-1 (tau - w x I w) gains energy
whenever a body tumbles near its intermediate axis. The procedural plan's move (procedural/substep.py) and the
capturing contact step's drift (capture/loop.py) both turn their bodies with it.
"""
from __future__ import annotations

import math

from .jit import kernel
from .vec import add3, cross3, quat_mul, quat_to_matrix, rotate, rotate_t, scale3, sub3

# the fixed-point iteration of the free rotation stops at this relative change of L (or after ROTATION_ITERATIONS)
ROTATION_TOLERANCE = 1e-15
ROTATION_ITERATIONS = 30


@kernel
def _cayley_turn(a0, a1, a2):
    """The unit quaternion of the Cayley map of the rotation vector a: (1, a/2) / |(1, a/2)|."""
    h0, h1, h2 = 0.5 * a0, 0.5 * a1, 0.5 * a2
    norm = math.sqrt(1.0 + h0 * h0 + h1 * h1 + h2 * h2)
    return 1.0 / norm, h0 / norm, h1 / norm, h2 / norm


@kernel
def free_rotation(bodies, b, y, R, torque, hs):
    """Body b's orientation and angular velocity moved by hs of free rotation with the torque's impulse
    (module docstring). R[b] is current on entry and on return."""
    # L = I_b R^T w + hs R^T tau (body frame)
    u = rotate_t(R, b, (y[b, 10], y[b, 11], y[b, 12]))
    L = add3(rotate(bodies.inertia, b, u), scale3(hs, rotate_t(R, b, (torque[b, 0], torque[b, 1], torque[b, 2]))))
    Lp = L
    q = (1.0, 0.0, 0.0, 0.0)
    size = abs(L[0]) + abs(L[1]) + abs(L[2])
    for _ in range(ROTATION_ITERATIONS):
        # u_mid = I_b^-1 (L + L') / 2, Q = cay(hs u_mid), L' = Q^T L
        u_mid = rotate(bodies.inv_inertia, b, scale3(0.5, add3(L, Lp)))
        q = _cayley_turn(hs * u_mid[0], hs * u_mid[1], hs * u_mid[2])
        # Q^T L = L turned by the conjugate of q: L - 2 q_w (v x L) + 2 v x (v x L), v = vec(q)
        v = (q[1], q[2], q[3])
        c = cross3(v, L)
        new = add3(sub3(L, scale3(2.0 * q[0], c)), scale3(2.0, cross3(v, c)))
        change = abs(new[0] - Lp[0]) + abs(new[1] - Lp[1]) + abs(new[2] - Lp[2])
        Lp = new
        if change <= ROTATION_TOLERANCE * size:
            break
    # R' = R Q: q' = q_b * q (a turn in the body frame)
    turned = quat_mul((y[b, 3], y[b, 4], y[b, 5], y[b, 6]), q)
    norm = math.sqrt(turned[0] ** 2 + turned[1] ** 2 + turned[2] ** 2 + turned[3] ** 2)
    y[b, 3], y[b, 4], y[b, 5], y[b, 6] = turned[0] / norm, turned[1] / norm, turned[2] / norm, turned[3] / norm
    quat_to_matrix(y[b, 3], y[b, 4], y[b, 5], y[b, 6], R, b)
    # w' = R' I_b^-1 L'
    w = rotate(R, b, rotate(bodies.inv_inertia, b, Lp))
    y[b, 10], y[b, 11], y[b, 12] = w
