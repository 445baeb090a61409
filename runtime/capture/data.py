"""The capturing step's data: the contacts of the current step and of the last one (warm starting), the broad
phase's sorted order and candidate pairs, and the run's checks. Plain arrays, allocated once per size and grown by
the Python side when a step finds more than they hold (the step is then taken again).

    Contacts   count (4,) int: [0] contacts this step, [1] found (> capacity: grow), [2] contacts last step,
               [3] the stamp of the entries of runs that are current (-1: runs to be rebuilt)
               a, b (C,) bodies; point (C,3) world; normal (C,3) from b toward a; depth (C,) m (< 0: a gap);
               feature (C,) which features made it; key (C,) pair key * FEATURES + feature (warm starting);
               rows 0, 1, 2: the normal and two tangents; jac (C,3,9) each row's (d, r_a x d, r_b x d), r the
               arms from the centres of mass; turn (C,3,6) a unit impulse's turn of each body (I_a^-1 (r_a x d),
               I_b^-1 (r_b x d)); inv (C,2) 1/m_a, 1/m_b (0: a body impulses do not move); mass (C,3) the
               rows' effective masses; mu, bounce (C,) friction and the normal speed restitution asks for
               (m/s; in the position pass, its target, NaN until made: position.py clear); e (C,) the pair's
               restitution; base (C,) hit before this generation (in the position pass, the least impulse);
               approach (C,) the fastest it approached when struck (m/s; 0: no impact; < 0: a landing that is
               an impact event without an impact, its normal speed: loop._touchdowns); hit (C,) the normal
               impulse of its impact (N s);
               lam (C,3) impulses (N s) of the normal and tangent rows; push (C,) the position pass's impulse;
               before (C,3) the rows' relative velocities before the solve; acc (C,) normal impulse
               since the last frame; old_key (C,), old_lam (C,3), old_acc (C,), old_point (C,3) the last step's,
               in its order (each pair's consecutive); runs (T,4) an open-addressing table (T a power of two
               over 2C) of the last step's pairs: [pair key, first, end, stamp]; old_used (C,) whether this
               step's contacts took an old one's impulses already; match (C,) the old contact whose impulses
               each took (-1: none); group (C,) each contact's island, member (C,) the contacts by island,
               kept (C,3) its island's impulses kept (islands.py); slides (C,) whether it slides in its island's
               Newton solve (newton.py); hit_t (C,2) the tangent rows' impulses of its impact (N s: its friction,
               solve.py `_rub`)
    Sweep      order (c,) the collidable bodies that are not planes; planes (p,);
               box (n+1,6) each body's world box [lo, hi] grown by its reach over the step; the grid (broad.py):
               cell (n+1,4) each body's cell (x, y, z) and bucket (-1: not in the grid), start (B+1,) where
               each of the B buckets (a power of two over 8c) starts in slots (c,), the bodies by bucket, and
               sorted_box (c,6) their boxes; fill (B,) scratch; frame (7,) the cells the grid spans
               [dense, x0, y0, z0, nx, ny, nz]; excluded (e,) sorted
               pair keys a * n + b (a < b) that never collide now; pairs (P,2), count (1,) the candidate pairs;
               work (16,4) the narrow phase's scratch (box-box clipping); struck_in (n+1,) the impact
               generation that last struck each body (solve.py impacts); held (n+1,) whether an active joint row
               joins each body to another moving body (valid while the scene has joints: loop.py `_mark_held`);
               reach (n+1,) a floor on each body's speed in its travel this step (m/s; 0 but where the step's
               impacts sent it farther than its contacts were found for: loop.py `_outran`)
    Checks     worst (8,) float: [0] deepest interpenetration (m), [1] its time, [2] its body a, [3] b,
               [4] largest energy a step's contact impulses created (J), [5] its time, [6] a, [7] b;
               counts (6,) int: [0] steps that found interpenetration over the limit, [1] steps whose contact
               impulses created energy over the tolerance, [2] contacts solved (sum over steps), [3] steps,
               [4] islands solved whole (islands.py; sum over steps), [5] steps whose solve was taken again
               (loop.py `_warm_again`)
    Islands    parent (n+1,), first (n+2,), fill (n+1,) int; rows (R,) int, dense (R,R), rhs (R,); y (n+1,13) an
               island's velocities kept: islands.py; local (n+1,) int, order (R/6,) int, step (n+1,13), grad (R,):
               newton.py
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

# a contact's key: its pair's key times this, plus its feature (below 2^24 for every closed-form pair)
FEATURES = 1 << 24

Contacts = namedtuple("Contacts", "count a b point normal depth feature key jac turn inv mass mu bounce lam push "
                                  "before acc old_key old_lam old_acc hit e base approach old_point old_used match runs group "
                                  "member kept slides hit_t")
Sweep = namedtuple("Sweep", "order planes box excluded pairs count work struck_in cell start slots fill sorted_box "
                             "frame held reach")
Checks = namedtuple("Checks", "worst counts")
Islands = namedtuple("Islands", "parent first fill rows dense rhs y local order step grad")
# the joints' rows (joints.py), by global row: lam (M,) impulse of the last step, mass (M,), target (M,) velocity
JointRows = namedtuple("JointRows", "lam mass target")
# events the step writes: one row per pair and impact, or per pair pressing at a frame
# [time, kind (0 impact, 1 contact), a, b, point (3), normal (3), impulse, tangential speed, normal speed, the
# feature of the pair's contact that took the most impulse (a compound pair's names its parts: compound.fold)]
EVENT_WIDTH = 14
IMPACT, PRESSING = 0, 1
Events = namedtuple("Events", "rows count")
# friction, restitution (n+1,) and has (n+1,) bool of every body; default (2,): friction and restitution of a pair
# of bodies without materials
Materials = namedtuple("Materials", "friction restitution has default")


def contacts(capacity: int) -> Contacts:
    c = max(int(capacity), 16)
    f, v, i = (lambda: np.zeros(c)), (lambda: np.zeros((c, 3))), (lambda: np.zeros(c, np.int64))
    # (count[3] -1: no index of last step's contacts yet; every entry of runs is free)
    return Contacts(np.array([0, 0, 0, -1], np.int64), i(), i(), v(), v(), f(), i(), i(), np.zeros((c, 3, 9)), np.zeros((c, 3, 6)),
                    np.zeros((c, 2)), v(), f(), f(), v(), f(), v(), f(), i(), v(), f(), f(), f(), f(), f(), v(), i(),
                    i(), np.zeros((1 << (2 * c - 1).bit_length(), 4), np.int64), i(), i(), v(), i(), np.zeros((c, 2)))


def grown(old: Contacts, capacity: int) -> Contacts:
    """Room for `capacity` contacts, keeping the last step's (warm starting goes on: solve.py indexes them again)."""
    new = contacts(capacity)
    kept = int(old.count[2])
    new.count[2], new.count[3] = kept, -1
    new.old_key[:kept], new.old_lam[:kept], new.old_acc[:kept] = old.old_key[:kept], old.old_lam[:kept], old.old_acc[:kept]
    new.old_point[:kept] = old.old_point[:kept]
    return new


def sweep(order, planes, n: int, excluded, capacity: int) -> Sweep:
    buckets = 1 << (8 * max(len(order), 1) - 1).bit_length()
    c = max(len(order), 1)
    return Sweep(np.ascontiguousarray(order, np.int64), np.ascontiguousarray(planes, np.int64), np.zeros((n + 1, 6)),
                 np.ascontiguousarray(np.sort(excluded), np.int64), np.zeros((max(int(capacity), 16), 2), np.int64),
                 np.zeros(1, np.int64), np.zeros((16, 4)), np.zeros(n + 1, np.int64), np.zeros((n + 1, 4), np.int64),
                 np.zeros(buckets + 1, np.int64), np.zeros(c, np.int64), np.zeros(buckets, np.int64), np.zeros((c, 6)),
                 np.zeros(7, np.int64), np.zeros(n + 1, np.bool_), np.zeros(n + 1))


def joint_rows(rows: int) -> JointRows:
    m = max(int(rows), 1)
    return JointRows(np.zeros(m), np.zeros(m), np.zeros(m))


def checks() -> Checks:
    return Checks(np.zeros(8), np.zeros(6, np.int64))


def islands(n: int, rows: int) -> Islands:
    i = (lambda size: np.zeros(size, np.int64))
    return Islands(i(n + 1), i(n + 2), i(n + 1), i(rows), np.zeros((rows, rows)), np.zeros(rows), np.zeros((n + 1, 13)),
                   np.full(n + 1, -1, np.int64), i(rows // 6), np.zeros((n + 1, 13)), np.zeros(rows))


def events(capacity: int) -> Events:
    return Events(np.zeros((max(int(capacity), 64), EVENT_WIDTH)), np.zeros(2, np.int64))
