"""The collision stage of one run: after every step, find the contacts, locate impacts in time, and apply the
impulses. Both plans use it: re-integrating part of a step is the simulation's `integrate` (the plan's own step).

    before_step: remember the state at the start of the step
    after_step:  scan      contacts at the end of the step (broad phase on boxes swept over the step)
                 locate    an impact that happened inside the step (a pair apart at the start, interpenetrating
                           at the end): rewind to the start, integrate to the time of impact
                           (regula falsi on the pair's distance, re-integrating from the start each time),
                           resolve there, integrate the rest of the step; repeat for the next impact
                 resolve   impacts (generations, restitution), resting contact and friction, position
                           correction (response.py); events (events.py)

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

from ..rotation import quat_to_matrix, world_inverse_inertia
from .events import EventLog
from .narrow import closed_form
from .pairs import BroadPhase
from .response import SLOP, Bodies, Contacts, Joints, Response, contact_rows, project_joints, row_velocity

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


class Collider:
    """The per-run stage: plan.collisions.start(simulation) builds it; the step loop calls before_step and
    after_step. stats counts the impacts located in time and the crossings the sweep test caught."""

    def __init__(self, cplan, sim):
        self.cp, self.sim, self.plan = cplan, sim, sim.plan
        n = self.plan.n
        self.saved = [np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))]
        self.t_saved = self.plan.start
        self.broad = BroadPhase(cplan.table, cplan.collidable, self.plan.dynamic, cplan.excluded, cplan.margin,
                                still=_never_moving(self.plan))
        self.fcl = None
        if len(cplan.fcl_bodies):
            from .meshes import FclPairs

            self.fcl = FclPairs(cplan.table, cplan.fcl_bodies)
        self.log = EventLog(self.plan.names, sim.events, self.plan.frame_times)
        self.gravity = float(np.linalg.norm(self.plan.gravity))  # |g|, m/s2
        self.resting_speed = max(RESTING_SPEED, RESTING_STEPS * self.gravity * self.plan.step)
        self.stats = {"impacts located": 0, "tunnelling caught": 0}

    # -- the hooks of the step loop -------------------------------------------------------------------------

    def before_step(self, h: float, epoch) -> None:
        s = self.sim.state
        for buffer, array in zip(self.saved, (s.x, s.q, s.v, s.w)):
            buffer[...] = array
        self.t_saved = s.t

    def after_step(self, h: float, epoch) -> None:
        s = self.sim.state
        t_end = s.t
        self.resting_speed = max(RESTING_SPEED, RESTING_STEPS * self.gravity * h)
        scan = self.scan()
        if scan is NOTHING_NEAR:  # no pair: no contact, no impact, nothing to resolve (most steps)
            self.log.flush(t_end)
            return
        for _ in range(MAX_TOI_PER_STEP):
            hit = self._earliest_hit(scan, t_end - self.t_saved)
            if hit is None:
                break
            pair, bracket, _ = hit
            self._locate(pair, bracket, epoch)  # the live state is now at the time of impact
            self.resolve(self.scan(), s.t, h, epoch, final=False, rewound=True)
            self.before_step(h, epoch)  # the new start of what is left of the step
            self._advance(t_end - s.t, epoch)
            s.t = t_end
            scan = self.scan()
        self.resolve(scan, t_end, h, epoch, final=True, rewound=False)
        self.log.flush(t_end)

    # -- detection ----------------------------------------------------------------------------------------------

    def scan(self) -> "Scan":
        """Contacts at the live state; the broad phase uses boxes swept from the saved start of the step.
        When no dynamic body's swept box comes near anything (most steps), nothing more is computed."""
        s = self.sim.state
        if not self.broad.anything_near(s.x, self._rotations, self.saved[0]):
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
        mu, e = self.cp.mix(a, b)
        return Contacts(a, b, np.concatenate([f[0] for f, _ in parts]), np.concatenate([f[1] for f, _ in parts]),
                        np.concatenate([f[2] for f, _ in parts]), pair, mu, e)

    def pair_contacts(self, i, j, x, R, margin):
        """(points, normals, depths, features, a, b) of bodies i and j, normals from b toward a."""
        table = self.cp.table
        test = closed_form(table.kind[i], table.kind[j])
        if test is None:
            return (*self.fcl.contacts(i, j, x, R, margin), i, j)
        function, swapped = test
        a, b = (j, i) if swapped else (i, j)
        return (*function(table, a, b, x, R, margin), a, b)

    def distance(self, i, j, x, R) -> float:
        """Signed distance of bodies i and j (negative: interpenetrating by that much)."""
        depths = self.pair_contacts(i, j, x, R, math.inf)[2]
        return -float(np.max(depths)) if len(depths) else math.inf

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
        return self.distance(pair[0], pair[1], s.x, quat_to_matrix(s.q))

    def _advance(self, tau: float, epoch) -> None:
        """Integrate the live state from its time s.t to s.t + tau with the plan's own step."""
        s = self.sim.state
        if tau > 0:
            self.sim.integrate(tau)
        s.t += tau

    # -- response ---------------------------------------------------------------------------------------------

    def resolve(self, scan, t, h, epoch, final: bool, rewound: bool) -> None:
        """Impulses for the contacts of `scan` at time t (the live state); with final, the position correction
        too (the end of the step). Events: an impact's time is t when rewound, else interpolated."""
        contacts = scan.contacts
        if contacts is not None:
            contacts = contacts.subset(contacts.depth >= -TOUCHING)
        if contacts is None:
            return
        s, plan = self.sim.state, self.plan
        if self._at_rest(contacts):
            return
        bodies = Bodies(s.v, s.w, plan.inv_mass, world_inverse_inertia(scan.R, plan.inv_inertia_body), plan.dynamic)
        response = Response(contacts, s.x, bodies, self._joints(t, epoch))
        response.impacts(self.resting_speed)
        response.resting()
        if final:
            moved = response.correct_positions(s.x, s.q)
            if len(moved) and plan.constraints is not None:
                self._joint_velocities(t, epoch, moved)
        self.log.record(contacts, response.outcome, self._impact_time(scan, contacts, t, rewound))

    def _at_rest(self, contacts) -> bool:
        """Nothing approaching and nothing to push apart: lam = 0 solves every row (touching balls of the
        cradle before the strike), so the solve is skipped."""
        s = self.sim.state
        u = row_velocity(contact_rows(contacts, s.x, contacts.normal), np.stack([contacts.a, contacts.b], 1), s.v, s.w)
        return bool(np.all(u >= -AT_REST_SPEED) and np.all(contacts.depth <= SLOP))

    def _joint_velocities(self, t, epoch, moved) -> None:
        """A position correction turned bodies, and with them their joints' Jacobians: put their velocities
        back on the joints (J V + ct = 0 at the new pose), or the joint drifts by |w| |turn| |arm| per second."""
        joints = self._joints(t, epoch)
        if not len(joints.J):
            return
        s, plan = self.sim.state, self.plan
        bodies = Bodies(s.v, s.w, plan.inv_mass, world_inverse_inertia(quat_to_matrix(s.q), plan.inv_inertia_body),
                        plan.dynamic)
        project_joints(joints, bodies, moved)

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


def _never_moving(plan) -> np.ndarray:
    """(n,) bool: static bodies (neither dynamic nor on a kinematic path) that start at rest: their boxes never
    change. (A static body given a velocity drifts with it: it moves.)"""
    still = ~np.asarray(plan.dynamic, bool)
    if plan.kinematics is not None:
        still[np.asarray(plan.kinematics.index, int)] = False
    still &= ~np.any(plan.v0 != 0, axis=1) & ~np.any(plan.w0 != 0, axis=1)
    return still


def _earlier(best, pair, bracket):
    """Keep the hit whose linear estimate of the time of impact is earliest."""
    t0, t1, d0, d1 = bracket
    estimate = t0 + (t1 - t0) * d0 / (d0 - d1)
    if best is None or estimate < best[2]:
        return pair, bracket, estimate
    return best
