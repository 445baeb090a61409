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

One Gauss-Seidel update of row d: lam' = max(0, lam + m_d (target - u_d)) for the normal, the tangents' pair
projected onto the disc, and the change applied to both bodies at once, so momentum is kept exactly by every
update. Interpenetration is removed by a separate pass on pseudo-velocities (split impulses): a contact deeper
than SLOP is pushed apart at BETA (depth - SLOP) / h, which moves positions only and never adds kinetic energy.

Energy: the impulses P change the kinetic energy by dK = (v+ - v-)^T M (v+ + v-) / 2 = sum over rows of
lam (u- + u+) / 2. With e <= 1 and friction opposing slip a converged solve has dK <= 0: a step whose contacts
create more than ENERGY_TOL of the scale is counted, with its time and the pair that created the most.
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from ..core.vec import cross3, dot3, rotate, scale3, sub3
from .broad import find_key, first_at_least
from .data import FEATURES

# sweeps of impacts in generations per step, at most (then restitution 0); sweeps over one pair's points
IMPACT_SWEEPS = 64
PAIR_SWEEPS = 16
# velocity sweeps (warm-started) and position sweeps per step
VELOCITY_SWEEPS = 16
POSITION_SWEEPS = 6
# interpenetration left alone (m), and the fraction of the rest removed per step by the position pass
SLOP = 1e-4
BETA = 0.3
# how far a contact's point may be from the last step's point of another feature of its pair for it to take that
# one's impulses as its warm start (m)
MATCH = 5e-4
# energy a step's contact impulses may create before it is counted, relative to the energy scale
ENERGY_TOL = 1e-6


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
def _velocity(y, b, r):
    return (y[b, 7] + y[b, 11] * r[2] - y[b, 12] * r[1], y[b, 8] + y[b, 12] * r[0] - y[b, 10] * r[2],
            y[b, 9] + y[b, 10] * r[1] - y[b, 11] * r[0])


@kernel
def relative(y, a, b, ra, rb, d):
    """u_d = d . (v_a + w_a x r_a - v_b - w_b x r_b)."""
    return dot3(d, sub3(_velocity(y, a, ra), _velocity(y, b, rb)))


@kernel
def _inverse_mass(bodies, invI, b, r, d):
    """1/m + (r x d) . I^-1 (r x d) of body b (0 for a body that does not move under impulses)."""
    if not bodies.dynamic[b]:
        return 0.0
    rd = cross3(r, d)
    return bodies.inv_mass[b] + dot3(rd, rotate(invI, b, rd))


@kernel
def row_mass(bodies, invI, a, b, ra, rb, d):
    w = _inverse_mass(bodies, invI, a, ra, d) + _inverse_mass(bodies, invI, b, rb, d)
    return 1.0 / w if w > 0.0 else 0.0


@kernel
def push(bodies, invI, y, col, a, b, ra, rb, d, p):
    """Impulse p d on a at r_a and -p d on b at r_b: y[:, col:col+3] += p d / m, y[:, col+3:col+6] += I^-1 (r x p d)."""
    for slot in range(2):
        body = a if slot == 0 else b
        if not bodies.dynamic[body]:
            continue
        sign = p if slot == 0 else -p
        r = ra if slot == 0 else rb
        turn = rotate(invI, body, cross3(r, scale3(sign, d)))
        for k in range(3):
            y[body, col + k] += sign * bodies.inv_mass[body] * d[k]
            y[body, col + 3 + k] += turn[k]


@kernel
def _row3(a, c):
    return (a[c, 0], a[c, 1], a[c, 2])


@kernel
def prepare(bodies, invI, ct, y, n, h):
    """Rows of every contact (module docstring): arms, tangents, masses, velocities before, the normal's target;
    then the last step's impulses of the same features applied (warm start)."""
    count = ct.count[0]
    for c in range(count):
        a, b = ct.a[c], ct.b[c]
        p, nrm = (ct.point[c, 0], ct.point[c, 1], ct.point[c, 2]), (ct.normal[c, 0], ct.normal[c, 1], ct.normal[c, 2])
        ra, rb = sub3(p, (y[a, 0], y[a, 1], y[a, 2])), sub3(p, (y[b, 0], y[b, 1], y[b, 2]))
        t1, t2 = tangents(nrm)
        for k in range(3):
            ct.ra[c, k], ct.rb[c, k], ct.t1[c, k], ct.t2[c, k] = ra[k], rb[k], t1[k], t2[k]
        ct.mass[c, 0] = row_mass(bodies, invI, a, b, ra, rb, nrm)
        ct.mass[c, 1] = row_mass(bodies, invI, a, b, ra, rb, t1)
        ct.mass[c, 2] = row_mass(bodies, invI, a, b, ra, rb, t2)
        un = relative(y, a, b, ra, rb, nrm)
        ct.before[c, 0], ct.before[c, 1], ct.before[c, 2] = un, relative(y, a, b, ra, rb, t1), relative(y, a, b, ra, rb, t2)
        gap = -ct.depth[c]
        ct.hit[c], ct.approach[c] = 0.0, 0.0
        ct.push[c] = max(gap, 0.0)  # (the gap, until `impacts` sets the targets)
        ct.key[c] = (a * n + b) * FEATURES + ct.feature[c]
    # the warm start after every contact's velocities before were measured (they are the step's own): the last
    # step's contact of the same feature, else the nearest of the same pair within MATCH (a point where two
    # features meet, as aligned edges of a stack, changes its feature with the slightest turn), each taken once
    old_count = ct.count[2]
    for i in range(old_count):
        ct.old_used[i] = 0
    for c in range(count):
        old = find_key(ct.old_key, old_count, ct.key[c])
        ct.bounce[c] = old  # (the match, until `impacts` sets the targets)
        if old >= 0:
            ct.old_used[old] = 1
    for c in range(count):
        if ct.bounce[c] < 0:
            ct.bounce[c] = _nearest_old(ct, c, old_count, ct.key[c] - ct.feature[c])
    for c in range(count):
        old = int(ct.bounce[c])
        ct.acc[c] = ct.old_acc[old] if old >= 0 else 0.0
        for k in range(3):
            ct.lam[c, k] = ct.old_lam[old, k] if old >= 0 else 0.0
        a, b, ra, rb = ct.a[c], ct.b[c], _row3(ct.ra, c), _row3(ct.rb, c)
        push(bodies, invI, y, 7, a, b, ra, rb, _row3(ct.normal, c), ct.lam[c, 0])
        push(bodies, invI, y, 7, a, b, ra, rb, _row3(ct.t1, c), ct.lam[c, 1])
        push(bodies, invI, y, 7, a, b, ra, rb, _row3(ct.t2, c), ct.lam[c, 2])


@kernel
def _nearest_old(ct, c, old_count, pair_key):
    """The last step's contact of contact c's pair nearest to its point within MATCH and not taken yet (marked
    taken), or -1. The old contacts are sorted by key, so the pair's are consecutive from the first key >= its
    own times FEATURES."""
    i = first_at_least(ct.old_key, old_count, pair_key)
    best, nearest = -1, MATCH * MATCH
    while i < old_count and ct.old_key[i] - pair_key < FEATURES:
        if ct.old_used[i] == 0:
            d = 0.0
            for k in range(3):
                d += (ct.old_point[i, k] - ct.point[c, k]) ** 2
            if d < nearest:
                best, nearest = i, d
        i += 1
    if best >= 0:
        ct.old_used[best] = 1
    return best


@kernel
def _strike(bodies, invI, ct, y, first, end, h, resting):
    """One generation's impact of the pair whose contacts are first..end-1, if one of them approaches faster than
    the resting speed within the step: its points together (a face landing on a face is one impact, not four that
    turn it), targets u+ = -e u- from their velocities now, ct.hit grown, each kept >= its value before
    (PGS on the pair's points). Returns whether it struck."""
    approaching = False
    for c in range(first, end):
        u = relative(y, ct.a[c], ct.b[c], _row3(ct.ra, c), _row3(ct.rb, c), _row3(ct.normal, c))
        closes = u * h <= -ct.push[c]
        # a contact that pressed in the last step (its warm start lam_n > 0) strikes only when this step's impulses
        # made it approach faster than before them: the residual speeds of a resting stack's solve are not impacts
        # (bouncing them fed the residual back: a pyramid of 28 boxes rocked at 0.5 rad/s)
        struck = u < -resting and closes and (ct.lam[c, 0] <= 0.0 or u < ct.before[c, 0] - resting)
        approaching = approaching or struck
        # its target u+ = -e u- (ct.bounce), or -1: not in this generation
        ct.bounce[c] = -ct.e[c] * u if (u < 0.0 and closes) else -1.0
        ct.base[c] = ct.hit[c]
        if struck:
            ct.approach[c] = max(ct.approach[c], -u)
    if not approaching:
        return False
    for _ in range(PAIR_SWEEPS):
        for c in range(first, end):
            if ct.bounce[c] < 0.0:
                continue
            a, b = ct.a[c], ct.b[c]
            ra, rb, nrm = _row3(ct.ra, c), _row3(ct.rb, c), _row3(ct.normal, c)
            # hit' = max(hit before the generation, hit + m_n (target - u)): a point may give back what this
            # generation gave it, never pull
            hit = max(ct.base[c], ct.hit[c] + ct.mass[c, 0] * (ct.bounce[c] - relative(y, a, b, ra, rb, nrm)))
            push(bodies, invI, y, 7, a, b, ra, rb, nrm, hit - ct.hit[c])
            ct.hit[c] = hit
    return True


@kernel
def impacts(bodies, invI, ct, y, h, resting, struck_in):
    """Impacts in generations (module docstring): sweeps over the pairs, each striking (`_strike`) while one of
    its contacts approaches faster than the resting speed, until none does or IMPACT_SWEEPS ran out (what is left
    is resolved without restitution by the solve). Then each contact's target for the solve. After the first
    sweep only the pairs of a body struck in this sweep or the last are looked at again (struck_in (n+1,): the
    sweep that last struck each body): a heap strikes somewhere at nearly every step, and every sweep over all of
    its pairs made 1000 spheres cost 13.8 times 125."""
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
            if generation == 0 or max(struck_in[a], struck_in[b]) >= generation - 1:
                if _strike(bodies, invI, ct, y, c, end, h, resting):
                    struck = True
                    struck_in[a], struck_in[b] = generation, generation
            c = end
        if not struck:
            break
    # the solve's targets: a contact apart may close its gap within the step, not cross it
    for c in range(count):
        ct.bounce[c] = -ct.push[c] / h


@kernel
def _friction(bodies, invI, ct, y, c, a, b, ra, rb):
    """The tangent rows of contact c: no slip, within Coulomb's disc of radius mu lam_n."""
    t1, t2 = _row3(ct.t1, c), _row3(ct.t2, c)
    l1 = ct.lam[c, 1] - ct.mass[c, 1] * relative(y, a, b, ra, rb, t1)
    l2 = ct.lam[c, 2] - ct.mass[c, 2] * relative(y, a, b, ra, rb, t2)
    limit = ct.mu[c] * ct.lam[c, 0]
    size = math.sqrt(l1 * l1 + l2 * l2)
    if size > limit:
        scale = limit / size if size > 0.0 else 0.0
        l1, l2 = l1 * scale, l2 * scale
    push(bodies, invI, y, 7, a, b, ra, rb, t1, l1 - ct.lam[c, 1])
    push(bodies, invI, y, 7, a, b, ra, rb, t2, l2 - ct.lam[c, 2])
    ct.lam[c, 1], ct.lam[c, 2] = l1, l2


@kernel
def sweep(bodies, invI, ct, y):
    """One sweep of projected Gauss-Seidel over the contacts: friction, then the normal row."""
    for c in range(ct.count[0]):
        a, b = ct.a[c], ct.b[c]
        ra, rb, nrm = _row3(ct.ra, c), _row3(ct.rb, c), _row3(ct.normal, c)
        if ct.mu[c] > 0.0:
            _friction(bodies, invI, ct, y, c, a, b, ra, rb)
        # lam_n' = max(0, lam_n + m_n (target - u_n))
        lam = max(0.0, ct.lam[c, 0] + ct.mass[c, 0] * (ct.bounce[c] - relative(y, a, b, ra, rb, nrm)))
        push(bodies, invI, y, 7, a, b, ra, rb, nrm, lam - ct.lam[c, 0])
        ct.lam[c, 0] = lam


@kernel
def deep(ct):
    """Whether a contact is deeper than SLOP (the position pass has work)."""
    for c in range(ct.count[0]):
        if ct.depth[c] > SLOP:
            return True
    return False


@kernel
def clear(pseudo, ct):
    """The position pass starts from rest: pseudo-velocities and the contacts' push impulses 0."""
    for b in range(len(pseudo)):
        for k in range(7, 13):
            pseudo[b, k] = 0.0
    for c in range(ct.count[0]):
        ct.push[c] = 0.0


@kernel
def separate(bodies, invI, ct, pseudo, h):
    """One sweep of the position pass over the contacts: pseudo-velocities (pseudo (n+1,13), columns 7..12 as v, w
    in y) that push every contact deeper than SLOP apart at BETA (depth - SLOP) / h (split impulses: they move
    positions only)."""
    for c in range(ct.count[0]):
        if ct.depth[c] <= SLOP:
            continue
        a, b = ct.a[c], ct.b[c]
        ra, rb, nrm = _row3(ct.ra, c), _row3(ct.rb, c), _row3(ct.normal, c)
        target = BETA * (ct.depth[c] - SLOP) / h
        lam = max(0.0, ct.push[c] + ct.mass[c, 0] * (target - relative(pseudo, a, b, ra, rb, nrm)))
        push(bodies, invI, pseudo, 7, a, b, ra, rb, nrm, lam - ct.push[c])
        ct.push[c] = lam


@kernel
def work(ct, y):
    """(energy the contact impulses created this step: sum over rows of lam (u- + u+) / 2, J; the contact that
    created the most)."""
    total, most, which = 0.0, 0.0, -1
    for c in range(ct.count[0]):
        a, b = ct.a[c], ct.b[c]
        ra, rb = _row3(ct.ra, c), _row3(ct.rb, c)
        mine = 0.5 * (ct.hit[c] + ct.lam[c, 0]) * (ct.before[c, 0] + relative(y, a, b, ra, rb, _row3(ct.normal, c)))
        mine += 0.5 * ct.lam[c, 1] * (ct.before[c, 1] + relative(y, a, b, ra, rb, _row3(ct.t1, c)))
        mine += 0.5 * ct.lam[c, 2] * (ct.before[c, 2] + relative(y, a, b, ra, rb, _row3(ct.t2, c)))
        total += mine
        if mine > most:
            most, which = mine, c
    return total, which
