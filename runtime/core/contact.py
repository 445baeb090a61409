"""Contact in the step, compiled: the rows of a resting or sliding contact, the friction of sliding, and the tests
after each step that hand a change of the contact set back to the collision stage (runtime/collide).

A contact holds a point P of body a (a box's corner; a sphere's centre with its radius rho) on a face of body b
(a plane of b's frame through S with normal N, tangents T1, T2 along the face's axes):

    normal      C = N . (P - S) - rho >= 0       lambda_n >= 0, complementary: held (C = 0) while it pushes
    sticking    point:  C_i = T_i . (P - A) = 0  (A, fixed in b, where P stuck: the point may not creep)
                sphere: T_i . (v_c,a - v_c,b) = 0 (the contact point's velocities: rolling without slipping,
                        a velocity row)             while sqrt(lambda_1^2 + lambda_2^2) <= mu lambda_n
    sliding     no tangent rows; the force -mu lambda_n u at the contact point, u the direction of the slip

The normal and sticking rows are rows of the multiplier system like any joint's (with the plane row's algebra:
rows.py), held on their manifold by the projection after each step, so that what holds a body holds its
position and RK4 keeps its order while the contact set stays. Sliding friction depends on lambda_n, found by
the solve itself: the solve is repeated with the friction of the last lambda_n until lambda_n no longer changes
(the factorization is the same: substitutions only).

Two spheres: C = |P_a - P_b| - (rho_a + rho_b), no friction rows.

After each step `contact_change` looks for what the rows cannot do themselves: a contact that pulls
(lambda_n < 0: the bodies part), a sticking contact outside its friction cone (it starts to slide), a sliding one
whose slip turned back (it stops), a point that left its face, and a pair not in contact whose bounding boxes,
swept over the step, come within the margin (`anything_near`): the run then stops after that step, and the
collision stage decides anew.
"""
from __future__ import annotations

import math

from . import model as M
from .bodies import rotations
from .data import COUNTER_TURNED_BACK
from .jit import kernel
from .vec import add3, cross3, dot3, norm3, rotate, rotate_t, row3, scale3, sub3

# the tests' tolerances: a normal force below -FORCE_TOL (N) pulls; the cone is exceeded beyond its (1 + CONE_TOL)
FORCE_TOL = 1e-9
CONE_TOL = 1e-9
# a point off its face by more than this (m) left it
EDGE_TOL = 1e-9
# sliding friction: the solve is repeated until lambda_n changes by less than this (relative), at most this often
FRICTION_TOL = 1e-13
FRICTION_ITERATIONS = 12
# a slip below this speed (m/s) has no direction of its own: the friction opposes the one it began in (T1)
STILL_SLIP = 1e-12
# change codes (status[2] of a run: the instance)
LIFTS, SLIPS, STOPS, LEAVES, NEAR = 1, 2, 3, 4, 5


@kernel
def _point_and_frame(k, cons, param, y, R):
    """World P (a's point), S, N, T1, T2 of contact instance k, and the contact point c (P - rho N)."""
    a, b = cons.body[k, 0], cons.body[k, 1]
    P = add3((y[a, 0], y[a, 1], y[a, 2]), rotate(R, a, row3(param, k, M.CONTACT_POINT)))
    S = add3((y[b, 0], y[b, 1], y[b, 2]), rotate(R, b, row3(param, k, M.CONTACT_ORIGIN)))
    N = rotate(R, b, row3(param, k, M.CONTACT_NORMAL))
    T1 = rotate(R, b, row3(param, k, M.CONTACT_T1))
    T2 = rotate(R, b, row3(param, k, M.CONTACT_T2))
    c = sub3(P, scale3(param[k, M.CONTACT_RADIUS], N))
    return P, S, N, T1, T2, c


@kernel
def _set(J, row, slot, lin, ang):
    J[row, slot, 0], J[row, slot, 1], J[row, slot, 2] = lin[0], lin[1], lin[2]
    J[row, slot, 3], J[row, slot, 4], J[row, slot, 5] = ang[0], ang[1], ang[2]


@kernel
def _surface_row(row, a, b, P, S, N, y, C, J, ct, bias, offset):
    """C = N . (P - S) - offset for a point P fixed in a and a plane (S, N) fixed in b (the plane row of rows.py,
    with S, N turning with b): J_a = [N, (P - x_a) x N], J_b = -[N, (P - x_b) x N]."""
    x_a, v_a, w_a = (y[a, 0], y[a, 1], y[a, 2]), (y[a, 7], y[a, 8], y[a, 9]), (y[a, 10], y[a, 11], y[a, 12])
    x_b, v_b, w_b = (y[b, 0], y[b, 1], y[b, 2]), (y[b, 7], y[b, 8], y[b, 9]), (y[b, 10], y[b, 11], y[b, 12])
    r_a, r_s = sub3(P, x_a), sub3(S, x_b)
    d = sub3(P, S)
    C[row] = dot3(N, d) - offset
    live_b = 1.0 if b >= 0 else 0.0
    _set(J, row, 0, N, cross3(r_a, N))
    _set(J, row, 1, scale3(-live_b, N), scale3(-live_b, cross3(sub3(P, x_b), N)))
    ct[row] = 0.0
    # bias = Ndd . d + 2 Nd . dd + N . ddd at zero accelerations, Nd = w_b x N (rows.py, the plane row)
    N_d = cross3(w_b, N)
    d_d = sub3(add3(v_a, cross3(w_a, r_a)), add3(v_b, cross3(w_b, r_s)))
    d_dd = sub3(_centripetal(w_a, r_a), _centripetal(w_b, r_s))
    bias[row] = dot3(_centripetal(w_b, N), d) + 2.0 * dot3(N_d, d_d) + dot3(N, d_dd)


@kernel
def _centripetal(w, r):
    return sub3(scale3(dot3(w, r), w), scale3(dot3(w, w), r))


@kernel
def _rolling_row(row, a, b, c, T, N, rho, y, C, J, ct, bias):
    """T . (v_a + w_a x (c - x_a) - v_b - w_b x (c - x_b)) = 0, c = P - rho N the contact point: a velocity row,
    J_a = [T, (-rho N) x T], J_b = -[T, (c - x_b) x T] (bias 0: exact for a face that does not turn)."""
    x_b = (y[b, 0], y[b, 1], y[b, 2])
    live_b = 1.0 if b >= 0 else 0.0
    _set(J, row, 0, T, cross3(scale3(-rho, N), T))
    _set(J, row, 1, scale3(-live_b, T), scale3(-live_b, cross3(sub3(c, x_b), T)))
    C[row], ct[row], bias[row] = 0.0, 0.0, 0.0


@kernel
def contact_rows(k, cons, param, y, R, C, J, ct, bias):
    """The rows of contact instance k at its first row (module docstring)."""
    row, a, b = cons.first_row[k], cons.body[k, 0], cons.body[k, 1]
    if cons.family[k] == M.CONTACT_SPHERES:
        _spheres_row(row, a, b, k, param, y, R, C, J, ct, bias)
        return
    P, S, N, T1, T2, c = _point_and_frame(k, cons, param, y, R)
    rho = param[k, M.CONTACT_RADIUS]
    _surface_row(row, a, b, P, S, N, y, C, J, ct, bias, rho)
    if cons.rows[k] < 3:
        return
    if rho > 0.0:
        _rolling_row(row + 1, a, b, c, T1, N, rho, y, C, J, ct, bias)
        _rolling_row(row + 2, a, b, c, T2, N, rho, y, C, J, ct, bias)
    else:
        A = add3((y[b, 0], y[b, 1], y[b, 2]), rotate(R, b, row3(param, k, M.CONTACT_ANCHOR)))
        _surface_row(row + 1, a, b, P, A, T1, y, C, J, ct, bias, 0.0)
        _surface_row(row + 2, a, b, P, A, T2, y, C, J, ct, bias, 0.0)


@kernel
def _spheres_row(row, a, b, k, param, y, R, C, J, ct, bias):
    """C = |P_a - P_b| - (rho_a + rho_b), n = (P_a - P_b) / |P_a - P_b|: J_a = [n, r_a x n], J_b = -[n, r_b x n];
    bias = (|dd|^2 - (n . dd)^2) / |d| + n . (w_a x (w_a x r_a) - w_b x (w_b x r_b))."""
    x_a, v_a, w_a = (y[a, 0], y[a, 1], y[a, 2]), (y[a, 7], y[a, 8], y[a, 9]), (y[a, 10], y[a, 11], y[a, 12])
    x_b, v_b, w_b = (y[b, 0], y[b, 1], y[b, 2]), (y[b, 7], y[b, 8], y[b, 9]), (y[b, 10], y[b, 11], y[b, 12])
    r_a = rotate(R, a, row3(param, k, M.SPHERES_A))
    r_b = rotate(R, b, row3(param, k, M.SPHERES_B))
    d = sub3(add3(x_a, r_a), add3(x_b, r_b))
    length = norm3(d)
    n = scale3(1.0 / max(length, 1e-300), d)
    C[row] = length - param[k, M.SPHERES_REACH]
    live_b = 1.0 if b >= 0 else 0.0
    _set(J, row, 0, n, cross3(r_a, n))
    _set(J, row, 1, scale3(-live_b, n), scale3(-live_b, cross3(r_b, n)))
    ct[row] = 0.0
    dd = sub3(add3(v_a, cross3(w_a, r_a)), add3(v_b, cross3(w_b, r_b)))
    along = dot3(n, dd)
    bias[row] = (dot3(dd, dd) - along * along) / max(length, 1e-300) + dot3(
        n, sub3(_centripetal(w_a, r_a), _centripetal(w_b, r_b)))


@kernel
def _slip(k, cons, param, y, R):
    """(the contact point's tangential relative velocity (3,), the contact point, N) of contact instance k."""
    a, b = cons.body[k, 0], cons.body[k, 1]
    P, S, N, T1, T2, c = _point_and_frame(k, cons, param, y, R)
    va = add3((y[a, 7], y[a, 8], y[a, 9]), cross3((y[a, 10], y[a, 11], y[a, 12]), sub3(c, (y[a, 0], y[a, 1], y[a, 2]))))
    vb = add3((y[b, 7], y[b, 8], y[b, 9]), cross3((y[b, 10], y[b, 11], y[b, 12]), sub3(c, (y[b, 0], y[b, 1], y[b, 2]))))
    u = sub3(va, vb)
    return sub3(u, scale3(dot3(N, u), N)), c, N


@kernel
def sliding_forces(act, cons, param, y, R, lam, local, out):
    """out (n+1,6) <- the friction of every sliding contact of the active rows, as forces and torques: -mu
    lambda_n u at the contact point c on a (u the slip's direction), the opposite on b; lambda_n from lam (local
    rows; local (M,) the local index of each global row). Returns the first instance whose slip has turned back
    (against T1, the direction it began in: it stopped in between), or -1."""
    for b in range(len(out)):
        for e in range(6):
            out[b, e] = 0.0
    turned_back = -1
    for i in range(len(act.instances)):
        k = act.instances[i]
        if cons.family[k] != M.CONTACT or param[k, M.CONTACT_SLIDE_MU] == 0.0:
            continue
        slip, c, N = _slip(k, cons, param, y, R)
        speed = norm3(slip)
        normal = lam[local[cons.first_row[k]]]
        T1 = rotate(R, cons.body[k, 1], row3(param, k, M.CONTACT_T1))
        if speed > STILL_SLIP and dot3(slip, T1) < 0.0 and turned_back < 0:
            turned_back = k
        if normal <= 0.0:
            continue
        # u: the slip's direction; a slip too slow to have one has just begun, along T1
        u = scale3(1.0 / speed, slip) if speed > STILL_SLIP else T1
        # F = -mu lambda_n u on a at c, and -F on b
        F = scale3(-param[k, M.CONTACT_SLIDE_MU] * normal, u)
        for slot in range(2):
            body = cons.body[k, slot]
            if body < 0:
                continue
            sign = 1.0 if slot == 0 else -1.0
            arm = sub3(c, (y[body, 0], y[body, 1], y[body, 2]))
            tau = cross3(arm, F)
            for e in range(3):
                out[body, e] += sign * F[e]
                out[body, 3 + e] += sign * tau[e]
    return turned_back


@kernel
def friction_impulses(act, cons, param, bodies, inv_inertia, y, R, lam, local, hs, dv):
    """The procedural plan's sliding friction, after a substep's velocities (its normal rows projected, lam the
    position multipliers: the normal impulse of the substep is lambda_n / hs): at each sliding contact, the
    impulse that takes the slip u away, at most mu lambda_n / hs,

        p = min(mu lambda_n / hs, |u| / w),   w = sum over the bodies of 1/m + (r x e) . I^-1 (r x e),  e = u / |u|

    -p e on a at the contact point, +p e on b; all from the same velocities (dv (n+1,6) gathers the changes: no
    contact's friction depends on the order of the others). Returns whether any impulse was applied. The rows
    must then see the change (procedural/project.py keep_rows, which turns away what the impulses would do
    along the rows: a box's friction tipping it about the corners that hold it), before `stopped_slips` looks
    for the slips they stopped."""
    for b in range(len(dv)):
        for d in range(6):
            dv[b, d] = 0.0
    for i in range(len(act.instances)):
        k = act.instances[i]
        if cons.family[k] != M.CONTACT or param[k, M.CONTACT_SLIDE_MU] == 0.0:
            continue
        normal = lam[local[cons.first_row[k]]] / hs
        slip, c, N = _slip(k, cons, param, y, R)
        speed = norm3(slip)
        if normal <= 0.0 or speed <= STILL_SLIP:
            continue
        e = scale3(1.0 / speed, slip)
        w = 0.0
        for slot in range(2):
            body = cons.body[k, slot]
            if body >= 0 and bodies.dynamic[body]:
                re = cross3(sub3(c, (y[body, 0], y[body, 1], y[body, 2])), e)
                w += bodies.inv_mass[body] + dot3(re, rotate(inv_inertia, body, re))
        if w <= 0.0:
            continue
        p = min(param[k, M.CONTACT_SLIDE_MU] * normal, speed / w)
        for slot in range(2):
            body = cons.body[k, slot]
            if body < 0 or not bodies.dynamic[body]:
                continue
            sign = -1.0 if slot == 0 else 1.0
            arm = sub3(c, (y[body, 0], y[body, 1], y[body, 2]))
            turn = rotate(inv_inertia, body, cross3(arm, scale3(sign * p, e)))
            for d in range(3):
                dv[body, d] += sign * p * bodies.inv_mass[body] * e[d]
                dv[body, 3 + d] += turn[d]
    applied = False
    for b in range(len(dv) - 1):
        for d in range(3):
            if dv[b, d] != 0.0 or dv[b, 3 + d] != 0.0:
                applied = True
            y[b, 7 + d] += dv[b, d]
            y[b, 10 + d] += dv[b, 3 + d]
    return applied


@kernel
def stopped_slips(act, cons, param, y, R, counters):
    """After a procedural substep's friction: a sliding contact whose slip turned back or came to rest stopped in
    the substep: counters[COUNTER_TURNED_BACK] <- 1 + the first such instance (its pair sticks: the collision
    stage's `on_stop`; the others are found at the next step's end)."""
    for i in range(len(act.instances)):
        k = act.instances[i]
        if cons.family[k] != M.CONTACT or param[k, M.CONTACT_SLIDE_MU] == 0.0:
            continue
        slip, c, N = _slip(k, cons, param, y, R)
        T1 = rotate(R, cons.body[k, 1], row3(param, k, M.CONTACT_T1))
        if dot3(slip, T1) <= STILL_SLIP and counters[COUNTER_TURNED_BACK] == 0:
            counters[COUNTER_TURNED_BACK] = k + 1


@kernel
def contact_change(act, cons, param, y, R, lam, local):
    """(code, instance) of the first active contact that its rows cannot keep (module docstring), or (0, -1)."""
    for i in range(len(act.instances)):
        k = act.instances[i]
        family = cons.family[k]
        if family != M.CONTACT and family != M.CONTACT_SPHERES:
            continue
        row = local[cons.first_row[k]]
        normal = lam[row]
        if normal < -FORCE_TOL:
            return LIFTS, k
        if family == M.CONTACT_SPHERES:
            continue
        if cons.rows[k] == 3:
            if _first_of_pair(act, cons, i) and _patch_slips(act, cons, param, R, lam, local, i):
                return SLIPS, k
        elif param[k, M.CONTACT_SLIDE_MU] > 0.0:
            slip, _, _ = _slip(k, cons, param, y, R)
            # the slip's direction when it began is T1 (the collision stage sets it so)
            T1 = rotate(R, cons.body[k, 1], row3(param, k, M.CONTACT_T1))
            if dot3(slip, T1) <= 0.0:
                return STOPS, k
        if _off_face(k, cons, param, y, R):
            return LEAVES, k
    return 0, -1


@kernel
def _same_pair(cons, k, j):
    """+1 when instances k and j join the same bodies in the same order, -1 in the other order, else 0."""
    a, b = cons.body[k, 0], cons.body[k, 1]
    if cons.body[j, 0] == a and cons.body[j, 1] == b:
        return 1.0
    if cons.body[j, 0] == b and cons.body[j, 1] == a:
        return -1.0
    return 0.0


@kernel
def _sticking(cons, k):
    return cons.family[k] == M.CONTACT and cons.rows[k] == 3


@kernel
def _first_of_pair(act, cons, i):
    """Whether active instance i is the first sticking contact of its pair."""
    k = act.instances[i]
    for e in range(i):
        j = act.instances[e]
        if _sticking(cons, j) and _same_pair(cons, k, j) != 0.0:
            return False
    return True


@kernel
def _patch_slips(act, cons, param, R, lam, local, i):
    """Whether the sticking contacts of the pair of active instance i, as one patch, need more friction than its
    cone: |F_t| > mu F_n for F the sum of their forces on the first's body a (the patch holds or slides as one:
    the share of a redundant patch's force each corner gets is arbitrary, the sum is not)."""
    k = act.instances[i]
    F = (0.0, 0.0, 0.0)
    for e in range(i, len(act.instances)):
        j = act.instances[e]
        sign = _same_pair(cons, k, j)
        if not _sticking(cons, j) or sign == 0.0:
            continue
        row = local[cons.first_row[j]]
        b = cons.body[j, 1]
        N = rotate(R, b, row3(param, j, M.CONTACT_NORMAL))
        T1 = rotate(R, b, row3(param, j, M.CONTACT_T1))
        T2 = rotate(R, b, row3(param, j, M.CONTACT_T2))
        # the force on a of contact j: lambda_n N + lambda_1 T1 + lambda_2 T2 (on j's a: signed for k's a)
        f = add3(scale3(lam[row], N), add3(scale3(lam[row + 1], T1), scale3(lam[row + 2], T2)))
        F = add3(F, scale3(sign, f))
    N = rotate(R, cons.body[k, 1], row3(param, k, M.CONTACT_NORMAL))
    normal = dot3(F, N)
    tangential = norm3(sub3(F, scale3(normal, N)))
    return tangential > param[k, M.CONTACT_MU] * normal * (1.0 + CONE_TOL) + FORCE_TOL


@kernel
def _off_face(k, cons, param, y, R):
    """Whether the contact point of instance k lies outside its face (beyond the half extents along T1, T2)."""
    P, S, N, T1, T2, c = _point_and_frame(k, cons, param, y, R)
    offset = sub3(c, S)
    return (abs(dot3(offset, T1)) > param[k, M.CONTACT_HALF1] + EDGE_TOL
            or abs(dot3(offset, T2)) > param[k, M.CONTACT_HALF2] + EDGE_TOL)


@kernel
def add_impulses(act, cons, lam, local, h, impulse):
    """impulse[k] += lambda_n h for every active contact instance k (its normal impulse over a step)."""
    for i in range(len(act.instances)):
        k = act.instances[i]
        if cons.family[k] == M.CONTACT or cons.family[k] == M.CONTACT_SPHERES:
            impulse[k] += lam[local[cons.first_row[k]]] * h


@kernel
def record_contacts(act, cons, param, y, R, impulse, out, f):
    """out[f, k] <- (impulse since the last frame, slip speed, point, normal) of every active contact instance k;
    its impulse accumulator back to 0 (module docstring of core/record.py)."""
    for k in range(out.shape[1]):
        for e in range(8):
            out[f, k, e] = 0.0
    for i in range(len(act.instances)):
        k = act.instances[i]
        family = cons.family[k]
        if family != M.CONTACT and family != M.CONTACT_SPHERES:
            continue
        if family == M.CONTACT:
            slip, c, N = _slip(k, cons, param, y, R)
            speed = norm3(slip)
        else:
            a, b = cons.body[k, 0], cons.body[k, 1]
            pa = add3((y[a, 0], y[a, 1], y[a, 2]), rotate(R, a, row3(param, k, M.SPHERES_A)))
            pb = add3((y[b, 0], y[b, 1], y[b, 2]), rotate(R, b, row3(param, k, M.SPHERES_B)))
            d = sub3(pa, pb)
            N = scale3(1.0 / max(norm3(d), 1e-300), d)
            c = sub3(pa, scale3(0.5 * norm3(d), N))
            speed = 0.0
        if k < out.shape[1]:
            out[f, k, 0], out[f, k, 1] = impulse[k], speed
            for e in range(3):
                out[f, k, 2 + e], out[f, k, 5 + e] = c[e], N[e]
        impulse[k] = 0.0


# ---------------------------------------------------------------- the broad phase between steps


@kernel
def _extent(shapes, b, R, axis):
    """Half the world extent of body b's shape along world axis `axis` (its bounding box turned by R)."""
    kind = shapes.kind[b]
    if kind == M.SHAPE_SPHERE:
        return shapes.radius[b]
    if kind == M.SHAPE_CAPSULE or kind == M.SHAPE_CYLINDER:
        a = R[b, axis, 2]
        side = shapes.radius[b] if kind == M.SHAPE_CAPSULE else shapes.radius[b] * math.sqrt(max(0.0, 1.0 - a * a))
        return abs(a) * shapes.half_length[b] + side
    return (abs(R[b, axis, 0]) * shapes.half[b, 0] + abs(R[b, axis, 1]) * shapes.half[b, 1]
            + abs(R[b, axis, 2]) * shapes.half[b, 2])


@kernel
def _box(shapes, b, y, R, axis):
    """(lo, hi) of body b's bounding box along world axis `axis`."""
    centre = y[b, axis] + R[b, axis, 0] * shapes.centre[b, 0] + R[b, axis, 1] * shapes.centre[b, 1] + \
        R[b, axis, 2] * shapes.centre[b, 2]
    e = _extent(shapes, b, R, axis)
    return centre - e, centre + e


@kernel
def _above_plane(shapes, body, plane, y, R):
    """How far body's bounding box is above the plane body's surface (negative: it reaches below it)."""
    n = rotate(R, plane, (shapes.normal[plane, 0], shapes.normal[plane, 1], shapes.normal[plane, 2]))
    height = dot3(n, sub3((y[body, 0], y[body, 1], y[body, 2]), (y[plane, 0], y[plane, 1], y[plane, 2])))
    reach = 0.0
    for axis in range(3):
        reach += abs(n[axis]) * _extent(shapes, body, R, axis)
    return height - reach


@kernel
def anything_near(shapes, pairs, y, R, y0, R0, margin):
    """The first pair not in contact (pairs.state 0) that may have come within `margin` of touching: not kept
    clear since its last look, and its bounding boxes, swept from (y0, R0) to (y, R), within `margin` of each other
    (or of a plane); or -1."""
    for p in range(len(pairs.a)):
        if pairs.state[p] != 0 or kept_clear(pairs, p, y, R):
            continue
        a, b = pairs.a[p], pairs.b[p]
        if shapes.kind[b] == M.SHAPE_PLANE or shapes.kind[a] == M.SHAPE_PLANE:
            body, plane = (a, b) if shapes.kind[b] == M.SHAPE_PLANE else (b, a)
            if min(_above_plane(shapes, body, plane, y, R), _above_plane(shapes, body, plane, y0, R0)) <= margin:
                return p
            continue
        apart = False
        for axis in range(3):
            lo_a, hi_a = _box(shapes, a, y, R, axis)
            lo_a0, hi_a0 = _box(shapes, a, y0, R0, axis)
            lo_b, hi_b = _box(shapes, b, y, R, axis)
            lo_b0, hi_b0 = _box(shapes, b, y0, R0, axis)
            if min(lo_a, lo_a0) > max(hi_b, hi_b0) + margin or min(lo_b, lo_b0) > max(hi_a, hi_a0) + margin:
                apart = True
                break
        if not apart:
            return p
    return -1


@kernel
def kept_clear(pairs, p, y, R):
    """Whether apart pair p cannot have come within the margin since the look that set its clearance. Of its
    bodies A (pairs.side) and B: A's point z (pairs.ref, in A's frame) has moved by delta in B's frame and A has
    turned by theta relative to B, so any point P of A has moved by at most delta + theta |P - z| in B's frame.
    At the look P was at least d from B, and at least |P - z| - K (K = |z - x_B| + B's reach), so the worst point
    is at |P - z| = K + d, and none has come within the margin while delta + theta (K + d) < d - margin
    (lever = K + d, clear = d - margin: set by the collision stage; clear 0: no clearance)."""
    if pairs.clear[p] <= 0.0:
        return False
    A, B = (pairs.a[p], pairs.b[p]) if pairs.side[p] == 0 else (pairs.b[p], pairs.a[p])
    # z in B's frame: R_B^T (x_A + R_A ref - x_B)
    z = rotate(R, A, (pairs.ref[p, 0], pairs.ref[p, 1], pairs.ref[p, 2]))
    z_B = rotate_t(R, B, (y[A, 0] + z[0] - y[B, 0], y[A, 1] + z[1] - y[B, 1], y[A, 2] + z[2] - y[B, 2]))
    delta = norm3(sub3(z_B, (pairs.seen[p, 0], pairs.seen[p, 1], pairs.seen[p, 2])))
    # theta = 2 acos(cos(theta / 2)) (the same angle for A turning relative to B and B relative to A)
    theta = 2.0 * math.acos(min(1.0, relative_cos_half(pairs, p, y)))
    return delta + theta * pairs.lever[p] < pairs.clear[p]


@kernel
def relative_cos_half(pairs, p, y):
    """cos(angle / 2) of the turn of pair p's bodies relative to each other since pairs.relative was set:
    |q_rel . q_rel0| for q_rel = conj(q_b) q_a."""
    a, b = pairs.a[p], pairs.b[p]
    qa = (y[a, 3], y[a, 4], y[a, 5], y[a, 6])
    qb = (y[b, 3], -y[b, 4], -y[b, 5], -y[b, 6])
    w = qb[0] * qa[0] - qb[1] * qa[1] - qb[2] * qa[2] - qb[3] * qa[3]
    x = qb[0] * qa[1] + qb[1] * qa[0] + qb[2] * qa[3] - qb[3] * qa[2]
    yy = qb[0] * qa[2] - qb[1] * qa[3] + qb[2] * qa[0] + qb[3] * qa[1]
    z = qb[0] * qa[3] + qb[1] * qa[2] - qb[2] * qa[1] + qb[3] * qa[0]
    return abs(w * pairs.relative[p, 0] + x * pairs.relative[p, 1] + yy * pairs.relative[p, 2]
               + z * pairs.relative[p, 3])


@kernel
def turned_pair(pairs, y):
    """The first pair in contact (pairs.state 1) whose relative orientation turned by more than pairs.turn (rad)
    since its contacts were found (a box that tips may bring other corners down), or -1."""
    for p in range(len(pairs.a)):
        if pairs.state[p] != 1:
            continue
        if relative_cos_half(pairs, p, y) < math.cos(0.5 * pairs.turn[p]):
            return p
    return -1


@kernel
def look_after_step(m, act, s, y):
    """(code, which) after a step from s.start to y, forces in s.lam: a change of the contact set that the
    collision stage must see (which: the contact instance, or the pair for NEAR), or (0, -1). A sliding contact
    whose slip a stage of the step saw turned back (s.counters) stopped within the step."""
    code, which = contact_change(act, m.constraints, s.param, y, s.R, s.lam, act.local)
    if code != 0:
        return code, which
    if s.counters[COUNTER_TURNED_BACK] > 0:  # a slip that stopped and turned back within the step
        return STOPS, s.counters[COUNTER_TURNED_BACK] - 1
    rotations(s.start, s.R0)
    which = anything_near(m.shapes, m.pairs, y, s.R, s.start, s.R0, m.margin)
    if which < 0:
        which = turned_pair(m.pairs, y)
    if which >= 0:
        return NEAR, which
    return 0, -1
