"""The capturing step's data: the contacts of the current step and of the last one (warm starting), the broad
phase's sorted order and candidate pairs, and the run's checks. Plain arrays, allocated once per size and grown by
the Python side when a step finds more than they hold (the step is then taken again).

    Contacts   count (4,) int: [0] contacts this step, [1] found (> capacity: grow), [2] contacts last step
               a, b (C,) bodies; point (C,3) world; normal (C,3) from b toward a; depth (C,) m (< 0: a gap);
               feature (C,) which features made it; key (C,) pair key * FEATURES + feature (warm starting);
               t1, t2 (C,3) tangents; ra, rb (C,3) arms from the centres of mass; mass (C,3) effective masses of
               the normal and tangent rows; mu, bounce (C,) friction and the normal speed restitution asks for
               (m/s); e (C,) the pair's restitution; base (C,) hit before this generation; approach (C,) the fastest
               it approached when struck (m/s; 0: no impact); hit (C,) the normal impulse of its impact (N s); lam (C,3) impulses (N s) of the normal and tangent rows; push (C,) the position pass's
               impulse; before (C,3) the rows' relative velocities before the solve; acc (C,) normal impulse
               since the last frame; old_key (C,), old_lam (C,3), old_acc (C,), old_point (C,3) the last step's,
               sorted by key; old_used (C,) whether this step's contacts took an old one's impulses already
    Sweep      order (c,) the collidable bodies that are not planes, sorted by their boxes' low x; planes (p,);
               box (n+1,6) each body's world box [lo, hi] grown by its reach over the step; excluded (e,) sorted
               pair keys a * n + b (a < b) that never collide now; pairs (P,2), count (1,) the candidate pairs;
               work (16,4) the narrow phase's scratch (box-box clipping)
    Checks     worst (8,) float: [0] deepest interpenetration (m), [1] its time, [2] its body a, [3] b,
               [4] largest energy a step's contact impulses created (J), [5] its time, [6] a, [7] b;
               counts (4,) int: [0] steps that found interpenetration over the limit, [1] steps whose contact
               impulses created energy over the tolerance, [2] contacts solved (sum over steps), [3] steps
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

# a contact's key: its pair's key times this, plus its feature (below 2^24 for every closed-form pair)
FEATURES = 1 << 24

Contacts = namedtuple("Contacts", "count a b point normal depth feature key t1 t2 ra rb mass mu bounce lam push "
                                  "before acc old_key old_lam old_acc hit e base approach old_point old_used")
Sweep = namedtuple("Sweep", "order planes box excluded pairs count work")
Checks = namedtuple("Checks", "worst counts")
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
    return Contacts(np.zeros(4, np.int64), i(), i(), v(), v(), f(), i(), i(), v(), v(), v(), v(), v(), f(), f(), v(),
                    f(), v(), f(), i(), v(), f(), f(), f(), f(), f(), v(), i())


def grown(old: Contacts, capacity: int) -> Contacts:
    """Room for `capacity` contacts, keeping the last step's (warm starting goes on)."""
    new = contacts(capacity)
    kept = int(old.count[2])
    new.count[2] = kept
    new.old_key[:kept], new.old_lam[:kept], new.old_acc[:kept] = old.old_key[:kept], old.old_lam[:kept], old.old_acc[:kept]
    new.old_point[:kept] = old.old_point[:kept]
    return new


def sweep(order, planes, n: int, excluded, capacity: int) -> Sweep:
    return Sweep(np.ascontiguousarray(order, np.int64), np.ascontiguousarray(planes, np.int64), np.zeros((n + 1, 6)),
                 np.ascontiguousarray(np.sort(excluded), np.int64), np.zeros((max(int(capacity), 16), 2), np.int64),
                 np.zeros(1, np.int64), np.zeros((16, 4)))


def joint_rows(rows: int) -> JointRows:
    m = max(int(rows), 1)
    return JointRows(np.zeros(m), np.zeros(m), np.zeros(m))


def checks() -> Checks:
    return Checks(np.zeros(8), np.zeros(4, np.int64))


def events(capacity: int) -> Events:
    return Events(np.zeros((max(int(capacity), 64), EVENT_WIDTH)), np.zeros(2, np.int64))
