"""The time table: every input of the kernels that is a function of time alone, tabulated once per run of steps.

Kinematic paths (pose, velocity, acceleration), moving constraint parameters (a nail's P(t) and its two
derivatives), user loads and the winds' speeds depend on t and not on the state. Before a kernel advances N steps
of h, the table is evaluated at the grid t0 + i h / D, i = 0 .. N D, with D grid points per step (2 for the
dynamics plan: RK4's stages at t, t + h/2 and t + h; the substeps for the procedural plan), each expression for
all times at once by the expression interpreter (isaac_ir/expr.py, vectorized over t). The kernels read row
i of the table: exact values at the stage times, with no Python in the loop. Column TIME holds the time itself.

Angular velocity of an orientation path q(t), in the world frame (runtime/plan/kinematics.py):
    w = 2 vec(dq/dt q*)         dw/dt = 2 vec(d2q/dt2 q* + dq/dt dq*/dt)
"""
from __future__ import annotations

import numpy as np

from isaac_ir import expr as E

from . import model as M

TIME = 0  # the column of the times themselves
# the largest table one call fills (rows x columns): longer runs of steps are cut into calls of this size
MAX_CELLS = 1 << 20


def tabulate(node, times: np.ndarray, width: int, functions=None) -> np.ndarray:
    """(G, width) values of an expression at the times (G,) (a constant is broadcast)."""
    value = np.asarray(E.evaluate(node, {"t": times}, functions), dtype=float)
    shape = (len(times),) if width == 1 else (len(times), width)
    return np.broadcast_to(value, shape).reshape(len(times), width)


def _quat_product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, pv, qw, qv = p[:, :1], p[:, 1:], q[:, :1], q[:, 1:]
    return np.concatenate((pw * qw - np.sum(pv * qv, axis=1, keepdims=True),
                           pw * qv + qw * pv + np.cross(pv, qv)), axis=1)


def _conjugate(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


class TimeTable:
    """The producers of the table's columns: each adds `width` columns from a function of the times."""

    def __init__(self):
        self.producers: list = []  # (column, width, produce(times) -> (G, width))
        self.width = 1  # column TIME
        # body index -> (x, q): a kinematic body held where an embedding program put it (Simulation.set_pose), the
        # run's input: the plan's paths are never written
        self.poses: dict = {}

    def add(self, width: int, produce) -> int:
        column = self.width
        self.producers.append((column, width, produce))
        self.width += width
        return column

    def steps_per_call(self, grid: int) -> int:
        """How many steps one call may cover so that its table stays within MAX_CELLS."""
        return max(1, MAX_CELLS // max(self.width * grid, 1))

    def evaluate(self, t0: float, spacing: float, rows: int) -> np.ndarray:
        """(rows, width) at the times t0 + i spacing."""
        return self.at(t0 + spacing * np.arange(rows))

    def at(self, times: np.ndarray) -> np.ndarray:
        """(rows, width) at the given times (rows,)."""
        table = np.zeros((len(times), self.width))
        table[:, TIME] = times
        for column, width, produce in self.producers:
            table[:, column:column + width] = produce(times)
        return table

    # -- the producers of the plan's stages -----------------------------------------------------------------

    def add_kinematic(self, paths, k: int) -> int:
        """KIN_WIDTH columns for kinematic body k of the plan's paths (or the pose a program holds it at)."""
        body = int(paths.index[k])

        def produce(times):
            out = np.zeros((len(times), M.KIN_WIDTH))
            if body in self.poses:  # held where a program put it (Simulation.set_pose)
                x, q = self.poses[body]
                out[:, M.KIN_X:M.KIN_X + 3], out[:, M.KIN_Q:M.KIN_Q + 4] = x, q
                return out
            out[:, M.KIN_X:M.KIN_X + 3] = tabulate(paths.position[k], times, 3)
            out[:, M.KIN_V:M.KIN_V + 3] = tabulate(paths.velocity[k], times, 3)
            out[:, M.KIN_A:M.KIN_A + 3] = tabulate(paths.acceleration[k], times, 3)
            q = tabulate(paths.orientation[k], times, 4)
            norm = np.linalg.norm(q, axis=1, keepdims=True)
            q = q / norm
            dq = tabulate(paths.orientation_rate[k], times, 4) / norm
            ddq = tabulate(paths.orientation_acceleration[k], times, 4) / norm
            out[:, M.KIN_Q:M.KIN_Q + 4] = q
            # w = 2 vec(dq q*),  dw/dt = 2 vec(ddq q* + dq dq*)
            out[:, M.KIN_W:M.KIN_W + 3] = 2.0 * _quat_product(dq, _conjugate(q))[:, 1:]
            out[:, M.KIN_ALPHA:M.KIN_ALPHA + 3] = 2.0 * (_quat_product(ddq, _conjugate(q))
                                                         + _quat_product(dq, _conjugate(dq)))[:, 1:]
            return out

        return self.add(M.KIN_WIDTH, produce)

    def add_moving(self, value, rate, accel, size: int) -> int:
        """3 size columns: a parameter of time (a world vector, size 3, or a number, size 1), its first and
        second derivatives."""
        def produce(times):
            return np.concatenate((tabulate(value, times, size), tabulate(rate, times, size),
                                   tabulate(accel, times, size)), axis=1)

        return self.add(3 * size, produce)

    def add_load(self, force, torque) -> int:
        """6 columns: a load's force and torque of time."""
        def produce(times):
            return np.concatenate((tabulate(force, times, 3), tabulate(torque, times, 3)), axis=1)

        return self.add(6, produce)
