"""Forces, compiled: gravity, springs and dampers, user loads, the gyroscopic term (and the wind's drag, through
runtime/wind/kernels.py), summed per body into force and torque (n+1,3). A scene without springs, loads or wind
has empty arrays for them: their loops do nothing.
"""
from __future__ import annotations

import math

from ..wind.kernels import wind_relax
from .bodies import rotations
from .jit import kernel
from .timetable import TIME
from .vec import add3, cross3, dot3, rotate, rotate_t, row3, scale3, sub3


@kernel
def body_point(y, R, b, p):
    """(world position, arm r = R p, velocity v + w x r) of body point p (body frame), or of the world point p
    for b = WORLD (the padded world row: x = 0, R = I, at rest)."""
    r = rotate(R, b, p)
    x = (y[b, 0], y[b, 1], y[b, 2])
    v = (y[b, 7], y[b, 8], y[b, 9])
    w = (y[b, 10], y[b, 11], y[b, 12])
    return add3(x, r), r, add3(v, cross3(w, r))


@kernel
def _point(points, s, j):
    """points[s, j] (a (k,2,3) array) as a 3-tuple."""
    return (points[s, j, 0], points[s, j, 1], points[s, j, 2])


@kernel
def _add(out, b, f):
    out[b, 0] += f[0]
    out[b, 1] += f[1]
    out[b, 2] += f[2]


@kernel
def add_springs(springs, y, R, force, torque):
    """F on a = (k (|d| - L0) + c d|d|/dt) d_hat, d = p_b - p_a; b gets -F; each torque r x F."""
    for s in range(len(springs.stiffness)):
        a, b = springs.body[s, 0], springs.body[s, 1]
        pa, ra, va = body_point(y, R, a, _point(springs.point, s, 0))
        pb, rb, vb = body_point(y, R, b, _point(springs.point, s, 1))
        d = sub3(pb, pa)
        length = math.sqrt(dot3(d, d))
        direction = scale3(1.0 / max(length, 1e-12), d)
        closing = dot3(sub3(vb, va), direction)
        f = scale3(springs.stiffness[s] * (length - springs.rest[s]) + springs.damping[s] * closing, direction)
        if a >= 0:
            _add(force, a, f)
            _add(torque, a, cross3(ra, f))
        if b >= 0:
            _add(force, b, scale3(-1.0, f))
            _add(torque, b, scale3(-1.0, cross3(rb, f)))


@kernel
def add_loads(loads, table, j, R, force, torque):
    """User forces and torques of time (table row j); a force at a body point also turns the body: tau = r x F."""
    for l in range(len(loads.body)):
        b, column = loads.body[l], loads.column[l]
        f = (table[j, column], table[j, column + 1], table[j, column + 2])
        tau = (table[j, column + 3], table[j, column + 4], table[j, column + 5])
        arm = rotate(R, b, row3(loads.point, l, 0))
        _add(force, b, f)
        _add(torque, b, add3(tau, cross3(arm, f)))


@kernel
def add_gyroscopic(bodies, y, R, torque):
    """tau -= w x (I w), I = R I_b R^T, for the bodies with unequal principal moments (written in the body frame:
    w x I w = R (u x I_b u), u = R^T w)."""
    for b in range(len(bodies.gyroscopic)):
        if not bodies.gyroscopic[b]:
            continue
        u = rotate_t(R, b, (y[b, 10], y[b, 11], y[b, 12]))
        gyro = rotate(R, b, cross3(u, rotate(bodies.inertia, b, u)))
        torque[b, 0] -= gyro[0]
        torque[b, 1] -= gyro[1]
        torque[b, 2] -= gyro[2]


@kernel
def weights(bodies, force, torque):
    """force <- m g (dynamic bodies), torque <- 0."""
    for b in range(len(bodies.inv_mass)):
        for c in range(3):
            force[b, c] = bodies.weight[b, c]
            torque[b, c] = 0.0


@kernel
def step_forces(m, s, y, table, j, h):
    """force, torque <- gravity, springs, loads at the step's start; bodies in the wind: relaxed over h."""
    rotations(y, s.R)
    weights(m.bodies, s.force, s.torque)
    add_springs(m.springs, y, s.R, s.force, s.torque)
    add_loads(m.loads, table, j, s.R, s.force, s.torque)
    if len(m.wind.body):
        speeds = table[j, m.wind_column:m.wind_column + m.wind_count]
        wind_relax(m.wind, y, s.R, speeds, table[j, TIME], h, s.force, s.torque, s.air)
