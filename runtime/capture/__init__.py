"""The capturing contact step (docs/design/physics.md section 5b): impacts, restitution and Coulomb friction of every
contact solved at velocity level in each step, inside the compiled loop, for scenes whose contacts change too often for
the exact path (runtime/collide: each impact located in time, each change of the contact set handed back to Python).

    broad.py    world boxes grown by each body's travel, hashed into a grid, neighbours paired
    narrow.py   closed-form contact points of a pair (boxes.py: box-box)
    compound.py a pair with a compound body: every pair of parts whose boxes meet, with narrow.py's tests
    solve.py    the velocity-level contact problem, projected Gauss-Seidel, warm-started by feature
    position.py the position pass: interpenetration removed on pseudo-velocities (split impulses)
    islands.py  the bodies that touch one another, grouped each step; an island of very unequal masses that the
                sweeps leave unsolved is solved whole (newton.py: its velocities, by Newton's method)
    loop.py     the step: kick, contacts, solve, drift, checks, events, frames
    data.py     the run's contacts, pairs, checks and events
    events.py   the loop's events as blocks of rows, dicts only when read

`choose(plan)` says whether a scene can take this path and whether it starts on it; `CaptureStage` stands where
the collision stage of the exact path stands (docs/collisions.md, "Many contacts").
"""
from __future__ import annotations

import json
import math

import numpy as np

from . import data as D
from .events import RowEvents

# a scene starts on the capturing path when it has at least this many moving bodies that collide (a heap)
CROWD = 24
# a scene with joints takes it when the exact path looked at its contacts LOOKS times within STEPS steps
LOOKS, STEPS = 20, 50
# the arrays of Frames with one entry per frame (core/record.py)
_PER_FRAME = ("y", "energy", "error", "worst", "contact")
# an interpenetration deeper than this is counted as a failure of the step (m)
DEPTH_LIMIT = 1e-3


def eligible(plan) -> str | None:
    """Why the scene cannot take the capturing path, or None when it can: every collidable shape, and every part of
    a compound body, has a compiled closed form against every shape or part it may meet (no meshes), and no pair of
    bodies has more pairs of parts than a contact's key can name (kinds.LOCAL_FEATURES)."""
    from .kinds import LOCAL_FEATURES, closed_form

    cp = plan.collisions
    if cp is None:
        return "no collisions"
    from ..collide.shapes import kinds_of
    elements = cp.table.elements
    if elements is not None:
        # the two bodies of most parts (a body that is its own shape has one element)
        largest = np.sort(np.maximum(elements.count[cp.collidable], 1))[-2:]
        if int(np.prod(largest)) * LOCAL_FEATURES > D.FEATURES:
            return "compound bodies with more pairs of parts than a contact key holds"
    kinds = set().union(*(kinds_of(cp.table, i) for i in cp.collidable))
    moving = set().union(*(kinds_of(cp.table, i) for i in cp.collidable if plan.dynamic[i]))
    for ka in sorted(moving):
        for kb in sorted(kinds):
            if not closed_form(ka, kb):
                return "a pair without a compiled closed form"
    return None


def jointed(plan) -> bool:
    """Whether the scene has joints: then it takes the capturing path only when its contacts change at most steps
    (a cradle's few strikes stay exact), not at its first impact between moving bodies."""
    return plan.constraints is not None and len(plan.constraints.row_bodies) > 0


def crowded(plan) -> bool:
    cp = plan.collisions
    return int(np.count_nonzero(plan.dynamic[cp.collidable])) >= CROWD


class _NoLasting:
    """What the simulation asks of the exact path's lasting contacts: none (contacts live in the loop's data)."""

    version = -1

    @staticmethod
    def active_rows():
        return np.zeros(0, np.int64)


class CaptureStage:
    """The collision stage on the capturing path: the exclusions of each epoch, and the events the loop wrote."""

    lasting = _NoLasting()

    def __init__(self, sim, events: list, why: str):
        from ..collide.events import EventLog
        from ..collide.shapes import PLANE

        plan, cp = sim.plan, sim.plan.collisions
        self.sim, self.cp, self.why = sim, cp, why
        self.log = EventLog(list(plan.names), events, plan.frame_times)
        self._quoted = [json.dumps(name) for name in self.log.names]  # (events.json's)
        n = plan.n
        kind = cp.table.kind
        planes = np.array([i for i in cp.collidable if kind[i] == PLANE], np.int64)
        order = np.array([i for i in cp.collidable if kind[i] != PLANE], np.int64)
        self.sweep = D.sweep(order, planes, n, cp.always_excluded, 8 * len(order) + 64)
        self.contacts = D.contacts(8 * len(order) + 64)
        self.checks = D.checks()
        from .islands import DIRECT_ROWS
        self.islands = D.islands(n, DIRECT_ROWS)
        self.joints = D.joint_rows(len(sim.compiled.model.constraints.row_instance))
        self.events = D.events(8192)
        self.pseudo = np.zeros((n + 1, 13))
        self.kicked = np.zeros((n + 1, 13))  # (a step's velocities after its forces, before its impulses)
        self.struck = np.zeros((n + 1, 13))  # (... after its impacts, before the rest of its solve)
        self.held = np.zeros((n + 1, 13))  # (the state at a step's start, while the loop takes it in parts)
        self.materials = D.Materials(*_materials(cp, n))
        self.parts, self.poses = _compounds(cp, n)
        # (whether an event may name parts: `drain` looks them up only then)
        self.compound = cp.table.elements is not None and bool(np.any(cp.table.elements.count))
        self.switched_at = sim.state.t

    def start(self) -> None:
        pass

    def on_epoch(self, epoch, t: float) -> None:
        """A pair joined by a constraint now (unless a `collide` names it now), or excluded by a windowed
        `exclude`, does not collide (CollisionPlan.excluded_now)."""
        from ..collide.pairs import pair_keys

        n = self.sim.plan.n
        joined = np.zeros(0, np.int64)
        if epoch is not None and epoch.active.size:
            rb = self.sim.plan.constraints.row_bodies[epoch.active]
            both = rb[(rb[:, 0] >= 0) & (rb[:, 1] >= 0) & (rb[:, 0] != rb[:, 1])]
            joined = pair_keys(np.sort(both, axis=1), n)
        keys = self.cp.excluded_now(joined, t)
        self.sweep = self.sweep._replace(excluded=np.ascontiguousarray(np.sort(keys), np.int64))

    def frame_events(self, t: float, table) -> None:
        pass  # (the loop writes the pressing pairs' events at its frames)

    def on_stop(self, code: int, which: int, h: float, epoch) -> None:
        raise AssertionError("the capturing loop never stops for a change of contact")

    def grow(self) -> None:
        """Room for twice what the last step found."""
        ct, sw = self.contacts, self.sweep
        if ct.count[1] > len(ct.a):
            self.contacts = D.grown(ct, 2 * int(ct.count[1]))
        if sw.count[0] > len(sw.pairs):
            self.sweep = sw._replace(pairs=np.zeros((2 * int(sw.count[0]), 2), np.int64))

    def drain(self) -> None:
        """The loop's events into the run's events (impacts and pressing pairs, in the order written), as a block of
        rows (collide/events.py RowEvents: dicts only when read)."""
        ev = self.events
        count = int(ev.count[0])
        rows = ev.rows[:min(count, len(ev.rows))].copy()
        self.log.events.add_rows(RowEvents(rows, self.log.names, self._quoted, self._parts if self.compound else None))
        if count > len(ev.rows):
            self.events = D.events(2 * count)
        ev.count[0] = 0

    def _parts(self, a: int, b: int, feature: int) -> list:
        """[part of a, part of b] (names, None for a body of one shape) that a contact's feature names: a compound
        pair's is folded as local + LOCAL_FEATURES (part_a max(count_b, 1) + part_b) (compound.fold)."""
        from .kinds import LOCAL_FEATURES

        elements = self.cp.table.elements
        if elements is None or not (elements.count[a] or elements.count[b]):
            return [None, None]
        pair, count_b = feature // LOCAL_FEATURES, max(int(elements.count[b]), 1)
        part_a = pair // count_b if elements.count[a] else -1
        part_b = pair % count_b if elements.count[b] else -1
        return [elements.part_name(a, part_a), elements.part_name(b, part_b)]

    def report(self) -> dict:
        """What the run's report says of this path (report.json `contact`)."""
        w, c = self.checks.worst, self.checks.counts
        names = self.sim.plan.names
        return {"path": "capturing", "why": self.why, "since": float(self.switched_at),
                "steps": int(c[3]), "contacts_solved": int(c[2]),
                "deepest": float(w[0]), "deepest_time": float(w[1]),
                "deepest_pair": [names[int(w[2])], names[int(w[3])]] if w[0] > 0 else [],
                "steps_too_deep": int(c[0]), "depth_limit": DEPTH_LIMIT,
                "energy_created": float(w[4]), "energy_created_time": float(w[5]),
                "energy_created_pair": [names[int(w[6])], names[int(w[7])]] if w[4] > 0 else [],
                "steps_creating_energy": int(c[1]), "islands_solved_whole": int(c[4]),
                "solves_taken_again": int(c[5])}


def can_bounce(cp) -> bool:
    """Whether a pair that may touch can have a restitution above 0: a collidable body or part with one, or without
    a material (it may take the default's)."""
    from ..collide import DEFAULT_RESTITUTION

    elements = cp.table.elements
    rows = np.concatenate([elements.of(i) if elements is not None else [i] for i in cp.collidable]).astype(np.int64)
    restitution = np.where(cp.has_material[rows], cp.restitution[rows], DEFAULT_RESTITUTION)
    return bool(np.any(restitution > 0.0))


def _materials(cp, n):
    """friction, restitution, has of the bodies (0..n-1), the world (n), then the parts of the compound bodies
    (element e at e + 1: compound.material_of); the defaults of a pair without materials."""
    from ..collide import DEFAULT_FRICTION, DEFAULT_RESTITUTION

    size = len(cp.friction) + 1
    friction, restitution, has = np.zeros(size), np.zeros(size), np.zeros(size, np.bool_)
    for mine, theirs in ((friction, cp.friction), (restitution, cp.restitution), (has, cp.has_material)):
        mine[:n], mine[n + 1:] = theirs[:n], theirs[n:]
    return friction, restitution, has, np.array([DEFAULT_FRICTION, DEFAULT_RESTITUTION])


def _compounds(cp, n):
    """(Parts, Poses) of capture/compound.py: the compound bodies' parts (collide/compound_compiled.py), or, in a
    scene without any, arrays of the same types in which every body is its own shape."""
    from .compound import Parts, Poses

    if cp.table.elements is not None:
        from ..collide.compound_compiled import compound_arrays

        return compound_arrays(cp.table.elements)
    from ..core.model import Shapes

    f, i = (lambda *shape: np.zeros(shape)), (lambda *shape: np.zeros(shape, np.int64))
    shapes = Shapes(i(n), f(n), f(n, 3), f(n), f(n, 3), f(n, 3))
    turn = np.ascontiguousarray(np.tile(np.eye(3), (n, 1, 1)))
    parts = Parts(shapes, np.arange(n, dtype=np.int64), np.full(n, -1, np.int64), f(n, 3), turn, i(n), i(n),
                  i(7, 7), f(n))
    return parts, Poses(f(n, 3), f(n, 3, 3), f(n, 6), f(1))


class CaptureStepper:
    """The Python side of the capturing loop: calls it, grows its buffers, hands on its events."""

    grid = 1
    rest_after = 0

    def __init__(self, compiled, plan, stage: CaptureStage):
        from ..core.jit import Bound
        from ..core.build import energy_scale
        from ..collide.collider import RESTING_SPEED, RESTING_STEPS
        from .loop import BOUNCE_SPEED, run  # (the compiled loop: imported by the runs that take this path only)

        self.compiled, self.stage = compiled, stage
        g = float(np.linalg.norm(plan.gravity)) if getattr(plan, "gravity", None) is not None else 9.81
        exact = max(RESTING_SPEED, RESTING_STEPS * g * plan.step)  # (the exact path's resting speed)
        self.resting = max(exact, BOUNCE_SPEED)
        # where no pair can bounce (every restitution 0: the clock), a contact that lands faster than the exact
        # path's resting speed is an impact event, its impulse the solve's (loop._touchdowns: a tick lands at 7 cm/s)
        self.touch = math.inf if can_bounce(plan.collisions) else exact
        self.energy_tol = 1e-6 * max(energy_scale(plan), 1e-12)
        # the procedural plan's substeps are the capturing loop's steps (a position-level plan steps coarsely)
        self.substeps = int(plan.scene.solver.substeps) if plan.solver == "procedural" else 1
        self._run = Bound(run)
        self.entries = (run,)  # the compiled entry points it calls

    def run(self, act, y, t0: float, h: float, steps: int, frame_step, frames, status) -> int:
        """`steps` steps of h (loop.run), each in `substeps` steps of the loop (the procedural plan's substeps);
        buffers grown and events handed on between calls of the loop until every step is taken or a body ran
        away. Returns the steps taken."""
        from .loop import DRAIN, GROW

        c, st, k = self.compiled, self.stage, self.substeps
        hs, total = h / k, steps * k
        table = c.tabulate(t0, h, steps, self.grid * k)  # (the rows of each step's substeps, from its start)
        frame_at = np.asarray(frame_step, np.int64) * k
        done, first = 0, 0  # loop steps taken, frames recorded
        while True:
            later = frame_at[first:] - done
            part = frames._replace(**{name: getattr(frames, name)[first:] for name in _PER_FRAME})
            taken = self._run(c.model, act, c.scratch, st.contacts, st.sweep, st.joints, st.checks, st.events, st.pseudo,
                              st.kicked, st.struck, st.held, st.materials, y, table[done * self.grid:], hs, total - done,
                              self.grid, later, part, status, self.resting, DEPTH_LIMIT, self.energy_tol, st.parts,
                              st.poses, self.touch, st.islands)
            st.drain()
            first += int(np.count_nonzero(later <= taken))
            done += taken
            if status[0] == GROW:
                st.grow()
            if status[0] not in (GROW, DRAIN) or done >= total:
                break
        if status[0] in (GROW, DRAIN):
            status[0] = 0
        status[1] = -(-int(status[1]) // k) if status[0] else status[1]
        return done // k

    def enter(self, act, y, t: float) -> None:
        pass
