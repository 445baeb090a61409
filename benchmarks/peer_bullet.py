"""PyBullet models of the mechanisms, built in code, and a runner that yields our trajectory dict.

Settings that would spoil the comparison, set explicitly (PyBullet 3.2 defaults in brackets):
- multibody links are damped [linear and angular damping 0.04] and joint speeds capped [maxJointVelocity 100
  rad/s]: set to 0 and 1e9; bodies may fall asleep when slow [on]: sleeping disabled;
- inertia comes from the collision shape's bounding box [a sphere of radius r gets m (2r)^2 / 6, not 2/5 m r^2]:
  every body gets a box with exactly our principal moments (a box's bounding-box inertia is exact), and the
  result is checked against our plan; shapes never collide (collision group and mask 0; our scenes here have no
  contacts either). changeDynamics(localInertiaDiagonal) is not used: on a maximal-coordinate body it makes
  the state NaN (PyBullet 3.2.7);
- joints of a multibody carry a default velocity motor: switched off (force 0);
- point-to-point constraints limit their force [500 N]: raised to 1e9 N;
- one step per stepSimulation (numSubSteps 0), the solver's 50 iterations written out. PyBullet integrates
  with semi-implicit Euler only, so it is compared with our `euler` at equal step.
Formulations: reduced = one Featherstone multibody (fixed base, links joined by spherical, revolute or
prismatic joints; gears as JOINT_GEAR constraints between joint speeds); maximal = one floating-base body per
body, joined by point-to-point constraints (a hinge: two on its axis), solved by the constraint solver.
"""
from __future__ import annotations

import numpy as np

from .mechanisms import Mechanism

SOLVER_ITERATIONS = 50
BIG_FORCE = 1e9
_client = None


def available() -> bool:
    try:
        import pybullet  # noqa: F401
    except ImportError:
        return False
    return True


def _connect():
    global _client
    import pybullet as p

    if _client is None:
        _client = p.connect(p.DIRECT)
    return p


def box_with_inertia(mass: float, inertia: np.ndarray) -> list:
    """Half extents of the solid box with these principal moments: I_xx = m (b^2 + c^2) / 12, ..."""
    i = np.diag(inertia)
    full_sq = 6.0 / mass * np.array([i[1] + i[2] - i[0], i[0] + i[2] - i[1], i[0] + i[1] - i[2]])
    return list(0.5 * np.sqrt(np.maximum(full_sq, 1e-18)))


def _shape(p, m: Mechanism, name: str) -> int:
    i = m.index(name)
    return p.createCollisionShape(p.GEOM_BOX, halfExtents=box_with_inertia(m.physics.mass[i], m.physics.inertia[i]))


def _free_dynamics(p, body: int, link: int) -> None:
    p.changeDynamics(body, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0, maxJointVelocity=1e9,
                     activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING)
    p.setCollisionFilterGroupMask(body, link, 0, 0)


JOINT_TYPES = {"ball": "JOINT_SPHERICAL", "hinge": "JOINT_REVOLUTE", "slide": "JOINT_PRISMATIC"}


def _build_reduced(p, m: Mechanism) -> tuple:
    order = m.order()
    link_of = {name: k for k, name in enumerate(order)}
    parents = m.parent_of()
    joints = {j.body: j for j in m.joints}
    frames = {}  # link frame origin (the joint) in world, at t = 0
    positions, inertial, parent_index, types, axes = [], [], [], [], []
    for name in order:
        j = joints[name]
        origin = np.asarray(j.anchor, float) if j.kind != "slide" else m.x0(name)
        frames[name] = origin
        parent = parents[name]
        positions.append(list(origin - (frames[parent] if parent else np.zeros(3))))
        inertial.append(list(m.x0(name) - origin))
        parent_index.append(link_of[parent] + 1 if parent else 0)
        types.append(getattr(p, JOINT_TYPES[j.kind]))
        axes.append(list(j.axis))
    n = len(order)
    body = p.createMultiBody(
        baseMass=0, baseCollisionShapeIndex=-1, basePosition=[0, 0, 0], linkMasses=[float(m.physics.mass[m.index(b)])
                                                                                    for b in order],
        linkCollisionShapeIndices=[_shape(p, m, b) for b in order], linkVisualShapeIndices=[-1] * n,
        linkPositions=positions, linkOrientations=[[0, 0, 0, 1]] * n, linkInertialFramePositions=inertial,
        linkInertialFrameOrientations=[[0, 0, 0, 1]] * n, linkParentIndices=parent_index, linkJointTypes=types,
        linkJointAxis=axes)
    _free_dynamics(p, body, -1)
    for k, name in enumerate(order):
        _free_dynamics(p, body, k)
        if joints[name].kind == "ball":
            p.setJointMotorControlMultiDof(body, k, p.POSITION_CONTROL, targetPosition=[0, 0, 0, 1],
                                           targetVelocity=[0, 0, 0], positionGain=0, velocityGain=0, force=[0, 0, 0])
        else:
            p.setJointMotorControl2(body, k, p.VELOCITY_CONTROL, targetVelocity=0, force=0)
    for c in m.couplings:  # q_a = ratio q_b; btMultiBodyGearConstraint's row: qdot_A + gearRatio qdot_B = 0
        cid = p.createConstraint(body, link_of[c.a], body, link_of[c.b], p.JOINT_GEAR, [0, 0, 1], [0, 0, 0], [0, 0, 0])
        p.changeConstraint(cid, gearRatio=-c.ratio, maxForce=BIG_FORCE)
    return [(body, link_of[name]) if name in link_of else None for name in m.physics.names]


def _build_maximal(p, m: Mechanism) -> tuple:
    handles = {}
    for name in m.physics.names:
        i = m.index(name)
        if not m.physics.dynamic[i]:
            continue
        body = p.createMultiBody(baseMass=float(m.physics.mass[i]), baseCollisionShapeIndex=_shape(p, m, name),
                                 basePosition=list(m.x0(name)))
        _free_dynamics(p, body, -1)
        handles[name] = body
    for tie in m.maximal_ties():
        if tie.start > 0:
            raise ValueError("PyBullet's constraints have no stabilization curve to switch on")
        child = handles[tie.b] if tie.b else -1
        cid = p.createConstraint(handles[tie.a], -1, child, -1, p.JOINT_POINT2POINT, [0, 0, 0], list(tie.point_a),
                                 list(tie.point_b))
        p.changeConstraint(cid, maxForce=BIG_FORCE)
    return [(handles[name], -1) if name in handles else None for name in m.physics.names]


class Runner:
    def __init__(self, m: Mechanism, formulation: str, integrator: str, h: float):
        if integrator != "euler":
            raise ValueError("PyBullet integrates with semi-implicit Euler only")
        p = self.p = _connect()
        p.resetSimulation()
        p.setGravity(*m.gravity)
        p.setPhysicsEngineParameter(fixedTimeStep=h, numSubSteps=0, numSolverIterations=SOLVER_ITERATIONS)
        self.handles = _build_reduced(p, m) if formulation == "reduced" else _build_maximal(p, m)
        self.h, self.t, self.x0 = h, 0.0, m.physics.x0
        self._check_inertia(m)

    def _check_inertia(self, m: Mechanism) -> None:
        for name, handle in zip(m.physics.names, self.handles):
            if handle is None:
                continue
            got = np.array(self.p.getDynamicsInfo(*handle)[2])
            want = np.diag(m.physics.inertia[m.index(name)])
            if not np.allclose(got, want, rtol=1e-9, atol=0):
                raise AssertionError(f"PyBullet inertia of {name}: {got} instead of {want}")

    def advance(self, steps: int, probe=None, every: int = 1) -> None:
        step = self.p.stepSimulation
        for k in range(1, steps + 1):
            step()
            self.t += self.h
            if probe is not None and k % every == 0:
                probe.record(*self.sample())

    def sample(self):
        p, n = self.p, len(self.handles)
        x, q, v, w = self.x0.copy(), np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))
        for i, handle in enumerate(self.handles):
            if handle is None:
                continue
            body, link = handle
            if link < 0:
                pos, orn = p.getBasePositionAndOrientation(body)
                lin, ang = p.getBaseVelocity(body)
            else:
                state = p.getLinkState(body, link, computeLinkVelocity=1)
                pos, orn, lin, ang = state[0], state[1], state[6], state[7]
            x[i], q[i], v[i], w[i] = pos, (orn[3], orn[0], orn[1], orn[2]), lin, ang
        return self.t, x, q, v, w

    def finite(self) -> bool:
        _, x, _, v, _ = self.sample()
        return bool(np.all(np.isfinite(x)) and np.all(np.isfinite(v)))


def per_step_floor() -> float:
    """Seconds of one stepSimulation of an empty world: the fixed cost under every PyBullet figure."""
    import time

    p = _connect()
    p.resetSimulation()
    begin = time.perf_counter()
    for _ in range(1000):
        p.stepSimulation()
    return (time.perf_counter() - begin) / 1000
