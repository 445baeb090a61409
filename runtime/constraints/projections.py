"""Position-level projections of every constraint family: the constraint stage of the procedural (XPBD) plan.

Each `project_<family>(fam, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *, x_prev, q_prev)`
moves the bodies of the instances `idx` of one family so that their constraints hold again, mass-weighted,
updating x (n,3) and q (n,4) in place and accumulating the XPBD multipliers in lam ((k,3) for point families,
(k,) otherwise; compliance (k,)). The instances of idx must share no dynamic body (one colour of
`colour_instances`): a kernel is vectorized over them, and Gauss-Seidel runs across colours.

XPBD (Mueller et al. 2020). A row C(x, q) has gradient blocks per body slot s in {a, b}: linear l_s
(dC = l_s . dx_s) and angular g_s (dC = g_s . dphi_s for a small world rotation, q_s += 0.5 (0, dphi_s) q_s).
With alpha~ = alpha / h^2 (h the substep) and d_s = (ld_s, gd_s) the direction the correction is applied along:

    dlam   = (-C - alpha~ lam) / (sum_s  l_s . ld_s / m_s + g_s^T I_s^-1 gd_s  + alpha~)
    dx_s   = dlam ld_s / m_s          dphi_s = dlam I_s^-1 gd_s          lam += dlam

For a point constraint along unit n at arms r: l = n, g = r x n, and with d = (l, g) the denominator is the
generalized inverse mass w = 1/m + (r x n)^T I^-1 (r x n) of each body.

Direction (a decision): Mueller et al. take d = the gradient at the current iterate, which damps (a 60 degree
pendulum at h = 1/60 with 20 substeps loses 0.4 % of its period per swing). Given x_prev, q_prev (the pose at
the start of the substep), we take d = the gradient there, as SHAKE does (Ryckaert, Ciccotti, Berendsen 1977):
the constraint force acts along the constraint normal of the start of the step, which makes the substep a
symplectic Verlet step for point masses and planar bodies, so energy does not drift and the pendulum's period
is kept to 1e-5. Where the two gradients disagree (a body turned by more than about 60 degrees within one
substep) the current gradient is used. Gear families are on increments, and use the current gradient.
WORLD (-1) slots and bodies with zero inverse mass (static, kinematic) take part with w = 0 and never move.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .layout import WORLD, Element, GearToGear, GearToWeight, Orientation, PointOnPlane, PointToNail, PointToPoint

# |T x N| below this: T is (anti)parallel to N and the correction axis is taken perpendicular to T instead
PARALLEL_EPS = 1e-12
# use the start-of-substep direction only while its effective mass is at least this fraction of the current one
MIN_DIRECTION_ALIGNMENT = 0.5

# ---------------------------------------------------------------- small fast kernels on (k,3) stacks
# (numpy's cross and moveaxis cost ~15 us per call at k ~ 10; these are a few us)

_EYE = np.eye(3)
_IDENTITY_Q = np.array([1.0, 0.0, 0.0, 0.0])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])
_SKEW = np.zeros((3, 9))  # skew(v).reshape(9) = v @ _SKEW, [v]x = [[0,-z,y],[z,0,-x],[-y,x,0]]
_SKEW[2, 1], _SKEW[1, 2], _SKEW[2, 3], _SKEW[0, 5], _SKEW[1, 6], _SKEW[0, 7] = -1, 1, 1, -1, -1, 1
_P1, _P2 = np.array([1, 2, 0]), np.array([2, 0, 1])


def skew(v):
    """[v]x (k,3,3)."""
    return (v @ _SKEW).reshape(-1, 3, 3)


def cross(a, b):
    """a x b for (k,3) stacks."""
    return a.take(_P1, axis=1) * b.take(_P2, axis=1) - a.take(_P2, axis=1) * b.take(_P1, axis=1)


def dot(a, b):
    return (a * b).sum(axis=1)


def matvec(M, v):
    return (M @ v[:, :, None])[:, :, 0]


def rotation_matrix(q):
    """R (k,3,3) of unit quaternions (k,4): R = I + 2 w [v]x + 2 [v]x^2."""
    S = skew(q[:, 1:])
    return _EYE + 2.0 * (q[:, :1, None] * S + S @ S)


def quat_mul(p, q):
    """Hamilton product of (k,4) stacks: (p0 q0 - pv . qv, p0 qv + q0 pv + pv x qv)."""
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[:, 0] = p[:, 0] * q[:, 0] - dot(p[:, 1:], q[:, 1:])
    out[:, 1:] = p[:, :1] * q[:, 1:] + q[:, :1] * p[:, 1:] + cross(p[:, 1:], q[:, 1:])
    return out


def quat_conj(q):
    return q * _CONJ


def turn_since(q, q_prev):
    """(s (k,), v (k,3)) of dq = q q_prev^-1, sign fixed to s >= 0: the turn a body made since q_prev."""
    dq = quat_mul(q, quat_conj(q_prev))
    dq *= np.where(dq[:, :1] < 0.0, -1.0, 1.0)
    return dq[:, 0], dq[:, 1:]


# ---------------------------------------------------------------- body slots: gather, apply, solve


@dataclass
class Slot:
    """One body slot of k instances, gathered from the state (WORLD: identity pose, no mobility).

    index (k,) body index (WORLD kept); moves (k,) bool; x (k,3); q (k,4); R (k,3,3);
    inv_m (k,) inverse mass and inv_I (k,3,3) world inverse inertia R I_b^-1 R^T (zero unless moves;
    None for a pose-only slot).
    """

    index: np.ndarray
    moves: np.ndarray | None
    x: np.ndarray
    q: np.ndarray
    R: np.ndarray
    inv_m: np.ndarray | None = None
    inv_I: np.ndarray | None = None


def gather(body, x, q, inv_mass=None, inv_inertia_body=None) -> Slot:
    """Slot of bodies `body` (k,), which may hold WORLD; pose only when inv_mass is None."""
    real = body != WORLD
    if real.all():
        safe, xs, qs = body, x[body], q[body]
    else:
        safe = np.where(real, body, 0)
        xs = np.where(real[:, None], x[safe], 0.0)
        qs = np.where(real[:, None], q[safe], _IDENTITY_Q)
    R = rotation_matrix(qs)
    if inv_mass is None:
        return Slot(body, None, xs, qs, R)
    inv_m = np.where(real, inv_mass[safe], 0.0)
    moves = inv_m > 0.0
    inv_I = R @ inv_inertia_body[safe] @ np.swapaxes(R, 1, 2)
    if not moves.all():
        inv_m = np.where(moves, inv_m, 0.0)
        inv_I = np.where(moves[:, None, None], inv_I, 0.0)
    return Slot(body, moves, xs, qs, R, inv_m, inv_I)


def apply(slot: Slot, dx, dphi, x, q) -> None:
    """x += dx, q += 0.5 (0, dphi) q (renormalized), for the moving bodies of the slot."""
    qs = slot.q
    dq = np.empty_like(qs)
    dq[:, 0] = -0.5 * dot(dphi, qs[:, 1:])
    dq[:, 1:] = 0.5 * (qs[:, :1] * dphi + cross(dphi, qs[:, 1:]))
    qs = qs + dq
    qs /= np.sqrt((qs * qs).sum(axis=1))[:, None]
    m = slot.moves
    if m.all():
        x[slot.index] = slot.x + dx
        q[slot.index] = qs
    else:
        x[slot.index[m]] = (slot.x + dx)[m]
        q[slot.index[m]] = qs[m]


def solve_rows(a: Slot, b: Slot, grad, direction, C, alpha_t, lam, x, q) -> None:
    """One XPBD update of k scalar rows (module docstring). grad = direction = (la, ga, lb, gb), (k,3) each;
    direction None: along grad. lam (k,) is updated in place."""
    la, ga, lb, gb = grad
    Ia, Ib = matvec(a.inv_I, ga), matvec(b.inv_I, gb)
    # w = sum_s l_s . l_s / m_s + g_s^T I_s^-1 g_s: the generalized inverse mass of the row
    w = a.inv_m * dot(la, la) + dot(ga, Ia) + b.inv_m * dot(lb, lb) + dot(gb, Ib)
    if direction is not None:
        da, dga, db, dgb = direction
        Ida, Idb = matvec(a.inv_I, dga), matvec(b.inv_I, dgb)
        wd = a.inv_m * dot(la, da) + dot(ga, Ida) + b.inv_m * dot(lb, db) + dot(gb, Idb)
        ok = (wd > MIN_DIRECTION_ALIGNMENT * w)[:, None]
        w = np.where(ok[:, 0], wd, w)
        la, Ia, lb, Ib = np.where(ok, da, la), np.where(ok, Ida, Ia), np.where(ok, db, lb), np.where(ok, Idb, Ib)
    denom = w + alpha_t
    # dlam = (-C - alpha~ lam) / (w + alpha~); rows no body can satisfy (w = 0, rigid) are left alone
    dlam = np.divide(-C - alpha_t * lam, denom, out=np.zeros_like(C), where=denom > 0.0)
    lam += dlam
    apply(a, (dlam * a.inv_m)[:, None] * la, dlam[:, None] * Ia, x, q)
    apply(b, (dlam * b.inv_m)[:, None] * lb, dlam[:, None] * Ib, x, q)


def solve_point(a: Slot, b: Slot, ra, rb, da, db, C, alpha_t, lam, keep, x, q) -> None:
    """XPBD block update of a 3-row point constraint C = P_a - P_b (k,3): arms ra, rb now, da, db at the start
    of the substep (the impulse's lever arms; ra, rb for none).

    An impulse p (+p on a, -p on b) applied at arms d moves C by K p, K = sum_s (I3 / m_s - [r_s]x I_s^-1 [d_s]x)
    (with d = r, the 3-D generalized inverse mass: n^T K n = sum_s 1/m_s + (r_s x n)^T I_s^-1 (r_s x n)).
    Solve (K + alpha~ I) dlam = -C - alpha~ lam on the kept rows only (keep (k,3)), so a subtracted row stays free.
    """
    # use the start-of-substep arm only while it is within ~60 degrees of the current one
    da = np.where((dot(da, ra) >= MIN_DIRECTION_ALIGNMENT * dot(ra, ra))[:, None], da, ra)
    db = np.where((dot(db, rb) >= MIN_DIRECTION_ALIGNMENT * dot(rb, rb))[:, None], db, rb)
    Da, Db = skew(da), skew(db)
    K = (a.inv_m + b.inv_m)[:, None, None] * _EYE - skew(ra) @ a.inv_I @ Da - skew(rb) @ b.inv_I @ Db
    active = keep & (np.einsum("kii->ki", K) > 0.0)  # rows neither body can move are left alone
    if active.all():
        K = K + alpha_t[:, None, None] * _EYE
        rhs = -C - alpha_t[:, None] * lam
    else:
        both = active[:, :, None] & active[:, None, :]
        K = np.where(both, K + alpha_t[:, None, None] * _EYE, 0.0) + (~active)[:, :, None] * _EYE
        rhs = np.where(active, -C - alpha_t[:, None] * lam, 0.0)
    dlam = np.linalg.solve(K, rhs[:, :, None])[:, :, 0]
    lam += dlam
    # dphi_s = I_s^-1 (d_s x p) = -I_s^-1 [p]x d_s
    apply(a, a.inv_m[:, None] * dlam, -matvec(a.inv_I, matvec(skew(dlam), da)), x, q)
    apply(b, -b.inv_m[:, None] * dlam, matvec(b.inv_I, matvec(skew(dlam), db)), x, q)


def _alpha(compliance, idx, h):
    return np.asarray(compliance, dtype=float)[idx] / (h * h)


def _keep(keep, idx):
    return np.ones((len(idx), 3), dtype=bool) if keep is None else np.asarray(keep, dtype=bool)[idx]


def _project_rows(rows, fam, idx, body_a, body_b, x, q, inv_mass, inv_inertia_body, compliance, h, lam,
                  x_prev, q_prev):
    """Shared driver of the 1-row families: rows(fam, idx, a, b) -> (C, (la, ga, lb, gb)) on a pose pair."""
    a = gather(body_a, x, q, inv_mass, inv_inertia_body)
    b = gather(body_b, x, q, inv_mass, inv_inertia_body)
    C, grad = rows(fam, idx, a, b)
    direction = None
    if x_prev is not None:
        direction = rows(fam, idx, gather(body_a, x_prev, q_prev), gather(body_b, x_prev, q_prev))[1]
    lam_k = lam[idx]
    solve_rows(a, b, grad, direction, C, _alpha(compliance, idx, h), lam_k, x, q)
    lam[idx] = lam_k


# ---------------------------------------------------------------- the families


def project_point_to_point(fam: PointToPoint, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           x_prev=None, q_prev=None, keep=None):
    """Ball joint, C = x_a + R_a p_a - x_b - R_b p_b (3 rows, lam (k,3)); keep (k,3) masks subtracted rows."""
    body_a, body_b = fam.body_a[idx], fam.body_b[idx]
    a = gather(body_a, x, q, inv_mass, inv_inertia_body)
    b = gather(body_b, x, q, inv_mass, inv_inertia_body)
    pa, pb = fam.point_a[idx], fam.point_b[idx]
    ra, rb = matvec(a.R, pa), matvec(b.R, pb)
    da, db = ra, rb
    if q_prev is not None:
        da, db = matvec(gather(body_a, x_prev, q_prev).R, pa), matvec(gather(body_b, x_prev, q_prev).R, pb)
    lam_k = lam[idx]
    solve_point(a, b, ra, rb, da, db, a.x + ra - b.x - rb, _alpha(compliance, idx, h), lam_k, _keep(keep, idx), x, q)
    lam[idx] = lam_k


def project_point_to_nail(fam: PointToNail, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                          x_prev=None, q_prev=None, keep=None):
    """Body point at the world point P (fam.target, refreshed by the caller when it moves): C = x + R p - P."""
    body = fam.body[idx]
    a = gather(body, x, q, inv_mass, inv_inertia_body)
    b = gather(np.full(len(body), WORLD), x, q, inv_mass, inv_inertia_body)
    ra = matvec(a.R, fam.point[idx])
    da = ra if q_prev is None else matvec(gather(body, x_prev, q_prev).R, fam.point[idx])
    zero = np.zeros_like(ra)
    lam_k = lam[idx]
    solve_point(a, b, ra, zero, da, zero, a.x + ra - fam.target[idx], _alpha(compliance, idx, h), lam_k,
                _keep(keep, idx), x, q)
    lam[idx] = lam_k


def _orientation_rows(fam, idx, a, b):
    # T . N = 0 as the angle from perpendicular, theta = asin(T . N), about n = unit(T x N): turning a by dphi
    # about n turns T toward N at unit rate, b the other way: g_a = n, g_b = -n.
    T, N = matvec(a.R, fam.axis_a[idx]), matvec(b.R, fam.axis_b[idx])
    n = cross(T, N)
    size = np.sqrt(dot(n, n))
    if not (size > PARALLEL_EPS).all():  # T parallel to N: turn T about T x (the world axis least along T)
        fallback = cross(T, _EYE[np.argmin(np.abs(T), axis=1)])
        n = np.where((size > PARALLEL_EPS)[:, None], n, fallback)
        size = np.sqrt(dot(n, n))
    n = n / size[:, None]
    zero = np.zeros_like(n)
    return np.arcsin(np.clip(dot(T, N), -1.0, 1.0)), (zero, n, zero, -n)


def project_orientation(fam: Orientation, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                        x_prev=None, q_prev=None):
    """Body-fixed T of a kept perpendicular to N (world or fixed in b): C = T . N, solved as asin(T . N)."""
    _project_rows(_orientation_rows, fam, idx, fam.body_a[idx], fam.body_b[idx], x, q, inv_mass, inv_inertia_body,
                  compliance, h, lam, x_prev, q_prev)


def _plane_rows(fam, idx, a, b):
    # C = N . (P - S): l_a = N, g_a = (P - x_a) x N; b opposite with arm P - x_b (the plane turning about x_b)
    P = a.x + matvec(a.R, fam.point_a[idx])
    S = b.x + matvec(b.R, fam.plane_point[idx])
    N = matvec(b.R, fam.plane_normal[idx])
    return dot(N, P - S), (N, cross(P - a.x, N), -N, -cross(P - b.x, N))


def project_point_on_plane(fam: PointOnPlane, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           x_prev=None, q_prev=None):
    """Body point P of a on the plane through S with normal N (world or fixed in b): C = N . (P - S)."""
    _project_rows(_plane_rows, fam, idx, fam.body_a[idx], fam.body_b[idx], x, q, inv_mass, inv_inertia_body,
                  compliance, h, lam, x_prev, q_prev)


def _element_translation_rows(fam, idx, a, b):
    # C = e . (x_a - x_b) - offset, e = R_b axis: l_a = e, g_a = 0, l_b = -e, g_b = -((x_a - x_b) x e)
    e = matvec(b.R, fam.axis[idx])
    d = a.x - b.x
    return dot(e, d) - fam.offset[idx], (e, np.zeros_like(e), -e, -cross(d, e))


def _element_rotation_rows(fam, idx, a, b):
    # q_err = conj(q_b) q_a conj(ref) = (s, v), s >= 0; C = 2 v . axis (axis in b's frame). q_a += 0.5 (0, dphi) q_a
    # moves q_err by 0.5 (0, R_b^T dphi) q_err, so dC = dphi . R_b (s axis + v x axis) (exact): g_a = that, g_b = -g_a.
    err = quat_mul(quat_mul(quat_conj(b.q), a.q), quat_conj(fam.reference_rotation[idx]))
    err *= np.where(err[:, :1] < 0.0, -1.0, 1.0)
    s, v, axis = err[:, :1], err[:, 1:], fam.axis[idx]
    g = matvec(b.R, s * axis + cross(v, axis))
    zero = np.zeros_like(g)
    return 2.0 * dot(v, axis), (zero, g, zero, -g)


def project_element(fam: Element, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                    x_prev=None, q_prev=None):
    """Element rows: fix translation along / rotation about an axis (world or b's frame); translational and
    rotational instances of idx are projected as two vectorized groups, translations first."""
    idx = np.asarray(idx)
    rot = fam.rotational[idx]
    for group, rows in ((idx[~rot], _element_translation_rows), (idx[rot], _element_rotation_rows)):
        if len(group):
            _project_rows(rows, fam, group, fam.body_a[group], fam.body_b[group], x, q, inv_mass, inv_inertia_body,
                          compliance, h, lam, x_prev, q_prev)


def _gear_rows(fam, idx, a, b, q_prev):
    # C = r_a dtheta_a + r_b dtheta_b, dtheta = 2 vec(dq) . A, dq = q q_prev^-1 = (s, v), A = R axis.
    # q += 0.5 (0, dphi) q moves v by 0.5 (s dphi + dphi x v) and A by dphi x A: dC = dphi . r (s A + A x v).
    sa, va = turn_since(a.q, _prev_orientation(a, q_prev))
    sb, vb = turn_since(b.q, _prev_orientation(b, q_prev))
    Aa, Ab = matvec(a.R, fam.axis_a[idx]), matvec(b.R, fam.axis_b[idx])
    ra, rb = fam.radius_a[idx][:, None], fam.radius_b[idx][:, None]
    C = 2.0 * dot(ra * va, Aa) + 2.0 * dot(rb * vb, Ab)
    zero = np.zeros_like(Aa)
    return C, (zero, ra * (sa[:, None] * Aa + cross(Aa, va)), zero, rb * (sb[:, None] * Ab + cross(Ab, vb)))


def _prev_orientation(slot: Slot, q_prev):
    """q_prev of the slot's bodies; the current q (no turn) for WORLD."""
    real = slot.index != WORLD
    return q_prev[slot.index] if real.all() else np.where(real[:, None], q_prev[np.where(real, slot.index, 0)], slot.q)


def project_gear_to_gear(fam: GearToGear, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                         x_prev=None, q_prev):
    """Gears, made positional per substep: r_a dtheta_a + r_b dtheta_b = 0 for the turn made since q_prev.

    dtheta = 2 vec(q q_prev^-1) . A (A the gear's world axis, scalar part of the turn made >= 0) is the very
    quantity the solver turns into angular velocity, w = 2 vec(q q_prev^-1) / h. So once the row holds,
    r_a w_a . A_a + r_b w_b . A_b = 0 at the end of every substep to solver tolerance, exactly, rather than on
    average; and no angle error is carried into the next substep (there is no C(x) to drift, so no stabilization):
    the total turns, sums of per-substep turns that each keep the ratio, keep it too. The gradient is exact
    (see _gear_rows), so a projection lands on the row up to O(dphi^2) renormalization.
    """
    a = gather(fam.body_a[idx], x, q, inv_mass, inv_inertia_body)
    b = gather(fam.body_b[idx], x, q, inv_mass, inv_inertia_body)
    C, grad = _gear_rows(fam, idx, a, b, q_prev)
    lam_k = lam[idx]
    solve_rows(a, b, grad, None, C, _alpha(compliance, idx, h), lam_k, x, q)
    lam[idx] = lam_k


def project_gear_to_weight(fam: GearToWeight, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           x_prev, q_prev):
    """Rope over a gear, per substep: the weight's displacement along the rope equals the rim's travel,
    C = (dtheta x arm) . d - (x_w - x_w_prev) . d, dtheta = 2 vec(q_g q_g_prev^-1) (scalar part >= 0).

    As for gears, the row is on the increments the solver turns into velocities, so rope speed equals rim speed
    at the end of every substep and the rope never creeps. With u = arm x d, C = 2 v . u - dx_w . d, and
    (as in project_gear_to_gear) g_gear = s u + v x u exactly; l_weight = -d.
    """
    g = gather(fam.gear[idx], x, q, inv_mass, inv_inertia_body)
    wt = gather(fam.weight[idx], x, q, inv_mass, inv_inertia_body)
    s, v = turn_since(g.q, _prev_orientation(g, q_prev))
    d = fam.direction[idx]
    u = cross(fam.arm[idx], d)
    real = wt.index != WORLD
    moved = np.where(real[:, None], wt.x - x_prev[np.where(real, wt.index, 0)], 0.0)
    C = 2.0 * dot(v, u) - dot(moved, d)
    zero = np.zeros_like(d)
    lam_k = lam[idx]
    solve_rows(g, wt, (zero, s[:, None] * u + cross(v, u), -d, zero), None, C, _alpha(compliance, idx, h), lam_k,
               x, q)
    lam[idx] = lam_k


# ---------------------------------------------------------------- dispatch and colouring

PROJECTIONS = {
    PointToPoint: project_point_to_point,
    PointToNail: project_point_to_nail,
    Orientation: project_orientation,
    PointOnPlane: project_point_on_plane,
    Element: project_element,
    GearToGear: project_gear_to_gear,
    GearToWeight: project_gear_to_weight,
}


def instance_bodies(fam) -> tuple[np.ndarray, np.ndarray]:
    """The two body slots (k,), (k,) of every instance of a family (WORLD where a slot is unused)."""
    if isinstance(fam, PointToNail):
        return fam.body, np.full(len(fam.body), WORLD, dtype=np.int64)
    if isinstance(fam, GearToWeight):
        return fam.gear, fam.weight
    return fam.body_a, fam.body_b


def lam_shape(fam) -> tuple[int, ...]:
    """Shape of a family's accumulated multipliers: (k, 3) for point constraints, (k,) otherwise."""
    k = len(instance_bodies(fam)[0])
    return (k, 3) if fam.ROWS == 3 else (k,)


def colour_instances(body_a, body_b, dynamic=None) -> list[np.ndarray]:
    """Greedy colouring: instance i gets the lowest colour not yet used by either of its dynamic bodies.

    Returns index arrays, one per colour, each ascending; within a colour no two instances share a dynamic
    body, so a colour can be projected at once. dynamic (n,) bool marks the bodies that move (default: every
    body but WORLD). A chain takes 2 colours; a star around one body as many as it has arms.
    """
    body_a, body_b = np.asarray(body_a).reshape(-1), np.asarray(body_b).reshape(-1)
    used: dict[int, set[int]] = {}
    colour_of = np.empty(len(body_a), dtype=np.int64)
    for i, pair in enumerate(zip(body_a.tolist(), body_b.tolist())):
        mine = [bd for bd in pair if bd != WORLD and (dynamic is None or dynamic[bd])]
        taken = set().union(*(used.get(bd, set()) for bd in mine))
        colour_of[i] = c = next(c for c in range(len(taken) + 1) if c not in taken)
        for bd in mine:
            used.setdefault(bd, set()).add(c)
    return [np.flatnonzero(colour_of == c) for c in range(colour_of.max() + 1)] if len(colour_of) else []
