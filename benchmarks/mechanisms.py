"""The known-answer scenes as engine-neutral mechanisms, for building the same physics in MuJoCo and PyBullet.

Masses, inertias and initial positions come from our own compiled plan (cases.physics), so the peers simulate
exactly the bodies we do. Every body of these scenes starts with identity orientation, so body frames start
aligned with the world and a joint is an anchor point and an axis given in world coordinates at t = 0.

Two formulations, where the scene allows them:
- reduced: a kinematic tree of joints (generalized coordinates; MuJoCo bodies nested in bodies, a PyBullet
  Featherstone multibody); gear couplings between joint coordinates;
- maximal: every body free (6 DOF) and the joints as constraints (MuJoCo `connect` equalities, PyBullet's
  maximal-coordinate multibody). A hinge is two ball constraints on its axis (redundant rows, as a windmill's).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .cases import Case, Physics, physics

# a hinge in maximal coordinates: a second ball constraint this far along the axis from the first
HINGE_SPAN = 0.1  # m


@dataclass(frozen=True)
class Joint:
    kind: str  # ball | hinge | slide
    body: str
    parent: str | None  # None: the world
    anchor: tuple  # world point at t = 0 (for slide: unused)
    axis: tuple = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Coupling:
    """Joint coordinates tied linearly, q_a = ratio * q_b (gears; reduced coordinates only)."""

    a: str  # body whose joint is driven
    b: str
    ratio: float


@dataclass(frozen=True)
class Tie:
    """A ball constraint between two body points (body frames), maximal coordinates only, possibly switching on
    at `start` and pulling the points together with stabilization (ks 1/s2, kd 1/s) rather than a stiff spring."""

    a: str
    point_a: tuple
    b: str
    point_b: tuple
    start: float = 0.0
    gains: tuple | None = None


@dataclass
class Mechanism:
    case: Case
    physics: Physics
    gravity: tuple
    joints: list = field(default_factory=list)
    couplings: list = field(default_factory=list)
    ties: list = field(default_factory=list)
    reduced: bool = True
    maximal: bool = True

    def index(self, name: str) -> int:
        return self.physics.names.index(name)

    def x0(self, name: str) -> np.ndarray:
        return self.physics.x0[self.index(name)]

    def parent_of(self) -> dict:
        return {j.body: j.parent for j in self.joints}

    def order(self) -> list:
        """Jointed bodies, parents before children."""
        parent, done, out = self.parent_of(), set(), []
        while len(out) < len(parent):
            for body, p in parent.items():
                if body not in done and (p is None or p in done):
                    done.add(body)
                    out.append(body)
        return out

    def maximal_ties(self) -> list:
        """The joints as ball constraints between body points (a hinge: two on its axis), plus the ties."""
        out = []
        for j in self.joints:
            if j.kind == "slide":
                raise ValueError("a slide joint has no maximal-coordinate form here")
            anchors = [np.asarray(j.anchor, float)]
            if j.kind == "hinge":
                anchors.append(anchors[0] + HINGE_SPAN * np.asarray(j.axis, float))
            for a in anchors:
                point_b = tuple(a - self.x0(j.parent)) if j.parent else tuple(a)
                out.append(Tie(j.body, tuple(a - self.x0(j.body)), j.parent, point_b))
        return out + list(self.ties)


def mechanism(case: Case) -> Mechanism:
    ph = physics(case)
    scene = case.load()
    m = Mechanism(case, ph, tuple(scene.gravity))
    if case.scene == "pendulum":
        m.joints.append(Joint("ball", "bob", None, (0.0, 1.0, 0.0)))
    elif case.scene == "windmill":
        m.joints.append(Joint("hinge", "blade", None, (0.0, 0.0, 0.0)))
    elif case.scene == "chain":
        m.joints += chain_joints(len(ph.names))
    elif case.scene == "gears":
        m.joints += [Joint("hinge", "drive", None, (0.0, 0.0, 0.0)), Joint("hinge", "wheel", None, (0.4, 0.0, 0.0)),
                     Joint("slide", "weight", None, (-0.1, -0.5, 0.0), (0.0, 1.0, 0.0))]
        # 0.1 w_drive + 0.3 w_wheel = 0;  the rope: v_weight = w_drive x (-0.1, 0, 0) = (0, -0.1 w_drive, 0)
        m.couplings += [Coupling("wheel", "drive", -0.1 / 0.3), Coupling("weight", "drive", -0.1)]
        m.maximal = False  # neither peer has a velocity (gear) constraint between free bodies
    elif case.scene == "selfassembly":
        omega = 2 * np.pi * 2.0  # stabilize 2 Hz, damping 1
        m.ties.append(Tie("a", (0.05, 0.0, 0.0), "b", (-0.05, 0.0, 0.0), 1.0, (omega**2, 2 * omega)))
        m.reduced = False  # the joint switches on with its points apart: no joint coordinate can say that
    else:
        raise ValueError(f"no mechanism for {case.scene}")
    return m


def chain_joints(links: int, length: float = 0.2) -> list:
    joints = [Joint("ball", "link0", None, (0.0, 0.0, 0.0))]
    for i in range(1, links):
        joints.append(Joint("ball", f"link{i}", f"link{i - 1}", (length * i, 0.0, 0.0)))
    return joints


def chain_mechanism(links: int) -> Mechanism:
    """The chain scene with N links, for the scaling runs (physics from our plan of the same text)."""
    case = Case(f"chain{links}", "chain", 1.0, ("energy_drift", "joint_drift"), (("links", str(links)),))
    m = Mechanism(case, physics(case), (0.0, -9.81, 0.0))
    m.joints += chain_joints(links)
    return m
