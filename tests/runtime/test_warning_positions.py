"""Issue 32: run-time warnings point at their cause (the constraint's or body's declaration) and print with the
line and caret; a settling warning judges only the time actually run."""
from __future__ import annotations

from types import SimpleNamespace

import pytest

from runtime import checks
from runtime.run import contact_check, contact_warnings, format_warning, too_deep_warning

SCENE_TEXT = ("scene s {\n"
              "  body a sphere { radius 5 cm  mass 1 kg }\n"
              "  body b sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) m }\n"
              "  constraint hold nail(a)\n"
              "  constraint hinge weld(a, b)\n"
              "}\n")


def declared(name, source, start=0.0, frequency=None):
    return SimpleNamespace(name=name, source=source, start=start, stabilize_frequency=frequency, damping_ratio=1.0)


def a_scene():
    return SimpleNamespace(
        constraints=[declared("hold", "s.isaac:4:3"), declared("hinge", "s.isaac:5:3")],
        bodies=[declared("a", "s.isaac:2:3"), declared("b", "s.isaac:3:3")])


def a_plan(scene):
    constraints = SimpleNamespace(names=["hold", "hinge"], row_constraint=[0, 0, 0, 1, 1, 1, 1, 1, 1])
    return SimpleNamespace(scene=scene, constraints=constraints)


def test_the_redundant_rows_warning_is_at_the_constraint():
    text = checks.redundant_warning(a_plan(a_scene()), [5, 6])
    assert text.startswith("s.isaac:5:3: redundant constraints: rows of `hinge` repeat those of other constraints")
    assert "\nhint: " in text


def test_the_conflict_warning_is_at_the_worst_constraint():
    conflict = {"constraints": ["hinge", "hold"], "errors": {"hinge": 0.2, "hold": 0.1}, "partners": [],
                "bodies": ["a"], "threshold": 0.01}
    text = checks.conflict_warning(conflict, a_scene())
    assert text.startswith("s.isaac:5:3: constraints that cannot all hold: `hinge` (0.2), `hold` (0.1) keep")
    assert text.endswith("\nhint: check their points, axes and targets (two nails that disagree, a doubled "
                         "orientation)")


def test_contact_warnings_are_at_the_first_body_of_the_pair():
    contact = {"path": "capturing", "steps_too_deep": 3, "deepest_pair": ["b", "ground"], "depth_limit": 1e-3,
               "deepest": 2e-3, "deepest_time": 0.5, "steps_creating_energy": 2, "energy_created_pair": ["a", "b"],
               "energy_created": 0.1, "energy_created_time": 0.25}
    (energy,) = contact_warnings(contact, a_scene())  # (too deep is an error: tests/lang/test_cli_conventions.py)
    assert energy.startswith("s.isaac:2:3: contact impulses created energy in 2 steps")


def test_too_deep_is_a_warning_at_the_first_body_of_the_pair_where_the_run_goes_on():
    """`isaac live` does not exit on a broken tolerance: a run deeper than the limit says so among its warnings."""
    contact = {"path": "capturing", "steps_too_deep": 3, "deepest_pair": ["b", "ground"], "depth_limit": 1e-3,
               "deepest": 2e-3, "deepest_time": 0.5, "steps_creating_energy": 0}
    report = {"contact": contact, "checks": {"contact": contact_check(contact)}}
    assert report["checks"]["contact"] == {"depth_limit": 1e-3, "deepest": 2e-3, "steps_too_deep": 3, "ok": False}
    (said,) = too_deep_warning(report, a_scene())
    assert said.startswith("s.isaac:3:3: bodies interpenetrated by more than 1 mm in 3 steps; deepest 2 mm, `b` and "
                           "`ground` at t = 0.5 s\nhint: a smaller step")
    within = {**contact, "steps_too_deep": 0, "deepest": 5e-4}
    assert too_deep_warning({"contact": within, "checks": {"contact": contact_check(within)}}, a_scene()) == []
    assert contact_check({"path": "exact"}) is None and contact_warnings(within, a_scene()) == []


def test_a_positioned_warning_prints_with_its_line_and_caret(tmp_path):
    (tmp_path / "s.isaac").write_text(SCENE_TEXT, encoding="utf-8")
    text = checks.redundant_warning(a_plan(a_scene()), [5])
    said = format_warning(text, tmp_path / "s.isaac")
    lines = said.splitlines()
    assert lines[0].startswith(f"{(tmp_path / 's.isaac').as_posix()}:5:3: warning: redundant constraints")
    assert lines[1] == "    5 |   constraint hinge weld(a, b)"
    assert lines[2] == "      |   ^"
    assert lines[3].startswith("hint: ")


def test_a_constraint_switched_on_at_the_last_frame_is_not_judged_settled():
    scene = SimpleNamespace(constraints=[declared("join", "s.isaac:5:3", start=1.0, frequency=2.0)],
                            solver=SimpleNamespace(stabilize_frequency=None, damping_ratio=1.0))
    plan = SimpleNamespace(start=0.0, end=1.0, step=1e-3)
    windows = checks.settling_windows(scene, plan)
    assert windows and windows[0][0] == 1.0
    assert not checks.outside_windows([0.5, 1.0], windows)[-1]


# -- the energy yardstick of a sweep's variants (issue 32) -----------------------------------------------------

def a_drop(height: float):
    """The plan of one ball above a static ground, as the run sees it (x0, mass, gravity, dynamic)."""
    import numpy as np

    return SimpleNamespace(x0=np.array([[0.0, 0.0, 0.0], [0.0, height, 0.0]]), v0=np.zeros((2, 3)),
                           w0=np.zeros((2, 3)), inertia_body=np.stack([np.eye(3)] * 2), mass=np.array([0.0, 2.0]),
                           gravity=np.array([0.0, -9.81, 0.0]), dynamic=np.array([False, True]))


def test_each_drop_height_has_its_own_energy_scale():
    from runtime.run import drift_scale

    low, high = drift_scale(a_drop(0.5)), drift_scale(a_drop(8.0))
    assert high == pytest.approx(2.0 * 9.81 * 8.0)
    assert high > low
    assert low == pytest.approx(2.0 * 9.81 * 1.0)  # never below the core's yardstick (m |g| 1 m for one body)
