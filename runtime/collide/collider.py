"""The collision stage of one run. The compiled step holds the lasting contacts itself (their rows: contacts.py,
core/contact.py) and stops when it sees a change it cannot handle (a pair coming near, a contact pulling, slipping,
stopping, leaving its face, a pair in contact turning); this stage then looks:

    scan      contacts at the end of the step (broad phase on boxes swept over the step, narrow phase)
    locate    an impact that happened inside the step (a pair apart at the start, interpenetrating at the end):
              rewind to the start, integrate to the time of impact (regula falsi on the pair's distance,
              re-integrating from the start each time), resolve there, integrate the rest of the step; repeat
    resolve   impacts (generations, restitution, the joints exact: response.py), then a resting pass that leaves
              no contact approaching; events (events.py)
    keep      the touching points that do not part become (or stay) the step's contact rows

Tunnelling: the end-of-step scan would miss a small fast body that crossed a thin one within one step. When a
pair's relative travel over the step exceeds the sum of their smallest half-extents, its path is sampled at
that spacing (positions linear, orientations by normalized lerp) and the first interpenetrating sample
brackets the time of impact. Limit: MAX_SWEEP_SAMPLES samples, so no tunnelling while the relative travel per
step stays below MAX_SWEEP_SAMPLES x (thin_a + thin_b): a 1 cm sphere (thin 1 cm) against a 1 cm board
(thin 5 mm) at the default 1 ms step, 960 m/s. Rotation is not swept (a spinning thin bar can cross a thin
board if it turns through it within one step). Planes are half-spaces: nothing gets through them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.build import PAIR_TURN
from ..core.contact import LIFTS, SLIPS, STOPS
from ..core.data import COUNTER_TURNED_BACK
from ..core.rotation import quat_to_matrix, world_inverse_inertia
from ..plan.kinematics import never_moving
from .compound import contact_elements
from .contacts import ContactSet, set_relative
from .events import EventLog
from .handover import HandOver
from .narrow import closed_form
from .pairs import BroadPhase, is_excluded, pair_keys
from .shapes import PLANE, SPHERE, kinds_of, reach
from .response import Bodies, Contacts, Joints, Response, contact_rows, row_velocity

# an impact is rewound to its time when the bodies interpenetrate by more than this at the end of the step, m
TOI_TOLERANCE = 1e-6
# the time of impact is located to a distance of this, m
TOI_LOCATE = 1e-8
# regula falsi iterations for one time of impact (each re-integrates the step up to the trial time)
TOI_ITERATIONS = 12
# contacts act (impulses) only when the surfaces are within this of touching, m; a contact further apart is
# left alone: if the bodies meet within the next step, that step's time-of-impact search finds when
TOUCHING = 1e-6
# impacts located inside one step at most (a further impact in the same step is resolved at the step's end)
MAX_TOI_PER_STEP = 8
# samples along one pair's path within a step, at most (the tunnelling limit, see the module docstring)
MAX_SWEEP_SAMPLES = 64
# contacts approaching slower than max(RESTING_SPEED, RESTING_STEPS |g| h) are resting (restitution 0):
# a body lying on a floor approaches it at |g| h each step, and must not bounce off it
RESTING_SPEED = 1e-3  # m/s
RESTING_STEPS = 2.0
# contacts approaching slower than this (round-off) with nothing to correct need no solve at all, m/s
AT_REST_SPEED = 1e-9
# a stop inside a step is found from a shorter step the slip survives, halved at most this often
STOP_HALVINGS = 20
# the least turn (rad) after which a pair in contact is looked at again (a feature touching but not held)
MIN_TURN = 1e-6


class Collider(HandOver):
    """The per-run stage: plan.collisions.start(simulation) builds it; the simulation calls `start` once,
    `on_epoch` when it enters an epoch and `on_stop` when the compiled step asks for a look. stats counts the
    impacts located in time and the crossings the sweep test caught; `lasting` holds the contact rows."""

    def __init__(self, cplan, sim):
        self.cp, self.sim, self.plan = cplan, sim, sim.plan
        n = self.plan.n
        self.saved = [np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))]
        self.t_saved = self.plan.start
        self.broad = BroadPhase(cplan.table, cplan.collidable, self.plan.dynamic, cplan.excluded, cplan.margin,
                                still=never_moving(self.plan))
        self.fcl, self.compound = None, None
        elements = cplan.table.elements
        if len(cplan.fcl_bodies):
            from .meshes import FclPairs

            # over the elements when there are compound bodies (their first n entries are the bodies' own)
            held = cplan.fcl_bodies if cplan.fcl_elements is None else cplan.fcl_elements
            self.fcl = FclPairs(elements.table if elements is not None else cplan.table, held)
        if elements is not None:
            from .compound import CompoundPairs

            self.compound = CompoundPairs(elements, self.fcl)
        self.log = EventLog(self.plan.names, sim.events, self.plan.frame_times, elements)
        self.lasting = ContactSet(sim, cplan)
        self.gravity = float(np.linalg.norm(self.plan.gravity))  # |g|, m/s2
        self.resting_speed = max(RESTING_SPEED, RESTING_STEPS * self.gravity * self.plan.step)
        self.stats = {"impacts located": 0, "tunnelling caught": 0}
        # the capturing path (runtime/capture): whether this scene may take it (Simulation says), and why it should
        # now (an impact between two moving bodies: things falling on things make the contact set change at
        # every step, which this stage would follow one look at a time)
        self.may_capture, self.wants_capture = False, None
        # bodies whose any impact hands over: with `jointed_strike` (Simulation sets it), those an active joint holds
        self.jointed_strike, self.strikers = False, np.zeros(self.plan.n, bool)
        self.reach = reach(cplan.table)
        self.kinds = [kinds_of(cplan.table, i) for i in range(self.plan.n)]  # (each body's shape kinds, its parts')
        pairs = sim.compiled.model.pairs
        # the compiled step's pair of bodies (i, j), in either order
        self.pair_index = {**{(int(a), int(b)): p for p, (a, b) in enumerate(zip(pairs.a, pairs.b))},
                           **{(int(b), int(a)): p for p, (a, b) in enumerate(zip(pairs.a, pairs.b))}}

    # -- the hooks of the step loop -------------------------------------------------------------------------

    def start(self, epoch=None) -> None:
        """The contacts the run starts with (a stack standing on a floor). A pair that starts touching and
        approaching is an impact at the start (a striker placed against a row of balls: it passes its momentum
        down the row, where keeping the pair as a lasting contact made the row move off together), which may hand
        the run over to the capturing path (`wants_capture`)."""
        self._save_start()
        scan = self.scan(always=True)
        if self._heavy_on_light(self._touching(scan), self.sim.state.t):
            return
        self.resolve(scan, self.sim.state.t, rewound=True, epoch=epoch)
        if not self.wants_capture:
            self._keep_contacts(scan)  # (resolve changes velocities only: the scan of these positions stands)

    def on_epoch(self, epoch, t: float) -> None:
        """A new epoch (or a windowed `exclude` began or ended at t): a pair joined by a constraint is excluded
        while the constraint is on (and collides before and after), a pair an `exclude` names while its window
        lasts (always, without one); a pair a `collide` names collides while it lasts, joined or not
        (CollisionPlan.excluded_now)."""
        n = self.plan.n
        joined = np.zeros(0, np.int64)
        if epoch is not None and epoch.active.size:
            rb = self.plan.constraints.row_bodies[epoch.active]
            both = rb[(rb[:, 0] >= 0) & (rb[:, 1] >= 0) & (rb[:, 0] != rb[:, 1])]
            joined = pair_keys(both, n)
        keys = self.cp.excluded_now(joined, t)
        self.broad.excluded = keys
        self.strikers[:] = False
        if self.jointed_strike and epoch is not None and epoch.active.size:
            held = self.plan.constraints.row_bodies[epoch.active]
            self.strikers[held[held >= 0]] = True
        pairs = self.sim.compiled.model.pairs
        now = is_excluded(pair_keys(np.stack([pairs.a, pairs.b], 1), n), keys)
        pairs.clear[:] = 0.0  # (a clearance holds only while its pair stays apart)
        pairs.state[now] = 2
        pairs.state[~now & (pairs.state == 2)] = 0
        if len(self.lasting.contacts):
            excluded = {(int(a), int(b)) for a, b in zip(pairs.a[now], pairs.b[now])}
            kept = {k: c for k, c in self.lasting.contacts.items()
                    if (min(c.a, c.b), max(c.a, c.b)) not in excluded}
            if len(kept) != len(self.lasting.contacts):
                self.lasting.contacts = kept
                self.lasting.write()

    def on_stop(self, code: int, which: int, h: float, epoch) -> None:
        """The step of h that ended at the state's time asked for a look (core/contact.py's codes). A contact that
        lifts or slips was wrong for the whole step: the step is taken again without it, or sliding. One that stops
        stops inside the step: the step is taken again up to the time its slip is 0 (the secant: under constant
        friction the slip falls linearly), sticking from there (procedural: the friction impulse of a substep
        stopped it, core/contact.py friction_impulses: it sticks where it is). Then a pair that came near in the same
        step is looked at now: the compiled step reports one change a step (a ball reaching a wall as a brick
        stopped was found a step late, 7 cm deep)."""
        s = self.sim.state
        if code == LIFTS or code == SLIPS:
            lam = self.sim.compiled.scratch.lam.copy()
            self._rewind(h)
            if code == LIFTS:
                self.lasting.remove(which)
            else:
                self.lasting.to_sliding(which, lam, s.q)
            self.sim.active_rows()
            self._advance(h, epoch)
        elif code == STOPS and self.plan.solver == "procedural":
            self.lasting.to_sticking(which, s.x, s.q)
        elif code == STOPS:
            t_end = s.t
            self._rewind(h)
            self._advance(self._stop_time(which, h, epoch), epoch)
            self.lasting.to_sticking(which, s.x, s.q)
            self.sim.active_rows()
            self._advance(t_end - s.t, epoch)
            s.t = t_end
        else:  # NEAR or LEAVES: something new may touch
            self._look(h, epoch)
            return
        self._save_start()
        if self.broad.anything_near(s.x, self._rotations, self.saved[0]):
            self._look(h, epoch)

    def _rewind(self, h: float) -> None:
        """The live state back to the start of the step of h that just ended (the compiled loop keeps it)."""
        s = self.sim.state
        self._save_start()
        self.t_saved = s.t - h
        self._restore_saved()

    def _restore_saved(self) -> None:
        s = self.sim.state
        for array, buffer in zip((s.x, s.q, s.v, s.w), self.saved):
            array[...] = buffer
        s.t = self.t_saved

    def _stop_time(self, which: int, h: float, epoch) -> float:
        """When, within the step of h from the (restored) start, the slip of sliding contact `which` reaches 0:
        the slip falls linearly while it slides (constant friction), so the secant through the start and a
        shorter step that the slip survives (halved until it does) finds it. Leaves the live state at the start."""
        s, counters = self.sim.state, self.sim.compiled.scratch.counters
        before = self.lasting.slip_along_t1(which, s.x, s.q, s.v, s.w)
        tau, after = h, before
        for _ in range(STOP_HALVINGS):
            tau *= 0.5
            self._advance(tau, epoch)
            after = self.lasting.slip_along_t1(which, s.x, s.q, s.v, s.w)
            self._restore_saved()
            if counters[COUNTER_TURNED_BACK] == 0 and 0.0 < after < before:
                break
        # slip(t) = before + (after - before) t / tau = 0
        return min(h, tau * before / (before - after)) if before > after else 0.0

    def frame_events(self, t: float, table) -> None:
        """The "contact" events of the frame that ends at t, from the compiled step's record of the contacts
        (table (K, 8)), or from the live state when the frame is recorded here (table None)."""
        if not self.lasting.instance_of:
            return
        if table is None:
            from ..core.entries import frame_contacts

            c = self.sim.compiled
            out = np.zeros((1, len(c.model.constraints.family), 8))
            frame_contacts(c.model, self.sim.rows_now, c.scratch, self.sim.state.y, out)
            table = out[0]
        contacts = self.lasting.contacts
        bodies = {k: (contacts[key].a, contacts[key].b, contacts[key].part_a, contacts[key].part_b)
                  for key, k in self.lasting.instance_of.items()}
        self.log.frame(t, table, bodies)

    def _save_start(self) -> None:
        """The start of the last step (the compiled loop keeps it), where a time-of-impact search rewinds to."""
        n = self.plan.n
        start = self.sim.compiled.scratch.start
        for buffer, columns in zip(self.saved, (slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13))):
            buffer[...] = start[:n, columns]

    def _look(self, h: float, epoch) -> None:
        s = self.sim.state
        t_end = s.t
        self._save_start()
        self.t_saved = t_end - h
        self.resting_speed = max(RESTING_SPEED, RESTING_STEPS * self.gravity * h)
        scan = self.scan(always=True)
        for _ in range(MAX_TOI_PER_STEP):
            hit = self._earliest_hit(scan, t_end - self.t_saved)
            if hit is None:
                break
            pair, bracket, _ = hit
            self._locate(pair, bracket, epoch)  # the live state is now at the time of impact
            self.resolve(self.scan(always=True), s.t, rewound=True, epoch=epoch)
            if self.wants_capture:
                return  # (the rest of the step is the capturing path's: Simulation.switch_to_capture)
            self._keep_contacts()
            self.sim.active_rows()
            self._save_start_here()  # the new start of what is left of the step
            self._advance(t_end - s.t, epoch)
            s.t = t_end
            scan = self.scan(always=True)
        self.resolve(scan, t_end, rewound=False, epoch=epoch)
        if self.wants_capture:
            return
        self._keep_contacts(scan)  # (resolve changes velocities only: the scan of these positions stands)
        self._clearances(scan)

    def _clearances(self, scan) -> None:
        """For each pair apart that the broad phase finds near (scan.pairs), the clearance that lets the compiled
        step go on without a look (core/contact.py kept_clear): its distance d now and its nearest point z, seen
        as a point of the body whose turning moves it least (the shorter lever K + d, K = |z - x_B| + B's reach
        for z a point of A). A pair with a plane keeps the plane's own test (exact, and as cheap)."""
        if not len(scan.pairs):
            return
        s, pairs, kind = self.sim.state, self.sim.compiled.model.pairs, self.cp.table.kind
        for i, j in scan.pairs.tolist():
            p = self.pair_index.get((i, j))
            if p is None or pairs.state[p] != 0 or PLANE in (kind[i], kind[j]):
                continue
            d, z = self.nearest(i, j, s.x, scan.R)
            if z is None or not d > self.cp.margin:
                continue
            a, b = int(pairs.a[p]), int(pairs.b[p])
            levers = (np.linalg.norm(z - s.x[b]) + self.reach[b] + d, np.linalg.norm(z - s.x[a]) + self.reach[a] + d)
            side = int(levers[1] < levers[0])
            A, B = (a, b) if side == 0 else (b, a)
            pairs.side[p], pairs.lever[p] = side, levers[side]
            pairs.ref[p], pairs.seen[p] = scan.R[A].T @ (z - s.x[A]), scan.R[B].T @ (z - s.x[B])
            set_relative(pairs, p, s.q)
            pairs.clear[p] = d - self.cp.margin

    def _keep_contacts(self, scan=None) -> None:
        """The lasting contacts from the touching points at the live state (`scan`: a full scan of these
        positions, made since they last changed); then, for each pair in contact, the turn after which it is
        looked at again: before the gap of its nearest other feature can close (a rocking box's lifted edge: a turn
        of a brings a point at most reach * a nearer)."""
        s = self.sim.state
        scan = self.scan(always=True) if scan is None else scan
        self.lasting.update(self._touching(scan), s.x, s.q, s.v, s.w, self.resting_speed, self.plan.step)
        pairs = self.sim.compiled.model.pairs
        touching = np.flatnonzero(pairs.state == 1)
        if not len(touching):
            return
        R = quat_to_matrix(s.q)
        kind = self.cp.table.kind
        levers = self._held_levers(s.x, R)
        for p in touching.tolist():
            i, j = int(pairs.a[p]), int(pairs.b[p])
            if {kind[i], kind[j]} <= {SPHERE, PLANE}:
                continue  # a sphere on a sphere or a plane: nothing new comes from turning (it rolls on its rows)
            gap = max(self.distance(i, j, s.x, R, self._known_features(i, j)), 0.0)
            # a turn a about a held point z brings a point that was d away at most (K + d) a nearer (K = |z - x_B|
            # + B's reach: core/contact.py kept_clear), and no point further than the larger reach
            reach, held = max(self.reach[i], self.reach[j], 1e-300), levers.get(frozenset((i, j)), math.inf)
            pairs.turn[p] = min(PAIR_TURN, gap / min(reach, held + gap) + MIN_TURN)

    def _held_levers(self, x, R) -> dict:
        """{pair of bodies: K}, K = |z - x_B| + B's reach for the best of the pair's held points z and of its two
        bodies as B."""
        levers = {}
        for c in self.lasting.contacts.values():
            if c.a < 0 or c.b < 0:
                continue
            z = x[c.a] + R[c.a] @ c.point
            K = min(np.linalg.norm(z - x[c.a]) + self.reach[c.a], np.linalg.norm(z - x[c.b]) + self.reach[c.b])
            key = frozenset((c.a, c.b))
            levers[key] = min(levers.get(key, math.inf), K)
        return levers

    def _save_start_here(self) -> None:
        s = self.sim.state
        for buffer, array in zip(self.saved, (s.x, s.q, s.v, s.w)):
            buffer[...] = array
        self.t_saved = s.t

    def _touching(self, scan):
        contacts = scan.contacts
        return None if contacts is None else contacts.subset(contacts.depth >= -TOUCHING)

    # -- detection ----------------------------------------------------------------------------------------------

    def scan(self, always: bool = False) -> "Scan":
        """Contacts at the live state; the broad phase uses boxes swept from the saved start of the step.
        When no dynamic body's swept box comes near anything, nothing more is computed (unless `always`)."""
        s = self.sim.state
        if not always and not self.broad.anything_near(s.x, self._rotations, self.saved[0]):
            return NOTHING_NEAR
        R, R0 = quat_to_matrix(s.q), quat_to_matrix(self.saved[1])
        pairs = self.broad.pairs((s.x, R), (self.saved[0], R0))
        return Scan(self.contacts(pairs, s.x, R, self.cp.margin), pairs, R, R0)

    def _rotations(self, index) -> tuple:
        """(R now, R at the saved start of the step) of bodies `index`, (k,3,3) each."""
        return quat_to_matrix(self.sim.state.q[index]), quat_to_matrix(self.saved[1][index])

    def contacts(self, pairs, x, R, margin):
        parts = []
        for p, (i, j) in enumerate(pairs.tolist()):
            found = self.pair_contacts(i, j, x, R, margin)
            if len(found[2]):
                parts.append((found, p))
        if not parts:
            return None
        a = np.concatenate([np.full(len(f[2]), f[4]) for f, _ in parts])
        b = np.concatenate([np.full(len(f[2]), f[5]) for f, _ in parts])
        pair = np.concatenate([np.full(len(f[2]), p) for f, p in parts])
        features = np.concatenate([np.asarray(f[3], np.int64) for f, _ in parts])
        mu, e = self.cp.mix(*contact_elements(self.cp.table.elements, a, b, features))  # each part's material
        return Contacts(a, b, np.concatenate([f[0] for f, _ in parts]), np.concatenate([f[1] for f, _ in parts]),
                        np.concatenate([f[2] for f, _ in parts]), pair, mu, e, features)

    def pair_contacts(self, i, j, x, R, margin):
        """(points, normals, depths, features, a, b) of bodies i and j, normals from b toward a (a and b: the
        pair's bodies in the order of its test; for a compound body, one order per pair of parts, arrays)."""
        table = self.cp.table
        if self.compound is not None and (table.compound(i) or table.compound(j)):
            return self.compound.contacts(i, j, x, R, margin)
        test = closed_form(table.kind[i], table.kind[j])
        if test is None:
            return (*self.fcl.contacts(i, j, x, R, margin), i, j)
        function, swapped = test
        a, b = (j, i) if swapped else (i, j)
        return (*function(table, a, b, x, R, margin), a, b)

    def distance(self, i, j, x, R, known=frozenset()) -> float:
        """Signed distance of bodies i and j (negative: interpenetrating by that much); with `known` (features),
        of their other features only."""
        return self.nearest(i, j, x, R, known)[0]

    def nearest(self, i, j, x, R, known=frozenset()) -> tuple:
        """(the signed distance of bodies i and j, the world point of the feature that gives it, or None without
        one); with `known` (features), of their other features only."""
        if self.compound is not None and (self.cp.table.compound(i) or self.cp.table.compound(j)):
            return self.compound.nearest(i, j, x, R, known)
        points, normals, depths, features, a, b = self.pair_contacts(i, j, x, R, math.inf)
        if known:
            other = [int(f) not in known for f in features]
            points, depths = points[other], depths[other]
        if not len(depths):
            return math.inf, None
        deepest = int(np.argmax(depths))
        return -float(depths[deepest]), points[deepest]

    def _touching_features(self, i, j, x, R) -> frozenset:
        """The features of the pair (i, j) that touch (or interpenetrate) at the pose (x, R)."""
        _, _, depths, features, _, _ = self.pair_contacts(i, j, x, R, math.inf)
        return frozenset(int(f) for f, d in zip(features, depths) if d >= -TOUCHING)

    def _known_features(self, i, j) -> frozenset:
        """The features of the lasting contacts of the pair (i, j)."""
        return frozenset(key[2] for key in self.lasting.contacts if {key[0], key[1]} == {i, j})

    # -- time of impact -----------------------------------------------------------------------------------------

    def _earliest_hit(self, scan, span: float):
        """(pair (i, j), bracket (t0, t1, d0, d1) relative to the saved start) of the earliest impact inside the
        step, or None."""
        contacts, pairs = scan.contacts, scan.pairs
        x0, R0 = self.saved[0], scan.R0
        x1, R1 = self.sim.state.x, scan.R
        best = None
        deep = {}
        if contacts is not None:
            # a pair apart at the start (checked below) and interpenetrating now met inside the step, however
            # slowly it came (a slow one at a 10 ms step can end 2 mm deep) and whatever the normal says now
            # (a small body that reached the middle of a thin one has a normal pointing out of its far side)
            hits = contacts.depth > TOI_TOLERANCE
            for p in np.unique(contacts.pair[hits]):
                deep[int(p)] = float(contacts.depth[contacts.pair == p].max())
        for p, (i, j) in enumerate(pairs.tolist()):
            if p in deep:
                d0 = self.distance(i, j, x0, R0)
                if d0 > TOI_TOLERANCE:
                    bracket = (0.0, span, d0, -deep[p])
                    best = _earlier(best, (i, j), bracket)
                    continue
                # a pair in contact: a feature of it that was apart and is inside now (a corner of a rocking
                # body coming down) met inside the step too. Its features in contact at the start are its lasting
                # contacts', or, with none, those touching then: a box that struck the floor with one corner and
                # bounced off it came down on a second within the step (procedural plan, 10 ms), unseen: it was
                # resolved 3.9 mm deep at the step's end, and the projection threw it up with twice the energy
                known = self._known_features(i, j) or self._touching_features(i, j, x0, R0)
                if known:
                    d0, d1 = self.distance(i, j, x0, R0, known), self.distance(i, j, x1, R1, known)
                    if d1 < -TOI_TOLERANCE and d0 > 0.0:
                        best = _earlier(best, (i, j, known), (0.0, span, d0, d1))
                    elif d1 < -TOI_TOLERANCE and d0 > -TOUCHING:
                        # touching but not held at the start (it was parting): it met at the start
                        best = _earlier(best, (i, j, known), (0.0, 0.0, d0, d0 - 1.0))
            else:  # even a pair found just apart now may have crossed (ending within the margin beyond)
                bracket = self._sweep(i, j, x0, R0, x1, R1, span)
                if bracket is not None:
                    best = _earlier(best, (i, j), bracket)
        return best

    def _sweep(self, i, j, x0, R0, x1, R1, span):
        """Sample the path of a pair that moved further than it is thin; the first interpenetrating sample and
        the one before bracket the impact."""
        table = self.cp.table
        thin = table.thin[i] + table.thin[j]
        travel = float(np.linalg.norm((x1[i] - x0[i]) - (x1[j] - x0[j])))
        if not np.isfinite(thin) or travel <= thin:
            return None
        count = min(MAX_SWEEP_SAMPLES, math.ceil(travel / thin))
        q0, q1 = self.saved[1], self.sim.state.q
        previous = (0.0, self.distance(i, j, x0, R0))
        if previous[1] <= 0:
            return None
        x, R = x1.copy(), R1.copy()
        for k in range(1, count):
            u = k / count
            for body in (i, j):
                x[body] = (1 - u) * x0[body] + u * x1[body]
                b = q1[body] if q0[body] @ q1[body] >= 0 else -q1[body]
                q = (1 - u) * q0[body] + u * b
                R[body] = quat_to_matrix(q / np.linalg.norm(q))
            d = self.distance(i, j, x, R)
            if d < -TOI_TOLERANCE:
                self.stats["tunnelling caught"] += 1
                return (previous[0], u * span, previous[1], d)
            previous = (u * span, d)
        return None

    def _locate(self, pair, bracket, epoch) -> float:
        """Time of impact (from the saved start) by the Illinois variant of regula falsi; leaves the live state
        (and its time) there, the pair touching."""
        ta, tb, fa, fb = bracket
        side, t, f = 0, tb, fb
        for _ in range(TOI_ITERATIONS):
            t = tb - fb * (tb - ta) / (fb - fa)
            f = self._distance_at(pair, t, epoch)
            if abs(f) <= TOI_LOCATE or tb - ta <= 1e-15:
                break
            if f > 0:
                ta, fa = t, f
                if side == 1:
                    fb *= 0.5
                side = 1
            else:
                tb, fb = t, f
                if side == -1:
                    fa *= 0.5
                side = -1
        if f > self.cp.margin:  # not converged on the touching side: take the interpenetrating end
            t = tb
            self._distance_at(pair, t, epoch)
        self.stats["impacts located"] += 1
        return t

    def _distance_at(self, pair, tau, epoch) -> float:
        s = self.sim.state
        for array, buffer in zip((s.x, s.q, s.v, s.w), self.saved):
            array[...] = buffer
        s.t = self.t_saved
        self._advance(tau, epoch)
        s.t = self.t_saved + tau
        return self.distance(pair[0], pair[1], s.x, quat_to_matrix(s.q), pair[2] if len(pair) > 2 else frozenset())

    def _advance(self, tau: float, epoch) -> None:
        """Integrate the live state from its time s.t to s.t + tau with the plan's own step."""
        s = self.sim.state
        if tau > 0:
            self.sim.integrate(tau)
        s.t += tau

    # -- response ---------------------------------------------------------------------------------------------

    def resolve(self, scan, t, rewound: bool, epoch) -> None:
        """Impulses for the touching contacts of `scan` at time t (the live state): impacts, then the resting pass
        (restitution 0: nothing is left approaching). Impact events: at t when rewound, else interpolated."""
        contacts = scan.contacts
        if contacts is not None:
            contacts = contacts.subset(contacts.depth >= -TOUCHING)
        if contacts is None:
            return
        s, plan = self.sim.state, self.plan
        if self._at_rest(contacts) or self._hands_over(contacts, t):
            return
        bodies = Bodies(s.v, s.w, plan.inv_mass, world_inverse_inertia(scan.R, plan.inv_inertia_body), plan.dynamic)
        response = Response(contacts, s.x, bodies, self._joints(t, epoch))
        response.impacts(self.resting_speed)
        response.resting()
        self.log.record(contacts, response.outcome, self._impact_time(scan, contacts, t, rewound))

    def _at_rest(self, contacts) -> bool:
        """Nothing approaching: lam = 0 solves every row (touching balls of the cradle before the strike)."""
        s = self.sim.state
        u = row_velocity(contact_rows(contacts, s.x, contacts.normal), np.stack([contacts.a, contacts.b], 1), s.v, s.w)
        return bool(np.all(u >= -AT_REST_SPEED))

    def _joints(self, t, epoch) -> Joints:
        c = self.plan.constraints
        if c is None or epoch is None or not epoch.active.size:
            return Joints.none()
        J, ct = self.sim.joint_rows(epoch.active, t)
        return Joints(J, c.row_bodies[epoch.active], ct)

    def _impact_time(self, scan, contacts, t, rewound):
        """Time of an impact: t itself when located; else interpolated on the pair's distance between the start
        of the (rest of the) step, d0 > 0, and now, -depth."""
        if rewound:
            return lambda p: t
        x0, R0 = self.saved[0], scan.R0

        def interpolated(p):
            i, j = scan.pairs[p]
            d0 = self.distance(int(i), int(j), x0, R0)
            depth = float(contacts.depth[contacts.pair == p].max())
            if d0 <= 0 or depth <= 0:
                return t
            return self.t_saved + (t - self.t_saved) * d0 / (d0 + depth)

        return interpolated


@dataclass
class Scan:
    """Contacts (or None) and candidate pairs (k,2) at the live state, and the rotation matrices of the live
    state (R) and of the saved start of the step (R0), (n,3,3); R and R0 are None when there are no pairs
    (nothing reads them then)."""

    contacts: Contacts | None
    pairs: np.ndarray
    R: np.ndarray | None
    R0: np.ndarray | None


NO_PAIRS = np.zeros((0, 2), np.int64)
# the scan of a step where the broad phase's early-out finds nothing near (one object for every such step)
NOTHING_NEAR = Scan(None, NO_PAIRS, None, None)


def _earlier(best, pair, bracket):
    """Keep the hit whose linear estimate of the time of impact is earliest."""
    t0, t1, d0, d1 = bracket
    estimate = t0 + (t1 - t0) * d0 / (d0 - d1)
    return (pair, bracket, estimate) if best is None or estimate < best[2] else best
