"""Islands that projected Gauss-Seidel leaves unsolved, solved whole: the bodies that touch one another, with a
direct solve of the rows that hold (subspace minimization after the sweeps, the scheme Silcowitz, Niebe and Erleben
call PGS-SM: "A nonsmooth Newton method with applications to computer animation", 2010).

Gauss-Seidel passes an impulse from contact to contact one sweep at a time. Where a heavy body rests on a light
one, each sweep passes on about m_light / (m_heavy + m_light) of the weight: a 36 kg slab on a 0.1 kg cube on a floor
needs thousands of sweeps where 16 are taken, and the slab sank through the cube by 1.5 to 12 mm (400 sweeps: still
1.6 mm at 4 ms). An island is the dynamic bodies joined by contacts (a static or kinematic body joins nothing: the
floor under a heap does not make the heap one island with the next heap). After the sweeps, an island whose
heaviest body is RATIO times its lightest or more, whose rows still miss their targets by more than CONVERGED, and
that has at most DIRECT_ROWS rows that hold, is solved whole, SUBSPACE_ROUNDS times at most:

    the rows that hold: each normal row with lam_n > 0 or that approaches faster than its target, and the two
    friction rows of each contact that holds and sticks (friction inside Coulomb's disc, slipping slower than
    STUCK); a sliding contact's friction stays as the sweeps left it
    A dlam = target - u      A = J M^-1 J^T of those rows (dense, Cholesky; a row that depends on the rows before
                             it is dropped), u their speeds now
    lam_n' = max(0, lam_n + dlam_n), lam_t' = lam_t + dlam_t projected onto Coulomb's disc of mu lam_n'
    ISLAND_SWEEPS sweeps of the island's contacts (the projection's leftovers)

An island that the solve left missing its targets by more than the sweeps did, or whose contacts it made give its
bodies energy, is put back as they left it (a stack of 8 cubes of alternating densities: the rows that hold ask for
normal impulses down to -0.56 N s). The position
pass's islands are solved the same way after its sweeps, its normal rows only (`separate_islands`). A heap, whose
islands have more rows, is left to the sweeps. Data (data.py Islands): parent (n+1,), the union-find forest of the
bodies; first (n+2,), where each island's contacts start in the contacts' `member`; fill (n+1,) scratch; rows
(DIRECT_ROWS,) the rows solved (contact * 3 + row); dense (DIRECT_ROWS, DIRECT_ROWS) and rhs (DIRECT_ROWS,) the
system; y (n+1, 13) the island's velocities (or pseudo-velocities) before, to put back.
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from .solve import MOVED, contact_work, push, relax, separate_one, speed

# an island whose rows miss their targets by more than this after the sweeps is solved whole (m/s): 1 % of what
# gravity adds to a speed in a step of 1 ms
CONVERGED = 1e-4
# ... if the heaviest of its bodies is at least this many times its lightest: the sweeps solve bodies of like masses
# (a box alone on a floor misses by more than CONVERGED at most steps: solved whole, the pile of 125 boxes took
# 21 % more time)
RATIO = 10.0
# the most rows an island solved whole may have (a stack of 16 boxes, four points a face, all sticking; a dense solve
# costs k^3 / 6: without RATIO, solving islands of up to 192 rows made the shipped dominoes 44 % slower)
DIRECT_ROWS = 192
SUBSPACE_ROUNDS = 3
ISLAND_SWEEPS = 4
# a row whose pivot is below this fraction of its diagonal depends on the rows before it (`_solve_dense`): exact
# dependence leaves 1e-14 of it, a slab of 36 kg on a cube of 0.1 kg 3e-3
DEPENDENT = 1e-7
# friction within this fraction of the disc's edge is on it; a contact slipping faster than this (m/s) slides
EDGE = 1e-6
STUCK = 1e-2


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
def _holding_rows(ct, y, isl, first, end):
    """isl.rows <- the island's rows that hold (module docstring) as contact * 3 + row, a contact's normal row
    first, isl.rhs <- target - u of each. Returns their count (beyond DIRECT_ROWS: not filled past it)."""
    k = 0
    for i in range(first, end):
        c = ct.member[i]
        u = speed(ct, c, 0, y)
        if not (ct.lam[c, 0] > 0.0 or u < ct.bounce[c]):
            continue
        rows = 3 if _sticks(ct, c, y) else 1
        if k + rows <= DIRECT_ROWS:
            isl.rows[k], isl.rhs[k] = 3 * c, ct.bounce[c] - u
            for row in range(1, rows):
                isl.rows[k + row], isl.rhs[k + row] = 3 * c + row, -speed(ct, c, row, y)
        k += rows
    return k


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
def _solve_dense(isl, k):
    """isl.rhs <- A^-1 rhs for the k rows' A in isl.dense (lower triangle, overwritten by its Cholesky factor), each
    row that depends on the rows before it (its pivot below DEPENDENT of its diagonal) dropped: its change 0. A
    face's four points on a face hold a body by three independent rows, and their targets (each point's gap / h)
    need not agree: solved with A regularized, the fourth's disagreement of 1e-4 m/s came back as 2e4 N s."""
    A, x = isl.dense, isl.rhs
    # A = L L^T, L in A's lower triangle; a dropped row's column of L is 0
    for j in range(k):
        pivot = A[j, j]
        for p in range(j):
            pivot -= A[j, p] * A[j, p]
        if pivot <= DEPENDENT * A[j, j]:
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
    # L z = rhs, then L^T x = z
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
def _subspace(ct, y, isl, k):
    """One round of the direct solve of the k rows in isl.rows (module docstring): A assembled and solved, each
    contact's new impulses projected (lam_n >= 0, friction onto Coulomb's disc of mu lam_n') and applied."""
    for i in range(k):
        c, r = isl.rows[i] // 3, isl.rows[i] % 3
        for j in range(i + 1):
            isl.dense[i, j] = _coupling(ct, c, r, isl.rows[j] // 3, isl.rows[j] % 3)
    _solve_dense(isl, k)
    i = 0
    while i < k:
        c = isl.rows[i] // 3
        sticking = i + 1 < k and isl.rows[i + 1] // 3 == c
        normal = max(0.0, ct.lam[c, 0] + isl.rhs[i])
        l1, l2 = ct.lam[c, 1], ct.lam[c, 2]
        if sticking:
            l1, l2 = l1 + isl.rhs[i + 1], l2 + isl.rhs[i + 2]
        # |lam_t| <= mu lam_n'
        size, limit = math.sqrt(l1 * l1 + l2 * l2), ct.mu[c] * normal
        if size > limit:
            scale = limit / size
            l1, l2 = l1 * scale, l2 * scale
        push(ct, c, 0, y, normal - ct.lam[c, 0])
        push(ct, c, 1, y, l1 - ct.lam[c, 1])
        push(ct, c, 2, y, l2 - ct.lam[c, 2])
        ct.lam[c, 0], ct.lam[c, 1], ct.lam[c, 2] = normal, l1, l2
        i += 3 if sticking else 1


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
    _solve_dense(isl, k)
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
def _rows(ct, v, isl, first, end, positions):
    return _pushing_rows(ct, v, isl, first, end) if positions else _holding_rows(ct, v, isl, first, end)


@kernel
def _round(ct, v, y, h, isl, k, first, end, positions):
    """One direct solve of the island's k rows in isl.rows, then ISLAND_SWEEPS sweeps of its contacts."""
    if positions:
        _position_subspace(ct, v, isl, k)
    else:
        _subspace(ct, v, isl, k)
    for _ in range(ISLAND_SWEEPS):
        for i in range(first, end):
            if positions:
                separate_one(ct, ct.member[i], v, y, h)
            else:
                relax(ct, ct.member[i], v)


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
def _solve_whole(ct, v, y, h, isl, positions):
    """Each island (`_group`) that the sweeps left missing its targets by more than CONVERGED, with at most
    DIRECT_ROWS rows that hold, solved whole (module docstring); one that the solve left missing more than the
    sweeps did put back as they left it. v: the velocities (y), or the position pass's pseudo-velocities. Returns
    how many were solved."""
    solved = 0
    for g in range(len(isl.parent)):
        first, end = isl.first[g], isl.first[g + 1]
        held, lightest, heaviest = 0, math.inf, 0.0
        for i in range(first, end):
            c = ct.member[i]
            held += 1 if _held(ct, c, positions) else 0
            for side in range(2):
                if ct.inv[c, side] > 0.0:  # (1 / m)
                    lightest, heaviest = min(lightest, ct.inv[c, side]), max(heaviest, ct.inv[c, side])
        if end == first or held > DIRECT_ROWS or heaviest < RATIO * lightest:
            continue  # (a heap, or bodies of like masses: its speeds are not looked at)
        missed = _island_miss(ct, v, first, end, positions)
        if missed <= CONVERGED:
            continue
        k = _rows(ct, v, isl, first, end, positions)
        if k == 0 or k > DIRECT_ROWS:
            continue
        _keep(ct, v, isl, first, end, False, positions)
        given = 0.0 if positions else _island_work(ct, v, first, end)
        for round in range(SUBSPACE_ROUNDS):
            if round > 0:
                k = _rows(ct, v, isl, first, end, positions)
                if k == 0 or k > DIRECT_ROWS:
                    break
            _round(ct, v, y, h, isl, k, first, end, positions)
            if _island_miss(ct, v, first, end, positions) <= CONVERGED:
                break
        if _island_miss(ct, v, first, end, positions) > missed or (
                not positions and _island_work(ct, v, first, end) > max(given, 0.0)):
            _keep(ct, v, isl, first, end, True, positions)
        else:
            solved += 1
    return solved


@kernel
def solve_islands(dynamic, ct, y, isl):
    """The step's islands grouped (`_group`), and each that its velocity sweeps left unsolved solved whole
    (`_solve_whole`). Returns how many were."""
    _group(dynamic, ct, isl)
    return _solve_whole(ct, y, y, 0.0, isl, False)


@kernel
def separate_islands(ct, pseudo, y, h, isl):
    """The position pass's islands (grouped by `solve_islands` this step) that its sweeps left unsolved, solved
    whole as the velocities are: a heavy capsule on a light cube was pushed out of it by moving the cube into the
    floor, and sank 14 mm in 0.5 s with every velocity row met. Returns how many were."""
    return _solve_whole(ct, pseudo, y, h, isl, True)
