"""Kinematic paths stage: bodies whose pose is a function of time (keyframes or an expression of t).

Their position, velocity and acceleration come from the path and its exact time derivatives; to the solver
they have infinite mass. Angular velocity from a quaternion path q(t), in the world frame:

    w = 2 vec(dq/dt q*)            dw/dt = 2 vec(d2q/dt2 q* + dq/dt dq*/dt)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isaac_lang import expr as E
from isaac_lang import ir

from .rotation import quat_conjugate, quat_multiply


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


def evaluate_paths(paths: KinematicPaths, t: float, x, q, v, w, a=None, alpha=None) -> None:
    """Write the pose and velocity (and, if given, accelerations) of every kinematic body at time t."""
    env = {"t": t}
    for k, body in enumerate(paths.index):
        if body in paths.overrides:
            x[body], q[body] = paths.overrides[body]
            v[body] = w[body] = 0.0
            if a is not None:
                a[body] = alpha[body] = 0.0
            continue
        x[body] = E.evaluate(paths.position[k], env)
        v[body] = E.evaluate(paths.velocity[k], env)
        quat = np.asarray(E.evaluate(paths.orientation[k], env), dtype=float)
        norm = np.linalg.norm(quat)
        quat = quat / norm
        dq = np.asarray(E.evaluate(paths.orientation_rate[k], env), dtype=float) / norm
        q[body] = quat
        w[body] = 2.0 * quat_multiply(dq, quat_conjugate(quat))[1:]
        if a is not None:
            a[body] = E.evaluate(paths.acceleration[k], env)
            ddq = np.asarray(E.evaluate(paths.orientation_acceleration[k], env), dtype=float) / norm
            alpha[body] = 2.0 * (quat_multiply(ddq, quat_conjugate(quat)) + quat_multiply(dq, quat_conjugate(dq)))[1:]
