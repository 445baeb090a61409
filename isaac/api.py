"""The embedding API (docs/api.md): a Simulation built from a scene file or from text, which re-plans itself when a
parameter changes. The engine's Simulation (isaac_runtime.simulation) steps a plan and knows nothing of scene text;
this one remembers where its scene came from, so that `set_parameter` can load and plan it again."""

from __future__ import annotations

from pathlib import Path

from isaac_lang.load import load_scene, load_text
from isaac_runtime import simulation as engine
from isaac_runtime.plan import Plan, PlanOptions, compile_plan
from isaac_runtime.run import RunOptions, simulate  # noqa: F401 (the API's other half: a whole run in process)


def plan_file(path, overrides: dict | None = None, **options) -> Plan:
    """The plan of the scene file at `path`, its `let`s overridden (NAME -> value text, as `--set` gives them)."""
    scene = load_scene(Path(path), overrides).scene
    return compile_plan(scene, PlanOptions(folder=Path(path).parent, **options))


def plan_text(text: str, overrides: dict | None = None, folder=".", **options) -> Plan:
    """The plan of a scene given as text; includes and assets are found from `folder`."""
    scene = load_text(text, overrides=overrides, folder=folder).scene
    return compile_plan(scene, PlanOptions(folder=Path(folder), **options))


class Simulation(engine.Simulation):
    """A Simulation of a scene file or text (module docstring); everything else is the engine's."""

    def __init__(self, plan: Plan, replan=None, overrides: dict | None = None):
        super().__init__(plan)
        self._replan = replan  # overrides -> the plan of the same scene with them
        self.overrides = dict(overrides or {})

    @classmethod
    def from_file(cls, path, overrides: dict | None = None, **options) -> "Simulation":
        return cls(plan_file(path, overrides, **options), lambda changed: plan_file(path, changed, **options),
                   overrides)

    @classmethod
    def from_text(cls, text: str, overrides: dict | None = None, folder=".", **options) -> "Simulation":
        return cls(plan_text(text, overrides, folder, **options),
                   lambda changed: plan_text(text, changed, folder, **options), overrides)

    def set_parameter(self, name: str, value: str) -> None:
        """Change a scene parameter (a `let`) mid-run: the scene is lowered and planned again, and every body
        that still exists keeps its current state."""
        overrides = {**self.overrides, name: value}
        self.carry_on(self._replan(overrides))
        self.overrides = overrides
