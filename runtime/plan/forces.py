"""Forces stage, the plan's part: which forces act (gravity, springs and dampers, user loads, the gyroscopic
term, wind) and their constants. The forces themselves are computed by the compiled core (core/forces.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir

from ..core.rotation import quat_to_matrix


@dataclass
class Springs:
    """Springs and dampers between two body points, or a body point and a world point (body_b = -1)."""

    body_a: np.ndarray  # (k,) int
    point_a: np.ndarray  # (k,3) body frame
    body_b: np.ndarray  # (k,) int, -1 for a world point
    point_b: np.ndarray  # (k,3) body frame of b, or world
    stiffness: np.ndarray  # (k,) N/m
    rest: np.ndarray  # (k,) m
    damping: np.ndarray  # (k,) N s/m


@dataclass
class Loads:
    """User forces and torques, functions of time, applied at body points."""

    body: np.ndarray  # (k,) int
    point: np.ndarray  # (k,3) body frame
    force: list  # k expressions (3,)
    torque: list


@dataclass
class ForcePlan:
    weight: np.ndarray | None  # (n,3) m g for dynamic bodies; None when gravity is off or nothing falls
    springs: Springs | None
    loads: Loads | None
    gyroscopic: np.ndarray | None  # indices of dynamic bodies with unequal principal moments
    wind: object = None  # runtime.wind.WindPlan: aerodynamic drag, when the scene has winds and bodies feel them

    def stages(self) -> dict:
        return {"gravity": self.weight is not None, "springs": self.springs is not None,
                "loads": self.loads is not None, "gyroscopic": self.gyroscopic is not None}


def compile_forces(scene: ir.Scene, mass, dynamic, inertia_body, x0, q0) -> ForcePlan:
    gravity = np.asarray(scene.gravity, dtype=float)
    weight = None
    if np.any(gravity != 0) and np.any(dynamic):
        weight = np.where(dynamic[:, None], mass[:, None] * gravity[None, :], 0.0)
    moments = np.einsum("nii->ni", inertia_body)
    uneven = dynamic & (np.ptp(moments, axis=1) > 1e-12 * np.maximum(moments.max(axis=1), 1e-300))
    return ForcePlan(weight, _springs(scene, x0, q0), _loads(scene), np.flatnonzero(uneven) if uneven.any() else None)


def _springs(scene: ir.Scene, x0, q0) -> Springs | None:
    index = scene.body_index()
    chosen = [f for f in scene.forces if f.type in ("spring", "damper")]
    if not chosen:
        return None
    body_a, point_a, body_b, point_b, rest = [], [], [], [], []
    R0 = quat_to_matrix(q0)
    for force in chosen:
        a = index[force.bodies[0]]
        b = index[force.bodies[1]] if len(force.bodies) > 1 else -1
        body_a.append(a)
        point_a.append(force.points[0])
        body_b.append(b)
        point_b.append(force.points[1])
        world_a = x0[a] + R0[a] @ np.asarray(force.points[0])
        world_b = x0[b] + R0[b] @ np.asarray(force.points[1]) if b >= 0 else np.asarray(force.points[1])
        # the rest length defaults to the distance at the start
        rest.append(force.rest_length if force.rest_length is not None else float(np.linalg.norm(world_b - world_a)))
    return Springs(np.array(body_a), np.array(point_a, float), np.array(body_b), np.array(point_b, float),
                   np.array([f.stiffness for f in chosen]), np.array(rest), np.array([f.damping for f in chosen]))


def _loads(scene: ir.Scene) -> Loads | None:
    index = scene.body_index()
    chosen = [f for f in scene.forces if f.type == "load"]
    if not chosen:
        return None
    return Loads(np.array([index[f.bodies[0]] for f in chosen]), np.array([f.points[0] for f in chosen], float),
                 [f.force for f in chosen], [f.torque for f in chosen])
