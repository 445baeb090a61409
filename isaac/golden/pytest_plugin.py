"""The pytest plugin (entry point `isaac` in the `pytest11` group): every scene with golden files in the
folders pytest collects becomes a test, `SCENE.isaac::golden`, that runs the same check as `isaac golden`.

    pytest                      # in a project: every scenes/x.isaac that has scenes/x.golden/ is checked
    pytest --isaac-update       # record the goldens again (review the diff, then commit)
    pytest -p no:isaac          # without the plugin

A mismatch fails with the report of `isaac golden` (what moved, by how much); a problem in the scene fails with
its diagnostics. Nothing heavy is imported until a scene is checked.
"""
from __future__ import annotations

from pathlib import Path

import pytest


def pytest_addoption(parser) -> None:
    group = parser.getgroup("isaac", "isaac scene goldens")
    group.addoption("--isaac-update", action="store_true", default=False,
                    help="rewrite the golden files of the collected scenes from their runs")


def pytest_collect_file(file_path: Path, parent):
    if file_path.suffix == ".isaac" and (file_path.with_name(file_path.stem + ".golden") / "ir.json").is_file():
        return SceneFile.from_parent(parent, path=file_path)
    return None


class SceneFile(pytest.File):
    """A scene with goldens: one test."""

    def collect(self):
        yield GoldenItem.from_parent(self, name="golden")


class GoldenMismatch(Exception):
    """The scene moved beyond its tolerances; the message is the report."""


class GoldenItem(pytest.Item):
    def runtest(self) -> None:
        from isaac_ir.diagnostics import SceneError, SourceCache
        from isaac.golden import check_scene

        sources = SourceCache()
        update = self.config.getoption("--isaac-update")
        try:
            outcome = check_scene(self.path, update=update, sources=sources)
        except SceneError as error:
            raise GoldenMismatch(error.format(sources)) from None
        if not outcome.ok:
            raise GoldenMismatch(outcome.text(limit=40))

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, GoldenMismatch):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, 0, f"golden: {self.path.name}"
