"""Constraint parameters that are functions of time (issue 15): a world plane's point and normal, a world axis of
`orient`, a gear's radius; each carried exactly (RK4 at 1 ms), and a clear error where a parameter cannot move."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_runtime.core.rotation import quat_to_matrix
from isaac.api import Simulation

MOVING = """scene m {
  time 0 s .. 5 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  body bead sphere { radius 1 cm  mass 0.1 kg  velocity (0, 0.1, 0) m/s }
  constraint lift plane(bead @ (0, 0, 0), (0, 0.1 * sin(t), 0) m, y)
  body disc cylinder { radius 10 cm  length 1 cm  mass 1 kg  at (1, 0, 0)  spin (0, 0, 1) rad/s }
  constraint turn orient(disc.x, (-sin(t), cos(t), 0))
  body tilt sphere { radius 1 cm  mass 0.1 kg  at (0, 0, 2) }
  constraint slope plane(tilt @ (0, 0, 0), (0, 0, 2) m, (sin(0.3 * t), cos(0.3 * t), 0))
  body g1 cylinder { radius 10 cm  length 1 cm  mass 1 kg  at (2, 0, 0) }
  body g2 cylinder { radius 10 cm  length 1 cm  mass 1 kg  at (3, 0, 0)  spin (0, 0, 1) rad/s }
  constraint pins nail(g1 @ (0, 0, 0)) + nail(g2 @ (0, 0, 0))
  constraint mesh gear(g1, 0.1 m + 0.05 m/s * t, g2, 10 cm)
}"""


@pytest.mark.parametrize("solver,tolerance,speed", [(None, 1e-9, 1e-8), ("procedural", 1e-6, 1e-4)])
def test_moving_constraint_parameters_are_carried_exactly(solver, tolerance, speed):
    sim = Simulation.from_text(MOVING, **({"solver": solver} if solver else {}))
    worst = {"plane": 0.0, "orient": 0.0, "normal": 0.0, "gear": 0.0}
    while sim.state.t < 5.0 - 1e-9:
        sim.advance_to(sim.state.t + 0.01)
        t, x = sim.state.t, sim.state.x
        worst["plane"] = max(worst["plane"], abs(x[0, 1] - 0.1 * math.sin(t)))
        axis = quat_to_matrix(sim.state.q[1])[:, 0]
        worst["orient"] = max(worst["orient"], abs(axis @ [-math.sin(t), math.cos(t), 0.0]))
        normal = np.array([math.sin(0.3 * t), math.cos(0.3 * t), 0.0])
        worst["normal"] = max(worst["normal"], abs(normal @ (x[2] - [0.0, 0.0, 2.0])))
        # r1(t) w1 + r2 w2 = 0
        worst["gear"] = max(worst["gear"], abs((0.1 + 0.05 * t) * sim.state.w[3, 2] + 0.1 * sim.state.w[4, 2]))
    assert max(worst.values()) <= tolerance, worst
    # the bead rides the plane up and down, with the plane's velocity (the procedural plan's velocities come
    # from its positions: first order in the substep)
    assert sim.state.v[0, 1] == pytest.approx(0.1 * math.cos(5.0), abs=speed)


@pytest.mark.parametrize("text,message", [
    ("constraint c point(a @ (0, 0.1 * t, 0), b @ (0, 0, 0))", "cannot change over time"),
    ("constraint c orient(a.x, (0, 2 * cos(t), 0))", "must stay of length 1"),
    ("constraint c gear(a, 0.1 m - 0.1 m/s * t, b, 10 cm)", "must stay positive"),
])
def test_parameters_that_cannot_move_so_say_where(text, message):
    scene = f"""scene e {{
      body a sphere {{ radius 1 cm  mass 1 kg }}
      body b sphere {{ radius 1 cm  mass 1 kg  at (1, 0, 0) }}
      {text}
    }}"""
    with pytest.raises(SceneError) as caught:
        load_text(scene)
    [diagnostic] = caught.value.diagnostics
    assert message in diagnostic.message and diagnostic.pos.line == 4


# ---- motion that changes over time: `kinematic A .. B` ---------------------------------------------------------

WINDOWS = """scene r {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  body ball sphere { radius 5 cm  mass 1 kg  at (0.5 m/s * t, 1 m + 2 m/s * t, 0 m)  kinematic 0 s .. 0.5 s }
  body hand sphere { radius 5 cm  mass 1 kg  at (3 m + 0.1 m/s * t, 0 m, 0 m)  kinematic 1 s .. 1.5 s }
}"""


def test_a_keyframed_body_released_flies_on_ballistically_from_the_paths_velocity():
    sim = Simulation.from_text(WINDOWS)
    for t in (0.25, 0.5, 0.75, 1.0, 2.0):
        sim.advance_to(t)
        s = max(t - 0.5, 0.0)  # time since the release
        on_path = np.array([0.5 * min(t, 0.5), 1.0 + 2.0 * min(t, 0.5), 0.0])
        expected = on_path + np.array([0.5 * s, 2.0 * s - 0.5 * 9.81 * s * s, 0.0])
        assert np.abs(sim.state.x[0] - expected).max() <= 1e-12


def test_a_dynamic_body_is_caught_onto_its_path_and_released_again():
    sim = Simulation.from_text(WINDOWS)
    sim.advance_to(1.0)
    assert sim.state.x[1] == pytest.approx([3.1, 0.0, 0.0], abs=1e-12)  # it fell, then was put on its path
    sim.advance_to(1.5)
    assert sim.state.x[1] == pytest.approx([3.15, 0.0, 0.0], abs=1e-12)
    assert sim.state.v[1] == pytest.approx([0.1, 0.0, 0.0], abs=1e-12)
    sim.advance_to(2.0)
    assert sim.state.x[1] == pytest.approx([3.2, -0.5 * 9.81 * 0.25, 0.0], abs=1e-12)


def test_a_window_on_a_static_body_is_refused():
    with pytest.raises(SceneError) as caught:
        load_text("scene s { body a static box { size (1, 1, 1)  kinematic 0 s .. 1 s } }")
    assert "for a dynamic body" in caught.value.diagnostics[0].message
