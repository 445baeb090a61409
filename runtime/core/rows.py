"""Constraint rows, compiled: C, J, ct and bias of every family (docs/design/physics.md section 3).

Conventions (constraints/layout.py): a row touches the bodies of its two slots; its Jacobian block per slot acts
on (v, w), w the world angular velocity, r = R p the world arm of a body point p;

    dC/dt   = J v + ct          (ct: explicit time derivative, e.g. -dP/dt of a moving nail)
    d2C/dt2 = J a + bias        (bias: d2C/dt2 at zero linear and angular accelerations)

so the solver enforces J a = -bias - (stabilization). Velocity-only rows (gears, ropes) have C = 0, ct = 0 and
bias = 0 (their J does not change with the state along the motion they constrain). A WORLD slot (-1) reads the
world row of the padded state (identity pose, at rest) and gets a zero block. World-frame parameters that move
(a nail's target, a plane's origin and normal, an orientation's world axis) carry their first and second time
derivatives in the parameter row, written by the drivers before each evaluation.

`instance_rows` writes the rows of one instance at its first row; `write_rows` evaluates a list of instances.
The slow, obvious oracle is tests/runtime/rows_reference.py.
"""
from __future__ import annotations

from . import model as M
from .contact import contact_rows
from .jit import inlined, kernel
from .vec import add3, centripetal, cross3, dot3, quat_conj, quat_mul, rotate, rotate_t, row3, scale3, sub3


@kernel
def _set_block(J, row, slot, lin, ang):
    J[row, slot, 0], J[row, slot, 1], J[row, slot, 2] = lin[0], lin[1], lin[2]
    J[row, slot, 3], J[row, slot, 4], J[row, slot, 5] = ang[0], ang[1], ang[2]


@kernel
def _state(y, i):
    """(x, v, w) of body i of the padded state y (n+1, 13) as 3-tuples."""
    return (y[i, 0], y[i, 1], y[i, 2]), (y[i, 7], y[i, 8], y[i, 9]), (y[i, 10], y[i, 11], y[i, 12])


@kernel
def _point_rows(row, a, b, r_a, r_b, y, C, J, ct, bias, target, target_rate, target_accel):
    """Three world-axis rows of x_a + r_a - x_b - r_b - target (a ball joint, or a nail with b the world)."""
    x_a, v_a, w_a = _state(y, a)
    x_b, v_b, w_b = _state(y, b)
    # C = x_a + R_a p_a - x_b - R_b p_b - P(t)
    gap = sub3(sub3(add3(x_a, r_a), add3(x_b, r_b)), target)
    # bias = w_a x (w_a x r_a) - w_b x (w_b x r_b) - d2P/dt2
    spin = sub3(sub3(centripetal(w_a, r_a), centripetal(w_b, r_b)), target_accel)
    live_b = 1.0 if b >= 0 else 0.0
    for c in range(3):
        e = (1.0 if c == 0 else 0.0, 1.0 if c == 1 else 0.0, 1.0 if c == 2 else 0.0)
        # dC_c/dt = e_c . (v_a + w_a x r_a - v_b - w_b x r_b) - dP_c/dt:
        #   J_a = [e_c, r_a x e_c], J_b = -[e_c, r_b x e_c], ct = -dP_c/dt
        _set_block(J, row + c, 0, e, cross3(r_a, e))
        _set_block(J, row + c, 1, scale3(-live_b, e), scale3(-live_b, cross3(r_b, e)))
        C[row + c] = gap[c]
        ct[row + c] = -target_rate[c]
        bias[row + c] = spin[c]


@kernel
def _orientation_row(row, a, b, param, k, y, R, C, J, ct, bias):
    """T = R_a axis_a kept perpendicular to N = R_b axis_b (or a world axis N(t) for b = WORLD)."""
    _, _, w_a = _state(y, a)
    _, _, w_b = _state(y, b)
    T = rotate(R, a, row3(param, k, M.ORIENT_AXIS_A))
    N = rotate(R, b, row3(param, k, M.ORIENT_AXIS_B))
    N_t, N_tt = row3(param, k, M.ORIENT_AXIS_B_RATE), row3(param, k, M.ORIENT_AXIS_B_ACCEL)
    # C = T . N
    C[row] = dot3(T, N)
    # dC/dt = (w_a x T) . N + T . (w_b x N + N_t) = w_a . (T x N) + w_b . (N x T) + T . N_t
    TxN = cross3(T, N)
    _set_block(J, row, 0, (0.0, 0.0, 0.0), TxN)
    _set_block(J, row, 1, (0.0, 0.0, 0.0), scale3(-1.0 if b >= 0 else 0.0, TxN))
    ct[row] = dot3(T, N_t)
    # bias = Tdd . N + 2 Td . Nd + T . Ndd, with Td = w_a x T, Tdd = w_a x (w_a x T), Nd = w_b x N + N_t,
    #   Ndd = w_b x (w_b x N) + N_tt  (at zero angular accelerations; N_t, N_tt only for a world axis)
    T_d, N_d = cross3(w_a, T), add3(cross3(w_b, N), N_t)
    bias[row] = dot3(centripetal(w_a, T), N) + 2.0 * dot3(T_d, N_d) + dot3(T, add3(centripetal(w_b, N), N_tt))


@kernel
def _plane_row(row, a, b, param, k, y, R, C, J, ct, bias):
    """P = x_a + R_a p on the plane through S = x_b + R_b s with normal N = R_b n (S(t), N(t) for the world)."""
    x_a, v_a, w_a = _state(y, a)
    x_b, v_b, w_b = _state(y, b)
    r_a = rotate(R, a, row3(param, k, M.PLANE_POINT))
    r_s = rotate(R, b, row3(param, k, M.PLANE_ORIGIN))
    N = rotate(R, b, row3(param, k, M.PLANE_NORMAL))
    S_t, S_tt = row3(param, k, M.PLANE_ORIGIN_RATE), row3(param, k, M.PLANE_ORIGIN_ACCEL)
    N_t, N_tt = row3(param, k, M.PLANE_NORMAL_RATE), row3(param, k, M.PLANE_NORMAL_ACCEL)
    P = add3(x_a, r_a)
    d = sub3(P, add3(x_b, r_s))
    # C = N . (P - S)
    C[row] = dot3(N, d)
    # dC/dt = Nd . d + N . dd, Nd = w_b x N + N_t, dd = v_a + w_a x r_a - v_b - w_b x r_s - S_t; collecting w_b:
    #   J_a = [N, r_a x N], J_b = [-N, -(P - x_b) x N], ct = N_t . d - N . S_t
    _set_block(J, row, 0, N, cross3(r_a, N))
    live_b = 1.0 if b >= 0 else 0.0
    _set_block(J, row, 1, scale3(-live_b, N), scale3(-live_b, cross3(sub3(P, x_b), N)))
    ct[row] = dot3(N_t, d) - dot3(N, S_t)
    # bias = Ndd . d + 2 Nd . dd + N . ddd at zero accelerations:
    #   Ndd = w_b x (w_b x N) + N_tt, ddd = w_a x (w_a x r_a) - w_b x (w_b x r_s) - S_tt
    N_d = add3(cross3(w_b, N), N_t)
    d_d = sub3(sub3(add3(v_a, cross3(w_a, r_a)), add3(v_b, cross3(w_b, r_s))), S_t)
    d_dd = sub3(sub3(centripetal(w_a, r_a), centripetal(w_b, r_s)), S_tt)
    bias[row] = dot3(add3(centripetal(w_b, N), N_tt), d) + 2.0 * dot3(N_d, d_d) + dot3(N, d_dd)


@kernel
def _gear_row(row, a, b, param, k, y, R, C, J, ct, bias):
    """Velocity row r_a (w_a . A_a) + r_b (w_b . A_b) = 0, A = R axis: J_a = [0, r_a A_a], J_b = [0, r_b A_b];
    bias = d/dt(J) v = r_a' (w_a . A_a) + r_b' (w_b . A_b) (the radii may be functions of time; the axes'
    own turning gives r w . (w x A) = 0 identically)."""
    _, _, w_a = _state(y, a)
    _, _, w_b = _state(y, b)
    A_a = rotate(R, a, row3(param, k, M.GEAR_AXIS_A))
    A_b = rotate(R, b, row3(param, k, M.GEAR_AXIS_B))
    zero = (0.0, 0.0, 0.0)
    live_b = 1.0 if b >= 0 else 0.0
    _set_block(J, row, 0, zero, scale3(param[k, M.GEAR_RADIUS_A], A_a))
    _set_block(J, row, 1, zero, scale3(param[k, M.GEAR_RADIUS_B] * live_b, A_b))
    C[row], ct[row] = 0.0, 0.0
    bias[row] = param[k, M.GEAR_RADIUS_A_RATE] * dot3(w_a, A_a) + live_b * param[k, M.GEAR_RADIUS_B_RATE] * dot3(w_b, A_b)


@kernel
def _rope_row(row, a, b, param, k, C, J, ct, bias):
    """Velocity row (w_gear x arm) . d - v_weight . d = 0 (arm, d fixed in the world):
    J_gear = [0, arm x d], J_weight = [-d, 0]; bias = 0 (J is constant)."""
    arm, d = row3(param, k, M.ROPE_ARM), row3(param, k, M.ROPE_DIRECTION)
    zero = (0.0, 0.0, 0.0)
    _set_block(J, row, 0, zero, cross3(arm, d))
    _set_block(J, row, 1, scale3(-1.0 if b >= 0 else 0.0, d), zero)
    C[row], ct[row], bias[row] = 0.0, 0.0, 0.0


@kernel
def _element_translation_row(row, a, b, param, k, y, R, C, J, ct, bias):
    """C = e . (x_a - x_b) - offset, e = R_b axis (the world axis for b = WORLD)."""
    x_a, v_a, _ = _state(y, a)
    x_b, v_b, w_b = _state(y, b)
    e = rotate(R, b, row3(param, k, M.ELEMENT_AXIS))
    dx, dv = sub3(x_a, x_b), sub3(v_a, v_b)
    C[row] = dot3(e, dx) - param[k, M.ELEMENT_OFFSET]
    # dC/dt = (w_b x e) . dx + e . dv  =>  J_a = [e, 0], J_b = [-e, e x dx]
    live_b = 1.0 if b >= 0 else 0.0
    _set_block(J, row, 0, e, (0.0, 0.0, 0.0))
    _set_block(J, row, 1, scale3(-live_b, e), scale3(live_b, cross3(e, dx)))
    ct[row] = 0.0
    # bias = (w_b x (w_b x e)) . dx + 2 (w_b x e) . dv
    bias[row] = dot3(centripetal(w_b, e), dx) + 2.0 * dot3(cross3(w_b, e), dv)


@kernel
def _element_rotation_row(row, a, b, param, k, y, R, C, J, ct, bias):
    """C = 2 vec(q_err) . axis, q_err = conj(q_b) q_a conj(q_ref) = (s, u): a's small rotation relative to b
    since the start, about the axis (in b's frame)."""
    q_a = (y[a, 3], y[a, 4], y[a, 5], y[a, 6])
    q_b = (y[b, 3], y[b, 4], y[b, 5], y[b, 6])
    ref = (param[k, M.ELEMENT_REFERENCE], param[k, M.ELEMENT_REFERENCE + 1], param[k, M.ELEMENT_REFERENCE + 2],
           param[k, M.ELEMENT_REFERENCE + 3])
    err = quat_mul(quat_mul(quat_conj(q_b), q_a), quat_conj(ref))
    s, u = err[0], (err[1], err[2], err[3])
    axis = row3(param, k, M.ELEMENT_AXIS)
    C[row] = 2.0 * dot3(u, axis)
    # q_err' = 0.5 (0, om) q_err with om = R_b^T (w_a - w_b): u' = 0.5 (s om + om x u), s' = -0.5 om . u, and
    #   dC/dt = om . g, g = s axis + u x axis  =>  J_a = [0, R_b g], J_b = [0, -R_b g]
    g = add3(scale3(s, axis), cross3(u, axis))
    G = rotate(R, b, g)
    live_b = 1.0 if b >= 0 else 0.0
    _set_block(J, row, 0, (0.0, 0.0, 0.0), G)
    _set_block(J, row, 1, (0.0, 0.0, 0.0), scale3(-live_b, G))
    ct[row] = 0.0
    # bias = om' . g + om . g' at zero angular accelerations: om' = R_b^T (w_a x w_b), g' = s' axis + u' x axis
    _, _, w_a = _state(y, a)
    _, _, w_b = _state(y, b)
    om = rotate_t(R, b, sub3(w_a, w_b))
    om_d = rotate_t(R, b, cross3(w_a, w_b))
    s_d = -0.5 * dot3(om, u)
    u_d = scale3(0.5, add3(scale3(s, om), cross3(om, u)))
    g_d = add3(scale3(s_d, axis), cross3(u_d, axis))
    bias[row] = dot3(om_d, g) + dot3(om, g_d)


@inlined
def instance_rows(k, cons, param, y, R, C, J, ct, bias):
    """Write the rows of constraint instance k (at its first row) for the padded state y (n+1,13) and rotation
    matrices R (n+1,3,3); param (K, PARAMS) is the parameter table with the drivers' values applied. (Inlined:
    passed as a call's arguments, the constraints' arrays cost 40 % of a 10-link chain's evaluation.)"""
    family, row = cons.family[k], cons.first_row[k]
    a, b = cons.body[k, 0], cons.body[k, 1]
    if family == M.NAIL:
        r = rotate(R, a, row3(param, k, M.NAIL_POINT))
        _point_rows(row, a, b, r, (0.0, 0.0, 0.0), y, C, J, ct, bias, row3(param, k, M.NAIL_TARGET),
                    row3(param, k, M.NAIL_TARGET_RATE), row3(param, k, M.NAIL_TARGET_ACCEL))
    elif family == M.POINT:
        # (for a WORLD b, R_b = I and x_b = 0: r_b is the world point point_b)
        r_a = rotate(R, a, row3(param, k, M.POINT_A))
        r_b = rotate(R, b, row3(param, k, M.POINT_B))
        zero = (0.0, 0.0, 0.0)
        _point_rows(row, a, b, r_a, r_b, y, C, J, ct, bias, zero, zero, zero)
    elif family == M.ORIENT:
        _orientation_row(row, a, b, param, k, y, R, C, J, ct, bias)
    elif family == M.PLANE:
        _plane_row(row, a, b, param, k, y, R, C, J, ct, bias)
    elif family == M.GEAR:
        _gear_row(row, a, b, param, k, y, R, C, J, ct, bias)
    elif family == M.ROPE:
        _rope_row(row, a, b, param, k, C, J, ct, bias)
    elif family == M.CONTACT or family == M.CONTACT_SPHERES:
        contact_rows(k, cons, param, y, R, C, J, ct, bias)
    elif param[k, M.ELEMENT_ROTATIONAL] != 0.0:
        _element_rotation_row(row, a, b, param, k, y, R, C, J, ct, bias)
    else:
        _element_translation_row(row, a, b, param, k, y, R, C, J, ct, bias)


@kernel
def apply_drivers(cons, param, table, j):
    """param[instance, slot:slot+size] <- table[j, column:column+size] for every driver (moving parameters)."""
    for d in range(len(cons.driver_instance)):
        k, slot, column = cons.driver_instance[d], cons.driver_slot[d], cons.driver_column[d]
        for c in range(cons.driver_size[d]):
            param[k, slot + c] = table[j, column + c]


@kernel
def write_rows(instances, cons, param, y, R, C, J, ct, bias):
    """The rows of every instance listed in `instances` (k,)."""
    for i in range(len(instances)):
        instance_rows(instances[i], cons, param, y, R, C, J, ct, bias)


@inlined
def evaluate_rows(m, act, s, y, table, j):
    """C, J, ct, bias of the active instances at state y and grid row j (s.R current)."""
    apply_drivers(m.constraints, s.param, table, j)
    write_rows(act.instances, m.constraints, s.param, y, s.R, s.C, s.J, s.ct, s.bias)


@kernel
def row_motion(cons, r, y, motion, J, offset):
    """J_r . (the slot bodies' rows of `motion`, columns offset..offset+6): J v with motion = y (offset 7), J a
    with motion = the accelerations (offset 0). The world row of `motion` is zero."""
    k = cons.row_instance[r]
    total = 0.0
    for s in range(2):
        b = cons.body[k, s]
        if b < 0:
            continue
        for c in range(6):
            total += J[r, s, c] * motion[b, offset + c]
    return total
