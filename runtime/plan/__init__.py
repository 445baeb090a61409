"""Stage 4, plan: what this scene needs and nothing more, with its arrays preallocated.

The plan is read-only during the run (MuJoCo's mjModel): body masses and inverse inertias, the force stages,
the constraint families, the kinematic paths, the solver, the step. `describe()` is what `isaac plan` prints.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_ir.diagnostics import counted

from .budgets import check_budgets
from ..constraints.plan import ConstraintPlan, compile_constraints
from .forces import ForcePlan, compile_forces
from .kinematics import KinematicPaths, compile_kinematics

# default step: fine enough that RK4's error on a 1 m pendulum is ~1e-12 per period
DEFAULT_STEP = 1e-3
# the procedural plan's default step: one display frame
DEFAULT_PROCEDURAL_STEP = 1.0 / 60.0
# `auto` picks the procedural plan above this many dynamic bodies (docs/procedural.md)
AUTO_PROCEDURAL_BODIES = 200
# ... or for steps this long: beyond 5 ms the dynamics plan's joints open past 1 mm on the chain, and at 1/60 s
# it blows up, while the procedural plan holds them to 1e-6 m (benchmarks/bench_procedural.py)
AUTO_PROCEDURAL_STEP = 5e-3


@dataclass
class PlanOptions:
    solver: str | None = None  # overrides the scene's plan
    step: float | None = None  # overrides the scene's step
    until: float | None = None
    folder: object = None  # the scene's folder: recordings and meshes the scene names are found from here


@dataclass
class Plan:
    scene: ir.Scene
    solver: str  # dynamics | procedural
    integrator: str
    step: float
    step_reason: str
    start: float
    end: float
    frame_times: np.ndarray  # (T,) output sample times
    names: list  # body names
    mass: np.ndarray  # (n,)
    inv_mass: np.ndarray  # (n,) 0 for static and kinematic bodies
    inertia_body: np.ndarray  # (n,3,3)
    inv_inertia_body: np.ndarray  # (n,3,3) 0 for static and kinematic bodies
    dynamic: np.ndarray  # (n,) bool
    x0: np.ndarray
    q0: np.ndarray
    v0: np.ndarray
    w0: np.ndarray
    forces: ForcePlan
    constraints: ConstraintPlan | None
    kinematics: KinematicPaths | None
    gravity: np.ndarray
    folder: object = None  # the scene's folder (Path), where assets are looked up; None: the working directory
    # optional stages, each built only when the scene uses it (and its module imported only then)
    collisions: object = None  # runtime.collide: pairs that can touch, detection and impulses
    audio: object = None  # runtime.audio: the sound graph
    warnings: list = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.names)

    def stages(self) -> dict:
        """Each stage of the step loop and whether this scene runs it."""
        stages = {"kinematic paths": self.kinematics is not None}
        stages.update(self.forces.stages())
        stages["constraints"] = self.constraints is not None
        stages["collisions"] = self.collisions is not None
        stages["wind"] = self.forces.wind is not None
        stages["audio"] = self.audio is not None
        return stages

    def describe(self) -> str:
        lines = [f"scene {self.scene.name}: {counted(self.n, 'body')} ({int(self.dynamic.sum())} dynamic)",
                 f"solver: {self.solver}, integrator {self.integrator}, step {self.step:g} s ({self.step_reason})",
                 f"time: {self.start:g} s .. {self.end:g} s, {len(self.frame_times)} frames"]
        if self.constraints is not None:
            c = self.constraints
            families = ", ".join(f"{type(f).__name__} x{len(_first(f))}" for f in c.families)
            lines.append(f"constraints: {len(c.names)} declared, {c.total_rows} rows ({families})")
            for epoch in c.epochs:
                lines.append(f"  {epoch.start:g} s .. {epoch.end:g} s: {len(epoch.active)} active rows, "
                             f"{epoch.solver} Cholesky" if epoch.solver != "none" else "")
        for stage in (self.collisions, self.forces.wind, self.audio):
            if stage is not None and hasattr(stage, "describe"):
                lines.append(stage.describe())
        lines.append("stages:")
        for name, on in self.stages().items():
            lines.append(f"  {'on ' if on else 'off'} {name}")
        return "\n".join(lines)


def _first(family):
    for name in ("body_a", "body", "gear"):
        if hasattr(family, name):
            return getattr(family, name)
    return []


def compile_plan(scene: ir.Scene, options: PlanOptions | None = None) -> Plan:
    options = options or PlanOptions()
    solver = _choose_solver(scene, options)
    step, reason = _choose_step(scene, solver, options)
    end = min(scene.time.end, options.until) if options.until is not None else scene.time.end
    check_budgets(scene, solver, step, end, reason)  # what the plan would ask for, before it allocates anything
    bodies = _body_arrays(scene)
    kinematics = compile_kinematics(scene)
    x0, q0 = bodies["x0"], bodies["q0"]
    constraints = compile_constraints(scene, step, x0, q0) if scene.constraints else None
    forces = compile_forces(scene, bodies["mass"], bodies["dynamic"], bodies["inertia_body"], x0, q0)
    frames = _frame_times(scene.time.start, end, scene.time.frame_rate)
    warnings = []
    if step > 1.0 / scene.time.frame_rate + 1e-12:
        warnings.append(f"the step ({step:g} s) is longer than a frame; steps are cut at every frame, so the "
                        f"effective step is {1.0 / scene.time.frame_rate:g} s (lower `frames` for longer steps)")
        step, reason = 1.0 / scene.time.frame_rate, reason + ", cut to one frame"
    integrator = scene.solver.integrator if solver == "dynamics" else "xpbd"
    plan = Plan(scene=scene, solver=solver, integrator=integrator, step=step, step_reason=reason,
                start=scene.time.start, end=end, frame_times=frames, forces=forces, constraints=constraints,
                kinematics=kinematics, gravity=np.asarray(scene.gravity, float), folder=options.folder, warnings=warnings, **bodies)
    _optional_stages(scene, plan)
    return plan


def _optional_stages(scene: ir.Scene, plan: Plan) -> None:
    """Collisions, wind and audio: a cheap look at the IR first, so an unused stage is never even imported."""
    collidable = [b for b in scene.bodies if b.collide]
    if len(collidable) >= 2 and any(b.motion == "dynamic" for b in collidable):
        from ..collide import compile_collisions

        plan.collisions = compile_collisions(scene, plan)  # None when every pair is excluded
    if any(b.wind.enabled and b.motion == "dynamic" for b in scene.bodies):  # in a wind, or in still air
        from ..wind import compile_wind

        plan.forces.wind = compile_wind(scene, plan)
    if scene.sounds:
        from ..audio import compile_audio

        plan.audio = compile_audio(scene, plan)


def _choose_solver(scene: ir.Scene, options: PlanOptions) -> str:
    plan = options.solver or scene.solver.plan
    if plan != "auto":
        return plan
    dynamic = sum(1 for b in scene.bodies if b.motion == "dynamic")
    step = options.step or scene.solver.step or 0.0
    return "procedural" if dynamic > AUTO_PROCEDURAL_BODIES or step >= AUTO_PROCEDURAL_STEP else "dynamics"


def _choose_step(scene: ir.Scene, solver: str, options: PlanOptions) -> tuple:
    if options.step is not None:
        return options.step, "--step"
    # a step written for one plan does not carry over when the run switches to the other
    if scene.solver.step is not None and (scene.solver.plan == solver or scene.solver.plan == "auto"):
        return scene.solver.step, "set by the scene"
    frame = 1.0 / scene.time.frame_rate
    target = DEFAULT_PROCEDURAL_STEP if solver == "procedural" else DEFAULT_STEP
    # a whole number of steps per frame, no longer than the target
    steps_per_frame = max(1, math.ceil(frame / target - 1e-9))
    return frame / steps_per_frame, f"default: {steps_per_frame} per frame"


def _frame_times(start: float, end: float, rate: float) -> np.ndarray:
    count = int(math.floor((end - start) * rate + 1e-9)) + 1
    times = start + np.arange(count) / rate
    if times[-1] < end - 1e-12:
        times = np.append(times, end)
    return times


def _body_arrays(scene: ir.Scene) -> dict:
    n = len(scene.bodies)
    mass = np.zeros(n)
    inertia = np.tile(np.eye(3), (n, 1, 1))
    dynamic = np.array([b.motion == "dynamic" for b in scene.bodies], dtype=bool)
    x0, q0 = np.zeros((n, 3)), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    for i, body in enumerate(scene.bodies):
        mass[i] = body.mass or 0.0
        if body.inertia is not None:
            inertia[i] = np.asarray(body.inertia)
        x0[i] = E.evaluate(body.position, {"t": scene.time.start})
        q = np.asarray(E.evaluate(body.orientation, {"t": scene.time.start}), dtype=float)
        q0[i] = q / np.linalg.norm(q)
    inv_mass = np.where(dynamic, 1.0 / np.where(mass > 0, mass, 1.0), 0.0)
    inv_inertia = np.where(dynamic[:, None, None], np.linalg.inv(inertia), 0.0)
    return {"names": [b.name for b in scene.bodies], "mass": mass, "inv_mass": inv_mass, "inertia_body": inertia,
            "inv_inertia_body": inv_inertia, "dynamic": dynamic, "x0": x0, "q0": q0,
            "v0": np.array([b.velocity for b in scene.bodies], float).reshape(n, 3),
            "w0": np.array([b.angular_velocity for b in scene.bodies], float).reshape(n, 3)}
