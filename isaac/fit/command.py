"""`isaac fit SCENE [--set ...] [--workers N | --scheduler ADDRESS] [--out DIR]` (docs/goals.md).

Finds values of the scene's `vary`s that meet its goals (solve.py), prints a line per iteration and the values
found in the scene's units, then runs the scene at them as `isaac run` does (its usual outputs in DIR) and adds
fit.json: `parameters` (each varied name -> its value in SI), `goals` (each: met, error, tolerance, value,
target), `runs` (how many runs the search took). Exit 0 when every goal is met, 3 when not (the missed goals
named, with how far), 2 for a problem in the scene or the command line.
"""
from __future__ import annotations

import sys
from pathlib import Path

from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos
from isaac.writable import check_output_folder

EXIT_OK, EXIT_SCENE, EXIT_TOLERANCE = 0, 2, 3


def add_parser(commands, scene_command) -> None:
    """The `fit` subcommand, with the options every scene command has (scene_command: isaac.cli's)."""
    from isaac import options as opt

    fit = scene_command("fit", "find values of the scene's `vary`s that meet its goals; the fitted run and fit.json")
    fit.add_argument("--out", default=None, type=opt.output_folder, help="output folder (default out/<scene>/)")
    fit.add_argument("--workers", type=opt.positive_int, default=None,
                     help="spread the runs over a local Dask cluster of N processes (default: runs in this process)")
    fit.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="spread the runs over the Dask cluster at tcp://HOST:PORT")
    fit.add_argument("--viewer", action="store_true", help="write viewer.html beside the fitted run's outputs")


def cmd_fit(args, load, default_out, overrides: dict, limits, verbosity: int) -> int:
    """The body of `isaac fit` (load(args) -> the front end's Loaded, as `isaac run` loads)."""
    from isaac.fit.evaluate import DaskRuns, Evaluator, LocalRuns
    from isaac.fit.solve import Search, find

    scene = load(args).scene
    _check_fittable(scene, args)
    out = Path(args.out) if args.out else default_out(args.scene)
    check_output_folder(out, "--out")  # before the search's runs, not after them
    folder = Path(args.scene).parent
    runs = _runs(args, folder, limits, DaskRuns, LocalRuns)
    say = (lambda line: print(line, flush=True)) if verbosity >= 0 else (lambda line: None)
    try:
        search = Search(scene.varies, Evaluator(runs, scene.varies, overrides), say)
        find(search, scene.goals)
    finally:
        runs.close()
    point = search.to_si(search.best[1]) if search.best[1] is not None else [v.start for v in scene.varies]
    say_values(scene.varies, point, search, verbosity)
    return fitted_run(args, scene.varies, point, search, overrides, limits, out, verbosity)


def _check_fittable(scene, args) -> None:
    """A fit needs something to vary and something to meet; and one way of spreading its runs."""
    from isaac.sweep.command import check_scheduler_address, check_workers

    at_scene = SourcePos(Path(args.scene).name, 1, 1)  # a vary and a goal belong in the scene's text
    if not scene.varies:
        raise SceneError([Diagnostic("nothing to fit: the scene has no `vary`", at_scene,
                                     "free a parameter with `vary NAME in LOW .. HIGH` (docs/goals.md)")])
    if not scene.goals:
        raise SceneError([Diagnostic("nothing to fit: the scene has no `goal`", at_scene,
                                     "say what must happen, e.g. `goal hit: ball.position at 1 s = (2, 0, 0) m "
                                     "within 1 mm` (docs/goals.md)")])
    if args.workers is not None and args.scheduler:
        raise SceneError([Diagnostic("--workers N is the size of a local cluster: not with --scheduler", None,
                                     "the cluster's own workers run the fit's runs")])
    check_workers(args.workers)
    if args.scheduler:
        check_scheduler_address(args.scheduler)


def _runs(args, folder: Path, limits, dask_runs, local_runs):
    from isaac_runtime.run import RunOptions

    options = RunOptions(folder=folder, max_constraint_error=None)
    if args.workers is not None or args.scheduler:
        return dask_runs(Path(args.scene), options, args.workers, args.scheduler)
    return local_runs(Path(args.scene), options, limits)


def say_values(varies: tuple, point: list, search, verbosity: int) -> None:
    from isaac.fit.solve import format_value

    if verbosity < -1:
        return
    values = ", ".join(f"{v.name} = {format_value(x, v)}" for v, x in zip(varies, point))
    print(f"fit: {values} ({search.evaluator.count} runs, {search.iterations} iterations; "
          f"{' then '.join(search.methods)})")


def fitted_run(args, varies, point, search, overrides, limits, out: Path, verbosity: int) -> int:
    """The scene run at the values found, as `isaac run` runs it, with fit.json added to its outputs."""
    from isaac.fit.evaluate import overrides_at
    from isaac_lang.load import load_scene
    from isaac_runtime.outputs import write_json
    from isaac_runtime.run import RunOptions, run_scene

    scene = load_scene(Path(args.scene), overrides_at(varies, point, overrides), limits).scene
    options = RunOptions(folder=Path(args.scene).parent, viewer=args.viewer, verbosity=min(verbosity, 0),
                         strict=args.strict)
    said = {}

    def add_fit_json(folder: Path, result) -> list:
        said["goals"] = result.report.get("goals", [])
        document = fit_document(varies, point, said["goals"], search)
        write_json(folder / "fit.json", document)
        return [folder / "fit.json"]

    code = run_scene(scene, out, options, scene_path=Path(args.scene), more=add_fit_json)
    missed = [g for g in said.get("goals", []) if not g["met"]]
    if missed:
        from isaac_runtime.outputs.goals import describe_miss

        print(f"{args.scene}: fit: {len(missed)} goal{'s' if len(missed) > 1 else ''} not met: "
              + "; ".join(describe_miss(g) for g in missed), file=sys.stderr)
        return EXIT_TOLERANCE
    return code


def fit_document(varies, point, goals: list, search) -> dict:
    """fit.json."""
    from isaac.fit.solve import format_value

    return {
        "parameters": {v.name: float(x) for v, x in zip(varies, point)},
        "parameters_as_written": {v.name: format_value(x, v) for v, x in zip(varies, point)},
        "goals": [{key: g[key] for key in ("name", "met", "error", "tolerance", "value", "target")} for g in goals],
        "met": bool(goals) and all(g["met"] for g in goals),
        "runs": search.evaluator.count,
        "iterations": search.iterations,
        "methods": search.methods,
    }
