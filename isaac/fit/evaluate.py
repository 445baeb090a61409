"""One run of a fit: the scene loaded with the varied `let`s set to a point's values, simulated, its goals read.

A point is the varied parameters in SI. Runs go in process (`LocalRuns`) or to Dask workers (`DaskRuns`, the
scene's files sent once as a sweep's bundle); each answer is kept, so the optimizer never pays twice for a point.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from isaac_ir import units as U

# the residual of a goal that has no value at a point (no event, a state beyond a cut-short run), in tolerances:
# far, so that the optimizer leaves such points
MISSING = 1e9


@dataclass
class Outcome:
    """The goals of one run (report.json `goals`), or the problem that kept it from running."""

    goals: list | None
    problem: str | None = None

    def met(self) -> bool:
        return self.goals is not None and all(record["met"] for record in self.goals)


def override_text(value: float, dimension) -> str:
    """The `--set` text of a value in SI: `7.25 m/s`, `0.61 rad`, `0.3` (the let's own dimension)."""
    dimension = tuple(dimension)
    if dimension == U.DIMENSIONLESS:
        return repr(float(value))
    return f"{float(value)!r} {U.format_dim(dimension)}"


def overrides_at(varies: tuple, point, fixed: dict) -> dict:
    """The command line's --set values, and each varied let at the point's value."""
    values = dict(fixed)
    for vary, value in zip(varies, point):
        values[vary.name] = override_text(value, vary.dimension)
    return values


def run_at(load, values: dict, options) -> Outcome:
    """Load the scene with `values` (load(values) -> ir.Scene) and run it; its goals, or the problem."""
    from isaac_ir.diagnostics import SceneError
    from isaac_runtime.run import simulate

    try:
        result = simulate(load(values), options)
    except SceneError as error:
        return Outcome(None, error.format())
    if result.error is not None:
        return Outcome(result.report.get("goals"), f"the run blew up: {result.error}")
    return Outcome(result.report["goals"])


class LocalRuns:
    """Runs in this process, one after another."""

    def __init__(self, scene_path: Path, options, limits=None):
        self.scene_path, self.options, self.limits = Path(scene_path), options, limits

    def load(self, values: dict):
        from isaac_lang.load import load_scene

        return load_scene(self.scene_path, values, self.limits).scene

    def run_many(self, value_sets: list) -> list:
        return [run_at(self.load, values, self.options) for values in value_sets]

    def close(self) -> None:
        pass


def run_in_bundle(bundle, values: dict, options) -> Outcome:
    """On a worker: the scene unpacked from its bundle into a temporary folder, then run as run_at."""
    from isaac.sweep.bundle import unpack
    from isaac_lang.load import load_text

    with tempfile.TemporaryDirectory(prefix="isaac-fit-") as tmp:
        scene_file = unpack(bundle, Path(tmp) / "scene")
        options.folder = scene_file.parent

        def load(overrides):
            return load_text(bundle.text, name=scene_file.name, overrides=overrides, folder=scene_file.parent).scene

        return run_at(load, values, options)


class DaskRuns:
    """Runs as Dask tasks on a local cluster of `workers` processes or the cluster at `scheduler` (as a sweep's
    variants run: isaac/sweep/driver.py connect); the runs of one batch (a Jacobian's) run at once."""

    def __init__(self, scene_path: Path, options, workers: int | None, scheduler: str | None):
        from contextlib import ExitStack

        from isaac.sweep.bundle import collect
        from isaac.sweep.driver import connect

        self.options = options
        self.stack = ExitStack()
        self.client = self.stack.enter_context(connect(None, scheduler, workers))
        self.bundle = self.client.scatter(collect(scene_path), broadcast=True)

    def run_many(self, value_sets: list) -> list:
        futures = [self.client.submit(run_in_bundle, self.bundle, values, self.options, pure=False)
                   for values in value_sets]
        return self.client.gather(futures)

    def close(self) -> None:
        self.stack.close()


class Evaluator:
    """The fit's runs, counted and kept: `outcome(point)`, `outcomes(points)` (one batch, spread when it can)."""

    def __init__(self, runs, varies: tuple, fixed: dict):
        self.runs, self.varies, self.fixed = runs, varies, fixed
        self.kept: dict = {}
        self.count = 0

    def outcomes(self, points: list) -> list:
        keys = [tuple(float(v) for v in point) for point in points]
        todo = list(dict.fromkeys(key for key in keys if key not in self.kept))
        if todo:
            answers = self.runs.run_many([overrides_at(self.varies, key, self.fixed) for key in todo])
            self.count += len(todo)
            self.kept.update(zip(todo, answers))
        return [self.kept[key] for key in keys]

    def outcome(self, point) -> Outcome:
        return self.outcomes([point])[0]
