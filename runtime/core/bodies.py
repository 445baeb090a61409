"""Per-body kernels shared by both plans: kinematic bodies on their paths, rotation matrices, world inverse
inertias, the energy, and the blow-up test."""
from __future__ import annotations

import math

from . import model as M
from .jit import kernel
from .vec import dot3, quat_to_matrix, rotate, rotate_t, similarity

# a speed beyond this (m/s or rad/s) is a blow-up
RUNAWAY_SPEED = 1e6


@kernel
def place_kinematic(kin, table, j, y):
    """The kinematic bodies (those on their path now) at their paths' pose and velocity at grid row j."""
    for i in range(len(kin.body)):
        if not kin.on[i]:
            continue
        b, c = kin.body[i], kin.column[i]
        for e in range(3):
            y[b, e] = table[j, c + M.KIN_X + e]
            y[b, 7 + e] = table[j, c + M.KIN_V + e]
            y[b, 10 + e] = table[j, c + M.KIN_W + e]
        for e in range(4):
            y[b, 3 + e] = table[j, c + M.KIN_Q + e]


@kernel
def rotations(y, R):
    """R (n+1,3,3) <- the rotation matrices of the orientations in y."""
    for b in range(len(y)):
        quat_to_matrix(y[b, 3], y[b, 4], y[b, 5], y[b, 6], R, b)


@kernel
def copy_state(source, out):
    """out (n+1,13) <- source (element by element: numba's array assignment may allocate a temporary)."""
    for b in range(source.shape[0]):
        for c in range(source.shape[1]):
            out[b, c] = source[b, c]


@kernel
def world_inverse_inertia(bodies, R, out):
    """out (n+1,3,3) <- I^-1 = R I_b^-1 R^T of the dynamic bodies (the body's own for an isotropic one)."""
    for b in range(len(bodies.inv_mass)):
        if not bodies.dynamic[b]:
            continue
        if bodies.isotropic[b]:
            for i in range(3):
                for j in range(3):
                    out[b, i, j] = bodies.inv_inertia[b, i, j]
        elif bodies.principal[b]:
            # R diag(d) R^T = sum_k d_k r_k r_k^T, r_k the k-th column of R
            d0, d1, d2 = bodies.inv_moments[b, 0], bodies.inv_moments[b, 1], bodies.inv_moments[b, 2]
            for i in range(3):
                for j in range(i, 3):
                    value = d0 * R[b, i, 0] * R[b, j, 0] + d1 * R[b, i, 1] * R[b, j, 1] + d2 * R[b, i, 2] * R[b, j, 2]
                    out[b, i, j] = value
                    out[b, j, i] = value
        else:
            similarity(R, b, bodies.inv_inertia, out)


@kernel
def spin_energy(R, inertia, y, b):
    """w . I w of body b with I = R I_b R^T: u . I_b u, u = R^T w."""
    u = rotate_t(R, b, (y[b, 10], y[b, 11], y[b, 12]))
    return dot3(u, rotate(inertia, b, u))


@kernel
def kinetic(bodies, R, y, b):
    """Body b's kinetic energy (R current): 1/2 m v^2 + 1/2 w . I w."""
    speed2 = y[b, 7] ** 2 + y[b, 8] ** 2 + y[b, 9] ** 2
    return 0.5 * (bodies.mass[b] * speed2 + spin_energy(R, bodies.inertia, y, b))


@kernel
def energy(bodies, R, y):
    """Kinetic plus gravitational potential energy of the dynamic bodies (R current):
    E = sum 1/2 m v^2 + 1/2 w . I w - m g . x."""
    total = 0.0
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        height = bodies.weight[b, 0] * y[b, 0] + bodies.weight[b, 1] * y[b, 1] + bodies.weight[b, 2] * y[b, 2]
        total += kinetic(bodies, R, y, b) - height
    return total


@kernel
def runaway_body(bodies, y):
    """The first dynamic body whose state is not finite or whose speed passed RUNAWAY_SPEED, or -1."""
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        for c in range(13):
            value = y[b, c]
            if not (abs(value) < math.inf) or (c >= 7 and abs(value) >= RUNAWAY_SPEED):
                return b
    return -1


@kernel
def normalize_quaternions(y):
    for b in range(len(y)):
        norm = math.sqrt(y[b, 3] ** 2 + y[b, 4] ** 2 + y[b, 5] ** 2 + y[b, 6] ** 2)
        for c in range(3, 7):
            y[b, c] /= norm


@kernel
def turn(y, b, px, py, pz):
    """Body b turned by the small world rotation (px, py, pz): q += 0.5 (0, dphi) * q, renormalized."""
    w, x, yy, z = y[b, 3], y[b, 4], y[b, 5], y[b, 6]
    w2 = w + 0.5 * (-px * x - py * yy - pz * z)
    x2 = x + 0.5 * (px * w + py * z - pz * yy)
    y2 = yy + 0.5 * (-px * z + py * w + pz * x)
    z2 = z + 0.5 * (px * yy - py * x + pz * w)
    norm = math.sqrt(w2 * w2 + x2 * x2 + y2 * y2 + z2 * z2)
    y[b, 3], y[b, 4], y[b, 5], y[b, 6] = w2 / norm, x2 / norm, y2 / norm, z2 / norm


@kernel
def turn_since(y, y0, b):
    """The world rotation vector theta of body b from y0 to y in the Cayley map: 2 vec(dq) / dq_w with
    dq = q q0^-1 (exact inverse of turning by (1, theta / 2) normalized)."""
    w, x, yy, z = y[b, 3], y[b, 4], y[b, 5], y[b, 6]
    w0, x0, y0_, z0 = y0[b, 3], -y0[b, 4], -y0[b, 5], -y0[b, 6]
    dw = w * w0 - x * x0 - yy * y0_ - z * z0
    dx = w * x0 + x * w0 + yy * z0 - z * y0_
    dy = w * y0_ - x * z0 + yy * w0 + z * x0
    dz = w * z0 + x * y0_ - yy * x0 + z * w0
    if dw < 0.0:  # the shorter way round
        dw, dx, dy, dz = -dw, -dx, -dy, -dz
    return 2.0 * dx / dw, 2.0 * dy / dw, 2.0 * dz / dw
