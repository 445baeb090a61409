"""Islands that projected Gauss-Seidel leaves unsolved, solved whole: the bodies that touch one another.

Gauss-Seidel passes an impulse from contact to contact one sweep at a time. Where a heavy body rests on a light
one, each sweep passes on about m_light / (m_heavy + m_light) of the weight: a 36 kg slab on a 0.1 kg cube on a floor
needs thousands of sweeps where 16 are taken, and the slab sank through the cube by 1.5 to 12 mm (400 sweeps: still
1.6 mm at 4 ms). An island is the dynamic bodies joined by contacts (a static or kinematic body joins nothing: the
floor under a heap does not make the heap one island with the next heap). After the velocity sweeps, an island
whose heaviest body is MASS_RATIO times its lightest or more, whose rows still miss their targets by more than STILL,
and that has at most MOST_BODIES bodies, has its velocities solved whole by Newton's method (newton.py).

After the position pass's sweeps, such an island that misses by more than CONVERGED, with at most DIRECT_ROWS rows
that push, is solved whole in its push impulses (one row a contact, so a direct solve of them is determined up to
the rows that depend on others), SUBSPACE_ROUNDS times at most (subspace minimization after the sweeps, the scheme
Silcowitz, Niebe and Erleben call PGS-SM: "A nonsmooth Newton method with applications to computer animation",
2010):

    the rows that push: above their least impulse, or closing faster than their target
    A dp = target - u~       A = J M^-1 J^T of those rows (dense, Cholesky; a row that depends on the rows before
                             it is dropped), u~ their pseudo-velocities now
    p' = max(p_least, p + dp), then ISLAND_SWEEPS sweeps of the island's contacts (the projection's leftovers)

Either way, an island that the solve left missing its targets by more than the sweeps did, or (velocities) whose
contacts it made give its bodies energy, or whose bodies it left more kinetic energy than they had before the
step's impulses, is put back as they left it. Data (data.py Islands): parent (n+1,), the
union-find forest of the bodies; first (n+2,), where each island's contacts start in the contacts' `member`; fill
(n+1,) scratch; rows (DIRECT_ROWS,) the rows solved (contact * 3); dense (DIRECT_ROWS, DIRECT_ROWS) and rhs
(DIRECT_ROWS,) the system; y (n+1, 13) the island's velocities (or pseudo-velocities) before, to put back; local,
order, step and grad: newton.py's.
"""
from __future__ import annotations

import math

from ..core.bodies import kinetic
from ..core.build import MASS_RATIO
from ..core.jit import kernel
from .newton import STUCK, cholesky_solve, solve_island
from .position import separate_one
from .solve import MOVED, VELOCITY_SWEEPS, contact_work, push, speed, sweep_island

# an island whose rows miss their targets by more than this after the position pass's sweeps is solved whole (m/s
# of pseudo-velocity): 1 % of what gravity adds to a speed in a step of 1 ms
CONVERGED = 1e-4
# ... after the velocity sweeps (m/s): the Newton solve's own give leaves 3e-6 (newton.py STIFFNESS). A stack of 8
# cubes of alternating densities at 4 ms, looked at each frame: gated at 1e-4 its cubes turned at up to 9.2e-4
# rad/s, between steps solved whole and steps left to the sweeps, and it was solved 92 times in 1.4 s; at 1e-5,
# 8e-5 rad/s and 28 times
STILL = 1e-5
# (either, only if its heaviest body is MASS_RATIO times its lightest or more, core/build.py: the sweeps solve
# bodies of like masses, and a box alone on a floor misses by more than CONVERGED at most steps: solved whole, the
# pile of 125 boxes took 21 % more time)
# the most rows that push an island solved whole in the position pass may have (a stack of 48 boxes, four points a
# face; a dense solve costs k^3 / 6)
DIRECT_ROWS = 192
SUBSPACE_ROUNDS = 3
# the most bodies an island solved whole in its velocities may have (6 unknowns each: newton.py; its Hessian takes
# the place of the position pass's dense system)
MOST_BODIES = DIRECT_ROWS // 6
ISLAND_SWEEPS = 4
# a Newton solve that leaves its island's bodies more kinetic energy than they had before the step's impulses, by
# more than this fraction, is put back: contacts give no energy (restitution e <= 1, friction against the slip). The
# energy its rows' impulses account for, sum lam (u- + u+) / 2, holds only for impulses that make the velocities'
# change, and where the springs of a wall of 24 bricks struck by a ball 10 times heavier did not, it read -3.8e6 J
# while the bodies' speeds rose from 12 to 2658 m/s (exit 2 in the dynamics plan at 1 ms, 23 % of the energy
# created at 4 ms in the procedural one). Against the sweeps' energy instead, a block sliding on a light board was
# put back: the sweeps had slowed it more than Coulomb's friction does
KINETIC_RTOL = 1e-6
# a row whose pivot is below this fraction of its diagonal depends on the rows before it (newton.py
# `cholesky_solve`): exact dependence leaves 1e-14 of it; the smallest eigenvalue of the velocity rows of a slab of
# 36 kg on a cube of 0.1 kg that do not depend on others is 8.7e-3 of the largest (measured)
DEPENDENT = 1e-7
# friction within this fraction of the disc's edge is on it (a contact slipping faster than newton.STUCK slides)
EDGE = 1e-6


@kernel
def _root(parent, b):
    """The island of body b (its union-find root), halving the path."""
    while parent[b] != b:
        parent[b] = parent[parent[b]]
        b = parent[b]
    return b


@kernel
def _group(dynamic, ct, isl):
    """Each contact's island in ct.group, and the contacts by island in ct.member (island g's from isl.first[g] to
    isl.first[g + 1]): union-find over the contacts that join two dynamic bodies, then a counting sort."""
    n1 = len(isl.parent)
    for b in range(n1):
        isl.parent[b] = b
        isl.first[b] = 0
    isl.first[n1] = 0
    count = ct.count[0]
    for c in range(count):
        a, b = ct.a[c], ct.b[c]
        if dynamic[a] and dynamic[b]:
            ra, rb = _root(isl.parent, a), _root(isl.parent, b)
            if ra != rb:
                isl.parent[max(ra, rb)] = min(ra, rb)
    for c in range(count):
        g = _root(isl.parent, ct.a[c] if dynamic[ct.a[c]] else ct.b[c])
        ct.group[c] = g
        isl.first[g + 1] += 1
    for g in range(n1):
        isl.first[g + 1] += isl.first[g]
    for g in range(n1):
        isl.fill[g] = isl.first[g]  # (the next free place of island g)
    for c in range(count):
        g = ct.group[c]
        ct.member[isl.fill[g]] = c
        isl.fill[g] += 1


@kernel
def _sticks(ct, c, y):
    """Whether contact c holds with friction inside Coulomb's disc and slips slower than STUCK: its tangent rows
    hold (u_t = 0). A contact that slips faster slides, whatever its friction (a sliding block's friction, brought
    to the disc's edge, falls inside it when the sweep raises its normal impulse after its friction)."""
    limit = ct.mu[c] * ct.lam[c, 0]
    if limit <= 0.0 or math.sqrt(ct.lam[c, 1] ** 2 + ct.lam[c, 2] ** 2) >= (1.0 - EDGE) * limit:
        return False
    return speed(ct, c, 1, y) ** 2 + speed(ct, c, 2, y) ** 2 < STUCK * STUCK


@kernel
def _miss(ct, c, y):
    """How far contact c's rows are from what the solve asks (m/s): its normal row from its target while it holds,
    else by how much it approaches faster than its target; a contact that sticks (`_sticks`) by its slip."""
    u = speed(ct, c, 0, y)
    target = ct.bounce[c]
    miss = abs(target - u) if ct.lam[c, 0] > 0.0 else max(0.0, target - u)
    if _sticks(ct, c, y):
        miss = max(miss, math.sqrt(speed(ct, c, 1, y) ** 2 + speed(ct, c, 2, y) ** 2))
    return miss


@kernel
def _coupling(ct, c, r, d, s):
    """A's entry J_(c,r) M^-1 J_(d,s)^T: the change of row r of contact c's speed per unit impulse along row s of
    contact d, through each body they share: sign_c sign_d (d_c . d_d / m + (r_c x d_c) . I^-1 (r_d x d_d)), sign
    +1 for a contact's body a, -1 for its b (a body impulses do not move: 0)."""
    total = 0.0
    for side in range(2):
        body = ct.a[c] if side == 0 else ct.b[c]
        for other in range(2):
            if (ct.a[d] if other == 0 else ct.b[d]) != body:
                continue
            inv = ct.inv[d, other]
            if inv == 0.0:
                continue
            value = 0.0
            for k in range(3):
                value += inv * ct.jac[c, r, k] * ct.jac[d, s, k] + ct.jac[c, r, 3 + 3 * side + k] * ct.turn[d, s, 3 * other + k]
            total += value if side == other else -value
    return total


@kernel
def _position_miss(ct, c, pseudo):
    """How far contact c's row of the position pass is from its target (m/s of pseudo-velocity): while its impulse
    is above its least, from the target, else by how much it closes faster than it (0 while it has none yet)."""
    target = ct.bounce[c]
    if math.isnan(target):
        return 0.0
    u = speed(ct, c, 0, pseudo)
    return abs(target - u) if ct.push[c] > ct.base[c] else max(0.0, target - u)


@kernel
def _pushing_rows(ct, pseudo, isl, first, end):
    """isl.rows <- the island's rows of the position pass that push (above their least impulse, or closing faster
    than their target), isl.rhs <- target - u~ of each. Returns their count (beyond DIRECT_ROWS: not filled past
    it)."""
    k = 0
    for i in range(first, end):
        c = ct.member[i]
        if math.isnan(ct.bounce[c]):
            continue
        u = speed(ct, c, 0, pseudo)
        if ct.push[c] > ct.base[c] or u < ct.bounce[c]:
            if k < DIRECT_ROWS:
                isl.rows[k], isl.rhs[k] = 3 * c, ct.bounce[c] - u
            k += 1
    return k


@kernel
def _position_subspace(ct, pseudo, isl, k):
    """The direct solve of the position pass's k rows in isl.rows: each contact's push impulse projected onto its
    least (ct.base) and applied to the pseudo-velocities."""
    for i in range(k):
        for j in range(i + 1):
            isl.dense[i, j] = _coupling(ct, isl.rows[i] // 3, 0, isl.rows[j] // 3, 0)
    cholesky_solve(isl.dense, isl.rhs, k, DEPENDENT)
    for i in range(k):
        c = isl.rows[i] // 3
        lam = max(ct.base[c], ct.push[c] + isl.rhs[i])
        push(ct, c, 0, pseudo, lam - ct.push[c])
        ct.push[c] = lam
        pseudo[ct.a[c], MOVED], pseudo[ct.b[c], MOVED] = 1.0, 1.0


@kernel
def _held(ct, c, positions):
    """Whether contact c's row holds without a look at its speed: its impulse above 0 (in the position pass, above
    its least)."""
    return ct.push[c] > ct.base[c] if positions else ct.lam[c, 0] > 0.0


@kernel
def _island_miss(ct, v, first, end, positions):
    """The island's largest miss (`_miss`, or `_position_miss` in the position pass: v its pseudo-velocities)."""
    miss = 0.0
    for i in range(first, end):
        c = ct.member[i]
        miss = max(miss, _position_miss(ct, c, v) if positions else _miss(ct, c, v))
    return miss


@kernel
def _island_work(ct, y, first, end):
    """The energy the island's contact impulses gave its bodies this step (J; solve.py `work`): a solve that gives
    more than the sweeps did, and more than 0, is put back (a 36 kg slab landing on a light cube with e = 0.2, in the
    procedural plan at 4 ms, rose 2.3 % when it was not)."""
    total = 0.0
    for i in range(first, end):
        total += contact_work(ct, ct.member[i], y)
    return total


@kernel
def _kinetic(bodies, R, ct, v, isl, first, end):
    """The kinetic energy of the island's dynamic bodies at velocities v (J; each body once: isl.local marks it
    meanwhile, and is cleared again)."""
    total = 0.0
    for i in range(first, end):
        c = ct.member[i]
        for b in (ct.a[c], ct.b[c]):
            if bodies.dynamic[b] and isl.local[b] < 0:
                isl.local[b] = 0
                total += kinetic(bodies, R, v, b)
    for i in range(first, end):
        c = ct.member[i]
        isl.local[ct.a[c]], isl.local[ct.b[c]] = -1, -1
    return total


@kernel
def _round(ct, pseudo, y, h, isl, k, first, end):
    """One direct solve of the position pass's k rows in isl.rows, then ISLAND_SWEEPS sweeps of its contacts."""
    _position_subspace(ct, pseudo, isl, k)
    for _ in range(ISLAND_SWEEPS):
        for i in range(first, end):
            separate_one(ct, ct.member[i], pseudo, y, h)


@kernel
def _keep(ct, v, isl, first, end, back, positions):
    """The island's impulses (its pushes, in the position pass) and its bodies' velocities v (pseudo-velocities,
    with the column that marks a body moved) kept (back False) in ct.kept and isl.y, or put back (True)."""
    for i in range(first, end):
        c = ct.member[i]
        for row in range(1 if positions else 3):
            if back:
                if positions:
                    ct.push[c] = ct.kept[c, 0]
                else:
                    ct.lam[c, row] = ct.kept[c, row]
            else:
                ct.kept[c, row] = ct.push[c] if positions else ct.lam[c, row]
        for body in (ct.a[c], ct.b[c]):
            for k in range(0 if positions else 7, 13):
                if back:
                    v[body, k] = isl.y[body, k]
                else:
                    isl.y[body, k] = v[body, k]


@kernel
def _needs_solving(ct, v, isl, first, end, positions):
    """How far the island's rows miss their targets (`_island_miss`) if it is to be solved whole: its heaviest body
    at least MASS_RATIO times its lightest (and, in the position pass, at most DIRECT_ROWS rows that push), else 0."""
    held, lightest, heaviest = 0, math.inf, 0.0
    for i in range(first, end):
        c = ct.member[i]
        held += 1 if _held(ct, c, positions) else 0
        for side in range(2):
            if ct.inv[c, side] > 0.0:  # (1 / m)
                lightest, heaviest = min(lightest, ct.inv[c, side]), max(heaviest, ct.inv[c, side])
    if end == first or (positions and held > DIRECT_ROWS) or heaviest < MASS_RATIO * lightest:
        return 0.0  # (bodies of like masses: their speeds are not looked at)
    return _island_miss(ct, v, first, end, positions)


@kernel
def _separate_whole(ct, pseudo, y, h, isl, first, end):
    """The position pass's island solved whole, SUBSPACE_ROUNDS times at most (module docstring). Returns False
    if it was not (no rows that push, or more than DIRECT_ROWS)."""
    for round in range(SUBSPACE_ROUNDS):
        k = _pushing_rows(ct, pseudo, isl, first, end)
        if k == 0 or k > DIRECT_ROWS:
            return round > 0
        _round(ct, pseudo, y, h, isl, k, first, end)
        if _island_miss(ct, pseudo, first, end, True) <= CONVERGED:
            break
    return True


@kernel
def _solve_whole(bodies, R, ct, v, y, h, isl, positions, kicked):
    """Each island (`_group`) that the sweeps left missing its targets by more than CONVERGED, with bodies whose
    masses differ MASS_RATIO times or more, solved whole (module docstring); one that the solve left missing more than
    the sweeps did, or whose contacts it made give energy, or (velocities) whose bodies it left more kinetic energy
    than they had before the step's impulses (kicked: the velocities of the kick), put back as they left it. v: the
    velocities (y), or the position pass's pseudo-velocities. Returns how many were solved."""
    solved = 0
    for g in range(len(isl.parent)):
        first, end = isl.first[g], isl.first[g + 1]
        missed = _needs_solving(ct, v, isl, first, end, positions)
        if missed <= (CONVERGED if positions else STILL):
            continue
        _keep(ct, v, isl, first, end, False, positions)
        given = 0.0 if positions else _island_work(ct, v, first, end)
        moving = 0.0 if positions else _kinetic(bodies, R, ct, kicked, isl, first, end)
        if positions:
            done = _separate_whole(ct, v, y, h, isl, first, end)
        else:
            done = solve_island(bodies, R, ct, v, isl.y, isl, first, end, MOST_BODIES)
        if not done:
            continue
        if _island_miss(ct, v, first, end, positions) > missed or (not positions and (
                _island_work(ct, v, first, end) > max(given, 0.0)
                or _kinetic(bodies, R, ct, v, isl, first, end) > moving * (1.0 + KINETIC_RTOL))):
            _keep(ct, v, isl, first, end, True, positions)
        else:
            solved += 1
    return solved


@kernel
def sweep_islands(dynamic, ct, y, isl, regroup):
    """The velocity sweeps of a scene without joints, island by island (grouped first when regroup: `_group`),
    each island's ended at the first that leaves its rows' speeds as they were within solve.py SETTLED, VELOCITY_SWEEPS
    at most: the same updates in the same order as sweeps over all the contacts, since no two islands share a
    moving body, and none for an island that has settled."""
    if regroup:
        _group(dynamic, ct, isl)
    for g in range(len(isl.parent)):
        first, end = isl.first[g], isl.first[g + 1]
        for _ in range(VELOCITY_SWEEPS if end > first else 0):
            if not sweep_island(ct, y, first, end):
                break


@kernel
def solve_islands(bodies, R, ct, y, kicked, isl):
    """Each of the step's islands (grouped by `sweep_islands`) that its velocity sweeps left unsolved, solved whole
    (`_solve_whole`; kicked: the velocities before the step's impulses). Returns how many were."""
    return _solve_whole(bodies, R, ct, y, y, 0.0, isl, False, kicked)


@kernel
def separate_islands(bodies, R, ct, pseudo, y, h, isl):
    """The position pass's islands (grouped by `sweep_islands` this step) that its sweeps left unsolved, solved
    whole as the velocities are: a heavy capsule on a light cube was pushed out of it by moving the cube into the
    floor, and sank 14 mm in 0.5 s with every velocity row met. Returns how many were."""
    # (kicked: y, which the position pass never reads)
    return _solve_whole(bodies, R, ct, pseudo, y, h, isl, True, y)
