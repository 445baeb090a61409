"""The procedural plan (docs/design/physics.md section 6): the dissertation's position-level method in the form
position-based dynamics has today (XPBD with substeps, Mueller et al. 2020), compiled.

    substep.py   one substep's three stages: move (with the free rigid body's exact invariants), put back
    project.py   the constraint stage: all rows at once (direct, the default) or Gauss-Seidel over instances
    loop.py      forces once per step, the substeps, frames and blow-ups

`ProceduralStepper` is the Python side: per epoch it orders the instances for the sweep and records where each
assembling row starts its self-assembly curve; per run of steps it tabulates the time functions.
"""
from __future__ import annotations

import numpy as np

from ..core.entries import measure, row_errors
from ..core.jit import Bound
from ..core.model import GEAR, ROPE
from ..core.rest import REST_STEPS
from .loop import run
from .project import Curves, Sweep


class ProceduralStepper:
    entries = (run, measure)  # the compiled entry points it calls
    rest_after = REST_STEPS  # steps at rest before the loop stops integrating (core/rest.py; 0: never)

    def __init__(self, compiled, plan):
        options = plan.scene.solver
        self.compiled = compiled
        self.grid = int(options.substeps)  # time-table rows per step: one per substep
        self.iterations = int(options.iterations)
        self.projection = getattr(options, "projection", "auto")
        self._epochs: dict = {}  # id(Active) -> (Active, Sweep, Curves)
        self.last_rows = None  # the Active rows of the last run (its count of steps at rest goes on with them)
        self._run = Bound(run)

    def run(self, act, y, t0: float, h: float, steps: int, frame_step, frames, status) -> int:
        c = self.compiled
        table = c.tabulate(t0, h, steps, self.grid)
        _, sw, curves = self._epoch(act)
        carry, self.last_rows = self.last_rows is act, act
        # `projection auto` is all rows at once, whatever their number (docs/procedural.md): sweeps blow up on
        # binary trees of 63 bodies and more, and leave chains' joints open by tenths of a mm at twice the time
        all_at_once = self.projection != "gauss_seidel"
        return self._run(c.model, act, sw, curves, c.scratch, y, table, h, steps, self.grid, self.iterations,
                         all_at_once, frame_step, frames, status, self.rest_after, carry)

    def enter(self, act, y, t: float) -> None:
        """A new epoch at t: the sweep order of its instances, and the curves of its rows still assembling
        (C0, D0 = J v + ct now)."""
        m = len(act.rows)
        curves = Curves(np.full(m, t), np.zeros(m), np.zeros(m))
        if m:
            c = self.compiled
            row_errors(c.model, act.instances, c.scratch, y, c.table.evaluate(t, 0.0, 1))
            cons, s = c.model.constraints, c.scratch
            for i, r in enumerate(act.rows.tolist()):
                if act.held[i]:
                    continue
                k = cons.row_instance[r]
                rate = s.ct[r]
                for slot in range(2):
                    b = cons.body[k, slot]
                    if b >= 0:
                        rate += float(s.J[r, slot].dot(y[b, 7:13]))
                curves.C0[i], curves.D0[i] = (0.0 if cons.velocity_only[r] else s.C[r]), rate
        self._epochs[id(act)] = (act, self._sweep(act), curves)

    def _epoch(self, act):
        entry = self._epochs.get(id(act))
        if entry is None or entry[0] is not act:
            raise RuntimeError("procedural stepper: run() before enter() for this epoch")
        return entry

    def _sweep(self, act) -> Sweep:
        """The instances' row ranges in act.rows, ordered for Gauss-Seidel: by instance, then the ropes, then the
        gears (the instances swept last end a substep exact: the gear ratio is the one the eye checks)."""
        cons = self.compiled.model.constraints
        rows = act.rows
        if not len(rows):
            return Sweep(np.zeros(0, np.int64), np.zeros(0, np.int64))
        instance = cons.row_instance[rows]
        starts = np.flatnonzero(np.r_[True, instance[1:] != instance[:-1]])
        ends = np.r_[starts[1:], len(rows)]
        family = cons.family[instance[starts]]
        order = np.lexsort((instance[starts], np.where(family == GEAR, 2, np.where(family == ROPE, 1, 0))))
        return Sweep(np.ascontiguousarray(starts[order], np.int64), np.ascontiguousarray(ends[order], np.int64))
