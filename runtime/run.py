"""`isaac run`: plan, simulate frame by frame, write the outputs. The driver reads as the list of stages."""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from isaac_lang import ir

from .outputs import Recorder, write_json, write_npz
from .plan import PlanOptions, compile_plan
from .simulation import NumericalError, Simulation

EXIT_OK, EXIT_SCENE = 0, 2


@dataclass
class RunOptions:
    solver: str | None = None
    step: float | None = None
    until: float | None = None
    progress: bool = False
    folder: object = None  # the scene's folder, for the assets it names
    on_frame: object = None  # called as on_frame(simulation, recorder) after every recorded frame (watch mode)


@dataclass
class RunResult:
    simulation: Simulation
    recorder: Recorder
    report: dict
    error: NumericalError | None
    audio: object = None  # runtime.audio.AudioRun: the motion recorded for the sounds (scenes with sounds)


def simulate(scene: ir.Scene, options: RunOptions | None = None) -> RunResult:
    """Plan the scene and run it to the end, recording every frame (the in-process form of `isaac run`)."""
    options = options or RunOptions()
    started = time.perf_counter()
    plan = compile_plan(scene, PlanOptions(options.solver, options.step, options.until, options.folder))
    sim = Simulation(plan)
    audio = plan.audio.record(sim) if plan.audio is not None else None
    recorder = Recorder(plan.frame_times, plan.names)
    error = None
    with _progress(plan, options.progress) as bar:
        def on_frame(simulation, recorded):
            bar.update(1)
            if options.on_frame is not None:
                options.on_frame(simulation, recorded)

        try:
            sim.run_frames(plan.frame_times, recorder, on_frame if options.progress or options.on_frame else None)
        except NumericalError as failure:
            error = failure
    energy0 = float(recorder.energy[0]) if recorder.count else sim.energy()  # the first frame's: the start
    report = _report(sim, recorder, energy0, time.perf_counter() - started, error)
    return RunResult(sim, recorder, report, error, audio)


def write_outputs(scene: ir.Scene, result: RunResult, out: Path) -> None:
    """The files of ARCHITECTURE.md's contract, each written atomically; report.json last."""
    write_npz(out / "trajectory.npz", result.recorder.arrays())
    write_json(out / "events.json", result.simulation.events)
    write_json(out / "ir.json", ir.to_data(scene))
    if result.audio is not None:
        result.report["audio"] = result.audio.write(out / "audio.wav", result.report["wall_time"])
    write_json(out / "report.json", result.report)


def run_scene(scene: ir.Scene, out: Path, options: RunOptions, scene_path: Path | None = None) -> int:
    result = simulate(scene, options)
    write_outputs(scene, result, out)
    if result.error is not None:
        where = f"{scene_path}: " if scene_path else ""
        print(f"{where}error: {result.error}\n"
              f"hint: try a smaller step (`solver dynamics {{ step 0.5 ms }}` or --step), a lower stabilization "
              f"frequency, or the procedural solver (--solver procedural); the trajectory up to "
              f"t = {result.error.time:.6g} s is in {out / 'trajectory.npz'}", file=sys.stderr)
        return EXIT_SCENE
    r = result.report
    print(f"{scene.name}: {r['steps']} steps of {r['step']:g} s ({r['solver']}, {r['integrator']}) in "
          f"{r['wall_time']:.2f} s; max constraint error {r['max_constraint_error']:.2e}; outputs in {out}/")
    return EXIT_OK


def _report(sim: Simulation, recorder: Recorder, energy0: float, wall: float, error) -> dict:
    plan = sim.plan
    arrays = recorder.arrays()
    energy = arrays["energy"]
    scale = _energy_scale(plan)
    warnings = list(plan.warnings)
    if sim.rank_deficient():
        warnings.append("redundant constraints: J M^-1 J^T was singular; solved in the least-squares sense")
    stages = plan.stages()
    return {
        "scene": plan.scene.name, "solver": plan.solver, "integrator": plan.integrator, "step": plan.step,
        "step_reason": plan.step_reason, "steps": sim.state.steps, "simulated_time": sim.state.t - plan.start,
        "wall_time": wall, "frames": int(len(arrays["time"])),
        "stages_run": [k for k, v in stages.items() if v], "stages_skipped": [k for k, v in stages.items() if not v],
        "linear_solvers": sorted({e.solver for e in plan.constraints.epochs} - {"none"}) if plan.constraints else [],
        "max_constraint_error": float(np.nanmax(arrays["constraint_error"])) if len(energy) else 0.0,
        "energy_start": energy0,
        "energy_drift": float(np.nanmax(np.abs(energy - energy0))) if len(energy) else 0.0,
        "energy_drift_relative": float(np.nanmax(np.abs(energy - energy0)) / scale) if len(energy) else 0.0,
        "energy_scale": scale,
        "warnings": warnings,
        "error": str(error) if error else None,
    }


def _energy_scale(plan) -> float:
    """A yardstick for energy drift: m |g| (size of the scene) summed over dynamic bodies, or the kinetic
    energy at the start, whichever is larger (a scene that starts at rest at zero height has E0 = 0)."""
    d = plan.dynamic
    extent = float(np.ptp(plan.x0[d], axis=0).max()) if d.sum() > 1 else 1.0
    g = float(np.linalg.norm(plan.gravity))
    potential = float(np.sum(plan.mass[d]) * g * max(extent, 1e-3))
    kinetic = 0.5 * float(np.sum(plan.mass[d] * np.sum(plan.v0[d] ** 2, axis=1)))
    rotational = 0.5 * float(np.einsum("ni,nij,nj->", plan.w0[d], plan.inertia_body[d], plan.w0[d]))
    return max(potential, kinetic + rotational, 1e-12)


class _NoBar:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        pass


def _progress(plan, enabled: bool):
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    # shown only for runs longer than a second
    return tqdm(total=len(plan.frame_times), unit="frame", delay=1.0, leave=False)
