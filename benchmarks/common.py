"""Shared pieces of the benchmark suite (`isaac bench`): running our runtime on a scene with a light probe,
timing (best of repeats, wall and CPU), CSV writing, plotting, and what the machine looked like.

A *trajectory* here is the dict `isaac run` writes to trajectory.npz, sampled densely instead of at the frame rate:
    time (T,)  position (T,B,3)  orientation (T,B,4) (w,x,y,z)  linear_velocity (T,B,3)  angular_velocity (T,B,3)
Our runs and the peers' (benchmarks/peers.py) produce the same dict with the same body order, so that every
error below is computed by one function whoever simulated.
"""
from __future__ import annotations

import csv
import dataclasses
import importlib.metadata
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"
RESULTS = REPO / "benchmarks" / "results"

# the probe samples the state every k steps, k = round(SAMPLE_DT / h): dense enough for the Hermite crossings of
# the period measurement to be exact to ~1e-13 relative, sparse enough not to cost anything at small steps
SAMPLE_DT = 1e-3
# a run shorter than this (wall seconds) is repeated and the best time kept; a longer one runs once
REPEAT_BELOW = 1.0
REPEATS = 3


@dataclass
class Outcome:
    """One simulation run: what ran, how long it took, how it ended, and the trajectory it left."""

    engine: str  # isaac | mujoco | pybullet
    model: str  # dynamics | procedural (ours); reduced | maximal (peers)
    integrator: str
    step: float  # s, the step asked for
    steps: int = 0
    sim_time: float = 0.0  # simulated seconds reached
    wall_s: float = math.nan  # best wall time of the whole run
    cpu_s: float = math.nan  # process CPU time of that run
    status: str = "ok"  # ok | numerical error: ... | bug: ...
    trajectory: dict | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def step_us(self) -> float:
        return 1e6 * self.wall_s / self.steps if self.steps else math.nan

    @property
    def cost(self) -> float:
        """Wall seconds per simulated second: the figure work-precision plots put on the x axis."""
        return self.wall_s / self.sim_time if self.sim_time > 0 else math.nan


# -- scenes ----------------------------------------------------------------------------------------------------


def load(name: str, overrides: dict | None = None):
    """The ir.Scene of scenes/NAME.isaac with --set style overrides."""
    from isaac_lang.load import load_scene

    return load_scene(SCENES / f"{name}.isaac", overrides).scene


def load_source(text: str, name: str = "bench.isaac", overrides: dict | None = None):
    from isaac_lang.load import load_text

    return load_text(text, name=name, overrides=overrides, folder=SCENES).scene


def configured(scene, integrator: str | None = None, substeps: int | None = None, linear: str | None = None,
               frame_rate: float | None = None):
    """The scene with its solver block (or frame rate) changed: PlanOptions has no integrator, the IR is frozen,
    and the plan cuts a step longer than a frame down to the frame."""
    changes = {}
    if integrator is not None:
        changes["integrator"] = integrator
    if substeps is not None:
        changes["substeps"] = substeps
    if linear is not None:
        changes["linear_solver"] = linear
    if changes:
        scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, **changes))
    if frame_rate is not None:
        scene = dataclasses.replace(scene, time=dataclasses.replace(scene.time, frame_rate=frame_rate))
    return scene


def plan_for(scene, solver: str = "dynamics", step: float | None = None, until: float | None = None):
    """The plan of `scene` at `step`; a step longer than the scene's frames gets frames that long (the plan cuts
    steps at frames, and a benchmark run records none: the peers' steps are not cut either)."""
    import dataclasses

    from isaac_runtime.plan import PlanOptions, compile_plan

    if step is not None and step * scene.time.frame_rate > 1.0 + 1e-9:
        scene = dataclasses.replace(scene, time=dataclasses.replace(scene.time, frame_rate=1.0 / step))
    return compile_plan(scene, PlanOptions(solver=solver, step=step, until=until))


# -- the probe -------------------------------------------------------------------------------------------------


class Probe:
    """Copies the state into preallocated arrays every `every` steps (a Simulation observer: ~1 us a call)."""

    def __init__(self, n_bodies: int, capacity: int, every: int):
        self.every, self.count, self.calls = max(1, every), 0, 0
        self.time = np.full(capacity, np.nan)
        self.x = np.full((capacity, n_bodies, 3), np.nan)
        self.q = np.full((capacity, n_bodies, 4), np.nan)
        self.v = np.full((capacity, n_bodies, 3), np.nan)
        self.w = np.full((capacity, n_bodies, 3), np.nan)

    def record(self, t, x, q, v, w) -> None:
        k = self.count
        if k < len(self.time):
            self.time[k], self.x[k], self.q[k], self.v[k], self.w[k] = t, x, q, v, w
            self.count += 1

    def __call__(self, sim, h) -> None:
        self.calls += 1
        if self.calls % self.every == 0:
            s = sim.state
            self.record(s.t, s.x, s.q, s.v, s.w)

    def trajectory(self) -> dict:
        k = self.count
        return {"time": self.time[:k], "position": self.x[:k], "orientation": self.q[:k],
                "linear_velocity": self.v[:k], "angular_velocity": self.w[:k]}


def sample_every(step: float) -> int:
    return max(1, int(round(SAMPLE_DT / step)))


def probe_capacity(until: float, step: float, every: int) -> int:
    return int(math.ceil(until / step / every)) + 8


def run_isaac(scene, solver: str, step: float, until: float, probe: bool = True, repeat: bool = True) -> Outcome:
    """Step `scene` from its start to `until` with one Simulation.advance_to (the step is the one asked for, cut
    only at constraint switches). As for the peers (peers.py): the errors from a pass that probes the state (an
    observer: the steps are then taken one call at a time), the time from the best of up to REPEATS passes
    without it (many steps per call of the compiled loop, as a run takes them). The clock starts once the
    simulation is ready to step (built, its first epoch entered), as a peer's starts once its model is built."""
    integrator = scene.solver.integrator if solver == "dynamics" else "xpbd"
    out = Outcome("isaac", solver, integrator, step)
    if not probe:
        return _isaac_passes(scene, solver, step, until, False, repeat, out)
    probed = _isaac_passes(scene, solver, step, until, True, False, Outcome("isaac", solver, integrator, step))
    if probed.status != "ok":  # a run that fails is timed as it failed, once
        return probed
    timed = _isaac_passes(scene, solver, step, until, False, repeat, out)
    timed.trajectory = probed.trajectory
    return timed


def _isaac_passes(scene, solver: str, step: float, until: float, probe: bool, repeat: bool, out: Outcome) -> Outcome:
    from isaac_runtime.simulation import NumericalError, Simulation

    best = math.inf
    for attempt in range(REPEATS if repeat else 1):
        try:
            sim = Simulation(plan_for(scene, solver, step, until))
        except Exception as error:  # noqa: BLE001 (a runtime that cannot plan this is a result, not a crash)
            out.status = f"bug: {type(error).__name__}: {error}"
            return out
        p = None
        if probe:
            every = sample_every(step)
            p = Probe(sim.plan.n, probe_capacity(until, step, every), every)
            s = sim.state
            p.record(s.t, s.x, s.q, s.v, s.w)
            sim.observers.append(p)
        status = "ok"
        # ready to step, as a peer is once its model is built: the first epoch entered (its rows' structure and
        # which of them start on their manifold), no step taken
        sim.advance_to(sim.plan.start)
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            sim.advance_to(sim.plan.start + until)
        except NumericalError as error:
            status = f"numerical error: {error}"
        except Exception as error:  # noqa: BLE001
            status = f"bug: {type(error).__name__}: {error}"
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        if wall < best:
            best, out.wall_s, out.cpu_s = wall, wall, cpu
        out.steps, out.sim_time, out.status = sim.state.steps, sim.state.t - sim.plan.start, status
        out.trajectory = p.trajectory() if p is not None else None
        if status != "ok" or wall > REPEAT_BELOW:
            break
    return out


def best_time(fn, repeats: int = REPEATS, budget: float = REPEAT_BELOW) -> tuple:
    """(best wall, its CPU time) of fn() over up to `repeats` calls, stopping once a call exceeds `budget`."""
    best = (math.inf, math.inf)
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        best = min(best, (wall, cpu))
        if wall > budget:
            break
    return best


# -- output ----------------------------------------------------------------------------------------------------


def fmt(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def write_csv(path: Path, rows: list, keys: list | None = None) -> Path:
    """rows (list of dicts) as CSV, floats to 6 significant digits, NaN as an empty field."""
    keys = keys or list(dict.fromkeys(k for r in rows for k in r))
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(keys)
        for r in rows:
            writer.writerow([fmt(r.get(k, "")) for k in keys])
    return path


def read_csv(path: Path) -> list:
    def value(text):
        try:
            return float(text) if text != "" else math.nan
        except ValueError:
            return text

    with open(path, newline="") as handle:
        return [{k: value(v) for k, v in row.items()} for row in csv.DictReader(handle)]


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def machine() -> dict:
    """What the numbers were measured on (a loaded machine slows everything; ratios in one process less so)."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    versions = {"python": platform.python_version(), "numpy": np.__version__}
    for name in ("scipy", "mujoco", "pybullet"):
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "absent"
    return {"cpus": os.cpu_count(), "load_1min": load, "platform": platform.platform(terse=True),
            "when": time.strftime("%Y-%m-%d %H:%M"), **versions}


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
