"""Live stage, the mouse: a body dragged by a spring from the picked point to the pointer, as MuJoCo's perturbation.

While the button is down the page sends the body, the picked point in the body's frame and the pointer's point in
the world (on the plane through the picked point that faces the camera). A dynamic body is pulled by a spring of
rest length 0 from that point to the pointer (Simulation.pull: one more spring in the compiled model, integrated
with the other forces inside the kernels), stiff and damped in proportion to the mass it moves: the body and
every dynamic body joined to it by constraints (a disc of the mobile drags its rod and the levels below),

    k = m w^2,   c = 2 zeta m w,   w = 2 pi DRAG_FREQUENCY,

so that the mass would follow the pointer like a critically damped oscillator of that frequency, whatever it
weighs. A kinematic body is moved by its pose (Simulation.set_pose) so that the picked point is at the pointer.
A static body does not move. Releasing the button removes the spring (or gives the kinematic body back its path).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.rotation import quat_to_matrix

# Hz: how briskly a dragged body follows the pointer, and the damping ratio of that motion (1: critical)
DRAG_FREQUENCY = 2.0
DRAG_DAMPING = 1.0


def moved_mass(scene, plan, body: int) -> float:
    """kg: the dynamic bodies joined to `body` by constraints (through dynamic bodies only), body included."""
    index = {name: i for i, name in enumerate(plan.names)}
    parent = list(range(plan.n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for constraint in scene.constraints:
        for term in constraint.terms:
            joined = [index[b] for b in term.bodies if b in index and plan.dynamic[index[b]]]
            for a, b in zip(joined, joined[1:]):
                parent[root(a)] = root(b)
    group = root(body)
    return float(sum(plan.mass[i] for i in range(plan.n) if plan.dynamic[i] and root(i) == group))


class Drag:
    """The drag in progress (or none), put into each new simulation after a re-plan."""

    def __init__(self):
        self.command = None  # {"body", "point", "target"}
        self.count = 0  # drags begun
        self.kind = None  # dynamic | kinematic | static

    def apply(self, sim, command) -> None:
        """A new state of the mouse: a drag (begun or moved), or None (released)."""
        if command is None:
            self.release(sim)
            return
        if self.command is None or self.command["body"] != command["body"]:
            self.release(sim)
            self.count += 1
        if command["body"] not in sim.plan.names:
            self.command = None
            return
        self.command = command
        self._put(sim)

    def release(self, sim) -> None:
        if self.command is not None and self.command["body"] in sim.plan.names:
            if self.kind == "dynamic":
                sim.release_pull()
            elif self.kind == "kinematic":
                sim.release_pose(self.command["body"])
        self.command, self.kind = None, None

    def follow(self, sim) -> None:
        """A re-plan made a new simulation: the drag goes on in it."""
        if self.command is not None:
            if self.command["body"] in sim.plan.names:
                self._put(sim)
            else:
                self.command, self.kind = None, None

    def _put(self, sim) -> None:
        name, point, target = self.command["body"], self.command["point"], self.command["target"]
        b = sim.body(name)
        paths = sim.plan.kinematics
        if sim.plan.dynamic[b]:
            mass = moved_mass(sim.plan.scene, sim.plan, b)
            w = 2.0 * math.pi * DRAG_FREQUENCY
            sim.pull(name, point, target, mass * w * w, 2.0 * DRAG_DAMPING * mass * w)
            self.kind = "dynamic"
        elif paths is not None and b in paths.index:
            q = np.array(sim.state.q[b], float)
            sim.set_pose(name, np.asarray(target, float) - quat_to_matrix(q) @ np.asarray(point, float), q)
            self.kind = "kinematic"
        else:
            self.kind = "static"

    def overlay(self) -> dict | None:
        """What the page draws of the drag: the body, the picked point (its frame), the pointer (world)."""
        if self.command is None or self.kind == "static":
            return None
        return dict(self.command)
