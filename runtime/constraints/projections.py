"""Position-level projections of every constraint family: the constraint stage of the procedural (XPBD) plan.

`project_<family>(fam, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *, before=None)` moves the
bodies of the instances idx of one family so that their constraints hold again, mass-weighted, updating x (n,3)
and q (n,4) in place and accumulating the XPBD multipliers lam ((k,3) for the point families, (k,) otherwise;
compliance (k,), h the substep). The instances of idx must share no dynamic body (one colour of
`colour_instances`): a kernel is vectorized over them, and Gauss-Seidel runs across colours.
`before` is the Frame of the start of the substep (x_prev, q_prev and what follows from them).

XPBD (Mueller et al. 2020). A row C(x, q) has gradient blocks per body slot s in {a, b}: linear l_s
(dC = l_s . dx_s) and angular g_s (dC = g_s . dphi_s for a small world rotation, q_s += 0.5 (0, dphi_s) q_s).
With alpha~ = alpha / h^2 and (ld_s, gd_s) the direction the correction is applied along:

    dlam   = (-C - alpha~ lam) / (sum_s  l_s . ld_s / m_s + g_s^T I_s^-1 gd_s  + alpha~)
    dx_s   = dlam ld_s / m_s          dphi_s = dlam I_s^-1 gd_s          lam += dlam

For a point constraint along unit n at arms r: l = n, g = r x n, and with (ld, gd) = (l, g) the denominator is
the generalized inverse mass w = 1/m + (r x n)^T I^-1 (r x n) of each body.

Direction (a decision). Mueller et al. take (ld, gd) = the gradient now, which damps: a 60 degree pendulum at
h = 1/60 with 20 substeps swings 1.6e-3 short on its first period and 0.2 % shorter on each one after. Given
`before`, we take the gradient and the world inverse inertia of the start of the substep instead, as SHAKE does
(Ryckaert, Ciccotti, Berendsen 1977): the constraint force acts along the constraint normal of the start of the
step, which makes a substep a symplectic Verlet step for point masses and planar bodies, with no energy drift:
the same pendulum keeps its period to 3e-6 with 10 substeps. SHAKE's direction is only stable while the bodies
turn little within a substep, so the solver clears `before.use_directions` when one turns by more than
procedural.SHAKE_MAX_TURN, and the kernels then take the gradient now (a closest-point projection in the mass
metric: dissipative, stable at any step); where the two gradients disagree for one row (its effective mass
along the old one below MIN_DIRECTION_ALIGNMENT of the new) the current gradient is used too. Without
`before`, a kernel is plain XPBD (current gradient and inertia); the gear families need `before`.
The kernels here are Gauss-Seidel (one colour after another); procedural_direct.py projects all rows at once.

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
_CROSS_A, _CROSS_B = np.array([1, 2, 0, 2, 0, 1]), np.array([2, 0, 1, 1, 2, 0])


def _quadratic_forms():
    """Constant tensors that make a rotation matrix and a Hamilton product one matrix product each:
    R(q).reshape(9) = (q q^T).reshape(16) @ ROTATION, (p q).reshape(4) = (p q^T).reshape(16) @ PRODUCT."""
    rotation, product = np.zeros((4, 4, 9)), np.zeros((4, 4, 4))
    w, x, y, z = range(4)
    # R = [[w2+x2-y2-z2, 2(xy-wz), 2(xz+wy)], [2(xy+wz), w2-x2+y2-z2, 2(yz-wx)], [2(xz-wy), 2(yz+wx), w2-x2-y2+z2]]
    terms = {0: [(w, w, 1), (x, x, 1), (y, y, -1), (z, z, -1)], 1: [(x, y, 2), (w, z, -2)],
             2: [(x, z, 2), (w, y, 2)], 3: [(x, y, 2), (w, z, 2)], 4: [(w, w, 1), (x, x, -1), (y, y, 1), (z, z, -1)],
             5: [(y, z, 2), (w, x, -2)], 6: [(x, z, 2), (w, y, -2)], 7: [(y, z, 2), (w, x, 2)],
             8: [(w, w, 1), (x, x, -1), (y, y, -1), (z, z, 1)]}
    for k, entries in terms.items():
        for i, j, c in entries:
            rotation[i, j, k] += c
    # (p0 q0 - pv . qv, p0 qv + q0 pv + pv x qv)
    for i in range(4):
        for j in range(4):
            if i == 0 or j == 0:
                product[i, j, i + j] = 1.0
            elif i == j:
                product[i, j, 0] = -1.0
            else:
                product[i, j, 6 - i - j] = 1.0 if (i, j) in ((1, 2), (2, 3), (3, 1)) else -1.0
    return rotation.reshape(16, 9), product.reshape(16, 4)


_ROTATION, _PRODUCT = _quadratic_forms()


def skew(v):
    """[v]x (k,3,3) with [v]x u = v x u."""
    return (v @ _SKEW).reshape(-1, 3, 3)


def cross(a, b):
    """a x b for (k,3) stacks."""
    p = a.take(_CROSS_A, axis=1) * b.take(_CROSS_B, axis=1)
    return p[:, :3] - p[:, 3:]


def dot(a, b):
    return (a * b).sum(axis=1)


def matvec(M, v):
    return (M @ v[:, :, None])[:, :, 0]


def rotation_matrix(q):
    """R (k,3,3) of unit quaternions (k,4): R = I + 2 w [v]x + 2 [v]x^2, as a quadratic form in q."""
    return ((q[:, :, None] * q[:, None, :]).reshape(-1, 16) @ _ROTATION).reshape(-1, 3, 3)


def quat_mul(p, q):
    """Hamilton product of (k,4) stacks: (p0 q0 - pv . qv, p0 qv + q0 pv + pv x qv)."""
    return (p[:, :, None] * q[:, None, :]).reshape(-1, 16) @ _PRODUCT


def quat_conj(q):
    return q * _CONJ


def normalized(q):
    return q / np.sqrt(dot(q, q))[:, None]


def turn_since(q, q_prev):
    """The turn each body made since q_prev, theta (k,3) = 2 vec(dq) / dq_w with dq = q q_prev^-1: the Cayley
    map's inverse, a rotation vector of length 2 tan(angle / 2) (= the angle to O(angle^3)).

    It is the exact inverse of `turn_by` (q' = (1, hs w / 2) q, normalized), so a body spinning freely at w keeps
    w = theta / hs exactly (Mueller et al.'s 2 vec(dq) / hs would lose (w hs)^2 / 8 of it on every substep),
    and neither needs a sine, a cosine or an arctangent."""
    dq = quat_mul(q, q_prev * _CONJ)
    return 2.0 * dq[:, 1:] / dq[:, :1]


def turn_by(q, theta):
    """q turned by the rotation vector theta (k,3) in the Cayley map: (1, theta / 2) q, normalized (turn_since's
    inverse). For a small correction theta = dphi it is the first-order update q + 0.5 (0, dphi) q, normalized."""
    half = np.empty((len(theta), 4))
    half[:, 0] = 1.0
    half[:, 1:] = 0.5 * theta
    return normalized(quat_mul(half, q))


def turn_jacobian_t(theta, u):
    """(d theta / d phi)^T u for theta = turn_since(q, q_prev) and q turned by a small world rotation dphi:
    theta' = theta + (I - [theta]x / 2 + theta theta^T / 4) dphi + O(dphi^2), so d(theta . u) = dphi . g with
    g = u + theta x u / 2 + theta (theta . u) / 4."""
    return u + 0.5 * cross(theta, u) + (0.25 * dot(theta, u))[:, None] * theta


def _rows(a, idx):
    return a.take(idx, axis=0)


def _both(a, b):
    return np.concatenate((a, b))


# ---------------------------------------------------------------- the start of the substep, body pairs


@dataclass
class Frame:
    """Every body's pose at the start of the substep, built once per substep, plus one last row for the world
    (identity pose, no mobility), so that WORLD = -1 indexes it.

    x (n+1,3); q (n+1,4); R (n+1,3,3); inv_m (n+1,) inverse mass, 0 for bodies that do not move; inv_I (n+1,3,3)
    world inverse inertia R I_b^-1 R^T, 0 for bodies that do not move.
    """

    x: np.ndarray
    q: np.ndarray
    R: np.ndarray
    inv_m: np.ndarray
    inv_I: np.ndarray
    use_directions: bool = True  # correct along the gradients of this frame (False: along the current ones)

    @classmethod
    def empty(cls, inv_mass) -> "Frame":
        n = len(inv_mass)
        q = np.zeros((n + 1, 4))
        q[:, 0] = 1.0
        inv_m = np.zeros(n + 1)
        inv_m[:n] = np.maximum(inv_mass, 0.0)
        return cls(np.zeros((n + 1, 3)), q, np.tile(_EYE, (n + 1, 1, 1)), inv_m, np.zeros((n + 1, 3, 3)))

    @classmethod
    def of(cls, x, q, inv_mass, inv_inertia_body) -> "Frame":
        """The frame of pose (x, q) for bodies of inverse masses inv_mass (n,) and inverse inertias (n,3,3)."""
        frame = cls.empty(inv_mass)
        moving = np.flatnonzero(np.asarray(inv_mass) > 0.0)
        frame.refresh(x, q, moving, np.asarray(inv_inertia_body)[moving])
        return frame

    def refresh(self, x, q, moving, moving_inv_inertia_body) -> None:
        """Copy the pose (n rows), recompute every R and the I^-1 of the bodies `moving` (a slice or indices,
        with their body inverse inertias (m,3,3), 0 for bodies that do not move); the others' I^-1 stays 0."""
        n = len(x)
        self.x[:n], self.q[:n] = x, q
        R = self.R[:n]
        R[:] = rotation_matrix(q)
        if isinstance(moving, slice):
            np.matmul(R @ moving_inv_inertia_body, R.transpose(0, 2, 1), out=self.inv_I[:n])
        else:
            Rm = R[moving]
            self.inv_I[:n][moving] = Rm @ moving_inv_inertia_body @ Rm.transpose(0, 2, 1)

    def set_pose(self, x, q) -> None:
        """Copy the pose (n rows) and recompute every R; inverse masses and inertias are left as they are."""
        n = len(x)
        self.x[:n], self.q[:n] = x, q
        self.R[:n] = rotation_matrix(q)

    def pose(self, index) -> "Pair":
        """The pair of slots `index` (2k,) with their pose only (no inverse masses): what row functions read."""
        return Pair(len(index) // 2, index, _rows(self.x, index), _rows(self.q, index), _rows(self.R, index),
                    None, None, None)

    def pair(self, index) -> "Pair":
        inv_m = self.inv_m.take(index)
        return Pair(len(index) // 2, index, _rows(self.x, index), _rows(self.q, index), _rows(self.R, index),
                    inv_m > 0.0, inv_m, _rows(self.inv_I, index))


@dataclass
class Pair:
    """The two body slots of k instances, stacked: rows [0, k) are slot a, rows [k, 2k) slot b, so one numpy
    call serves both. WORLD rows have identity pose and no mobility.

    index (2k,) body index (WORLD kept); x (2k,3); q (2k,4); R (2k,3,3); moves (2k,) bool; inv_m (2k,) inverse
    mass and inv_I (2k,3,3) the world inverse inertia the corrections use (the start-of-substep one when there
    is a Frame), both 0 unless the body moves.
    """

    k: int
    index: np.ndarray
    x: np.ndarray
    q: np.ndarray
    R: np.ndarray
    moves: np.ndarray
    inv_m: np.ndarray
    inv_I: np.ndarray


def gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before: Frame | None = None) -> Pair:
    """Pair of slots body_a, body_b (k,) each (WORLD allowed) from the current state."""
    index = _both(body_a, body_b)
    real = index != WORLD
    everywhere = real.all()
    safe = index if everywhere else np.where(real, index, 0)
    xs, qs = _rows(x, safe), _rows(q, safe)
    if not everywhere:
        xs = np.where(real[:, None], xs, 0.0)
        qs = np.where(real[:, None], qs, _IDENTITY_Q)
    R = rotation_matrix(qs)
    if before is not None:
        inv_m, inv_I = before.inv_m.take(index), _rows(before.inv_I, index)
        return Pair(len(body_a), index, xs, qs, R, inv_m > 0.0, inv_m, inv_I)
    inv_m = np.where(real, inv_mass.take(safe), 0.0)
    moves = inv_m > 0.0
    inv_I = np.where(moves[:, None, None], R @ _rows(inv_inertia_body, safe) @ R.transpose(0, 2, 1), 0.0)
    return Pair(len(body_a), index, xs, qs, R, moves, np.where(moves, inv_m, 0.0), inv_I)


def apply(pair: Pair, dx, dphi, x, q) -> None:
    """x += dx, q += 0.5 (0, dphi) q (then renormalized), for the moving bodies of the pair (2k rows each)."""
    qs = turn_by(pair.q, dphi)
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
    Solve (K + alpha~ I) dlam = -C - alpha~ lam on the kept rows only (keep (k,3) or None: all), so a
    subtracted row stays free.
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
    active = K.diagonal(axis1=1, axis2=2) > 0.0  # rows neither body can move are left alone
    if keep is not None:
        active = active & keep
    if active.all():
        K = K + alpha_t[:, None, None] * _EYE
        rhs = -C - alpha_t[:, None] * lam
    else:
        both = active[:, :, None] & active[:, None, :]
        K = np.where(both, K + alpha_t[:, None, None] * _EYE, 0.0) + (~active)[:, :, None] * _EYE
        rhs = np.where(active, -C - alpha_t[:, None] * lam, 0.0)
    dlam = np.linalg.solve(K, rhs[:, :, None])[:, :, 0]
    lam += dlam
    _point_impulse(pair, _both(dlam, -dlam), d, x, q)


def _point_impulse(pair: Pair, p, d, x, q) -> None:
    # dx_s = p_s / m_s, dphi_s = I_s^-1 (d_s x p_s) = -I_s^-1 [p_s]x d_s
    apply(pair, pair.inv_m[:, None] * p, -matvec(pair.inv_I, matvec(skew(p), d)), x, q)


def _alpha(compliance, idx, h):
    return np.asarray(compliance, dtype=float).take(idx) / (h * h)


def _keep(keep, idx):
    return None if keep is None else _rows(np.asarray(keep, dtype=bool), idx)


# ---------------------------------------------------------------- the families: C and gradients on a pair


def _point_arms(fam, idx):
    """Body points of both slots (2k,3) and the world target (k,3) or 0 of a point family."""
    if isinstance(fam, PointToNail):
        p = _rows(fam.point, idx)
        return _both(p, np.zeros_like(p)), _rows(fam.target, idx)
    return _both(_rows(fam.point_a, idx), _rows(fam.point_b, idx)), 0.0


def _orientation_rows(fam, idx, pair, before):
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


def _plane_rows(fam, idx, pair, before):
    # C = N . (P - S): l_a = N, g_a = (P - x_a) x N; b opposite with arm P - x_b (the plane turning about x_b)
    k = pair.k
    PS = pair.x + matvec(pair.R, _both(_rows(fam.point_a, idx), _rows(fam.plane_point, idx)))
    N = matvec(pair.R[k:], _rows(fam.plane_normal, idx))
    NN = _both(N, -N)
    return dot(N, PS[:k] - PS[k:]), NN, cross(_both(PS[:k], PS[:k]) - pair.x, NN)


def _element_translation_rows(fam, idx, pair, before):
    # C = e . (x_a - x_b) - offset, e = R_b axis: l_a = e, g_a = 0, l_b = -e, g_b = (x_a - x_b) x (-e)
    k = pair.k
    e = matvec(pair.R[k:], _rows(fam.axis, idx))
    ee = _both(e, -e)
    xa = pair.x[:k]
    return dot(e, xa - pair.x[k:]) - fam.offset.take(idx), ee, cross(_both(xa, xa) - pair.x, ee)


def _element_rotation_rows(fam, idx, pair, before):
    # q_err = conj(q_b) q_a conj(ref) = (s, v), s >= 0; C = 2 v . axis (axis in b's frame). q_a += 0.5 (0, dphi) q_a
    # moves q_err by 0.5 (0, R_b^T dphi) q_err, so dC = dphi . R_b (s axis + v x axis) (exact): g_a = that, g_b = -g_a.
    k = pair.k
    err = quat_mul(quat_mul(quat_conj(pair.q[k:]), pair.q[:k]), quat_conj(_rows(fam.reference_rotation, idx)))
    err *= np.where(err[:, :1] < 0.0, -1.0, 1.0)
    s, v, axis = err[:, :1], err[:, 1:], _rows(fam.axis, idx)
    g = matvec(pair.R[k:], s * axis + cross(v, axis))
    return 2.0 * dot(v, axis), np.zeros((2 * k, 3)), _both(g, -g)


def _gear_rows(fam, idx, pair, before):
    # C = r_a theta_a . A_a + r_b theta_b . A_b, theta = turn_since(q, q_prev) the turn since the start of the
    # substep, A = R axis. A small turn dphi of q moves theta (turn_jacobian_t) and A by dphi x A:
    # g = r (turn_jacobian_t(theta, A) + A x theta).
    k = pair.k
    theta = turn_since(pair.q, _rows(before.q, pair.index))
    A = matvec(pair.R, _both(_rows(fam.axis_a, idx), _rows(fam.axis_b, idx)))
    r = _both(fam.radius_a.take(idx), fam.radius_b.take(idx))
    Cs = r * dot(theta, A)
    return Cs[:k] + Cs[k:], np.zeros_like(A), r[:, None] * (turn_jacobian_t(theta, A) + cross(A, theta))


def _weight_rows(fam, idx, pair, before):
    # C = (theta x arm) . d - (x_w - x_w_prev) . d = theta . u - dx_w . d, u = arm x d, theta the gear's turn;
    # g_gear = turn_jacobian_t(theta, u), l_weight = -d
    k = pair.k
    theta = turn_since(pair.q[:k], _rows(before.q, pair.index[:k]))
    d = _rows(fam.direction, idx)
    u = cross(_rows(fam.arm, idx), d)
    moved = pair.x[k:] - _rows(before.x, pair.index[k:])  # WORLD: 0 - 0
    zero = np.zeros_like(d)
    return dot(theta, u) - dot(moved, d), _both(zero, -d), _both(turn_jacobian_t(theta, u), zero)


def _project_rows(rows, fam, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, target=None):
    """Shared driver of the 1-row families: rows(fam, idx, pair, before) -> (C (k,), l (2k,3), g (2k,3)).
    target (k_f,) or None: the value each row is projected to (0 when None; self-assembly curves)."""
    body_a, body_b = (_rows(b, idx) for b in instance_bodies(fam))
    pair = gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before)
    C, l, g = rows(fam, idx, pair, before)
    if target is not None:
        C = C - target.take(idx)
    dl = dg = None
    if before is not None and before.use_directions:
        _, dl, dg = rows(fam, idx, before.pair(pair.index), before)
    lam_k = lam.take(idx)
    solve_rows(pair, l, g, C, _alpha(compliance, idx, h), lam_k, x, q, dl, dg)
    lam[idx] = lam_k


def _project_point(fam, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, keep, row_target=None):
    """Shared driver of the point families: C = x_a + R_a p_a - x_b - R_b p_b - P (P: the nail, 0 for joints)
    - row_target (k_f,3) (self-assembly curves; None: 0)."""
    body_a, body_b = (_rows(b, idx) for b in instance_bodies(fam))
    pair = gather(body_a, body_b, x, q, inv_mass, inv_inertia_body, before)
    points, target = _point_arms(fam, idx)
    if row_target is not None:
        target = target + _rows(row_target, idx)
    r = matvec(pair.R, points)
    d = None if before is None or not before.use_directions else matvec(_rows(before.R, pair.index), points)
    P = pair.x + r
    lam_k = _rows(lam, idx)
    solve_point(pair, r, P[: pair.k] - P[pair.k:] - target, _alpha(compliance, idx, h), lam_k,
                _keep(keep, idx), x, q, d)
    lam[idx] = lam_k


# ---------------------------------------------------------------- the kernels, one per family


def project_point_to_point(fam: PointToPoint, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame | None = None, keep=None, target=None):
    """Ball joint, C = x_a + R_a p_a - x_b - R_b p_b (3 rows, lam (k,3)); keep (k,3) masks subtracted rows."""
    _project_point(fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, keep, target)


def project_point_to_nail(fam: PointToNail, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                          before: Frame | None = None, keep=None, target=None):
    """Body point at the world point P (fam.target, refreshed by the caller when it moves): C = x + R p - P."""
    _project_point(fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, keep, target)


def project_orientation(fam: Orientation, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                        before: Frame | None = None, target=None):
    """Body-fixed T of a kept perpendicular to N (world or fixed in b): C = T . N, solved as asin(T . N)."""
    _project_rows(_orientation_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam,
                  before, target)


def project_point_on_plane(fam: PointOnPlane, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame | None = None, target=None):
    """Body point P of a on the plane through S with normal N (world or fixed in b): C = N . (P - S)."""
    _project_rows(_plane_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before,
                  target)


def _element_groups(fam, idx):
    rot = fam.rotational.take(idx)
    return [(g, rows) for g, rows in ((idx[~rot], _element_translation_rows), (idx[rot], _element_rotation_rows))
            if len(g)]


def project_element(fam: Element, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                    before: Frame | None = None, target=None):
    """Element rows: fix translation along / rotation about an axis (world or b's frame); the translational and
    the rotational instances of idx are projected as two vectorized groups."""
    for group, rows in _element_groups(fam, np.asarray(idx)):
        _project_rows(rows, fam, group, x, q, inv_mass, inv_inertia_body, compliance, h, lam, before, target)


def project_gear_to_gear(fam: GearToGear, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                         before: Frame, target=None):
    """Gears, made positional per substep: r_a dtheta_a + r_b dtheta_b = 0 for the turn made since the start of
    the substep (before.q).

    dtheta = theta . A, theta = turn_since(q, q_prev) the turn as a rotation vector and A the gear's world axis, is the
    very quantity the solver turns into angular velocity, w = theta / h. So once the row holds,
    r_a w_a . A_a + r_b w_b . A_b = 0 at the end of every substep, exactly rather than on average; and no angle
    error is carried into the next substep (there is no C(x) to drift, so no stabilization): the total turns,
    sums of per-substep turns that each keep the ratio, keep it too. The gradient is exact (see _gear_rows), so a
    projection lands on the row up to the O(dphi^2) renormalization.
    """
    _require(before)
    _project_rows(_gear_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before,
                  target)


def project_gear_to_weight(fam: GearToWeight, idx, x, q, inv_mass, inv_inertia_body, compliance, h, lam, *,
                           before: Frame, target=None):
    """Rope over a gear, per substep: the weight's displacement along the rope equals the rim's travel,
    C = (theta x arm) . d - (x_w - x_w_prev) . d, theta = turn_since(q_g, q_g_prev) the gear's turn.

    As for gears, the row is on the increments the solver turns into velocities, so rope speed equals rim speed
    at the end of every substep and the rope never creeps (exact gradient: _weight_rows).
    """
    _require(before)
    _project_rows(_weight_rows, fam, np.asarray(idx), x, q, inv_mass, inv_inertia_body, compliance, h, lam, before,
                  target)


def _require(before):
    if before is None:
        raise ValueError("before: gear rows are on the turn made since the start of the substep; pass its Frame")


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


# ---------------------------------------------------------------- rows for the direct projection and switch-on

# the 1-row families' C and gradients on a pair: rows(fam, idx, pair, before) -> (C (k,), l (2k,3), g (2k,3))
ROW_FUNCTIONS = {
    Orientation: _orientation_rows,
    PointOnPlane: _plane_rows,
    GearToGear: _gear_rows,
    GearToWeight: _weight_rows,
}
# families whose rows are velocity constraints made positional per substep: no C(x), so no assembly curve
VELOCITY_FAMILIES = (GearToGear, GearToWeight)


def row_groups(fam) -> list:
    """[(instance indices, row function)] covering a 1-row family: one group, or two for Element (the
    translational and the rotational rows are different functions)."""
    if isinstance(fam, Element):
        return _element_groups(fam, np.arange(len(fam.body_a)))
    return [(np.arange(len(instance_bodies(fam)[0])), ROW_FUNCTIONS[type(fam)])]
