"""runtime/checks.py: the settling windows after switch-ons, and the settled constraint error a run is held to."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime import checks
from isaac_runtime.plan import compile_plan

SCENE = """scene s {
  time 0 s .. 5 s
  body a sphere { radius 5 cm  mass 1 kg  at (-0.25, 0, 0) }
  body b sphere { radius 5 cm  mass 1 kg  at (0.25, 0, 0) }
  exclude a, b
  constraint join point(a @ (0.05, 0, 0), b @ (-0.05, 0, 0)) from 1 s { stabilize 2 Hz  damping 1 }
  constraint hold nail(a) + nail(b) until 1 s
}
"""


def test_a_window_after_every_switch_on_ten_decay_times_long():
    scene = load_text(SCENE, "s.isaac").scene
    windows = checks.settling_windows(scene, compile_plan(scene))
    # hold: from the start, at the default 10 Hz, critically damped: 10 / (2 pi 10) s; join: 10 / (2 pi 2) s
    assert windows == [pytest.approx((0.0, 10 / (2 * math.pi * 10))), pytest.approx((1.0, 1 + 10 / (2 * math.pi * 2)))]


def test_an_overdamped_row_decays_at_its_slow_root():
    scene = load_text(SCENE.replace("damping 1", "damping 2"), "s.isaac").scene
    (_, (start, end)) = checks.settling_windows(scene, compile_plan(scene))
    omega, zeta = 2 * math.pi * 2, 2.0
    assert end - start == pytest.approx(10 / (omega * (zeta - math.sqrt(zeta ** 2 - 1))))


def test_the_settled_error_skips_the_windows():
    time = np.linspace(0, 3, 31)
    error = np.where((time >= 1) & (time < 1.5), 0.4, 1e-9)
    assert checks.settled_error(time, error, [(1.0, 1.5)]) == (pytest.approx(1e-9), 0.0)
    assert checks.settled_error(time, error, []) == (0.4, pytest.approx(1.0))
    assert checks.settled_error(time, error, [(0.0, 3.1)]) == (None, None)  # too short a run to tell


def test_the_check_of_a_report():
    report = {"constraint_error_settled": 0.5, "constraint_error_settled_time": 2.0}
    assert checks.constraint_check(report, 0.1) == {"limit": 0.1, "value": 0.5, "time": 2.0, "ok": False,
                                                    "constraints": []}
    assert checks.constraint_check(report, None)["ok"] and checks.constraint_check(report, 1.0)["ok"]


# -- constraints no pose satisfies (checks.unsatisfiable), before the first step -------------------------------------

BOB = """scene s {
  time 0 s .. 3 s
  body bob box { size (0.1, 0.1, 0.1) m  mass 1 kg  at (1, 0, 0) }
%s
}
"""


def unsatisfiable(lines: str, solver: str = "dynamics", limit=checks.DEFAULT_MAX_CONSTRAINT_ERROR, turned=None):
    from isaac_runtime.plan import PlanOptions
    from isaac.api import Simulation

    text = BOB % lines
    if turned:
        text = text.replace("at (1, 0, 0) }", f"at (1, 0, 0)  orient {turned} }}")
    scene = load_text(text, "s.isaac").scene
    return checks.unsatisfiable(Simulation(compile_plan(scene, PlanOptions(solver=solver))), limit)


@pytest.fixture(params=["dynamics", "procedural"])
def solver(request):
    return request.param


def test_two_nails_that_disagree_leave_half_the_gap_each(solver):
    # one point held at two places 0.5 m apart: the closest pose is midway, 0.25 m from each
    found = unsatisfiable("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n"
                          "  constraint b nail(bob @ (-1, 0, 0), (0, 0.5, 0))", solver)
    assert found["constraints"] == ["a", "b"] and found["start"] == 0.0
    assert found["errors"] == {"a": pytest.approx(0.25, abs=1e-6), "b": pytest.approx(0.25, abs=1e-6)}


def test_two_points_of_a_body_held_too_far_apart(solver):
    # points 2 m apart on the body, targets 2.5 m apart: 0.25 m left at each end; 2 m apart they hold
    lines = "  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n  constraint b nail(bob @ (1, 0, 0), (%s, 0, 0))"
    found = unsatisfiable(lines % "2.5", solver)
    assert found["errors"] == {"a": pytest.approx(0.25, abs=1e-6), "b": pytest.approx(0.25, abs=1e-6)}
    assert unsatisfiable(lines % "2", solver) is None


def test_an_axis_perpendicular_to_all_three_world_axes_and_who_pulls_against_it():
    # a unit vector cannot be perpendicular to x, y and z: |C|^2 = (x.x)^2 + (x.y)^2 + (x.z)^2 = 1 in every pose
    # (the body starts turned, off the singular pose); the nail on the same body is no partner of theirs (without
    # it they still cannot hold)
    lines = ("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n"
             "  constraint o1 orient(bob.x, y) + orient(bob.x, z)\n  constraint o2 orient(bob.x, x)")
    found = unsatisfiable(lines, turned="(0, 0, 30)")
    assert found["constraints"] == ["o1", "o2"] and not found.get("stuck")
    assert sum(value ** 2 for value in found["errors"].values()) <= 1.0 + 1e-9
    assert max(found["errors"].values()) >= 1 / math.sqrt(3) - 1e-9  # the three squares sum to 1


def test_a_constraint_on_its_singular_pose_at_the_start_cannot_act(solver):
    # identity: body x along world x, so x.x = 1 with d(x.x)/dtheta = x cross x = 0: no motion changes it
    found = unsatisfiable("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n  constraint o orient(bob.x, x)", solver)
    assert found["stuck"] and found["constraints"] == ["o"] and found["errors"] == {"o": pytest.approx(1.0)}
    scene = load_text(BOB % "  constraint o orient(bob.x, x)", "s.isaac").scene
    assert checks.unsatisfiable_error(scene, found).format().startswith(
        "s.isaac:4:3: error: constraint `o` cannot act at the start: its error is 1 (m or rad)")
    # turned a little, it holds (the body turns the rest of the way)
    assert unsatisfiable("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n  constraint o orient(bob.x, x)",
                         solver, turned="(0, 0, 1)") is None


def test_redundant_constraints_that_agree_are_not_refused(solver):
    assert unsatisfiable("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n"
                         "  constraint o1 orient(bob.x, y)\n  constraint o2 orient(bob.x, y)", solver) is None
    assert unsatisfiable("  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n"
                         "  constraint b nail(bob @ (-1, 0, 0), (0, 0, 0))", solver) is None


def test_the_limit_decides_and_a_later_window_is_named():
    nails = "  constraint a nail(bob @ (-1, 0, 0), (0, 0, 0))\n  constraint b nail(bob @ (-1, 0, 0), (0, 0.5, 0))"
    assert unsatisfiable(nails, limit=0.3) is None and unsatisfiable(nails, limit=None) is None
    later = unsatisfiable(nails + " during 1 s .. 2 s")
    assert later["start"] == 1.0 and later["constraints"] == ["a", "b"]
    scene = load_text(BOB % (nails + " during 1 s .. 2 s"), "s.isaac").scene
    shown = checks.unsatisfiable_error(scene, later).format()
    assert shown.startswith("s.isaac:4:3: error: constraints `a` and `b` cannot both hold from t = 1 s:")
    assert "`b` is at line 5, column 3" in shown
