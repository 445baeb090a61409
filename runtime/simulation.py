"""Stage 5, the step loop, and the embedding API: a Simulation steps a plan and exposes its state.

    sim = Simulation.from_file("scenes/pendulum.isaac", overrides={"theta0": "30 deg"})
    sim.advance_to(2.0)
    sim.state.x[sim.body("bob")]

A step never crosses a constraint's switch time: the loop cuts time into segments at frames and switches and
takes equal steps no longer than the plan's inside each, so a switch happens exactly at its time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .dynamics import Dynamics, contiguous_slice
from .integrate import INTEGRATORS, PACKED, Q, V, W, X, Stages
from .kinematics import evaluate_paths
from .plan import Plan, PlanOptions, compile_plan
from .rotation import quat_to_matrix

# what counts as a blow-up: any non-finite number, a speed beyond this, or a constraint error beyond this
RUNAWAY_SPEED = 1e6  # m/s or rad/s
RUNAWAY_CONSTRAINT_ERROR = 1.0  # m (or rad): a joint this far apart is not a joint any more


class NumericalError(Exception):
    """The simulation became meaningless: says when (time and step) and what (body or constraint)."""

    def __init__(self, time: float, step: int, culprit: str, detail: str):
        self.time, self.step, self.culprit, self.detail = time, step, culprit, detail
        super().__init__(f"numerical blow-up at t = {time:.6g} s (step {step}): {culprit}: {detail}")


@dataclass
class State:
    """The mutable part: time and the struct-of-arrays state of every body.

    x, q, v, w are views of y, each body's state packed in one row (integrate.py's layout), which the integrator
    loads and advances in one numpy call each; write them in place (x[...] = ...), never rebind them."""

    t: float
    x: np.ndarray  # (n,3) centre of mass, m
    q: np.ndarray  # (n,4) orientation (w, x, y, z)
    v: np.ndarray  # (n,3) m/s
    w: np.ndarray  # (n,3) world angular velocity, rad/s
    steps: int = 0
    y: np.ndarray | None = None  # (n,13) rows [x q v w]; None for a State built from separate arrays

    @classmethod
    def initial(cls, plan: Plan) -> "State":
        y = np.empty((plan.n, PACKED))
        y[:, X], y[:, Q], y[:, V], y[:, W] = plan.x0, plan.q0, plan.v0, plan.w0
        return cls(plan.start, y[:, X], y[:, Q], y[:, V], y[:, W], y=y)

    def integrated(self):
        """What the integrators take: the packed array, or the tuple (x, q, v, w)."""
        return self.y if self.y is not None else (self.x, self.q, self.v, self.w)


def _equal_moments(inertia_body: np.ndarray) -> np.ndarray | None:
    """The moments (k,) of bodies whose inertia tensors (k,3,3) are each a multiple of the identity (spheres,
    cubes), or None if one of them is not."""
    moments = inertia_body[:, 0, 0]
    return moments if np.array_equal(inertia_body, moments[:, None, None] * np.eye(3)) else None


class Simulation:
    def __init__(self, plan: Plan, source: dict | None = None):
        self.plan = plan
        self.state = State.initial(plan)
        self.source = source or {}
        self.events: list = []
        self.dynamics = Dynamics(plan)
        self.procedural = None
        if plan.solver == "procedural":
            from .procedural_plan import ProceduralStepper

            self.procedural = ProceduralStepper(plan, self.dynamics)
        self._integrate = INTEGRATORS.get(plan.integrator)  # None for the procedural plan: it integrates itself
        self._stages = Stages(plan.n)
        self._a = np.zeros((plan.n, 3))
        self._alpha = np.zeros((plan.n, 3))
        self._switches = np.array(plan.constraints.switch_times() if plan.constraints else [])
        self._dynamic = contiguous_slice(np.flatnonzero(plan.dynamic))  # slice, or indices, of the dynamic bodies
        self._positions: dict[int, tuple] = {}  # id(epoch) -> (epoch, its active rows with a position-level C)
        self._moments = _equal_moments(plan.inertia_body[self._dynamic])
        # collisions: detection and impulses after every step (runtime.collide), built only when the plan has them
        self.collider = plan.collisions.start(self) if plan.collisions is not None else None
        # observers called after every step, e.g. the audio stage recording motion signals
        self.observers: list = []
        self._sync_kinematics()

    # -- construction -------------------------------------------------------------------------------------

    @classmethod
    def from_file(cls, path, overrides: dict | None = None, **options) -> "Simulation":
        from isaac_lang.load import load_scene

        scene = load_scene(Path(path), overrides).scene
        plan = compile_plan(scene, PlanOptions(folder=Path(path).parent, **options))
        return cls(plan, {"path": Path(path), "overrides": overrides or {},
                                                                  "options": options})

    @classmethod
    def from_text(cls, text: str, overrides: dict | None = None, folder=".", **options) -> "Simulation":
        from isaac_lang.load import load_text

        scene = load_text(text, overrides=overrides, folder=folder).scene
        plan = compile_plan(scene, PlanOptions(folder=Path(folder), **options))
        return cls(plan, {"text": text, "folder": folder,
                                                                  "overrides": overrides or {}, "options": options})

    # -- queries ------------------------------------------------------------------------------------------

    def body(self, name: str) -> int:
        return self.plan.names.index(name)

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy of the dynamic bodies, J."""
        plan, s, d = self.plan, self.state, self._dynamic
        mass, v, w = plan.mass[d], s.v[d], s.w[d]
        if self._moments is not None:
            # I = R (I_b 1) R^T = I_b 1 for bodies whose inertia is the same about every axis: w . I w = I_b |w|^2
            spin = self._moments.dot(np.vecdot(w, w))
        else:
            # the body-frame angular velocity u = R^T w: w . I w = w . R I_b R^T w = u . I_b u
            u = np.matmul(w[:, None, :], quat_to_matrix(s.q[d]))[:, 0]
            spin = np.add.reduce(np.vecdot(u, np.matmul(plan.inertia_body[d], u[:, :, None])[:, :, 0]))
        # E = sum 1/2 m v^2 + 1/2 w . I w - m g . x
        kinetic = 0.5 * (mass.dot(np.vecdot(v, v)) + spin)
        potential = -mass.dot(s.x[d].dot(plan.gravity))
        return float(kinetic + potential)

    def constraint_errors(self) -> tuple:
        """(max |C| over active position rows, index of that row or -1) at the current state."""
        c = self.plan.constraints
        if c is None:
            return 0.0, -1
        s = self.state
        positions = self._position_rows(c.epoch_at(s.t))
        if not positions.size:
            return 0.0, -1
        block = self.dynamics.positions_at(self.dynamics.frame(s.x, s.q, s.v, s.w, s.t))
        errors = np.abs(block.C[positions])
        worst = int(np.argmax(errors))
        return float(errors[worst]), int(positions[worst])

    def _position_rows(self, epoch) -> np.ndarray:
        """The epoch's active rows that have a position-level C (not velocity-only), found once per epoch."""
        entry = self._positions.get(id(epoch))
        if entry is None or entry[0] is not epoch:
            velocity_only = self.dynamics.scratch.rows.velocity_only  # structure: written once, with the rows
            entry = self._positions[id(epoch)] = (epoch, epoch.active[~velocity_only[epoch.active]])
        return entry[1]

    # -- live inputs --------------------------------------------------------------------------------------

    def set_pose(self, name: str, position, orientation=(1.0, 0.0, 0.0, 0.0)) -> None:
        """Drive a kinematic body from outside (a mouse, a tracker) until `release_pose`."""
        index = self.body(name)
        paths = self.plan.kinematics
        if paths is None or index not in paths.index:
            raise ValueError(f"body `{name}` is not kinematic; declare it `kinematic` to drive it")
        quat = np.asarray(orientation, float)
        paths.overrides[index] = (np.asarray(position, float), quat / np.linalg.norm(quat))
        self._sync_kinematics()

    def release_pose(self, name: str) -> None:
        self.plan.kinematics.overrides.pop(self.body(name), None)

    def set_parameter(self, name: str, value: str) -> None:
        """Change a scene parameter (a `let`) mid-run: the scene is re-lowered and re-planned, and every body
        that still exists keeps its current state."""
        overrides = {**self.source.get("overrides", {}), name: value}
        if "path" in self.source:
            fresh = Simulation.from_file(self.source["path"], overrides, **self.source["options"])
        else:
            fresh = Simulation.from_text(self.source["text"], overrides, self.source["folder"], **self.source["options"])
        old = {n: i for i, n in enumerate(self.plan.names)}
        for j, body in enumerate(fresh.plan.names):
            if body in old and fresh.plan.dynamic[j]:
                i = old[body]
                for array in ("x", "q", "v", "w"):
                    getattr(fresh.state, array)[j] = getattr(self.state, array)[i]
        fresh.state.t, fresh.state.steps = self.state.t, self.state.steps
        self.__dict__.update(fresh.__dict__)

    # -- stepping -----------------------------------------------------------------------------------------

    def advance_to(self, t_target: float) -> None:
        """Step until time t_target, landing exactly on every constraint switch on the way."""
        s = self.state
        while s.t < t_target - 1e-12:
            ahead = self._switches[self._switches > s.t + 1e-12]
            boundary = min(t_target, float(ahead[0])) if ahead.size else t_target
            count = max(1, math.ceil((boundary - s.t) / self.plan.step - 1e-9))
            h = (boundary - s.t) / count
            epoch = self.plan.constraints.epoch_at(s.t + 0.5 * h) if self.plan.constraints else None
            for _ in range(count):
                self._step(h, epoch)
            s.t = boundary  # no drift from summing h

    def step(self, h: float | None = None) -> None:
        """One step of the plan's size (or h), not crossing a switch."""
        self.advance_to(self.state.t + (h or self.plan.step))

    def _step(self, h: float, epoch) -> None:
        s = self.state
        if self.collider is not None:
            self.collider.before_step(h, epoch)
        if self.procedural is not None:
            self.procedural.step(s, h, epoch)
        else:
            self._integrate(self.dynamics.accelerations, s.t, h, s.integrated(), self._stages, epoch)
        s.t += h
        s.steps += 1
        self._sync_kinematics()
        if self.collider is not None:
            self.collider.after_step(h, epoch)
        self._check_finite()
        for observe in self.observers:
            observe(self, h)

    def _sync_kinematics(self) -> None:
        if self.plan.kinematics is not None:
            s = self.state
            evaluate_paths(self.plan.kinematics, s.t, s.x, s.q, s.v, s.w)

    def _check_finite(self) -> None:
        s = self.state
        # the largest |entry| of each state column, by one reduction (a NaN anywhere in a column gives NaN): every
        # position finite, and every |v| and |w| component below RUNAWAY_SPEED (NaN fails the comparison)
        packed = s.y if s.y is not None else np.concatenate((s.x, s.q, s.v, s.w), axis=1)
        largest = np.maximum.reduce(np.abs(packed), axis=0, initial=0.0).tolist()
        if all(c < RUNAWAY_SPEED for c in largest[V.start:]) and all(math.isfinite(c) for c in largest[X]):
            return
        speed = max(np.abs(s.v).max(initial=0.0), np.abs(s.w).max(initial=0.0))
        bad = ~(np.isfinite(s.x).all(axis=1) & np.isfinite(s.v).all(axis=1) & np.isfinite(s.w).all(axis=1))
        bad |= np.maximum(np.abs(s.v).max(axis=1), np.abs(s.w).max(axis=1)) >= RUNAWAY_SPEED
        name = self.plan.names[int(np.flatnonzero(bad)[0])] if bad.any() else "?"
        raise NumericalError(s.t, s.steps, f"body `{name}`", "its velocity is no longer finite"
                             if not np.isfinite(speed) else f"its speed passed {RUNAWAY_SPEED:g}")

    def check_constraints(self) -> float:
        """Constraint error now; a runaway error stops the run naming the constraint."""
        error, row = self.constraint_errors()
        if not np.isfinite(error) or error > RUNAWAY_CONSTRAINT_ERROR:
            name = self.plan.constraints.names[self.plan.constraints.row_constraint[row]] if row >= 0 else "?"
            raise NumericalError(self.state.t, self.state.steps, f"constraint `{name}`",
                                 f"its error grew to {error:.3g} (m or rad)")
        return error
