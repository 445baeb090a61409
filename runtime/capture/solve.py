"""The contact solve of the capturing step, compiled: one velocity-level problem for every contact of the step,
impacts and friction included (Moreau-Jean's scheme, with Newton's restitution), by projected Gauss-Seidel over
the contacts (sequential impulses), warm-started from the last step's impulses of the same features.

A contact c between bodies a and b at point p, normal n (from b toward a), has three rows, d = n, t1, t2:

    u_d = d . (v_a + w_a x r_a - v_b - w_b x r_b)                 the relative velocity along d
    m_d = 1 / (1/m_a + 1/m_b + (r_a x d) . I_a^-1 (r_a x d) + (r_b x d) . I_b^-1 (r_b x d))

    normal   u_n+ >= target,  lam_n >= 0,  lam_n (u_n+ - target) = 0
             target = 0; a contact still apart by a gap g that it does not close within the step: -g / h (it may
             close the gap, not cross it)
    friction |(lam_t1, lam_t2)| <= mu lam_n (Coulomb's disc), no slip while inside it

Impacts come first, in generations (`impacts`): while a contact approaches faster than the resting speed, it gets
the two-body impulse of Newton's restitution, p = -(1 + e) m_n u_n, and what that sets in motion is seen by the
next contacts of the sweep (a row of balls passes the striker's speed down the row, as Newton's cradle does; one
simultaneous solve would send the row off together). Each such impulse keeps or loses kinetic energy (e <= 1).
After each generation's normal impulses, the friction of its struck points (`_rub`): within Coulomb's disc of
radius mu hit, each move shortened so that it gives no energy (a ball landing with slip leaves rolling at 5/7 of it
even when it bounces). A contact still apart by a gap strikes where the gap closes: its arms reach each body's own
surface point (`prepare`), not the midway point.
The impacts see the velocities the forces and the earlier generations gave, not the warm start, which is applied
after them (`warm_start`): a guess of the sustained impulses that the sweeps may take back must not set off a
bounce that they cannot.

Each row is prepared once per step (`prepare`), as a sequential-impulse solver keeps it: its Jacobian
(d, r_a x d, r_b x d) and what a unit impulse along it does to each body (d / m, I^-1 (r x d); zero for a body
impulses do not move; 1/m kept once per contact), so a sweep's update costs a few dot products. One Gauss-Seidel
update of row d: lam' = max(0, lam + m_d (target - u_d)) for the normal, the tangents' pair projected onto the
disc, and the change applied to both bodies at once, so momentum is kept exactly by every update.
Interpenetration is removed by a separate pass on pseudo-velocities (position.py).

Energy: the impulses P change the kinetic energy by dK = (v+ - v-)^T M (v+ + v-) / 2 = sum over rows of
lam (u- + u+) / 2. With e <= 1 and friction opposing slip a converged solve has dK <= 0: a step whose contacts
create more than ENERGY_TOL of the scale is counted, with its time and the pair that created the most.
"""
from __future__ import annotations

import math

from ..core.jit import inlined, kernel
from ..core.vec import add3, cross3, dot3, rotate, scale3, sub3
from .data import FEATURES

# sweeps of impacts in generations per step, at most (then restitution 0); sweeps over one pair's points
IMPACT_SWEEPS = 64
PAIR_SWEEPS = 16
# velocity sweeps (warm-started) per step, at most
VELOCITY_SWEEPS = 16
# in a scene without joints each island (islands.py) takes its velocity sweeps alone, and ends them at the first
# that changes none of its rows' speeds by more than this (m/s): an island whose warm start already holds it takes
# one or two (a domino standing, or lying still), a heap's island all 16 (its sweeps still change speeds by 1e-3
# m/s at the 16th). Stopping a whole step's sweeps at 1e-6 m/s left a pyramid of 28 boxes turning at 3e-5 rad/s.
# Measured in one run: 12 % fewer cycles for a pile of 125 spheres, 19 % for 125 boxes, 17 % for the dominoes
SETTLED = 1e-9
# how far a contact's point may be from the last step's point of another feature of its pair for it to take that
# one's impulses as its warm start (m)
MATCH = 5e-4
# energy a step's contact impulses may create before it is counted, relative to the energy scale
ENERGY_TOL = 1e-6
# the column of the position pass's pseudo-velocities (columns 7..12) that marks a body it moved (1.0)
MOVED = 0


@kernel
def tangents(n):
    """Two unit tangents of the unit normal n, fixed by n alone (warm starting keeps their impulses)."""
    # the world axis least along n, crossed with it
    if abs(n[0]) <= abs(n[1]) and abs(n[0]) <= abs(n[2]):
        t = (0.0, n[2], -n[1])
    elif abs(n[1]) <= abs(n[2]):
        t = (-n[2], 0.0, n[0])
    else:
        t = (n[1], -n[0], 0.0)
    size = math.sqrt(dot3(t, t))
    t1 = scale3(1.0 / size, t)
    return t1, cross3(n, t1)


@kernel
def _jacobian(bodies, invI, ct, c, row, d, ra, rb):
    """Row `row` of contact c along the unit d: ct.jac[c, row] = (d, r_a x d, r_b x d), ct.turn[c, row] =
    (I_a^-1 (r_a x d), I_b^-1 (r_b x d)), and its effective mass ct.mass[c, row]; ct.inv[c] = (1/m_a, 1/m_b).
    A body that impulses do not move has 1/m and I^-1 zero."""
    a, b = ct.a[c], ct.b[c]
    rad, rbd = cross3(ra, d), cross3(rb, d)
    da = bodies.inv_mass[a] if bodies.dynamic[a] else 0.0
    db = bodies.inv_mass[b] if bodies.dynamic[b] else 0.0
    ta = rotate(invI, a, rad) if bodies.dynamic[a] else (0.0, 0.0, 0.0)
    tb = rotate(invI, b, rbd) if bodies.dynamic[b] else (0.0, 0.0, 0.0)
    for k in range(3):
        ct.jac[c, row, k], ct.jac[c, row, 3 + k], ct.jac[c, row, 6 + k] = d[k], rad[k], rbd[k]
        ct.turn[c, row, k], ct.turn[c, row, 3 + k] = ta[k], tb[k]
    ct.inv[c, 0], ct.inv[c, 1] = da, db
    # m_d = 1 / (1/m_a + (r_a x d) . I_a^-1 (r_a x d) + 1/m_b + (r_b x d) . I_b^-1 (r_b x d))
    w = da + dot3(rad, ta) + db + dot3(rbd, tb)
    ct.mass[c, row] = 1.0 / w if w > 0.0 else 0.0


@kernel
def speed(ct, c, row, y):
    """u_d = d . (v_a - v_b) + (r_a x d) . w_a - (r_b x d) . w_b, which is d . (v_a + w_a x r_a - v_b - w_b x r_b),
    of row `row` of contact c (y: the state, or the position pass's pseudo-velocities)."""
    a, b = ct.a[c], ct.b[c]
    u = 0.0
    for k in range(3):
        u += (ct.jac[c, row, k] * (y[a, 7 + k] - y[b, 7 + k]) + ct.jac[c, row, 3 + k] * y[a, 10 + k]
              - ct.jac[c, row, 6 + k] * y[b, 10 + k])
    return u


@kernel
def push(ct, c, row, y, p):
    """Impulse p along row `row` of contact c: +p d on a at r_a, -p d on b at r_b."""
    a, b = ct.a[c], ct.b[c]
    pa, pb = p * ct.inv[c, 0], p * ct.inv[c, 1]
    for k in range(3):
        y[a, 7 + k] += pa * ct.jac[c, row, k]
        y[a, 10 + k] += p * ct.turn[c, row, k]
        y[b, 7 + k] -= pb * ct.jac[c, row, k]
        y[b, 10 + k] -= p * ct.turn[c, row, 3 + k]


@kernel
def prepare(bodies, invI, ct, y, n, h):
    """Rows of every contact (module docstring): tangents, Jacobians, masses, velocities before, the normal's
    target; then the last step's impulses of the same features in ct.lam (the warm start, applied after the
    impacts: `warm_start`)."""
    count = ct.count[0]
    for c in range(count):
        a, b = ct.a[c], ct.b[c]
        p, nrm = (ct.point[c, 0], ct.point[c, 1], ct.point[c, 2]), (ct.normal[c, 0], ct.normal[c, 1], ct.normal[c, 2])
        # the arms reach each body's own surface point, p +- (g / 2) n, where a contact still apart by a gap g will
        # strike (the midway point p of two that overlap is common to both): from p, a ball landing across a gap had
        # an arm g / 2 too long, and its impact's friction left it rolling at 0.7216 m/s where 5/7 of 1 m/s is 0.7143
        half = 0.5 * max(-ct.depth[c], 0.0)
        ra = sub3(add3(p, scale3(half, nrm)), (y[a, 0], y[a, 1], y[a, 2]))
        rb = sub3(sub3(p, scale3(half, nrm)), (y[b, 0], y[b, 1], y[b, 2]))
        t1, t2 = tangents(nrm)
        _jacobian(bodies, invI, ct, c, 0, nrm, ra, rb)
        _jacobian(bodies, invI, ct, c, 1, t1, ra, rb)
        _jacobian(bodies, invI, ct, c, 2, t2, ra, rb)
        for row in range(3):
            ct.before[c, row] = speed(ct, c, row, y)
        gap = -ct.depth[c]
        ct.hit[c], ct.approach[c] = 0.0, 0.0
        ct.hit_t[c, 0], ct.hit_t[c, 1] = 0.0, 0.0
        ct.push[c] = max(gap, 0.0)  # (the gap, until `impacts` sets the targets)
        ct.key[c] = (a * n + b) * FEATURES + ct.feature[c]
    # the warm start after every contact's velocities before were measured (they are the step's own): the last
    # step's contact of the same feature, else the nearest of the same pair within MATCH (a point where two
    # features meet, as aligned edges of a stack, changes its feature with the slightest turn), each taken once
    if ct.count[3] < 0:
        _index_old(ct)  # (the buffers were grown: the last step's contacts were copied, not indexed)
    for i in range(ct.count[2]):
        ct.old_used[i] = 0
    for c in range(count):
        first, end = _old_run(ct, ct.key[c] // FEATURES)
        ct.match[c] = -1
        for i in range(first, end):
            if ct.old_key[i] == ct.key[c]:
                ct.match[c] = i
                ct.old_used[i] = 1
                break
    for c in range(count):
        if ct.match[c] < 0:
            ct.match[c] = _nearest_old(ct, c)
    for c in range(count):
        old = ct.match[c]
        ct.acc[c] = ct.old_acc[old] if old >= 0 else 0.0
        take_old(ct, c)


@kernel
def take_old(ct, c):
    """Contact c's impulses <- those its match (`prepare`) held at the last step's end, or none: its warm start."""
    old = ct.match[c]
    for row in range(3):
        ct.lam[c, row] = ct.old_lam[old, row] if old >= 0 else 0.0


@kernel
def warm_start(ct, y):
    """The warm start's impulses (ct.lam, from `prepare`) applied, after the impacts (`impacts`). Struck from
    velocities with the warm start in them, a sphere wedged in a tube was pushed into the wall by its neighbour's
    last impulse, bounced off it (e = 0.3), and kept the bounce when the sweeps took that impulse back: a column of
    12 spheres (3 cm, 2000 kg/m3) in a tube of planes gained 0.38 J, 3.5 % of what its fall makes available, at
    4 ms, and 1e-4 J with the warm start after the impacts; 15 steel ones (e = 0.7) gained 5 % at 0.5 ms (found
    2026-12-07)."""
    for c in range(ct.count[0]):
        for row in range(3):
            push(ct, c, row, y, ct.lam[c, row])


@kernel
def _nearest_old(ct, c):
    """The last step's contact of contact c's pair nearest to its point within MATCH and not taken yet (marked
    taken), or -1."""
    first, end = _old_run(ct, ct.key[c] // FEATURES)
    best, nearest = -1, MATCH * MATCH
    for i in range(first, end):
        if ct.old_used[i] == 0:
            d = 0.0
            for k in range(3):
                d += (ct.old_point[i, k] - ct.point[c, k]) ** 2
            if d < nearest:
                best, nearest = i, d
    if best >= 0:
        ct.old_used[best] = 1
    return best


@kernel
def keep_old(ct):
    """The step's contacts become the last step's (warm starting), in their order (each pair's consecutive), and
    each pair's run of them is indexed by its key."""
    count = ct.count[0]
    for c in range(count):
        ct.old_key[c], ct.old_acc[c] = ct.key[c], ct.acc[c]
        for k in range(3):
            ct.old_lam[c, k], ct.old_point[c, k] = ct.lam[c, k], ct.point[c, k]
    ct.count[2] = count
    _index_old(ct)


@kernel
def _slot(runs, pair, stamp):
    """Where pair's entry is, or would go, in the open-addressing table runs (linear probing from its hash;
    entries of another stamp are free)."""
    mask = len(runs) - 1
    # Fibonacci hashing: the pair key times 2^64 / golden ratio (mod 2^64), its high bits
    i = ((pair * -7046029254386353131) >> 40) & mask
    while runs[i, 3] == stamp and runs[i, 0] != pair:
        i = (i + 1) & mask
    return i


@kernel
def _index_old(ct):
    """ct.runs <- for each pair of the last step's contacts, where its run of them starts and ends, under a new
    stamp in ct.count[3] (every entry of the last index is free at once)."""
    stamp = max(ct.count[3], 0) + 1
    ct.count[3] = stamp
    c, count = 0, ct.count[2]
    while c < count:
        pair = ct.old_key[c] // FEATURES
        end = c
        while end < count and ct.old_key[end] // FEATURES == pair:
            end += 1
        i = _slot(ct.runs, pair, stamp)
        ct.runs[i, 0], ct.runs[i, 1], ct.runs[i, 2], ct.runs[i, 3] = pair, c, end, stamp
        c = end


@kernel
def _old_run(ct, pair):
    """(first, end) of the last step's contacts of pair ((0, 0): none)."""
    i = _slot(ct.runs, pair, ct.count[3])
    if ct.runs[i, 3] != ct.count[3]:
        return 0, 0
    return ct.runs[i, 1], ct.runs[i, 2]


@kernel
def _strikes(ct, c, u, h, resting):
    """Whether contact c, at normal speed u now, is an impact: it approaches faster than the resting speed and
    closes its gap within the step. A contact that pressed in the last step (its warm start lam_n > 0) strikes only
    when this step's impacts made it approach faster than before them: the residual speeds of a resting stack's
    solve are not impacts (bouncing them fed the residual back: a pyramid of 28 boxes rocked at 0.5 rad/s)."""
    return u < -resting and u * h <= -ct.push[c] and (ct.lam[c, 0] <= 0.0 or u < ct.before[c, 0] - resting)


@kernel
def _rebound(ct, c, u, h, start):
    """The normal speed contact c leaves its first impact of the step with, at normal speed u now (< 0): Newton's
    restitution at the impact's time tau (the gap closed at u: tau = gap / |u|), then the forces' for the rest of
    the step, u+ = -e u(tau) + a (h - tau), u(tau) = u - a (h - tau), a h = the kick's change of the normal speed
    (ct.before less its speed at the step's start, `start`'s velocities). Struck at u, the speed of the step's end,
    a ball bounced (1 + e) g (h - tau) too fast and its impulse was as much too large (rubber balls at 1 ms: up to
    1.4 % off; at their time, 0.025 %: tests/runtime/test_capture_landing.py). Not below 0: the contact stops."""
    kick = ct.before[c, 0] - speed(ct, c, 0, start)
    rest = h - min(h, ct.push[c] / -u)
    # u+ = -e u + (1 + e) a (h - tau)
    return max(0.0, -ct.e[c] * u + (1.0 + ct.e[c]) * kick * rest / h)


@kernel
def _strike(ct, y, first, end, h, resting, start):
    """One generation's impact of the pair whose contacts are first..end-1, if one of them approaches faster than
    the resting speed within the step: its points together (a face landing on a face is one impact, not four that
    turn it), targets u+ = -e u- from their velocities now (a contact's first impact of the step: at its time,
    `_rebound`), ct.hit grown, each kept >= its value before (PGS on the pair's points). Returns whether it struck."""
    approaching = False
    for c in range(first, end):
        u = speed(ct, c, 0, y)
        closes = u * h <= -ct.push[c]
        struck = _strikes(ct, c, u, h, resting)
        approaching = approaching or struck
        # its target u+ = -e u- (ct.bounce), or -1: not in this generation
        ct.bounce[c] = -1.0
        if u < 0.0 and closes:
            ct.bounce[c] = _rebound(ct, c, u, h, start) if ct.hit[c] == 0.0 else -ct.e[c] * u
        ct.base[c] = ct.hit[c]
        if struck:
            ct.approach[c] = max(ct.approach[c], -u)
    if not approaching:
        return False
    for _ in range(PAIR_SWEEPS):
        for c in range(first, end):
            if ct.bounce[c] < 0.0:
                continue
            # hit' = max(hit before the generation, hit + m_n (target - u)): a point may give back what this
            # generation gave it, never pull
            hit = max(ct.base[c], ct.hit[c] + ct.mass[c, 0] * (ct.bounce[c] - speed(ct, c, 0, y)))
            push(ct, c, 0, y, hit - ct.hit[c])
            ct.hit[c] = hit
    for _ in range(PAIR_SWEEPS):
        for c in range(first, end):
            if ct.mu[c] > 0.0 and ct.hit[c] > 0.0:
                _rub(ct, c, y)
    return True


@kernel
def _rub(ct, c, y):
    """One Gauss-Seidel update of the friction of contact c's impact: its tangential impulse ct.hit_t moved toward
    stopping the slip, in Coulomb's disc of radius mu hit (the impact's whole normal impulse), then shortened to
    where the kinetic energy is least along the move, so that no update gives energy. Along a move D of the
    tangential impulse, with u the slip now and W D what D does to the slip (W the tangents' block of the inverse
    mass seen at the contact), the energy changes by

        q(s) = s D . u + s^2 / 2 D . W D,  least at s = -D . u / D . W D,  kept within [0, 1]

    (q(s) <= 0 there, and hit_t + s D stays in the disc, which holds hit_t and hit_t + D). The impact's normal
    impulse is found first (`_strike`) and friction after it: what the friction does to the normal speeds is the
    next generation's to strike, each of its impulses losing energy as this one does. Sweeping the normal impulse
    and the friction together, to the normal's fixed target u+ = -e u-, is not bound to lose energy (at an
    eccentric point the friction's turn raises the normal speed that the target then keeps)."""
    u1, u2 = speed(ct, c, 1, y), speed(ct, c, 2, y)
    # the update of `relax`: h' = h - m_t u, projected on the disc |h'| <= mu hit
    h1, h2 = ct.hit_t[c, 0] - ct.mass[c, 1] * u1, ct.hit_t[c, 1] - ct.mass[c, 2] * u2
    limit = ct.mu[c] * ct.hit[c]
    size = math.sqrt(h1 * h1 + h2 * h2)
    if size > limit:
        h1, h2 = h1 * limit / size, h2 * limit / size
    d1, d2 = h1 - ct.hit_t[c, 0], h2 - ct.hit_t[c, 1]
    # q'(0) = D . u: a move that does not lower the energy at its start is not taken
    slope = d1 * u1 + d2 * u2
    if not slope < 0.0:
        return
    push(ct, c, 1, y, d1)
    push(ct, c, 2, y, d2)
    # D . W D = D . (u after the move - u before)
    curve = d1 * (speed(ct, c, 1, y) - u1) + d2 * (speed(ct, c, 2, y) - u2)
    s = min(1.0, -slope / curve) if curve > 0.0 else 1.0
    if s < 1.0:
        push(ct, c, 1, y, (s - 1.0) * d1)
        push(ct, c, 2, y, (s - 1.0) * d2)
    ct.hit_t[c, 0] += s * d1
    ct.hit_t[c, 1] += s * d2


@kernel
def _bounce_in_solve(ct, y, first, end, h, resting):
    """A pair with a body joined to another moving body, and restitution: its contacts that approach faster than the
    resting speed within the step (`_strikes`) get Newton's target u+ >= -e u- in the solve, with the
    joints' rows (approach <- u-, negative: an impact event whose impulse is the solve's). A pairwise strike is blind to
    the joints: a chain of capsules (e = 0.5) landing in a heap of its own links gained 6 % of its energy in the
    dynamics plan and 258 % in the procedural (found 2026-12-07)."""
    for c in range(first, end):
        u = speed(ct, c, 0, y)
        if _strikes(ct, c, u, h, resting):
            ct.approach[c] = u


@kernel
def impacts(ct, y, h, resting, struck_in, held, jointed, start):
    """Impacts in generations (module docstring): sweeps over the pairs, each striking (`_strike`) while one of its
    contacts approaches faster than the resting speed, until none does or IMPACT_SWEEPS ran out (what is left is
    resolved without restitution by the solve); a pair with a body joined to another moving body, and restitution, is
    not struck but bounces in the solve, with the joints (`_bounce_in_solve`). Then each contact's target for the solve.
    After the first sweep only the pairs of a body struck in this sweep or the last are looked at again (struck_in
    (n+1,): the sweep that last struck each body): a heap strikes somewhere at nearly every step, and every sweep over
    all of its pairs made 1000 spheres cost 13.8 times 125. start: the state at the step's start (`_rebound`)."""
    count = ct.count[0]
    for b in range(len(struck_in)):
        struck_in[b] = -2.0
    for generation in range(IMPACT_SWEEPS):
        struck = False
        c = 0
        while c < count:
            end = c
            while end < count and ct.a[end] == ct.a[c] and ct.b[end] == ct.b[c]:
                end += 1
            a, b = ct.a[c], ct.b[c]
            if jointed and ct.e[c] > 0.0 and (held[a] or held[b]):
                if generation == 0:
                    _bounce_in_solve(ct, y, c, end, h, resting)
            elif generation == 0 or max(struck_in[a], struck_in[b]) >= generation - 1:
                if _strike(ct, y, c, end, h, resting, start):
                    struck = True
                    struck_in[a], struck_in[b] = generation, generation
            c = end
        if not struck:
            break
    # the solve's targets: a contact apart may close its gap within the step, not cross it; one that bounces in
    # the solve (`_bounce_in_solve`) leaves at e times its approach
    for c in range(count):
        ct.bounce[c] = -ct.push[c] / h
        if ct.approach[c] < 0.0 and ct.e[c] > 0.0:
            ct.bounce[c] = max(ct.bounce[c], -ct.e[c] * ct.approach[c])


@kernel
def _velocities(y, a, b):
    """(v_a, w_a, v_b, w_b) of a contact's bodies, read once into locals for all three of its rows."""
    return ((y[a, 7], y[a, 8], y[a, 9]), (y[a, 10], y[a, 11], y[a, 12]), (y[b, 7], y[b, 8], y[b, 9]),
            (y[b, 10], y[b, 11], y[b, 12]))


@kernel
def _speed_of(ct, c, row, va, wa, vb, wb):
    """`speed` of row `row` of contact c from its bodies' velocities in locals, term by term as `speed` adds them
    (the same figure to the last bit)."""
    j = ct.jac
    u = 0.0
    u += j[c, row, 0] * (va[0] - vb[0]) + j[c, row, 3] * wa[0] - j[c, row, 6] * wb[0]
    u += j[c, row, 1] * (va[1] - vb[1]) + j[c, row, 4] * wa[1] - j[c, row, 7] * wb[1]
    u += j[c, row, 2] * (va[2] - vb[2]) + j[c, row, 5] * wa[2] - j[c, row, 8] * wb[2]
    return u


@kernel
def _pushed(ct, c, row, p, va, wa, vb, wb):
    """`push` of impulse p along row `row` of contact c on its bodies' velocities in locals: the new (v_a, w_a,
    v_b, w_b)."""
    j, turn = ct.jac, ct.turn
    pa, pb = p * ct.inv[c, 0], p * ct.inv[c, 1]
    va = (va[0] + pa * j[c, row, 0], va[1] + pa * j[c, row, 1], va[2] + pa * j[c, row, 2])
    wa = (wa[0] + p * turn[c, row, 0], wa[1] + p * turn[c, row, 1], wa[2] + p * turn[c, row, 2])
    vb = (vb[0] - pb * j[c, row, 0], vb[1] - pb * j[c, row, 1], vb[2] - pb * j[c, row, 2])
    wb = (wb[0] - p * turn[c, row, 3], wb[1] - p * turn[c, row, 4], wb[2] - p * turn[c, row, 5])
    return va, wa, vb, wb


@kernel
def _store(y, a, b, va, wa, vb, wb):
    for k in range(3):
        y[a, 7 + k], y[a, 10 + k], y[b, 7 + k], y[b, 10 + k] = va[k], wa[k], vb[k], wb[k]


@kernel
def sweep(ct, y):
    """One sweep of projected Gauss-Seidel over the contacts (`relax` each)."""
    for c in range(ct.count[0]):
        relax(ct, c, y, 0.0)


@kernel
def sweep_island(ct, y, first, end):
    """One sweep over the contacts of an island (ct.member[first:end], islands.py); whether it changed a row's
    speed by more than SETTLED (else the island's sweeps are over)."""
    moved = False
    for i in range(first, end):
        if relax(ct, ct.member[i], y, SETTLED):
            moved = True
    return moved


@inlined
def relax(ct, c, y, settled):
    """Contact c's update of a Gauss-Seidel sweep: friction (no slip, within Coulomb's disc of radius mu lam_n),
    then the normal row (inlined: called with the contacts' named tuple at every contact of every sweep). Its
    bodies' velocities are read once and written once, in locals between its three rows' updates (`speed` and
    `push` read and wrote them at every row: the same figures, to the last bit, in less time). Returns whether a
    row's impulse changed its speed by more than `settled` (m/s): |lam' - lam| > settled m_d."""
    a, b = ct.a[c], ct.b[c]
    va, wa, vb, wb = _velocities(y, a, b)
    changed = False
    moved = False
    # a contact that holds nothing (lam_n and its friction 0) has a disc of radius 0: its friction stays 0
    # (a resting heap's speculative contacts that stay apart: 423 of its 599)
    if ct.mu[c] > 0.0 and (ct.lam[c, 0] > 0.0 or ct.lam[c, 1] != 0.0 or ct.lam[c, 2] != 0.0):
        l1 = ct.lam[c, 1] - ct.mass[c, 1] * _speed_of(ct, c, 1, va, wa, vb, wb)
        l2 = ct.lam[c, 2] - ct.mass[c, 2] * _speed_of(ct, c, 2, va, wa, vb, wb)
        limit = ct.mu[c] * ct.lam[c, 0]
        size = math.sqrt(l1 * l1 + l2 * l2)
        if size > limit:
            scale = limit / size if size > 0.0 else 0.0
            l1, l2 = l1 * scale, l2 * scale
        va, wa, vb, wb = _pushed(ct, c, 1, l1 - ct.lam[c, 1], va, wa, vb, wb)
        va, wa, vb, wb = _pushed(ct, c, 2, l2 - ct.lam[c, 2], va, wa, vb, wb)
        moved = (abs(l1 - ct.lam[c, 1]) > settled * ct.mass[c, 1] or abs(l2 - ct.lam[c, 2]) > settled * ct.mass[c, 2])
        ct.lam[c, 1], ct.lam[c, 2] = l1, l2
        changed = True
    # lam_n' = max(0, lam_n + m_n (target - u_n))
    lam = max(0.0, ct.lam[c, 0] + ct.mass[c, 0] * (ct.bounce[c] - _speed_of(ct, c, 0, va, wa, vb, wb)))
    if lam != ct.lam[c, 0]:  # (a contact apart that stays apart: nothing to push)
        va, wa, vb, wb = _pushed(ct, c, 0, lam - ct.lam[c, 0], va, wa, vb, wb)
        moved = moved or abs(lam - ct.lam[c, 0]) > settled * ct.mass[c, 0]
        ct.lam[c, 0] = lam
        changed = True
    if changed:
        _store(y, a, b, va, wa, vb, wb)
    return moved


@kernel
def contact_work(ct, c, y):
    """The energy contact c's impulses gave its bodies this step (J): sum over its rows of lam (u- + u+) / 2."""
    mine = 0.5 * (ct.hit[c] + ct.lam[c, 0]) * (ct.before[c, 0] + speed(ct, c, 0, y))
    mine += 0.5 * (ct.hit_t[c, 0] + ct.lam[c, 1]) * (ct.before[c, 1] + speed(ct, c, 1, y))
    return mine + 0.5 * (ct.hit_t[c, 1] + ct.lam[c, 2]) * (ct.before[c, 2] + speed(ct, c, 2, y))


@kernel
def work(ct, y):
    """(energy the contact impulses created this step: sum over rows of lam (u- + u+) / 2, J; the contact that
    created the most)."""
    total, most, which = 0.0, 0.0, -1
    for c in range(ct.count[0]):
        mine = contact_work(ct, c, y)
        total += mine
        if mine > most:
            most, which = mine, c
    return total, which
