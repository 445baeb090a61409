"""The dynamics plan: Lagrange-multiplier constrained dynamics, integrated by RK4, midpoint or semi-implicit Euler,
with the held constraints projected back onto their manifold after every step (docs/design/physics.md section 2).

    accelerations.py   the right-hand side: forces, then the multiplier solve (core/solve.py)
    projection.py      positions and velocities back on the constraints after a step
    integrate.py       the integrators and the step loop: many steps per call, frames recorded inside

`DynamicsStepper` is the Python side: it tabulates the time functions of a run of steps and calls the loop.
"""
from __future__ import annotations

import numpy as np

from ..core.build import energy_scale
from ..core.jit import Bound
from ..core.rest import REST_STEPS
from .integrate import GRID, INTEGRATORS, run


class DynamicsStepper:
    grid = GRID  # time-table rows per step
    entries = (run,)  # the compiled entry points it calls
    rest_after = REST_STEPS  # steps at rest before the loop stops integrating (core/rest.py; 0: never)

    def __init__(self, compiled, plan):
        self.compiled = compiled
        self.integrator = INTEGRATORS[plan.integrator]
        self.tolerance = plan.scene.solver.tolerance  # RK4's error control (integrate.py; 0: off)
        self.energy_scale = energy_scale(plan)
        self.entering = None  # the Active rows of an epoch just entered, until its first run
        self.last_rows = None  # the Active rows of the last run (its count of steps at rest goes on with them)
        self.end_row = None  # the time table's row at the end of the last run
        self._run = Bound(run)

    def run(self, act, y, t0: float, h: float, steps: int, frame_step, frames, status) -> int:
        """`steps` steps of h from t0 (integrate.run); returns the steps taken."""
        c = self.compiled
        table = c.tabulate(t0, h, steps, GRID)
        entering, self.entering = self.entering is act, None
        carry, self.last_rows = self.last_rows is act, act
        # the inputs at the start are those the last run ended with (the loop then keeps its last slope, as it does
        # from one step to the next: a run steps alike whether a call covers one frame or many)
        same = self.end_row is not None and np.array_equal(table[0], self.end_row)
        taken = self._run(c.model, act, c.scratch, y, table, self.integrator, h, steps, frame_step, frames, status,
                          entering, self.rest_after, carry, same, self.tolerance, self.energy_scale)
        self.end_row = table[GRID * taken].copy()
        return taken

    def enter(self, act, y, t: float) -> None:
        """A new epoch begins at t: its first run starts by putting the held rows on their manifold."""
        self.entering = act
