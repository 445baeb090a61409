"""`isaac run`: plan, simulate frame by frame, write the outputs, hold the run to its tolerances.

The driver (`run_scene`) reads as the list of stages: check the output folder is isaac's, simulate (plan, extras,
step loop, report), write the files of docs/outputs.md's contract (and the viewer, the plots) as one set that
replaces the previous run's whole (runtime/outputs/outputset.py), say what happened (warnings, errors, the summary) and
return the exit code: 0, 2 for a blow-up (or a warning under --strict), 3 for a finished run that broke a
tolerance (--max-constraint-error).
"""
from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from isaac_ir import ir
from isaac_ir.diagnostics import SourceCache, warning_diagnostic

from . import checks
from .outputs import goals
from .plan.extras import check_extras
from .outputs import Recorder, write_json, write_npz
from .outputs.outputset import OutputSet
from .core.build import energy_scale
from .plan import PlanOptions, compile_plan
from .simulation import NumericalError, Simulation

EXIT_OK, EXIT_SCENE, EXIT_TOLERANCE = 0, 2, 3


@dataclass
class RunOptions:
    solver: str | None = None
    step: float | None = None
    until: float | None = None
    progress: bool = False
    folder: object = None  # the scene's folder, for the assets it names
    on_frame: object = None  # called as on_frame(simulation, recorder) after every recorded frame (watch mode)
    # run_scene only: what else to write, what to hold the run to, how much to say
    viewer: bool = False  # viewer.html beside the outputs
    plots: bool = False  # plots/ (needs matplotlib, checked with the plan)
    max_constraint_error: float | None = checks.DEFAULT_MAX_CONSTRAINT_ERROR  # m or rad; None: no limit
    strict: bool = False  # warnings are errors (exit 2)
    verbosity: int = 0  # -2 errors and warnings only, -1 no progress bar, 0 the summary, 1 the plan and files too
    scene_warnings: tuple = ()  # the front end's (isaac_lang check): in report.json, already said on stderr


@dataclass
class RunResult:
    simulation: Simulation
    recorder: Recorder
    report: dict
    error: NumericalError | None
    audio: object = None  # runtime.audio.AudioRun: the motion recorded for the sounds (scenes with sounds)


def load_core_in_background() -> None:
    """The dynamics plan's compiled step and measurements, loaded from numba's cache while the caller parses the
    scene (core/jit.py load_in_background)."""
    from .core.entries import measure
    from .core.jit import load_in_background
    from .dynamics.integrate import run

    load_in_background(run, measure)


def simulate(scene: ir.Scene, options: RunOptions | None = None) -> RunResult:
    """Plan the scene and run it to the end, recording every frame (the in-process form of `isaac run`)."""
    options = options or RunOptions()
    started = time.perf_counter()
    plan = compile_plan(scene, PlanOptions(options.solver, options.step, options.until, options.folder))
    check_extras(plan, plots=options.plots)  # a missing optional package stops the run now, not after it
    if options.verbosity > 0:
        print(plan.describe(), file=sys.stderr)
    sim = Simulation(plan)
    # constraints that pull against each other: a warning at the first, naming them all, and the run goes on (it
    # breaks the tolerance: exit 3); refused before the first step (exit 2) when no run could get anywhere: a
    # constraint that cannot act at the start (an axis along the direction it must be perpendicular to), or errors
    # that the step would stop at once as a blow-up
    found = checks.unsatisfiable(sim, options.max_constraint_error)
    if found is not None and checks.hopeless(found):
        raise checks.unsatisfiable_error(scene, found)
    plan_warnings = [checks.unsatisfiable_warning(scene, found)] if found is not None else []
    audio = plan.audio.record(sim) if plan.audio is not None else None
    recorder = Recorder(plan.frame_times, plan.names)
    error = None
    with _progress(plan, options.progress) as bar:
        def on_frame(simulation, recorded):
            bar.update(1)
            if options.on_frame is not None:
                options.on_frame(simulation, recorded)

        states = {}  # the states at the goals' times (runtime/outputs/goals.py)
        try:
            frame_call = on_frame if options.progress or options.on_frame else None
            if scene.goals:
                states = goals.run_with_goal_stops(sim, plan.frame_times, recorder, goals.goal_times(scene),
                                                   frame_call)
            else:
                sim.run_frames(plan.frame_times, recorder, frame_call)
        except NumericalError as failure:
            error = failure
    energy0 = float(recorder.energy[0]) if recorder.count else sim.energy()  # the first frame's: the start
    with np.errstate(all="ignore"), warnings.catch_warnings():  # a blown-up run's figures are NaN: null in JSON
        warnings.simplefilter("ignore", RuntimeWarning)
        report = run_report(sim, recorder, energy0, time.perf_counter() - started, error)
    report["warnings"] = list(options.scene_warnings) + plan_warnings + report["warnings"]
    report["compile_time"] = sim.compile_seconds
    conflict = _conflicts(sim, recorder, options.max_constraint_error) if error is None else None
    if conflict is not None:
        report["warnings"].append(checks.conflict_warning(conflict, scene))
    report["checks"] = tolerance_checks(report, options.max_constraint_error, conflict)
    if scene.goals:  # each goal a check: met or not (docs/goals.md)
        report["goals"] = goals.evaluate_goals(scene, plan.names, states, sim.events)
        report["checks"]["goals"] = goals.goals_check(report["goals"])
    return RunResult(sim, recorder, report, error, audio)


def _conflicts(sim: Simulation, recorder: Recorder, limit: float | None) -> dict | None:
    """The constraints that cannot all hold (runtime/checks.py), from the frames and the end of the run."""
    plan = sim.plan
    if plan.constraints is None:
        return None
    residuals, _ = sim.constraint_residuals()
    windows = checks.settling_windows(plan.scene, plan)
    return checks.conflicts(plan, recorder, residuals, windows, limit,
                            lambda rows: sim.joint_rows(np.asarray(rows, np.int64), sim.state.t)[0])


def write_outputs(scene: ir.Scene, result: RunResult, out: Path) -> list:
    """The files of docs/outputs.md's contract, each written atomically; report.json last. Returns their paths."""
    written = [out / "trajectory.npz", out / "events.json", out / "ir.json"]
    write_npz(written[0], result.recorder.arrays())
    write_json(written[1], result.simulation.events)
    write_json(written[2], ir.to_data(scene))
    if result.audio is not None:
        result.report["audio"] = result.audio.write(out / "audio.wav", result.report["wall_time"])
        written.append(out / "audio.wav")
    write_json(out / "report.json", result.report)
    return written + [out / "report.json"]


def run_scene(scene: ir.Scene, out: Path, options: RunOptions, scene_path: Path | None = None, more=None) -> int:
    """`isaac run` after the scene is loaded: the stages, then the exit code (module docstring). more(folder,
    result) -> paths: files another command (isaac export) adds to the run's set, written into folder."""
    outputs = OutputSet(out, "run")
    outputs.check()  # a folder that is not isaac's stops the run now, not after it
    result = simulate(scene, options)
    with outputs:
        written = write_outputs(scene, result, outputs.path) + write_extras(scene, result, outputs.path, options)
        if more is not None:
            written += more(outputs.path, result)
        written = outputs.commit(written, **set_info(scene, result))
    where = f"{scene_path}" if scene_path else scene.name
    warnings = _say_warnings(where, result.report["warnings"], options)
    if result.error is not None:
        _say_error(where, f"{result.error}", result.error.source, (
            f"{result.error.hint + '; ' if result.error.hint else ''}the trajectory up to t = "
            f"{result.error.time:.6g} s is in {out / 'trajectory.npz'}"))
        return EXIT_SCENE
    _say_summary(scene, result.report, out, written, options)
    if (_broken_tolerance(where, result.report) | _broken_contact(where, result.report, scene)
            | _missed_goals(where, result.report)):
        return EXIT_TOLERANCE
    return EXIT_SCENE if warnings and options.strict else EXIT_OK


def set_info(scene: ir.Scene, result: RunResult) -> dict:
    """What the output folder's manifest says of the run besides its files."""
    return {"scene": scene.name, "run": "blow-up" if result.error is not None else "complete"}


def write_extras(scene: ir.Scene, result: RunResult, out: Path, options: RunOptions) -> list:
    """viewer.html and plots/ when asked for; their paths."""
    arrays = result.recorder.arrays()
    audio = out / "audio.wav" if result.audio is not None else None
    written = []
    if options.viewer:
        from .viewer import write_viewer

        written.append(write_viewer(out / "viewer.html", scene, arrays, options.folder, audio=audio))
    if options.plots:
        from .outputs.plots import write_plots

        written += write_plots(out / "plots", arrays, audio, title=scene.name)
    return written


def _say_warnings(where: str, warnings: list, options: RunOptions) -> list:
    """Each warning of the plan and the run on stderr (those of the front end were said when it loaded); errors
    under --strict. Returns every warning of the run, the front end's included."""
    severity = "error" if options.strict else "warning"
    said = set(options.scene_warnings)
    for text in warnings:
        if text not in said:
            print(format_warning(text, where, severity), file=sys.stderr)
    return warnings


def format_warning(text: str, scene_path, severity: str = "warning") -> str:
    """`file:line:col: warning: message` for a warning that opens with its own position (its file named relative
    to the scene's folder, as the IR names it, printed as reached from here), else `scene: warning: text`."""
    diagnostic = warning_diagnostic(text, severity)
    pos = diagnostic.pos
    if pos is None:
        return diagnostic.format().replace(f"{severity}: ", f"{scene_path}: {severity}: ", 1)
    folder = Path(scene_path).parent if scene_path else Path(".")
    if folder != Path(".") and not Path(pos.file).is_absolute():
        diagnostic = dataclasses.replace(diagnostic, pos=dataclasses.replace(pos, file=(folder / pos.file).as_posix()))
    return diagnostic.format(_source_of(diagnostic.pos.file))


def _source_of(file: str) -> SourceCache:
    """The text of a scene file a warning points into, so that it prints with its line and caret (none when
    the file cannot be read)."""
    sources = SourceCache()
    try:
        sources.add(file, Path(file).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        pass
    return sources


def _say_error(where: str, message: str, source: str | None, hint: str) -> None:
    """`scene: error: message`, or at the culprit's declaration (`file:line:col: error:`) when it is known."""
    said = format_warning(f"{source}: {message}", where, "error") if source else f"{where}: error: {message}"
    print(f"{said}\nhint: {hint}", file=sys.stderr)


def _say_summary(scene: ir.Scene, r: dict, out: Path, written: list, options: RunOptions) -> None:
    if options.verbosity < -1:  # -qq: errors and warnings only
        return
    compiled = r.get("compile_time", 0.0)
    said = f" (after compiling the core in {compiled:.1f} s)" if compiled else ""
    print(f"{scene.name}: {r['steps']} steps of {r['step']:g} s ({r['solver']}, {r['integrator']}) in "
          f"{r['wall_time'] - compiled:.2f} s{said}; max constraint error {r['max_constraint_error']:.2e}; outputs in {out}/")
    plots = [Path(p).name for p in written if Path(p).parent == out / "plots"]
    if plots:
        print(f"plots: {', '.join(plots)} in {out / 'plots'}/")
    if options.verbosity > 0:
        if r.get("contact"):
            print(_contact_path(r["contact"]))
        for path in written:
            print(f"  wrote {path}")


def _contact_path(contact: dict) -> str:
    """-v's line on the contact path the run took, and why (docs/collisions.md, "Many contacts")."""
    if contact["path"] != "capturing":
        return f"contacts: the exact path ({contact['why']})"
    return (f"contacts: the capturing path from t = {contact['since']:.6g} s ({contact['why']}); deepest "
            f"{contact['deepest'] * 1e3:.3g} mm; {contact.get('islands_solved_whole', 0)} islands solved whole "
            f"(summed over steps)")


def _broken_tolerance(where: str, report: dict) -> bool:
    """Say so on stderr when the run kept a constraint error above --max-constraint-error."""
    check = report["checks"]["max_constraint_error"]
    if check["ok"]:
        return False
    named = f" (constraints {', '.join(f'`{n}`' for n in check['constraints'])})" if check.get("constraints") else ""
    _say_error(where, f"the constraint error stays at {check['value']:.3g} (m or rad) once switched-on constraints "
                      f"have settled (largest at t = {check['time']:.6g} s), above --max-constraint-error "
                      f"{check['limit']:g}{named}", None,
               "constraints that cannot all hold (two nails that disagree, a body tied to two places) keep their "
               "error: check the anchor points, or raise the limit with --max-constraint-error")
    return True


def _broken_contact(where: str, report: dict, scene: ir.Scene) -> bool:
    """Say so on stderr, at the first body of the deepest pair, when a contact went deeper than the depth limit
    (report.json checks.contact)."""
    contact = _broken_depth(report)
    if contact is None:
        return False
    _say_error(where, too_deep(contact), _pair_source(scene, *contact["deepest_pair"]), TOO_DEEP_HINT)
    return True


def _broken_depth(report: dict) -> dict | None:
    """report.json's `contact` when its check (checks.contact) failed, else None."""
    check = report["checks"].get("contact")
    return report["contact"] if check is not None and not check["ok"] else None


TOO_DEEP_HINT = ("a smaller step, or thicker bodies, keeps them apart; the trajectory is written, and report.json "
                 "holds the deepest pair (contact.deepest_pair)")


def too_deep(contact: dict) -> str:
    """What a run on the capturing path that went deeper than its depth limit says (report.json `contact`)."""
    a, b = contact["deepest_pair"]
    return (f"bodies interpenetrated by more than {contact['depth_limit'] * 1e3:g} mm in {contact['steps_too_deep']} "
            f"steps; deepest {contact['deepest'] * 1e3:.3g} mm, `{a}` and `{b}` at t = {contact['deepest_time']:.6g} s")


def too_deep_warning(report: dict, scene: ir.Scene) -> list:
    """[the warning of a run that broke the depth limit], for a run that does not exit on it (`isaac live`)."""
    contact = _broken_depth(report)
    if contact is None:
        return []
    return [checks.positioned(too_deep(contact), _pair_source(scene, *contact["deepest_pair"]), TOO_DEEP_HINT)]


def _missed_goals(where: str, report: dict) -> bool:
    """Say so on stderr for each goal the run missed (report.json `goals`)."""
    missed = [record for record in report.get("goals", ()) if not record["met"]]
    for record in missed:
        _say_error(where, f"goal {goals.describe_miss(record)}", record.get("source"),
                   "the goal is checked on this run; `isaac fit` finds the values of the `vary`s that meet it")
    return bool(missed)


def run_report(sim: Simulation, recorder: Recorder, energy0: float, wall: float, error) -> dict:
    plan = sim.plan
    arrays = recorder.arrays()
    energy = arrays["energy"]
    scale = drift_scale(plan)
    warnings = list(plan.warnings)
    if sim.rank_deficient():
        warnings.append(checks.redundant_warning(plan, sim.constraint_residuals()[1]))
    control = sim.error_control() if plan.solver == "dynamics" else {}
    stages = plan.stages()
    return {
        "scene": plan.scene.name, "solver": plan.solver, "integrator": plan.integrator, "step": plan.step,
        "step_reason": plan.step_reason, "steps": sim.state.steps, "steps_at_rest": sim.steps_at_rest(),
        "tolerance": plan.scene.solver.tolerance if plan.integrator == "rk4" else None, **control,
        "simulated_time": sim.state.t - plan.start,
        "wall_time": wall, "frames": int(len(arrays["time"])),
        "stages_run": [k for k, v in stages.items() if v], "stages_skipped": [k for k, v in stages.items() if not v],
        "linear_solvers": sorted({e.solver for e in plan.constraints.epochs} - {"none"}) if plan.constraints else [],
        "max_constraint_error": float(np.nanmax(arrays["constraint_error"])) if len(energy) else 0.0,
        **_settled(plan, arrays),
        "energy_start": energy0,
        "energy_drift": float(np.nanmax(np.abs(energy - energy0))) if len(energy) else 0.0,
        "energy_drift_relative": float(np.nanmax(np.abs(energy - energy0)) / scale) if len(energy) else 0.0,
        "energy_scale": scale,
        "contact": sim.contact_report(),
        "warnings": warnings + contact_warnings(sim.contact_report(), plan.scene),
        "error": str(error) if error else None,
    }


def drift_scale(plan) -> float:
    """The yardstick of the energy drift: the core's (runtime/core/build.py energy_scale: m |g| times the spread
    of the dynamic bodies, 1 m for one body, or the kinetic energy at the start), or the potential energy of the
    dynamic bodies above the lowest body of the scene, whichever is larger: each variant of a sweep over drop
    heights measures its drift against its own drop."""
    return max(energy_scale(plan), _potential_above_lowest(plan))


def _potential_above_lowest(plan) -> float:
    """m |g| h summed over the dynamic bodies, h the height (against gravity) above the lowest body, static ones
    included (a ground, a table); 0 without gravity or without a body below."""
    gravity = np.asarray(plan.gravity, float)
    g = float(np.linalg.norm(gravity))
    dynamic = np.asarray(plan.dynamic, bool)
    positions = np.asarray(plan.x0, float)
    if g == 0.0 or not dynamic.any() or not np.isfinite(g):
        return 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        heights = positions @ (-gravity / g)
        above = heights[dynamic] - np.nanmin(heights)
        potential = float(np.sum(np.asarray(plan.mass, float)[dynamic] * g * above))
    return potential if np.isfinite(potential) else 0.0


def tolerance_checks(report: dict, limit: float | None, conflict: dict | None = None) -> dict:
    """report.json's `checks`: the settled constraint error against --max-constraint-error, and, on the
    capturing path, the interpenetration against its depth limit (`contact_check`)."""
    said = {"max_constraint_error": checks.constraint_check(report, limit, conflict)}
    contact = contact_check(report.get("contact"))
    if contact is not None:
        said["contact"] = contact
    return said


def contact_check(contact: dict | None) -> dict | None:
    """report.json's checks.contact for a run on the capturing path (else None): ok unless a contact went deeper
    than the depth limit (capture DEPTH_LIMIT, 1 mm) at some step. Energy created by the contact impulses is a
    warning: the step's work of the contact impulses alone, while joints and other contacts take it back (a
    chain of capsules piling on a floor: 3 % of the energy scale in a step, its energy rising by 0.1 % at most
    between frames)."""
    if not contact or contact.get("path") != "capturing":
        return None
    return {"depth_limit": contact["depth_limit"], "deepest": contact["deepest"],
            "steps_too_deep": contact["steps_too_deep"], "ok": contact["steps_too_deep"] == 0}


def contact_warnings(contact: dict | None, scene: ir.Scene | None = None) -> list:
    """The capturing path's warnings (energy created by contact impulses), with the worst case's time and pair, at
    the declaration of the pair's first body (when the scene is given). Interpenetration deeper than the limit
    breaks the run's tolerance: an error (`_broken_contact`)."""
    if not contact or contact.get("path") != "capturing" or not contact["steps_creating_energy"]:
        return []
    a, b = contact["energy_created_pair"]
    return [checks.positioned(
        f"contact impulses created energy in {contact['steps_creating_energy']} steps; most "
        f"{contact['energy_created']:.3g} J, `{a}` and `{b}` at t = {contact['energy_created_time']:.6g} s",
        _pair_source(scene, a, b), "a smaller step keeps contacts from adding energy")]


def _pair_source(scene, a: str, b: str) -> str | None:
    """Where the first declared body of a contact pair is declared (a dynamic body before the ground)."""
    return checks.body_source(scene, a) or checks.body_source(scene, b)


def _settled(plan, arrays: dict) -> dict:
    """The constraint error that stays (runtime/checks.py): outside the settling windows after switch-ons."""
    windows = checks.settling_windows(plan.scene, plan)
    value, at = checks.settled_error(arrays["time"], arrays["constraint_error"], windows)
    return {"constraint_error_settled": value, "constraint_error_settled_time": at,
            "settling_windows": [list(w) for w in windows]}


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
