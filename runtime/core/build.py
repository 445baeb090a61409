"""From a Plan to what the kernels read: the model, the time table's producers, the scratch, and the Active rows of
each epoch (built on first use, with which rows are held and which still assemble)."""
from __future__ import annotations

import numpy as np

from . import data as D
from . import model as M
from .entries import row_errors
from .structure import build_active, empty_active
from .timetable import TimeTable

# a row that switches on with |C| above this (m or rad), or |dC/dt| above omega times this, assembles along its
# constraint's curve (Baumgarte at its frequency and damping ratio) before it is held; within both it is held
# from the start (the projection closes what is left). A velocity row (gears) is held from the start.
ASSEMBLE_ABOVE = 1e-10


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
        self.model = M.Model(plan.n, M.build_bodies(plan), kinematic, M.build_springs(plan), loads, cons, wind,
                             wind_column, wind_count)
        self.scratch = D.allocate_scratch(plan.n, cons.param, len(cons.row_instance))
        self._actives: dict = {}  # id(epoch) -> (epoch, Active)
        self.row_held = np.zeros(len(cons.row_instance), np.bool_)  # per global row: held when last active
        self.row_seen = np.zeros(len(cons.row_instance), np.bool_)  # per global row: active in an epoch before
        self.empty = empty_active()

    # -- producers ----------------------------------------------------------------------------------------------

    def _kinematic(self, plan) -> M.Kinematic:
        paths = plan.kinematics
        if paths is None:
            return M.Kinematic(np.zeros(0, np.int64), np.zeros(0, np.int64))
        columns = [self.table.add_kinematic(paths, k) for k in range(len(paths.index))]
        return M.Kinematic(np.asarray(paths.index, np.int64).copy(), np.asarray(columns, np.int64))

    def _loads(self, plan) -> M.Loads:
        loads = plan.forces.loads
        if loads is None:
            return M.Loads(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64))
        columns = [self.table.add_load(f, tau) for f, tau in zip(loads.force, loads.torque)]
        return M.Loads(np.asarray(loads.body, np.int64).copy(), np.asarray(loads.point, float).copy(),
                       np.asarray(columns, np.int64))

    def _drivers(self, plan) -> list:
        """(instance, slot, column, size) of every moving nail: its target and two derivatives."""
        c = plan.constraints
        first = np.cumsum([0] + [M.instance_count(f) for f in c.families])
        drivers = []
        for nail in c.moving_nails:
            column = self.table.add_moving_vector(nail.position, nail.velocity, nail.acceleration)
            drivers.append((int(first[nail.family] + nail.instance), M.NAIL_TARGET, column, 9))
        return drivers

    def _wind(self, plan):
        from ..wind.kernels import empty_wind_model, speeds_table, wind_model

        wind = plan.forces.wind
        if wind is None:
            return empty_wind_model(), 0, 0
        count = len(wind.fields.names)
        column = self.table.add(count, lambda times: speeds_table(wind, times))
        return wind_model(wind), column, count

    # -- epochs -----------------------------------------------------------------------------------------------

    def active(self, epoch, y: np.ndarray, t: float):
        """The Active rows of an epoch (None: no constraints), built when the run first enters it: a row that was
        active before keeps its held flag; a new one is held if it is on its manifold (ASSEMBLE_ABOVE)."""
        if epoch is None or not epoch.active.size:
            return self.empty
        entry = self._actives.get(id(epoch))
        if entry is not None and entry[0] is epoch:
            return entry[1]
        cons = self.model.constraints
        rows = np.asarray(epoch.active, np.int64)
        C, rate = self._errors_at(rows, y, t)
        omega = np.sqrt(np.maximum(cons.ks[rows], 1.0))
        on_manifold = (np.abs(C) <= ASSEMBLE_ABOVE) & (np.abs(rate) <= ASSEMBLE_ABOVE * omega)
        fresh = ~self.row_seen[rows]
        held = np.where(fresh, on_manifold | cons.velocity_only[rows], self.row_held[rows]) & cons.settles[rows]
        act = build_active(cons, rows, self.model.bodies.dynamic, held, dense=epoch.solver == "dense")
        if len(act.Li) > len(self.scratch.Lx):
            self.scratch = self.scratch._replace(Lx=np.zeros(len(act.Li)))
        self._actives[id(epoch)] = (epoch, act)
        return act

    def leave(self, act) -> None:
        """Remember which rows of an epoch being left were held (for the epochs after it)."""
        if len(act.rows):
            self.row_seen[act.rows] = True
            self.row_held[act.rows] = act.held

    def _errors_at(self, rows, y, t) -> tuple:
        """(C, dC/dt = J v + ct) of the given rows at state y, time t."""
        cons, s = self.model.constraints, self.scratch
        instances = np.unique(cons.row_instance[rows])
        row_errors(self.model, instances, s, y, self.table.evaluate(t, 0.0, 1))
        bodies = cons.body[cons.row_instance[rows]]  # (m,2), WORLD = -1: the world row, at rest
        motion = y[bodies, 7:13]  # (m,2,6)
        rate = np.einsum("msk,msk->m", s.J[rows], motion) + s.ct[rows]
        return s.C[rows].copy(), rate

    def tabulate(self, t0: float, h: float, steps: int, grid: int) -> np.ndarray:
        """The time table of `steps` steps of h from t0, `grid` rows per step."""
        return self.table.evaluate(t0, h / grid, grid * steps + 1)
