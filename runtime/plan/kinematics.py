"""Kinematic paths stage, the plan's part: bodies whose pose is a function of time (keyframes or an expression of
t), with the exact time derivatives of their paths. To the solver they have infinite mass. The values at the
steps' times are tabulated by core/timetable.py (angular velocity and acceleration from the quaternion path).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isaac_ir import expr as E
from isaac_ir.derivative import derivative
from isaac_ir import ir



@dataclass
class KinematicPaths:
    index: np.ndarray  # (k,) body indices
    position: list  # expressions (3,), and their first and second derivatives
    velocity: list
    acceleration: list
    orientation: list  # expressions (4,)
    orientation_rate: list
    orientation_acceleration: list
    windows: np.ndarray = None  # (k, 2) s: when each is on its path (-inf, inf: throughout; else dynamic outside)


def compile_kinematics(scene: ir.Scene) -> KinematicPaths | None:
    chosen = [(i, b) for i, b in enumerate(scene.bodies)
              if b.motion == "kinematic" or getattr(b, "path_window", None) is not None]
    if not chosen:
        return None
    windows = np.array([b.path_window if getattr(b, "path_window", None) is not None else (-np.inf, np.inf)
                        for _, b in chosen], float).reshape(-1, 2)
    position = [b.position for _, b in chosen]
    velocity = [derivative(p) for p in position]
    orientation = [b.orientation for _, b in chosen]
    rate = [derivative(q) for q in orientation]
    acceleration, turning = [derivative(v) for v in velocity], [derivative(r) for r in rate]
    bodies = [b for _, b in chosen]
    return KinematicPaths(np.array([i for i, _ in chosen]), _guarded(position, bodies, "position"),
                          _guarded(velocity, bodies, "velocity"), _guarded(acceleration, bodies, "acceleration"),
                          _guarded(orientation, bodies, "orientation"),
                          _guarded(rate, bodies, "rate of turning"), _guarded(turning, bodies, "angular acceleration"),
                          windows)


def _guarded(paths: list, bodies: list, what: str) -> list:
    """Each path expression as evaluated at every step: a value that is not finite there (a division by zero at
    some t, an overflow) stops the run with the time, the expression and the body's declaration
    (isaac_ir.expr.Guard), rather than a silent NaN in the state. Constants need no guard."""
    return [path if isinstance(path, E.Const) else E.Guard(path, f"the {what} of body `{body.name}` on its path",
                                                           body.source)
            for path, body in zip(paths, bodies)]


def window_switches(paths: KinematicPaths | None) -> list:
    """The times a body goes onto its path or leaves it."""
    if paths is None:
        return []
    return sorted({float(v) for v in paths.windows.ravel() if np.isfinite(v)})


def on_path(paths: KinematicPaths, t: float) -> np.ndarray:
    """(k,) bool: which of the paths' bodies are on their path at time t (windows are [start, end))."""
    return (paths.windows[:, 0] <= t) & (t < paths.windows[:, 1])


def never_moving(plan) -> np.ndarray:
    """(n,) bool: bodies that stay where they start: static, not on a kinematic path, at rest (a static body given
    a velocity drifts with it). The collision stage keeps their boxes; the audio stage's wind probes skip them."""
    still = ~np.asarray(plan.dynamic, bool)
    if plan.kinematics is not None:
        still[np.asarray(plan.kinematics.index, int)] = False
    return still & ~np.any(plan.v0 != 0, axis=1) & ~np.any(plan.w0 != 0, axis=1)
