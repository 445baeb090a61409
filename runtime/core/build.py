"""From a Plan to what the kernels read: the model, the time table's producers, the scratch, and the Active rows of
each epoch (built on first use, with which rows are held and which still assemble)."""
from __future__ import annotations

import numpy as np

from . import data as D
from . import model as M
from .entries import row_errors
from .structure import build_active, empty_active
from .timetable import TimeTable

# a pair in contact is looked at again when it has turned since its contacts were found by as much as brings a
# point of either body margin nearer (margin / reach; the collision stage narrows it to the gap of the pair's
# other features), and at most this much (rad)
PAIR_TURN = 0.05
# a row that switches on with |C| above this (m or rad), or |dC/dt| above omega times this, assembles along its
# constraint's curve (Baumgarte at its frequency and damping ratio) before it is held; within both it is held
# from the start (the projection closes what is left). A velocity row (gears) is held from the start.
ASSEMBLE_ABOVE = 1e-10
# bodies whose masses differ this many times or more: Gauss-Seidel passes the heavy one's weight through the light
# one slowly, so the capturing step solves their island whole (capture/islands.py), and the exact path hands a run
# that starts with one touching the other over to it (collide/collider.py `_heavy_on_light`)
MASS_RATIO = 10.0


class CompiledPlan:
    """model (core.model.Model), table (TimeTable), scratch (core.data.Scratch), and `active(epoch, y, t)`."""

    def __init__(self, plan):
        self.plan = plan
        self.table = TimeTable()
        kinematic = self._kinematic(plan)
        loads = self._loads(plan)
        wind, wind_column, wind_count = self._wind(plan)
        c = plan.constraints
        cons = M.pack_constraints(c, self._drivers(plan)) if c is not None else M.empty_constraints()
        shapes, pairs, margin = self._collisions(plan)
        self.model = M.Model(plan.n, M.build_bodies(plan), kinematic, M.build_springs(plan), loads, cons, wind,
                             wind_column, wind_count, shapes, pairs, margin)
        self.joint_instances, self.joint_rows = len(cons.family), len(cons.row_instance)
        self.scratch = D.allocate_scratch(plan.n, cons.param, len(cons.row_instance))
        self._actives: dict = {}  # id(epoch) -> (epoch, Active)
        self.row_held = np.zeros(len(cons.row_instance), np.bool_)  # per global row: held when last active
        self.row_seen = np.zeros(len(cons.row_instance), np.bool_)  # per global row: active in an epoch before
        self.empty = empty_active()

    # -- producers ----------------------------------------------------------------------------------------------

    def _kinematic(self, plan) -> M.Kinematic:
        paths = plan.kinematics
        if paths is None:
            return M.Kinematic(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.bool_))
        columns = [self.table.add_kinematic(paths, k) for k in range(len(paths.index))]
        # a body with a window starts off its path; Simulation puts it on (set_on_path) when its window begins
        on = ~np.isfinite(paths.windows).any(axis=1)
        return M.Kinematic(np.asarray(paths.index, np.int64).copy(), np.asarray(columns, np.int64), on)

    def set_on_path(self, k: int, on: bool) -> None:
        """Path k's body follows its path (kinematic: no mass for the solve) or leaves it (dynamic, with the
        mass properties of the plan), from now on. The solve's structures are built anew."""
        kin, bodies, plan = self.model.kinematic, self.model.bodies, self.plan
        b = int(kin.body[k])
        kin.on[k] = on
        bodies.dynamic[b] = not on
        bodies.inv_mass[b] = 0.0 if on else 1.0 / plan.mass[b]
        bodies.inv_inertia[b] = 0.0 if on else np.linalg.inv(plan.inertia_body[b])
        bodies.inv_moments[b] = np.diag(bodies.inv_inertia[b])
        self._actives.clear()

    def _loads(self, plan) -> M.Loads:
        loads = plan.forces.loads
        if loads is None:
            return M.Loads(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64))
        columns = [self.table.add_load(f, tau) for f, tau in zip(loads.force, loads.torque)]
        return M.Loads(np.asarray(loads.body, np.int64).copy(), np.asarray(loads.point, float).copy(),
                       np.asarray(columns, np.int64))

    def _drivers(self, plan) -> list:
        """(instance, slot, column, size) of every moving constraint parameter: its value and two derivatives,
        each into its slot (M.MOVING_SLOTS)."""
        c = plan.constraints
        first = np.cumsum([0] + [M.instance_count(f) for f in c.families])
        drivers = []
        for moving in c.moving:
            family = M.FAMILY_OF_LAYOUT[type(c.families[moving.family])]
            slots, size = M.MOVING_SLOTS[family, moving.name]
            column = self.table.add_moving(moving.value, moving.rate, moving.acceleration, size)
            instance = int(first[moving.family] + moving.instance)
            drivers += [(instance, slot, column + size * e, size) for e, slot in enumerate(slots)]
        return drivers

    def _wind(self, plan):
        from ..wind.kernels import empty_wind_model, speeds_table, wind_model, wind_table

        wind = plan.forces.wind
        if wind is None:
            return empty_wind_model(), 0, 0
        m = len(wind.fields.names)
        if not any(wind.fields.moves):  # the speeds alone: the kernels read the points and directions of the model
            return wind_model(wind), self.table.add(m, lambda times: speeds_table(wind, times)), m
        # per wind: its speed, its source point (3) and its direction (3), all of t
        column = self.table.add(7 * m, lambda times: wind_table(wind, times))
        return wind_model(wind), column, 7 * m

    def _collisions(self, plan) -> tuple:
        """(Shapes, Pairs, margin) of the collision stage, padded with the world row; no pairs without one."""
        n, cp = plan.n, plan.collisions
        if cp is None:
            return M.no_shapes(n), M.no_pairs(), 0.0
        table = cp.table
        pad = lambda a: np.concatenate((np.asarray(a, float), np.zeros((1,) + np.shape(a)[1:])))  # noqa: E731
        shapes = M.Shapes(np.concatenate((table.kind, [M.SHAPE_NONE])).astype(np.int64), pad(table.radius),
                          np.ascontiguousarray(np.nan_to_num(pad(table.half), posinf=1e300)), pad(table.half_length),
                          pad(table.normal), pad(table.centre))
        a, b = candidate_pairs(cp, plan.dynamic)
        # a sphere on a sphere or on a plane: the one point of contact rolls with its rows, turning brings nothing
        round_ = np.isin(table.kind[a], (M.SHAPE_SPHERE, M.SHAPE_PLANE)) & np.isin(table.kind[b], (M.SHAPE_SPHERE,
                                                                                                   M.SHAPE_PLANE))
        from ..collide.shapes import reach

        arm = np.maximum(np.maximum(reach(table)[a], reach(table)[b]), 1e-300)
        turn = np.minimum(PAIR_TURN, cp.margin / arm)
        turn = np.where(round_, 10.0, turn)
        relative = np.tile([1.0, 0.0, 0.0, 0.0], (len(a), 1))
        P = len(a)
        return shapes, M.Pairs(a, b, np.zeros(P, np.int64), relative, turn, np.zeros(P), np.zeros(P, np.int64),
                               np.zeros((P, 3)), np.zeros((P, 3)), np.zeros(P)), float(cp.margin)

    def reserve_contacts(self, instances: int, rows: int) -> None:
        """Room for at least `instances` contact instances and `rows` contact rows after the joints'."""
        cons = self.model.constraints
        have_i, have_r = len(cons.family) - self.joint_instances, len(cons.row_instance) - self.joint_rows
        if instances <= have_i and rows <= have_r:
            return
        grow_i, grow_r = max(instances, 2 * have_i, 8) - have_i, max(rows, 2 * have_r, 24) - have_r
        cons = M.with_capacity(cons, grow_i, grow_r)
        self.model = self.model._replace(constraints=cons)
        old = self.scratch
        self.scratch = D.allocate_scratch(self.plan.n, cons.param, len(cons.row_instance), len(old.Lx))
        self.scratch.param[:len(old.param)] = old.param
        for counter in D.CUMULATIVE_COUNTERS:  # (the others describe the old buffers: they start afresh)
            self.scratch.counters[counter] = old.counters[counter]
        self.row_held = np.concatenate((self.row_held, np.zeros(grow_r, np.bool_)))
        self.row_seen = np.concatenate((self.row_seen, np.zeros(grow_r, np.bool_)))
        self._actives.clear()

    # -- epochs -----------------------------------------------------------------------------------------------

    def active(self, epoch, y: np.ndarray, t: float, contacts: np.ndarray | None = None, version: int = 0):
        """The Active rows of an epoch and of the contacts (their global rows, written as of `version`), built
        when the run first enters that combination: a joint row that was active before keeps its held flag; a new
        one is held if it is on its manifold (ASSEMBLE_ABOVE); contact rows are always held."""
        joints = np.asarray(epoch.active, np.int64) if epoch is not None else np.zeros(0, np.int64)
        contacts = np.zeros(0, np.int64) if contacts is None else np.asarray(contacts, np.int64)
        if not joints.size and not contacts.size:
            return self.empty
        key = (id(epoch), version)
        entry = self._actives.get(key)
        if entry is not None and entry[0] is epoch:
            return entry[1]
        cons = self.model.constraints
        held_joints = self._held(joints, y, t) if joints.size else np.zeros(0, np.bool_)
        rows = np.concatenate((joints, contacts))
        held = np.concatenate((held_joints, np.ones(len(contacts), np.bool_)))
        act = build_active(cons, rows, self.model.bodies.dynamic, held,
                           dense=epoch is not None and epoch.solver == "dense")
        if len(act.Li) > len(self.scratch.Lx):
            self.scratch = self.scratch._replace(Lx=np.zeros(len(act.Li)))
        if len(self._actives) > 64:  # (contact sets come and go: keep the cache small)
            self._actives.clear()
        self._actives[key] = (epoch, act)
        return act

    def _held(self, rows, y, t) -> np.ndarray:
        cons = self.model.constraints
        fresh = ~self.row_seen[rows]
        held = self.row_held[rows].copy()
        if fresh.any():  # (only a row not seen before is evaluated: a contact set that changes keeps its joints')
            new = rows[fresh]
            C, rate = self._errors_at(new, y, t)
            omega = np.sqrt(np.maximum(cons.ks[new], 1.0))
            on_manifold = (np.abs(C) <= ASSEMBLE_ABOVE) & (np.abs(rate) <= ASSEMBLE_ABOVE * omega)
            held[fresh] = on_manifold | cons.velocity_only[new]
        return held & cons.settles[rows]

    def leave(self, act) -> None:
        """Remember which joint rows of an epoch being left were held (for the epochs after it)."""
        joints = act.rows < self.joint_rows
        if joints.any():
            self.row_seen[act.rows[joints]] = True
            self.row_held[act.rows[joints]] = act.held[joints]

    def _errors_at(self, rows, y, t) -> tuple:
        """(C, dC/dt = J v + ct) of the given rows at state y, time t."""
        cons, s = self.model.constraints, self.scratch
        instances = np.unique(cons.row_instance[rows])
        row_errors(self.model, instances, s, y, self.table.evaluate(t, 0.0, 1))
        bodies = cons.body[cons.row_instance[rows]]  # (m,2), WORLD = -1: the world row, at rest
        motion = y[bodies, 7:13]  # (m,2,6)
        rate = np.einsum("msk,msk->m", s.J[rows], motion) + s.ct[rows]
        return s.C[rows].copy(), rate

    def tabulate(self, t0, h: float, steps: int, grid: int) -> np.ndarray:
        """The time table of `steps` steps of h, `grid` rows per step. t0: the time of the first step, or the time
        of every step's start and of the last one's end ((steps + 1,): Simulation's `step_times`, the same
        whatever steps a call covers): the rows of step i at t_i + g h / grid, the last row at the end."""
        if np.ndim(t0) == 0:
            return self.table.evaluate(t0, h / grid, grid * steps + 1)
        times = np.empty(grid * steps + 1)
        times[:-1] = (t0[:steps, None] + (h / grid) * np.arange(grid)).ravel()
        times[-1] = t0[steps]
        return self.table.at(times)


def candidate_pairs(cp, dynamic) -> tuple:
    """(a, b) of every pair of collidable bodies with a dynamic one that no `exclude` removes, a < b."""
    from isaac_runtime.collide.pairs import is_excluded, pair_keys

    c = np.asarray(cp.collidable, np.int64)
    i, j = np.triu_indices(len(c), 1)
    a, b = c[i], c[j]
    n = len(dynamic)
    keep = (dynamic[a] | dynamic[b]) & ~is_excluded(pair_keys(np.stack([a, b], 1), n), cp.always_excluded)
    return np.ascontiguousarray(a[keep], np.int64), np.ascontiguousarray(b[keep], np.int64)


def energy_scale(plan) -> float:
    """A yardstick for energy drift: m |g| (size of the scene) summed over dynamic bodies, or the kinetic
    energy at the start, whichever is larger (a scene that starts at rest at zero height has E0 = 0)."""
    with np.errstate(over="ignore", invalid="ignore"):  # (a hostile scene's speeds: an infinite scale)
        return _energy_scale(plan)


def _energy_scale(plan) -> float:
    d = plan.dynamic
    extent = float(np.ptp(plan.x0[d], axis=0).max()) if d.sum() > 1 else 1.0
    g = float(np.linalg.norm(plan.gravity))
    potential = float(np.sum(plan.mass[d]) * g * max(extent, 1e-3))
    kinetic = 0.5 * float(np.sum(plan.mass[d] * np.sum(plan.v0[d] ** 2, axis=1)))
    rotational = 0.5 * float(np.einsum("ni,nij,nj->", plan.w0[d], plan.inertia_body[d], plan.w0[d]))
    return max(potential, kinetic + rotational, 1e-12)
