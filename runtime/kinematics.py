"""Kinematic paths stage, the plan's part: bodies whose pose is a function of time (keyframes or an expression of
t), with the exact time derivatives of their paths. To the solver they have infinite mass. The values at the
steps' times are tabulated by core/timetable.py (angular velocity and acceleration from the quaternion path).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isaac_lang import expr as E
from isaac_lang import ir



@dataclass
class KinematicPaths:
    index: np.ndarray  # (k,) body indices
    position: list  # expressions (3,), and their first and second derivatives
    velocity: list
    acceleration: list
    orientation: list  # expressions (4,)
    orientation_rate: list
    orientation_acceleration: list
    overrides: dict  # body index -> (x, q) set live by an embedding program (Simulation.set_pose)


def compile_kinematics(scene: ir.Scene) -> KinematicPaths | None:
    chosen = [(i, b) for i, b in enumerate(scene.bodies) if b.motion == "kinematic"]
    if not chosen:
        return None
    position = [b.position for _, b in chosen]
    velocity = [E.derivative(p) for p in position]
    orientation = [b.orientation for _, b in chosen]
    rate = [E.derivative(q) for q in orientation]
    return KinematicPaths(np.array([i for i, _ in chosen]), position, velocity,
                          [E.derivative(v) for v in velocity], orientation, rate,
                          [E.derivative(r) for r in rate], {})
