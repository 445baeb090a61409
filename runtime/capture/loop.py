"""The capturing step loop, compiled: every step finds its contacts and solves them at velocity level with the
forces, so contacts that appear, part, stick or slide never leave the loop (docs/design/physics.md section 5b,
Moreau-Jean):

    1. forces at the step's start; v- = v + h F / m, w- = w + h I^-1 tau       (kick)
    2. broad phase (broad.py), narrow phase of every candidate pair (narrow.py; a pair with a compound body: each
       pair of parts, compound.py), with the gap each pair can close in the step (speculative contacts: nothing
       tunnels while it moves less than the margin it was given); found again, with the impacts of stage 3, when
       those send a body farther than its pairs were found for (`_outran`)
    3. the contact solve (solve.py): impacts in generations, then impulses so that v+ meets the contacts (friction
       included) and the joints' rows (joints.py), one Gauss-Seidel sweep over both after another, warm-started
       (the last step's impulses applied after the impacts, which are struck from the velocities of the forces);
       a solve whose impulses created energy is taken again with only so much of the warm start as lowers the energy.
       In a scene without joints the sweeps go island by island, each island's ending once they change nothing
       (islands.py `sweep_islands`)
    4. x += h v+ (a body whose velocity changed smoothly: the mean, h (v + v+) / 2, `_drift`); the free rotation
       of w+ over h (energy-keeping, procedural/substep.py); the position pass's
       pseudo-velocities move the positions only (drift); the joints projected back on their manifold as the exact
       path's semi-implicit Euler projects them (dynamics/projection.py)
    5. checks: interpenetration beyond the limit, energy created by the contacts (counted, the worst kept with
       its time and pair), a body that ran away (the call ends); events: impacts and, at frames, pressing pairs

A step that finds more pairs or contacts than the buffers hold is undone and the call ends (GROW): the Python side
grows them and calls again. The model is never written; contacts, pairs and checks are the run's data.
"""
from __future__ import annotations

import math

from ..core.bodies import (copy_state, energy, kinetic, place_kinematic, rotations, runaway_body, turn,
                           world_inverse_inertia)
from ..core.forces import step_forces
from ..core.free_rotation import free_rotation
from ..core.jit import entry, kernel
from ..core.record import DONE, RUNAWAY_BODY, RUNAWAY_CONSTRAINT_ERROR, RUNAWAY_ROW, constraint_error, trace_step
from ..core.rows import evaluate_rows
from ..core.timetable import TIME
from ..core.projection import project
from ..core.model import SHAPE_SPHERE
from .broad import SPECULATION, body_reach, find_pairs, meets_more, point_speed, travel
from .compound import Found, fold, material_of, place, pose, posed_contacts
from .data import IMPACT, PRESSING
from .islands import separate_islands, solve_islands, sweep_islands
from .narrow import pair_contacts
from .joints import close_joints, prepare_joints, sweep_joints, warm_start_joints
from .position import POSITION_SWEEPS, clear, deep, separate
from .solve import VELOCITY_SWEEPS, impacts, keep_old, prepare, push, sweep, take_old, warm_start, work

GROW, DRAIN = 4, 5
# a step whose bodies in contact turn fast is taken in parts (`_split`): the farthest point of a body that is not
# round turns by at most this much in each (m), in at most this many parts
TURN_PER_STEP = 3e-4
MAX_SPLIT = 8
# an approach slower than this does not bounce (m/s): the speed of a fall through 0.5 mm. A larger threshold than
# the exact path's, which locates every impact and so never sees a body resting on a contact approach it: here the
# solve's residual speeds (a few cm/s in a heap of boxes) bounced at 0.05 m/s, and 64 boxes still rocked at
# 0.5 rad/s after 2.5 s (below 1.5e-3 at 0.1 m/s; at 0.2 m/s the dominoes' wave lost its steady speed)
BOUNCE_SPEED = 0.1
# a body whose velocity changed by at most this many times what its forces alone change it by in a step moves at the
# mean of its velocities before and after (`_drift`): a sliding block's friction (mu g, mu <= 1 takes 2) and a rolling
# ball's spin (5/2 mu g at its rim) are inside it, an impact (0.1 m/s and more: 10 g h at 1 ms) is not
SMOOTH = 4.0
# the step's contacts are found again, at most this many times, when its impacts send a body farther than they
# were found for by more than OUTRUN (m; `_outran`): a contact missed by that much is found at the next step that
# deep, and the position pass takes it out
FIND_AGAIN = 4
OUTRUN = 2.5e-4
# a landing contact whose warm start already holds back this fraction of its approach (of m_n |u|, the impulse
# that stops it) is pressing, not landing (`_touchdowns`)
LANDED = 0.05


@kernel
def _kick(bodies, s, y, h):
    """v += h F / m, w += h I^-1 tau of the dynamic bodies; the torque is spent (the drift turns freely)."""
    for b in range(len(y) - 1):
        if not bodies.dynamic[b]:
            continue
        for k in range(3):
            y[b, 7 + k] += h * bodies.inv_mass[b] * s.force[b, k]
        for k in range(3):
            y[b, 10 + k] += h * (s.inv_inertia[b, k, 0] * s.torque[b, 0] + s.inv_inertia[b, k, 1] * s.torque[b, 1]
                                 + s.inv_inertia[b, k, 2] * s.torque[b, 2])
        for k in range(3):
            s.torque[b, k] = 0.0


@kernel
def _mix(mats, a, b):
    """(friction sqrt(mu_a mu_b), restitution max(e_a, e_b)); a body without a material takes the other's, two
    without take the defaults (collide/__init__.py mix)."""
    ha, hb = mats.has[a], mats.has[b]
    if ha and hb:
        return math.sqrt(mats.friction[a] * mats.friction[b]), max(mats.restitution[a], mats.restitution[b])
    if ha:
        return mats.friction[a], mats.restitution[a]
    if hb:
        return mats.friction[b], mats.restitution[b]
    return mats.default[0], mats.default[1]


@kernel
def _compound(ct, sw, mats, y, R, a, b, margin, first, parts, poses):
    """The contacts of a pair with a compound body at slots first.. (compound.py, every pair of parts; its compound
    bodies posed by `place` this step): turned to the pair's order (a, b) with features unique in it
    (compound.fold), each with its parts' materials. Returns their count."""
    for body in (a, b):
        if parts.count[body] == 0:
            pose(parts, poses, y, R, body)
    out = Found(ct.point[first:], ct.normal[first:], ct.depth[first:], ct.feature[first:], ct.a[first:],
                ct.b[first:])
    k = posed_contacts(parts, poses, a, b, margin, out, sw.work)
    for c in range(min(k, len(out.depth))):
        part_a, part_b = fold(parts, out, c, a, b)
        mu, e = _mix(mats, material_of(parts, a, part_a), material_of(parts, b, part_b))
        ct.mu[first + c], ct.e[first + c] = mu, e
    return k


@kernel
def _narrow(m, s, ct, sw, mats, y, h, parts, poses):
    """Contacts of every candidate pair; returns how many were found (beyond the capacity: grow)."""
    found = 0
    capacity = len(ct.a)
    for p in range(sw.count[0]):
        a, b = sw.pairs[p, 0], sw.pairs[p, 1]
        margin = m.margin + travel(m.shapes, a, y, h, parts, sw.reach) + travel(m.shapes, b, y, h, parts, sw.reach)
        if parts.count[a] > 0 or parts.count[b] > 0:
            found += _compound(ct, sw, mats, y, s.R, a, b, margin, found, parts, poses)
            continue
        k = pair_contacts(m.shapes, a, b, y, s.R, margin, ct.point, ct.normal, ct.depth, ct.feature, found, capacity,
                           sw.work)
        mu, e = _mix(mats, a, b)
        for c in range(found, min(found + k, capacity)):
            ct.a[c], ct.b[c], ct.mu[c], ct.e[c] = a, b, mu, e
        found += k
    return found


@kernel
def _touchdowns(ct, h, touch):
    """Mark the contacts that land this step faster than `touch` (m/s; before the step's impulses, closing their
    gap within it) without holding their approach back yet (a warm start lam_n below LANDED of m_n |u|, the
    impulse that stops them): approach <- their (negative) normal speed, which an impact of theirs (`impacts`: approach
    > 0) overrides. They are impact events whose impulse is the solve's (`_pair_events`). Called between
    `prepare` and `impacts` (lam holds the warm start). Asking for a warm start of 0 missed the clock's tick at
    1.886 s: the step before, its tooth 0.075 mm from the pallet took 2.6e-6 N s of the landing's 1.3e-3 (ticks in
    30 s: 60; the exact path's 61). At half of m_n |u|, the second step of a landing taken in two was a tick of
    its own (72); at LANDED, 61.

    touch is the exact path's resting speed in a scene where no pair can bounce (capture CaptureStepper), else inf
    (none: a scene that can bounce keeps its events). Such a landing is not struck in generations: striking it
    (restitution 0, but with pairwise impulses blind to the joints) threw the clock's wheel back at 0.26 rad/s from
    each tick, three strikes a tick."""
    for c in range(ct.count[0]):
        u = ct.before[c, 0]
        if u < -touch and ct.lam[c, 0] < LANDED * ct.mass[c, 0] * -u and u * h <= -ct.push[c]:
            ct.approach[c] = u


@kernel
def _mark_held(m, act, held):
    """held[b] <- whether an active joint row joins body b to another moving body (a link of a chain, a clapper
    hung in its bell; not a ball of the cradle on its string to the frame, whose strikes a pairwise impulse passes
    down the row as the cradle does: bounced in the solve, the row moved off together)."""
    for b in range(len(held)):
        held[b] = False
    for i in range(len(act.rows)):
        k = m.constraints.row_instance[act.rows[i]]
        a, b = m.constraints.body[k, 0], m.constraints.body[k, 1]
        if a >= 0 and b >= 0 and m.bodies.dynamic[a] and m.bodies.dynamic[b]:
            held[a], held[b] = True, True


@kernel
def _event(ev, t, kind, a, b, point, normal, impulse, slip, approach, feature):
    i = ev.count[0]
    ev.count[0] = i + 1
    if i >= len(ev.rows):
        return
    row = ev.rows[i]
    row[0], row[1], row[2], row[3] = t, kind, a, b
    for k in range(3):
        row[4 + k], row[7 + k] = point[k], normal[k]
    row[10], row[11], row[12], row[13] = impulse, slip, approach, feature


@kernel
def _pair_events(ct, ev, t, h, pressing):
    """One event per pair of consecutive contacts: its impacts now (pressing False; an impact's impulse, or a
    touchdown's (approach < 0: `_touchdowns`) the solve's), or, at a frame, its impulse since the last frame
    (pressing True; acc reset); with the feature of the contact that took the most."""
    c = 0
    count = ct.count[0]
    while c < count:
        end = c
        while end < count and ct.a[end] == ct.a[c] and ct.b[end] == ct.b[c]:
            end += 1
        impulse, px, py, pz, nx, ny, nz, slip, approach, soonest = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, h
        most, feature = 0.0, 0
        for i in range(c, end):
            if pressing:
                p = ct.acc[i]
                ct.acc[i] = 0.0
            else:
                # (struck, approaching faster than resting; or landed: a touchdown)
                p = ct.hit[i] if ct.approach[i] > 0.0 else (ct.lam[i, 0] if ct.approach[i] < 0.0 else 0.0)
                if p > 0.0:
                    # the time its gap closed within the step, at the speed it approached when struck
                    soonest = min(soonest, max(0.0, -ct.depth[i]) / abs(ct.approach[i]))
                    approach = max(approach, abs(ct.approach[i]))
                    slip = max(slip, math.sqrt(ct.before[i, 1] ** 2 + ct.before[i, 2] ** 2))
            if p <= 0.0:
                continue
            if p > most:
                most, feature = p, ct.feature[i]
            impulse += p
            px, py, pz = px + p * ct.point[i, 0], py + p * ct.point[i, 1], pz + p * ct.point[i, 2]
            nx, ny, nz = nx + p * ct.normal[i, 0], ny + p * ct.normal[i, 1], nz + p * ct.normal[i, 2]
        if impulse > 0.0:
            size = math.sqrt(nx * nx + ny * ny + nz * nz)
            kind = PRESSING if pressing else IMPACT
            _event(ev, t if pressing else t + soonest, kind, ct.a[c], ct.b[c], (px / impulse, py / impulse, pz / impulse),
                   (nx / size, ny / size, nz / size), impulse, slip, approach, feature)
        c = end


@kernel
def _check(ct, chk, t, depth_limit, energy_tol, created, most):
    """The step's checks (data.py Checks): the deepest contact, and the energy its impulses created (created, J;
    most: the contact that created the most, solve.py `work`)."""
    chk.counts[2] += ct.count[0]
    chk.counts[3] += 1
    deepest, which = 0.0, -1
    for c in range(ct.count[0]):
        if ct.depth[c] > deepest:
            deepest, which = ct.depth[c], c
    if deepest > depth_limit:
        chk.counts[0] += 1
    if deepest > chk.worst[0]:
        chk.worst[0], chk.worst[1], chk.worst[2], chk.worst[3] = deepest, t, ct.a[which], ct.b[which]
    if created > energy_tol:
        chk.counts[1] += 1
    if created > chk.worst[4] and most >= 0:
        chk.worst[4], chk.worst[5], chk.worst[6], chk.worst[7] = created, t, ct.a[most], ct.b[most]


@kernel
def _solve_velocities(m, act, s, ct, jt, isl, y, kicked, jointed, again):
    """The sweeps over the contacts and the joints' rows from the impulses they hold; in a scene without joints,
    island by island (grouped unless `again`: the step's solve taken again), then the islands solved whole. Returns
    how many were."""
    if jointed:
        for _ in range(VELOCITY_SWEEPS):
            sweep_joints(m, act, s, s.inv_inertia, jt, y)
            sweep(ct, y)
        return 0
    sweep_islands(m.bodies.dynamic, ct, y, isl, not again)
    return solve_islands(m.bodies, s.R, ct, y, kicked, isl)


@kernel
def _warm_again(bodies, R, act, ct, jt, y, tol):
    """The warm start taken again (y: the velocities after the impacts), only so far as it lowers the kinetic
    energy: along the line of the last step's impulses the energy is a parabola through its values at 0, 1/2 and
    1 of them, E(k) = E0 + a k + b k^2, least at k = -a / (2 b), and the impulses are scaled to that, within [0, 1].
    When all of them raise it by no more than tol (J), the energy came from the sweeps and the solve starts cold:
    no impulses. The joints' rows start cold either way."""
    for i in range(len(act.rows)):
        jt.lam[act.rows[i]] = 0.0
    for c in range(ct.count[0]):
        take_old(ct, c)
    before = _kinetic_sum(bodies, R, y)
    warm_start(ct, y)
    whole = _kinetic_sum(bodies, R, y)
    _scale_warm_start(ct, y, 0.5)
    if whole <= before + tol:
        _scale_warm_start(ct, y, 0.0)
        return
    half = _kinetic_sum(bodies, R, y)
    # E(k) = E0 + a k + b k^2 through E(0), E(1/2), E(1)
    b = 2.0 * (whole - 2.0 * half + before)
    a = whole - before - b
    keep = min(1.0, max(0.0, -a / (2.0 * b))) if b > 0.0 else 0.0
    _scale_warm_start(ct, y, 2.0 * keep)


@kernel
def _kinetic_sum(bodies, R, y):
    """The kinetic energy of the dynamic bodies (J): all that the warm start's impulses change."""
    total = 0.0
    for b in range(len(y) - 1):
        if bodies.dynamic[b]:
            total += kinetic(bodies, R, y, b)
    return total


@kernel
def _scale_warm_start(ct, y, factor):
    """The impulses ct.lam, applied to y, scaled by factor (the difference applied)."""
    for c in range(ct.count[0]):
        for row in range(3):
            change = (factor - 1.0) * ct.lam[c, row]
            push(ct, c, row, y, change)
            ct.lam[c, row] += change


@kernel
def _smooth(m, s, y, b, h, parts):
    """Whether body b's velocity changed this step by no more than SMOOTH times what its forces alone change it by
    (|F| h / m): a flight, a slide, a roll, a rest, and no impact (v: s.start's, before the step)."""
    a = math.sqrt(s.force[b, 0] ** 2 + s.force[b, 1] ** 2 + s.force[b, 2] ** 2) * m.bodies.inv_mass[b]
    dv = math.sqrt((y[b, 7] - s.start[b, 7]) ** 2 + (y[b, 8] - s.start[b, 8]) ** 2 + (y[b, 9] - s.start[b, 9]) ** 2)
    dw = math.sqrt((y[b, 10] - s.start[b, 10]) ** 2 + (y[b, 11] - s.start[b, 11]) ** 2
                   + (y[b, 12] - s.start[b, 12]) ** 2)
    limit = SMOOTH * a * h
    return dv <= limit and dw * body_reach(m.shapes, parts, b) <= limit


@kernel
def _drift(m, s, y, pseudo, moved, h, parts, jointed):
    """x += h (v+ + v~), the free rotation of w+ over h, then the turn h w~ (v~, w~: the position pass's). A body
    whose velocity changed smoothly (`_smooth`; in a scene without joints) moves at the mean of its velocities at
    the step's start (v, s.start's) and after it, (v + v+) / 2, and turns the same: the trapezoid, exact for a
    constant force (a flight, a slide under Coulomb friction), where moving at v+ (symplectic Euler) stops a
    sliding block v0 h / 2 short. An impact's change is taken whole at the step's start (the scheme's impulses):
    averaged, a bounce lands late."""
    for b in range(len(y) - 1):
        if not m.bodies.dynamic[b]:
            continue
        mean = not jointed and _smooth(m, s, y, b, h, parts)
        for k in range(3):
            v = y[b, 7 + k]
            if mean:
                # (v + v+) / 2
                v = 0.5 * (s.start[b, 7 + k] + v)
            y[b, k] += h * (v + (pseudo[b, 7 + k] if moved else 0.0))
        free_rotation(m.bodies, b, y, s.R, s.torque, h)
        if mean:
            # the free rotation of w+ over h, turned back by h (w+ - w) / 2: the turn of the mean
            turn(y, b, 0.5 * h * (s.start[b, 10] - y[b, 10]), 0.5 * h * (s.start[b, 11] - y[b, 11]),
                 0.5 * h * (s.start[b, 12] - y[b, 12]))
        if moved:
            turn(y, b, h * pseudo[b, 10], h * pseudo[b, 11], h * pseudo[b, 12])


@kernel
def _split(m, ct, y, h, parts):
    """In how many steps to take the step of h: its bodies in contact last step that are not round turn their
    farthest point by at most TURN_PER_STEP in each (at most MAX_SPLIT steps). A box spinning onto another touches
    edge on edge, one pair of edges a step, and a turn of 2.5 mm a step brought the next pair 3.5 mm deep."""
    most = 0.0
    for c in range(ct.count[0]):
        for slot in range(2):
            b = ct.a[c] if slot == 0 else ct.b[c]
            if m.shapes.kind[b] == SHAPE_SPHERE or not m.bodies.dynamic[b]:
                continue
            w = math.sqrt(y[b, 10] ** 2 + y[b, 11] ** 2 + y[b, 12] ** 2)
            most = max(most, w * body_reach(m.shapes, parts, b) * h)
    return min(MAX_SPLIT, max(1, int(math.ceil(most / TURN_PER_STEP))))


@kernel
def _contacts(m, s, ct, sw, mats, y, h, parts, poses):
    """The step's candidate pairs (broad.py) and their contacts (`_narrow`) into ct; returns their count, or -1
    when the buffers are too small (grow, and take the step again)."""
    find_pairs(m.shapes, sw, m.bodies.dynamic, y, s.R, h, m.margin, parts, poses)
    if sw.count[0] > len(sw.pairs):
        return -1
    found = _narrow(m, s, ct, sw, mats, y, h, parts, poses)
    ct.count[1] = found
    if found > len(ct.a):
        return -1
    ct.count[0] = found
    return found


@kernel
def _outran(m, s, sw, y, kicked, h, parts):
    """Whether the step's impacts sent a body farther than its contacts were found for, by more than OUTRUN (its
    farthest point's travel at its speed now against the travel its pairs were found with, at its velocities after
    the kick, kicked), toward a body or plane it has no pair with (broad.py `meets_more`). Each such body's
    sw.reach <- that speed, so that its contacts are found again with it. Struck across a 1 mm gap at 1.5 m/s in a
    step of 2 ms, the third of a row of balls was sent 3 mm into the fourth, whose pair had not been looked at:
    2.3 mm deep."""
    out = False
    for idx in range(len(sw.order)):
        b = sw.order[idx]
        if not m.bodies.dynamic[b]:
            continue
        now = point_speed(m.shapes, b, y, parts)
        before = travel(m.shapes, b, kicked, h, parts, sw.reach)
        if now * h > m.margin + before + OUTRUN and meets_more(m.shapes, sw, y, s.R, b, SPECULATION * now * h - before):
            sw.reach[b] = now
            out = True
    return out


@kernel
def capture_step(m, act, s, ct, sw, jt, chk, ev, pseudo, kicked, struck, mats, y, table, j, grid, h, resting,
                 depth_limit, energy_tol, since, last, parts, poses, touch, isl):
    """One step of h from grid row j, `since` s after its time (a part of a step taken in parts; the kinematic
    bodies placed at row j + grid after the `last` part) (module docstring). Returns False when the buffers were too
    small (y is then as it was at the step's start). parts, poses: the compound bodies (compound.py); touch: the
    speed of a landing that is an impact event without an impact (`_touchdowns`)."""
    t = table[j, TIME] + since
    copy_state(y, s.start)
    step_forces(m, s, y, table, j, h)  # (R current)
    world_inverse_inertia(m.bodies, s.R, s.inv_inertia)
    _kick(m.bodies, s, y, h)
    place(parts, poses, y, s.R, sw.order)
    # the step's contacts and impacts, found again while the impacts send a body farther than its contacts were
    # found for (`_outran`); kicked keeps the velocities of the kick, for that and for the islands solved whole
    # (their energy before the step's impulses)
    copy_state(y, kicked)
    for b in range(len(sw.reach)):
        sw.reach[b] = 0.0
    jointed = len(act.rows) > 0
    for attempt in range(FIND_AGAIN + 1):
        found = _contacts(m, s, ct, sw, mats, y, h, parts, poses)
        if found < 0:
            copy_state(s.start, y)
            return False
        prepare(m.bodies, s.inv_inertia, ct, y, len(y) - 1, h)
        _touchdowns(ct, h, touch)
        if jointed:
            evaluate_rows(m, act, s, y, table, j)
            prepare_joints(m, act, s, s.inv_inertia, jt, h)
            _mark_held(m, act, sw.held)
        impacts(ct, y, h, resting, sw.struck_in, sw.held, jointed, s.start)
        if attempt == FIND_AGAIN or not _outran(m, s, sw, y, kicked, h, parts):
            break
        copy_state(kicked, y)
    # the solve, warm-started from the last step's impulses; one whose impulses created energy is taken again from
    # the impacts' velocities (struck) with only so much of them as lowers the energy (`_warm_again`). Contacts keep
    # their impulses from where they were: in a light wall struck by a ball ten times heavier, the impulses of the
    # step before, large among the bricks, raised the energy of a step's 118 contacts' bodies from 44 J to 2234 J;
    # the sweeps brought back all but 12 J (found 2026-12-07). Taken again with none of them, a column of 15 steel
    # balls landing in a tube sank 0.36 mm, and 0.26 mm with them scaled
    copy_state(y, struck)
    if jointed:
        warm_start_joints(m, act, s, s.inv_inertia, jt, y)
    warm_start(ct, y)
    chk.counts[4] += _solve_velocities(m, act, s, ct, jt, isl, y, kicked, jointed, False)
    created, most = work(ct, y)
    if created > energy_tol:
        copy_state(struck, y)
        _warm_again(m.bodies, s.R, act, ct, jt, y, energy_tol)
        chk.counts[4] += _solve_velocities(m, act, s, ct, jt, isl, y, kicked, jointed, True)
        chk.counts[5] += 1
        created, most = work(ct, y)
    _check(ct, chk, t, depth_limit, energy_tol, created, most)
    for c in range(found):
        ct.acc[c] += ct.lam[c, 0] + ct.hit[c]
    _pair_events(ct, ev, t, h, False)
    # the position pass: contacts deeper than the slop apart, those struck across a gap brought to where their
    # impact's time puts them, the joints' errors closed; positions only
    moved = jointed or deep(ct)
    if moved:
        clear(pseudo, ct, y, h, jointed)
        for _ in range(POSITION_SWEEPS):
            if jointed:
                close_joints(m, act, s, s.inv_inertia, jt, pseudo)
            separate(ct, pseudo, y, h)
        if not jointed:
            chk.counts[4] += separate_islands(m.bodies, s.R, ct, pseudo, y, h, isl)
    _drift(m, s, y, pseudo, moved, h, parts, jointed)
    if last:
        place_kinematic(m.kinematic, table, j + grid, y)
    if jointed:
        # the joints exactly on their manifold, as the exact path's semi-implicit Euler has them (SHAKE's impulse:
        # dynamics/projection.py): the sweeps leave gears and cords a few mm off
        project(m, act, s, y, table, j + grid, True, h)
    keep_old(ct)
    return True


@kernel
def _record(m, act, s, y, table, j, frames, f):
    """Frame f: the state, its energy and the largest error of the active joint rows."""
    copy_state(y, frames.y[f])
    rotations(y, s.R)
    frames.energy[f] = energy(m.bodies, s.R, y)
    frames.error[f], frames.worst[f] = constraint_error(m, act, s, y, table, j)


@entry
def run(m, act, s, ct, sw, jt, chk, ev, pseudo, kicked, struck, held, mats, y, table, h, steps, grid, frame_step,
        frames, status, resting, depth_limit, energy_tol, parts, poses, touch, isl):
    """Advance y by `steps` steps of h (module docstring); frames recorded at frame_step (steps counted from the
    call's start, 0: before the first). Returns the steps taken; status (4,) <- (code, step, body, 0). parts (read
    only) and poses (scratch): the compound bodies (compound.py; a scene without any: every count 0); touch: the
    landing speed of an impact event without an impact (`_touchdowns`; inf: none)."""
    status[0], status[1], status[2], status[3] = DONE, 0, -1, 0
    f = 0
    while f < len(frame_step) and frame_step[f] == 0:
        _record(m, act, s, y, table, 0, frames, f)
        f += 1
    for step in range(steps):
        j = grid * step
        pieces = _split(m, ct, y, h, parts)
        copy_state(y, held)
        grown = True
        for piece in range(pieces):
            grown = capture_step(m, act, s, ct, sw, jt, chk, ev, pseudo, kicked, struck, mats, y, table, j, grid,
                                 h / pieces, resting, depth_limit, energy_tol, piece * h / pieces, piece == pieces - 1,
                                 parts, poses, touch, isl)
            if not grown:
                break
        if not grown:
            copy_state(held, y)  # (the whole step is taken again)
            status[0], status[1] = GROW, step
            return step
        trace_step(y, frames, step)
        body = runaway_body(m.bodies, y)
        if body >= 0:
            status[0], status[1], status[2] = RUNAWAY_BODY, step + 1, body
            return step + 1
        while f < len(frame_step) and frame_step[f] == step + 1:
            _record(m, act, s, y, table, j + grid, frames, f)
            if not frames.error[f] <= RUNAWAY_CONSTRAINT_ERROR:
                status[0], status[1], status[2] = RUNAWAY_ROW, step + 1, frames.worst[f]
                return step + 1
            _pair_events(ct, ev, table[j + grid, TIME], h, True)
            for c in range(ct.count[2]):
                ct.old_acc[c] = 0.0  # (every pressing pair's impulse was handed on: the next frame counts anew)
            f += 1
        if ev.count[0] * 2 > len(ev.rows):
            status[0], status[1] = DRAIN, step + 1
            return step + 1
    return steps
