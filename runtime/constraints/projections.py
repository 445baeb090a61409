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
# (numpy's cross, moveaxis and 2-D fancy indexing cost 2-15 us per call at k ~ 10; these cost 1-3 us)

_EYE = np.eye(3)
_IDENTITY_Q = np.array([1.0, 0.0, 0.0, 0.0])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])
_SKEW = np.zeros((3, 9))  # skew(v).reshape(9) = v @ _SKEW, [v]x = [[0,-z,y],[z,0,-x],[-y,x,0]]
_SKEW[2, 1], _SKEW[1, 2], _SKEW[2, 3], _SKEW[0, 5], _SKEW[1, 6], _SKEW[0, 7] = -1, 1, 1, -1, -1, 1
_P1, _P2 = np.array([1, 2, 0]), np.array([2, 0, 1])


def skew(v):
    """[v]x (k,3,3) with [v]x u = v x u."""
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


def _rows(a, idx):
    return a.take(idx, axis=0)


def _both(a, b):
    return np.concatenate((a, b))


# ---------------------------------------------------------------- the start of the substep, body pairs


@dataclass
class Frame:
    """Every body's pose at the start of the substep, built once per substep, plus one last row for the world
    (identity pose, no mobility), so that WORLD = -1 indexes it.

    x (n+1,3); q (n+1,4); R (n+1,3,3); inv_I (n+1,3,3) world inverse inertia R I_b^-1 R^T, zero for bodies that
    do not move (inverse mass 0).
    """

    x: np.ndarray
    q: np.ndarray
    R: np.ndarray
    inv_I: np.ndarray

    @classmethod
    def empty(cls, n: int) -> "Frame":
        q = np.zeros((n + 1, 4))
        q[:, 0] = 1.0
        return cls(np.zeros((n + 1, 3)), q, np.tile(_EYE, (n + 1, 1, 1)), np.zeros((n + 1, 3, 3)))

    @classmethod
    def of(cls, x, q, inv_mass, inv_inertia_body) -> "Frame":
        """The frame of pose (x, q) for bodies with inverse masses inv_mass (n,), inverse inertias (n,3,3)."""
        frame = cls.empty(len(x))
        moving = np.flatnonzero(np.asarray(inv_mass) > 0.0)
        frame.refresh(x, q, moving, np.asarray(inv_inertia_body)[moving])
        return frame

    def refresh(self, x, q, moving, moving_inv_inertia_body) -> None:
        """Copy the pose (n rows), recompute every R and the I^-1 of the bodies `moving` (a slice or indices,
        with their body inverse inertias (m,3,3)); the others' I^-1 stays 0."""
        n = len(x)
        self.x[:n], self.q[:n] = x, q
        R = rotation_matrix(q)
        self.R[:n] = R
        Rm = R[moving]
        self.inv_I[:n][moving] = Rm @ moving_inv_inertia_body @ Rm.transpose(0, 2, 1)

    def pair(self, index, k) -> "Pair":
        return Pair(k, index, _rows(self.x, index), _rows(self.q, index), _rows(self.R, index))


@dataclass
class Pair:
    """The two body slots of k instances, stacked: rows [0, k) are slot a, rows [k, 2k) slot b, so one numpy
    call serves both. WORLD rows have identity pose and no mobility.

    index (2k,) body index (WORLD kept); x (2k,3); q (2k,4); R (2k,3,3); moves (2k,) bool; inv_m (2k,) inverse
    mass, zero unless the body moves; inv_I (2k,3,3) the world inverse inertia corrections use (the start-of-
    substep one when a Frame is given), zero unless the body moves. A pose-only pair has None there.
    """

    k: int
    index: np.ndarray
    x: np.ndarray
    q: np.ndarray
    R: np.ndarray
    moves: np.ndarray | None = None
    inv_m: np.ndarray | None = None
    inv_I: np.ndarray | None = None


def gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before: Frame | None = None) -> Pair:
    """Pair of slots body_a, body_b (k,) each (WORLD allowed) from the current state."""
    index = _both(body_a, body_b)
    real = index != WORLD
    everywhere = real.all()
    safe = index if everywhere else np.where(real, index, 0)
    xs, qs, inv_m = _rows(x, safe), _rows(q, safe), inv_mass.take(safe)
    if not everywhere:
        xs = np.where(real[:, None], xs, 0.0)
        qs = np.where(real[:, None], qs, _IDENTITY_Q)
        inv_m = np.where(real, inv_m, 0.0)
    moves = inv_m > 0.0
    if not moves.all():
        inv_m = np.where(moves, inv_m, 0.0)
    R = rotation_matrix(qs)
    if before is not None:
        inv_I = _rows(before.inv_I, index)
    else:
        inv_I = R @ _rows(inv_inertia_body, safe) @ R.transpose(0, 2, 1)
        if not moves.all():
            inv_I = np.where(moves[:, None, None], inv_I, 0.0)
    return Pair(len(body_a), index, xs, qs, R, moves, inv_m, inv_I)


def apply(pair: Pair, dx, dphi, x, q) -> None:
    """x += dx, q += 0.5 (0, dphi) q (then renormalized), for the moving bodies of the pair (2k rows each)."""
    qs = pair.q
    dq = np.empty_like(qs)
    dq[:, 0] = -0.5 * dot(dphi, qs[:, 1:])
    dq[:, 1:] = 0.5 * (qs[:, :1] * dphi + cross(dphi, qs[:, 1:]))
    qs = qs + dq
    qs /= np.sqrt(dot(qs, qs))[:, None]
    xs = pair.x + dx
    m = pair.moves
    if m.all():
        x[pair.index], q[pair.index] = xs, qs
    else:
        x[pair.index[m]], q[pair.index[m]] = xs[m], qs[m]


def solve_rows(pair: Pair, l, g, C, alpha_t, lam, x, q, dl=None, dg=None) -> None:
    """One XPBD update of k scalar rows (module docstring): gradients l, g (2k,3), stacked a over b; the
    correction goes along (dl, dg), the gradients at the start of the substep, where given and aligned
    with the current ones. lam (k,) is updated in place."""
    k = pair.k
    Ig = matvec(pair.inv_I, g)
    # w = sum_s l_s . l_s / m_s + g_s^T I_s^-1 g_s: the generalized inverse mass of the row
    ws = pair.inv_m * dot(l, l) + dot(g, Ig)
    w = ws[:k] + ws[k:]
    if dl is not None:
        Idg = matvec(pair.inv_I, dg)
        ws = pair.inv_m * dot(l, dl) + dot(g, Idg)
        wd = ws[:k] + ws[k:]
        ok = wd > MIN_DIRECTION_ALIGNMENT * w
        if ok.all():
            l, Ig, w = dl, Idg, wd
        else:
            ok2 = _both(ok, ok)[:, None]
            l, Ig, w = np.where(ok2, dl, l), np.where(ok2, Idg, Ig), np.where(ok, wd, w)
    denom = w + alpha_t
    # dlam = (-C - alpha~ lam) / (w + alpha~); rows no body can satisfy (w = 0, rigid) are left alone
    dlam = np.divide(-C - alpha_t * lam, denom, out=np.zeros_like(C), where=denom > 0.0)
    lam += dlam
    dlam = _both(dlam, dlam)
    # dx_s = dlam l_s / m_s, dphi_s = dlam I_s^-1 g_s
    apply(pair, (dlam * pair.inv_m)[:, None] * l, dlam[:, None] * Ig, x, q)


def solve_point(pair: Pair, r, C, alpha_t, lam, keep, x, q, d=None) -> None:
    """XPBD block update of a 3-row point constraint C = P_a - P_b (k,3), arms r (2k,3) stacked a over b;
    d (2k,3): the arms at the start of the substep, where the impulse acts (default r).

    An impulse p (+p on a, -p on b) at arms d moves C by K p, K = sum_s I3 / m_s - [r_s]x I_s^-1 [d_s]x
    (with d = r, the 3-D generalized inverse mass: n^T K n = sum_s 1/m_s + (r_s x n)^T I_s^-1 (r_s x n)).
    Solve (K + alpha~ I) dlam = -C - alpha~ lam on the kept rows only (keep (k,3)), so a subtracted row stays free.
    """
    k = pair.k
    if d is None:
        d = r
    else:
        ok = dot(d, r) >= MIN_DIRECTION_ALIGNMENT * dot(r, r)  # within ~60 degrees of the current arm
        if not ok.all():
            d = np.where(ok[:, None], d, r)
    M = skew(r) @ pair.inv_I @ skew(d)
    K = (pair.inv_m[:k] + pair.inv_m[k:])[:, None, None] * _EYE - M[:k] - M[k:]
    active = keep & (K.diagonal(axis1=1, axis2=2) > 0.0)  # rows neither body can move are left alone
    if active.all():
        K = K + alpha_t[:, None, None] * _EYE
        rhs = -C - alpha_t[:, None] * lam
    else:
        both = active[:, :, None] & active[:, None, :]
        K = np.where(both, K + alpha_t[:, None, None] * _EYE, 0.0) + (~active)[:, :, None] * _EYE
        rhs = np.where(active, -C - alpha_t[:, None] * lam, 0.0)
    dlam = np.linalg.solve(K, rhs[:, :, None])[:, :, 0]
    lam += dlam
    p = _both(dlam, -dlam)
    # dx_s = p_s / m_s, dphi_s = I_s^-1 (d_s x p_s) = -I_s^-1 [p_s]x d_s
    apply(pair, pair.inv_m[:, None] * p, -matvec(pair.inv_I, matvec(skew(p), d)), x, q)


def _alpha(compliance, idx, h):
    return np.asarray(compliance, dtype=float).take(idx) / (h * h)


def _keep(keep, idx):
    return np.ones((len(idx), 3), dtype=bool) if keep is None else _rows(np.asarray(keep, dtype=bool), idx)


def _project_rows(rows, fam, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before):
    """Shared driver of the 1-row position families: rows(fam, idx, pair) -> (C (k,), l (2k,3), g (2k,3))."""
    body_a, body_b = (_rows(b, idx) for b in instance_bodies(fam))
    pair = gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before)
    C, l, g = rows(fam, idx, pair)
    dl = dg = None
    if before is not None:
        _, dl, dg = rows(fam, idx, before.pair(pair.index, pair.k))
    lam_k = lam.take(idx)
    solve_rows(pair, l, g, C, _alpha(compliance, idx, h), lam_k, x, q, dl, dg)
    lam[idx] = lam_k


# ---------------------------------------------------------------- the families


def _project_point(fam, idx, points, target, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, keep):
    body_a, body_b = (_rows(b, idx) for b in instance_bodies(fam))
    pair = gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before)
    r = matvec(pair.R, points)
    d = None if before is None else matvec(_rows(before.R, pair.index), points)
    P = pair.x + r
    lam_k = _rows(lam, idx)
    solve_point(pair, r, P[: len(idx)] - P[len(idx):] - target, _alpha(compliance, idx, h), lam_k,
                _keep(keep, idx), x, q, d)
    lam[idx] = lam_k


def project_point_to_point(fam: PointToPoint, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame | None = None, keep=None):
    """Ball joint, C = x_a + R_a p_a - x_b - R_b p_b (3 rows, lam (k,3)); keep (k,3) masks subtracted rows."""
    idx = np.asarray(idx)
    points = _both(_rows(fam.point_a, idx), _rows(fam.point_b, idx))
    _project_point(fam, idx, points, 0.0, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, keep)


def project_point_to_nail(fam: PointToNail, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                          before: Frame | None = None, keep=None):
    """Body point at the world point P (fam.target, refreshed by the caller when it moves): C = x + R p - P."""
    idx = np.asarray(idx)
    p = _rows(fam.point, idx)
    _project_point(fam, idx, _both(p, np.zeros_like(p)), _rows(fam.target, idx), x, q, inv_mass, inv_inertia_body,
                   compliance, h, lam, before, keep)


def _orientation_rows(fam, idx, pair):
    # T . N = 0 as the angle from perpendicular, theta = asin(T . N), about n = unit(T x N): turning a by dphi
    # about n turns T toward N at unit rate, b the other way: g_a = n, g_b = -n.
    k = pair.k
    TN = matvec(pair.R, _both(_rows(fam.axis_a, idx), _rows(fam.axis_b, idx)))
    T, N = TN[:k], TN[k:]
    n = cross(T, N)
    size = np.sqrt(dot(n, n))
    if not (size > PARALLEL_EPS).all():  # T parallel to N: turn T about T x (the world axis least along T)
        n = np.where((size > PARALLEL_EPS)[:, None], n, cross(T, _EYE[np.argmin(np.abs(T), axis=1)]))
        size = np.sqrt(dot(n, n))
    n = n / size[:, None]
    return np.arcsin(np.clip(dot(T, N), -1.0, 1.0)), np.zeros_like(TN), _both(n, -n)


def project_orientation(fam: Orientation, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                        before: Frame | None = None):
    """Body-fixed T of a kept perpendicular to N (world or fixed in b): C = T . N, solved as asin(T . N)."""
    _project_rows(_orientation_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam,
                  before)


def _plane_rows(fam, idx, pair):
    # C = N . (P - S): l_a = N, g_a = (P - x_a) x N; b opposite with arm P - x_b (the plane turning about x_b)
    k = pair.k
    PS = pair.x + matvec(pair.R, _both(_rows(fam.point_a, idx), _rows(fam.plane_point, idx)))
    N = matvec(pair.R[k:], _rows(fam.plane_normal, idx))
    NN = _both(N, -N)
    return dot(N, PS[:k] - PS[k:]), NN, cross(_both(PS[:k], PS[:k]) - pair.x, NN)


def project_point_on_plane(fam: PointOnPlane, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame | None = None):
    """Body point P of a on the plane through S with normal N (world or fixed in b): C = N . (P - S)."""
    _project_rows(_plane_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before)


def _element_translation_rows(fam, idx, pair):
    # C = e . (x_a - x_b) - offset, e = R_b axis: l_a = e, g_a = 0, l_b = -e, g_b = (x_a - x_b) x (-e)
    k = pair.k
    e = matvec(pair.R[k:], _rows(fam.axis, idx))
    ee = _both(e, -e)
    xa = pair.x[:k]
    return dot(e, xa - pair.x[k:]) - fam.offset.take(idx), ee, cross(_both(xa, xa) - pair.x, ee)


def _element_rotation_rows(fam, idx, pair):
    # q_err = conj(q_b) q_a conj(ref) = (s, v), s >= 0; C = 2 v . axis (axis in b's frame). q_a += 0.5 (0, dphi) q_a
    # moves q_err by 0.5 (0, R_b^T dphi) q_err, so dC = dphi . R_b (s axis + v x axis) (exact): g_a = that, g_b = -g_a.
    k = pair.k
    err = quat_mul(quat_mul(quat_conj(pair.q[k:]), pair.q[:k]), quat_conj(_rows(fam.reference_rotation, idx)))
    err *= np.where(err[:, :1] < 0.0, -1.0, 1.0)
    s, v, axis = err[:, :1], err[:, 1:], _rows(fam.axis, idx)
    g = matvec(pair.R[k:], s * axis + cross(v, axis))
    return 2.0 * dot(v, axis), np.zeros((2 * k, 3)), _both(g, -g)


def project_element(fam: Element, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                    before: Frame | None = None):
    """Element rows: fix translation along / rotation about an axis (world or b's frame); the translational and
    the rotational instances of idx are projected as two vectorized groups."""
    idx = np.asarray(idx)
    rot = fam.rotational.take(idx)
    for group, rows in ((idx[~rot], _element_translation_rows), (idx[rot], _element_rotation_rows)):
        if len(group):
            _project_rows(rows, fam, group, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before)


def _require(before):
    if before is None:
        raise ValueError("before: gear families are on the turn made since the start of the substep; pass its Frame")


def project_gear_to_gear(fam: GearToGear, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                         before: Frame):
    """Gears, made positional per substep: r_a dtheta_a + r_b dtheta_b = 0 for the turn made since the start of
    the substep (before.q).

    dtheta = 2 vec(q q_prev^-1) . A (A the gear's world axis, scalar part of the turn made >= 0) is the very
    quantity the solver turns into angular velocity, w = 2 vec(q q_prev^-1) / h. So once the row holds,
    r_a w_a . A_a + r_b w_b . A_b = 0 at the end of every substep, exactly rather than on average; and no angle
    error is carried into the next substep (there is no C(x) to drift, so no stabilization): the total turns,
    sums of per-substep turns that each keep the ratio, keep it too. Exact gradient: q += 0.5 (0, dphi) q moves
    vec(dq) = v by 0.5 (s dphi + dphi x v) and A by dphi x A, so dC = dphi . r (s A + A x v); a projection
    lands on the row up to the O(dphi^2) renormalization.
    """
    _require(before)
    idx = np.asarray(idx)
    k = len(idx)
    pair = gather(_rows(fam.body_a, idx), _rows(fam.body_b, idx), x, q, inv_mass, inv_inertia_body, before)
    s, v = turn_since(pair.q, _rows(before.q, pair.index))
    A = matvec(pair.R, _both(_rows(fam.axis_a, idx), _rows(fam.axis_b, idx)))
    r = _both(fam.radius_a.take(idx), fam.radius_b.take(idx))
    Cs = 2.0 * r * dot(v, A)
    g = r[:, None] * (s[:, None] * A + cross(A, v))
    lam_k = lam.take(idx)
    solve_rows(pair, np.zeros_like(g), g, Cs[:k] + Cs[k:], _alpha(compliance, idx, h), lam_k, x, q)
    lam[idx] = lam_k


def project_gear_to_weight(fam: GearToWeight, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame):
    """Rope over a gear, per substep: the weight's displacement along the rope equals the rim's travel,
    C = (dtheta x arm) . d - (x_w - x_w_prev) . d, dtheta = 2 vec(q_g q_g_prev^-1) (scalar part >= 0).

    As for gears, the row is on the increments the solver turns into velocities, so rope speed equals rim speed
    at the end of every substep and the rope never creeps. With u = arm x d, C = 2 v . u - dx_w . d, and
    (as in project_gear_to_gear) g_gear = s u + v x u exactly; l_weight = -d.
    """
    _require(before)
    idx = np.asarray(idx)
    k = len(idx)
    pair = gather(_rows(fam.gear, idx), _rows(fam.weight, idx), x, q, inv_mass, inv_inertia_body, before)
    s, v = turn_since(pair.q[:k], _rows(before.q, pair.index[:k]))
    d = _rows(fam.direction, idx)
    u = cross(_rows(fam.arm, idx), d)
    moved = pair.x[k:] - _rows(before.x, pair.index[k:])  # WORLD: 0 - 0
    zero = np.zeros_like(d)
    lam_k = lam.take(idx)
    solve_rows(pair, _both(zero, -d), _both(s[:, None] * u + cross(v, u), zero), 2.0 * dot(v, u) - dot(moved, d),
               _alpha(compliance, idx, h), lam_k, x, q)
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
