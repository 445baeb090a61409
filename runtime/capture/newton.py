"""An island's velocities solved whole in the velocities themselves (the primal problem): each contact row a stiff
one-sided spring on the speed it measures, and the velocities that minimize the island's energy found by Newton's
method with an exact line search (the scheme of MuJoCo's Newton solver: Todorov, "Convex and
analytically-invertible dynamics with contacts and constraints", ICRA 2014).

Why not the impulses (the dual): the rows of a box resting on a box outnumber its six degrees of freedom (four
points a face, two friction rows each), so their impulses are not determined, and a direct solve of them asked some
for negative normal impulses (a stack of 8 cubes of alternating densities: down to -2.5 N s, where the sweeps held
0.01 N s at least). In the velocities the problem is strictly convex whatever the rows: six unknowns a body, and a
row that is not needed holds nothing.

For the island's bodies (velocities v; before the solve v0, with the impulses lam0 that the sweeps gave; lam_s the
sliding contacts' friction), masses M, and each row i's speed u_i = J_i v, target t_i and stiffness D_i:

    f(v) = 1/2 (v - v0)^T M (v - v0) + (J^T (lam0 - lam_s)) . v + sum_i D_i / 2 min(0, u_i - t_i)^2
    lam_i(v) = D_i max(0, t_i - u_i)                      the row's impulse: it pushes while u_i < t_i
    g = M (v - v0) - J^T (lam(v) + lam_s - lam0)          f's gradient
    H = M + sum over the rows that push of D_i J_i^T J_i  f's Hessian (piecewise constant)
    v <- v - alpha H^-1 g                                 alpha: f's least value along the step (`_search`)

The rows: a contact that grips (slipping slower than STUCK before the step's impulses) has four, along the edges of
Coulomb's pyramid, J_n +/- mu J_t1 and J_n +/- mu J_t2, each with the normal's target: their impulses e >= 0 give
lam_n = sum e and a friction sum e (a1, a2) within the disc's inscribed square. A contact that slides has its
normal row alone, and a friction of mu lam_n against its slip, lam_n from the round before (the sweeps' for the
first): the solve is done again, SLIDE_ROUNDS times at most, until those frictions settle, and a contact whose slip
the solve stops or turns back grips from the next round on. (Pyramid rows on a sliding contact ask for a normal
speed of mu times its slip: an 8 kg block sliding on a light board jumped off it at 0.2 m/s.) A contact without
friction has its normal row alone. D_i = STIFFNESS m_i (m_i the normal row's effective mass): a row that pushes gives
way lam_i / D_i, the speed its impulse would make alone over STIFFNESS.

Found 2026-12-07: the impulses' direct solve (islands.py before this) was put back at most steps of the stack, whose
cubes then rocked at 1.7-2.5 cm/s and drifted 4-20 mm; solved here they rest within 0.01 mm of their places. A slab of
36 kg landing on a cube of 0.1 kg: keeping the sweeps' friction for contacts that slid after the sweeps (the cube,
which they spun at 2.4 rad/s) left it spinning, and the next step blew up; judged before the step's impulses, those
contacts grip, and the slab and the cube rest after the one step of the impact.

Data (data.py Islands): local (n+1,) each body's place in the island (-1: none), order (MOST_BODIES,) the island's
bodies, step (n+1, 13) Newton's step dv in columns 7 to 12 (where solve.py `speed` reads velocities), grad (6k,) g,
dense and rhs the system H dv = -g; and the contacts' slides (data.py Contacts), which of them slide.
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from .solve import speed

# a row's stiffness over its effective mass: it gives way a millionth of the speed its impulse would make alone
STIFFNESS = 1e6
# Newton steps at most; they stop when no velocity changes by more than SETTLED (m/s, rad/s)
NEWTON_STEPS = 16
SETTLED = 1e-9
# steps of the line search at most (Newton's method on f's slope along the step, kept inside a bracket)
SEARCH_STEPS = 40
# a contact slipping faster than this before the step's impulses (m/s) slides: its friction is mu lam_n against the
# slip, lam_n from the round before; one whose slip the solve stops or turns back grips in the next round
STUCK = 1e-2
# rounds at most, each a whole Newton solve (sliding friction from the last round's normal impulses)
SLIDE_ROUNDS = 4
# a round whose sliding friction changed by less than this fraction of mu lam_n (or 1e-9 N s) is the last
SETTLED_FRICTION = 1e-6


@kernel
def cholesky_solve(A, x, k, dependent):
    """x <- A^-1 x for the k x k symmetric A given by its lower triangle (overwritten by its Cholesky factor L). A
    row whose pivot is at most `dependent` times its diagonal depends on the rows before it and is dropped: its
    column of L and its entry of the answer are 0 (dependent 0: only a pivot that is not positive)."""
    # A = L L^T
    for j in range(k):
        pivot = A[j, j]
        for p in range(j):
            pivot -= A[j, p] * A[j, p]
        if pivot <= dependent * A[j, j]:
            for i in range(j, k):
                A[i, j] = 0.0
            continue
        pivot = math.sqrt(pivot)
        A[j, j] = pivot
        for i in range(j + 1, k):
            value = A[i, j]
            for p in range(j):
                value -= A[i, p] * A[j, p]
            A[i, j] = value / pivot
    # L z = x, then L^T x = z
    for i in range(k):
        value = x[i]
        for p in range(i):
            value -= A[i, p] * x[p]
        x[i] = value / A[i, i] if A[i, i] > 0.0 else 0.0
    for i in range(k - 1, -1, -1):
        value = x[i]
        for p in range(i + 1, k):
            value -= A[p, i] * x[p]
        x[i] = value / A[i, i] if A[i, i] > 0.0 else 0.0


@kernel
def _slip(ct, c):
    """Contact c's slip before the step's impulses (ct.before, with the forces' kick in it): its speed and unit
    direction (s1, s2) in its tangents ((1, 0) where it does not slip). Not after the sweeps: their velocities are
    what the solve corrects (under a 36 kg slab landing on it, they spun a 0.1 kg cube at 2.4 rad/s)."""
    u1, u2 = ct.before[c, 1], ct.before[c, 2]
    size = math.sqrt(u1 * u1 + u2 * u2)
    return (size, u1 / size, u2 / size) if size > 0.0 else (0.0, 1.0, 0.0)


@kernel
def _rows_of(ct, c):
    """The kinds of the rows contact c takes in the solve: 1 to 4, its pyramid's edges, if it grips; else 0, its
    normal alone (it slides, or has no friction). Returns (first kind, last kind + 1)."""
    return (1, 5) if ct.mu[c] > 0.0 and ct.slides[c] == 0 else (0, 1)


@kernel
def _edge(ct, c, kind):
    """Row `kind` of contact c is J_n + a1 J_t1 + a2 J_t2: kind 0 its normal, 1 to 4 its pyramid's edges (mu along
    +t1, -t1, +t2, -t2). Returns (a1, a2)."""
    mu = ct.mu[c]
    if kind == 0:
        return 0.0, 0.0
    if kind == 1:
        return mu, 0.0
    if kind == 2:
        return -mu, 0.0
    return (0.0, mu) if kind == 3 else (0.0, -mu)


@kernel
def _row_speed(ct, c, a1, a2, w):
    """u = (J_n + a1 J_t1 + a2 J_t2) w of contact c at the velocities w (or Newton's step)."""
    u = speed(ct, c, 0, w)
    if a1 != 0.0 or a2 != 0.0:
        u += a1 * speed(ct, c, 1, w) + a2 * speed(ct, c, 2, w)
    return u


@kernel
def _stiffness(ct, c):
    return STIFFNESS * ct.mass[c, 0]


@kernel
def _impulse(ct, c, a1, a2, y):
    """lam = D max(0, t - u) of the row (J_n + a1 J_t1 + a2 J_t2) of contact c at the velocities y."""
    return _stiffness(ct, c) * max(0.0, ct.bounce[c] - _row_speed(ct, c, a1, a2, y))


@kernel
def _members(dynamic, ct, isl, first, end, most):
    """isl.order <- the island's dynamic bodies, isl.local[b] <- each one's place. Returns their count, or -1 if
    there are more than `most` (isl.local is then cleared)."""
    k = 0
    for i in range(first, end):
        c = ct.member[i]
        for b in (ct.a[c], ct.b[c]):
            if dynamic[b] and isl.local[b] < 0:
                if k == most:
                    _forget(isl, k)
                    return -1
                isl.local[b] = k
                isl.order[k] = b
                k += 1
    return k


@kernel
def _forget(isl, k):
    """isl.local and isl.step of the island's k bodies cleared for the next island."""
    for i in range(k):
        b = isl.order[i]
        isl.local[b] = -1
        for col in range(7, 13):
            isl.step[b, col] = 0.0


@kernel
def _body_row(ct, c, normal, a1, a2, side):
    """(normal J_n + a1 J_t1 + a2 J_t2) of contact c on its body `side` (0: a, 1: b): (d, r x d), negated for b
    (6 values)."""
    sign = 1.0 if side == 0 else -1.0
    off = 3 if side == 0 else 6
    j = ct.jac
    return (sign * (normal * j[c, 0, 0] + a1 * j[c, 1, 0] + a2 * j[c, 2, 0]),
            sign * (normal * j[c, 0, 1] + a1 * j[c, 1, 1] + a2 * j[c, 2, 1]),
            sign * (normal * j[c, 0, 2] + a1 * j[c, 1, 2] + a2 * j[c, 2, 2]),
            sign * (normal * j[c, 0, off] + a1 * j[c, 1, off] + a2 * j[c, 2, off]),
            sign * (normal * j[c, 0, off + 1] + a1 * j[c, 1, off + 1] + a2 * j[c, 2, off + 1]),
            sign * (normal * j[c, 0, off + 2] + a1 * j[c, 1, off + 2] + a2 * j[c, 2, off + 2]))


@kernel
def _inertia(bodies, R, b, p, q):
    """(R I_body R^T)[p, q] of body b: its inertia in the world."""
    total = 0.0
    for k in range(3):
        for l in range(3):
            total += R[b, p, k] * bodies.inertia[b, k, l] * R[b, q, l]
    return total


@kernel
def _velocity(w, b):
    """Body b's 6 velocities in w (columns 7 to 12)."""
    return w[b, 7], w[b, 8], w[b, 9], w[b, 10], w[b, 11], w[b, 12]


@kernel
def _difference(w, base, b):
    """w_b - base_b of body b's 6 velocities."""
    return (w[b, 7] - base[b, 7], w[b, 8] - base[b, 8], w[b, 9] - base[b, 9], w[b, 10] - base[b, 10],
            w[b, 11] - base[b, 11], w[b, 12] - base[b, 12])


@kernel
def _turning(bodies, R, b, p, d):
    """(I d_w)[p] of body b (I its inertia in the world, d_w the last three of d)."""
    return (_inertia(bodies, R, b, p, 0) * d[3] + _inertia(bodies, R, b, p, 1) * d[4]
            + _inertia(bodies, R, b, p, 2) * d[5])


@kernel
def _moment(bodies, R, b, d):
    """M_b d = (m d_v, I d_w) of body b for its 6 velocities' d."""
    m = bodies.mass[b]
    return (m * d[0], m * d[1], m * d[2], _turning(bodies, R, b, 0, d), _turning(bodies, R, b, 1, d),
            _turning(bodies, R, b, 2, d))


@kernel
def _local(ct, c, isl, side):
    """The place in the island of contact c's body `side` (0: a, 1: b); -1 if it is not one of its bodies."""
    return isl.local[ct.a[c] if side == 0 else ct.b[c]]


@kernel
def _add_row(ct, c, normal, a1, a2, isl, impulse, stiffness):
    """Row (normal J_n + a1 J_t1 + a2 J_t2) of contact c: J^T impulse added to -g (isl.rhs), and stiffness J^T J to
    H (isl.dense, both triangles)."""
    for side in range(2):
        i = _local(ct, c, isl, side)
        if i < 0:
            continue
        ji = _body_row(ct, c, normal, a1, a2, side)
        for p in range(6):
            isl.rhs[6 * i + p] += impulse * ji[p]
        for other in range(2):
            j = _local(ct, c, isl, other)
            if stiffness != 0.0 and j >= 0:
                jj = _body_row(ct, c, normal, a1, a2, other)
                for p in range(6):
                    for q in range(6):
                        isl.dense[6 * i + p, 6 * j + q] += stiffness * ji[p] * jj[q]


@kernel
def _system(bodies, R, ct, y, y0, isl, first, end, k):
    """isl.rhs <- -g, isl.dense <- H at the velocities y (module docstring), for the island's k bodies."""
    size = 6 * k
    for p in range(size):
        isl.rhs[p] = 0.0
        for q in range(size):
            isl.dense[p, q] = 0.0
    # -g = -M (v - v0) + J^T (lam + lam_s - lam0); H = M + sum over the rows that push of D J^T J
    for i in range(k):
        b = isl.order[i]
        moment = _moment(bodies, R, b, _difference(y, y0, b))
        for p in range(6):
            isl.rhs[6 * i + p] = -moment[p]
        for p in range(3):
            isl.dense[6 * i + p, 6 * i + p] = bodies.mass[b]
            for q in range(3):
                isl.dense[6 * i + 3 + p, 6 * i + 3 + q] = _inertia(bodies, R, b, p, q)
    for m in range(first, end):
        c = ct.member[m]
        # -J^T lam0 (kept by islands.py before the solve), and a sliding contact's friction this round
        _add_row(ct, c, 1.0, 0.0, 0.0, isl, -ct.kept[c, 0], 0.0)
        _add_row(ct, c, 0.0, 1.0, 0.0, isl, -ct.kept[c, 1], 0.0)
        _add_row(ct, c, 0.0, 0.0, 1.0, isl, -ct.kept[c, 2], 0.0)
        if ct.slides[c] != 0:
            _add_row(ct, c, 0.0, 1.0, 0.0, isl, ct.lam[c, 1], 0.0)
            _add_row(ct, c, 0.0, 0.0, 1.0, isl, ct.lam[c, 2], 0.0)
        start, stop = _rows_of(ct, c)
        for kind in range(start, stop):
            a1, a2 = _edge(ct, c, kind)
            lam = _impulse(ct, c, a1, a2, y)
            if lam > 0.0:
                _add_row(ct, c, 1.0, a1, a2, isl, lam, _stiffness(ct, c))


@kernel
def _slope(ct, isl, y, first, end, alpha, c0, c1):
    """f's slope along Newton's step dv (isl.step) at alpha, and its rate of change there: c0 + alpha c1 -
    sum_i du_i (lam_i(v + alpha dv) - lam_i(v)), and c1 + sum over the rows that push of D_i du_i^2 (du_i = J_i
    dv; c0 = dv . g, c1 = dv^T M dv)."""
    slope, curve = c0 + alpha * c1, c1
    for m in range(first, end):
        c = ct.member[m]
        d = _stiffness(ct, c)
        start, stop = _rows_of(ct, c)
        for kind in range(start, stop):
            a1, a2 = _edge(ct, c, kind)
            du = _row_speed(ct, c, a1, a2, isl.step)
            short = ct.bounce[c] - _row_speed(ct, c, a1, a2, y)
            later = short - alpha * du
            slope -= du * d * (max(0.0, later) - max(0.0, short))
            if later > 0.0:
                curve += d * du * du
    return slope, curve


@kernel
def _search(ct, isl, y, first, end, c0, c1):
    """The step length alpha where f stops falling along dv: f's slope along dv is piecewise linear and rises
    from c0 < 0, so its root is bracketed (doubling from 1) and found by Newton's method kept inside the bracket
    (bisection where it would leave it)."""
    low, high = 0.0, 1.0
    slope, curve = _slope(ct, isl, y, first, end, high, c0, c1)
    while slope < 0.0 and high < 1e6:
        low, high = high, 2.0 * high
        slope, curve = _slope(ct, isl, y, first, end, high, c0, c1)
    if slope <= 0.0:
        return high
    alpha = high
    for _ in range(SEARCH_STEPS):
        if abs(slope) <= 1e-12 * abs(c0):
            break
        if slope < 0.0:
            low = alpha
        else:
            high = alpha
        guess = alpha - slope / curve if curve > 0.0 else 0.5 * (low + high)
        alpha = guess if low < guess < high else 0.5 * (low + high)
        slope, curve = _slope(ct, isl, y, first, end, alpha, c0, c1)
    return alpha


@kernel
def _begin_slides(ct, first, end):
    """Which of the island's contacts slide (ct.slides: `_slip` faster than STUCK), each with friction mu lam0_n
    against its slip."""
    for m in range(first, end):
        c = ct.member[m]
        size, s1, s2 = _slip(ct, c)
        ct.slides[c] = 1 if ct.mu[c] > 0.0 and size > STUCK else 0
        if ct.slides[c] != 0:
            limit = ct.mu[c] * ct.kept[c, 0]
            ct.lam[c, 1], ct.lam[c, 2] = -limit * s1, -limit * s2


@kernel
def _next_slides(ct, y, first, end):
    """After a round: a sliding contact whose slip the solve stopped or turned back grips from now on; the others'
    friction becomes mu lam_n of this round against their slip at v0. Returns whether any changed by more than
    SETTLED_FRICTION (another round is needed)."""
    changed = False
    for m in range(first, end):
        c = ct.member[m]
        if ct.slides[c] == 0:
            continue
        size, s1, s2 = _slip(ct, c)
        # the slip now along the one before
        if speed(ct, c, 1, y) * s1 + speed(ct, c, 2, y) * s2 <= 0.0:
            ct.slides[c] = 0
            changed = True
            continue
        limit = ct.mu[c] * _impulse(ct, c, 0.0, 0.0, y)
        l1, l2 = -limit * s1, -limit * s2
        if abs(l1 - ct.lam[c, 1]) + abs(l2 - ct.lam[c, 2]) > SETTLED_FRICTION * limit + 1e-9:
            changed = True
        ct.lam[c, 1], ct.lam[c, 2] = l1, l2
    return changed


@kernel
def _impulses(ct, y, first, end):
    """Each contact's impulses from the solved velocities: lam_n the sum of its rows' impulses e; a contact that
    grips its friction sum e (a1, a2) (module docstring), one that slides the friction of the last round."""
    for m in range(first, end):
        c = ct.member[m]
        start, stop = _rows_of(ct, c)
        ct.lam[c, 0] = 0.0
        if start > 0:
            ct.lam[c, 1], ct.lam[c, 2] = 0.0, 0.0
        for kind in range(start, stop):
            a1, a2 = _edge(ct, c, kind)
            e = _impulse(ct, c, a1, a2, y)
            ct.lam[c, 0] += e
            ct.lam[c, 1] += a1 * e
            ct.lam[c, 2] += a2 * e


@kernel
def _newton(bodies, R, ct, y, y0, isl, first, end, k):
    """Newton's method on f (module docstring) for the island's k bodies, from the velocities y."""
    size = 6 * k
    for _ in range(NEWTON_STEPS):
        _system(bodies, R, ct, y, y0, isl, first, end, k)
        for p in range(size):
            isl.grad[p] = -isl.rhs[p]
        # H dv = -g
        cholesky_solve(isl.dense, isl.rhs, size, 0.0)
        c0, c1 = 0.0, 0.0
        for i in range(k):
            b = isl.order[i]
            for p in range(6):
                isl.step[b, 7 + p] = isl.rhs[6 * i + p]
                c0 += isl.rhs[6 * i + p] * isl.grad[6 * i + p]
            moment = _moment(bodies, R, b, _velocity(isl.step, b))
            for p in range(6):
                c1 += isl.step[b, 7 + p] * moment[p]
        if not c0 < 0.0:
            return  # (no descent left)
        alpha = _search(ct, isl, y, first, end, c0, c1)
        largest = 0.0
        for i in range(k):
            b = isl.order[i]
            for p in range(6):
                change = alpha * isl.step[b, 7 + p]
                y[b, 7 + p] += change
                largest = max(largest, abs(change))
        if largest < SETTLED:
            return


@kernel
def solve_island(bodies, R, ct, y, y0, isl, first, end, most):
    """The velocities y of the island whose contacts are ct.member[first:end] solved whole (module docstring), and
    its contacts' impulses set from them; y0: the velocities before (y as the sweeps left it), ct.kept the impulses
    before. Returns False, changing nothing, if it has more than `most` bodies."""
    k = _members(bodies.dynamic, ct, isl, first, end, most)
    if k < 0:
        return False
    _begin_slides(ct, first, end)
    for round in range(SLIDE_ROUNDS):
        _newton(bodies, R, ct, y, y0, isl, first, end, k)
        if round == SLIDE_ROUNDS - 1 or not _next_slides(ct, y, first, end):
            break
    _impulses(ct, y, first, end)
    _forget(isl, k)
    return True
