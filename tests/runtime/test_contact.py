"""Contact in the step (issue 14), against exact answers, in both plans: static friction holds position as well
as velocity, sliding stops where Coulomb says, rolling goes at 5/7 g sin(theta) without slip, a stack stands,
a pair joined by a constraint collides once the constraint ends, and still air is air."""
from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.plan import compile_plan
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"
G = 9.81
PLANS = [None, "procedural"]


@functools.lru_cache(maxsize=None)
def finished(name: str, solver: str | None):
    """The simulation of scenes/NAME.isaac run to its end, with the positions it started from."""
    sim = Simulation.from_file(SCENES / f"{name}.isaac", **({"solver": solver} if solver else {}))
    start = sim.state.x.copy()
    sim.advance_to(sim.plan.end)
    return sim, start


@pytest.mark.parametrize("solver,creep", [(None, 1e-9), ("procedural", 1e-6)])
def test_static_friction_holds_a_block_on_a_slope(solver, creep):
    sim, start = finished("slope", solver)
    assert np.abs(sim.state.x - start).max() <= creep
    assert np.abs(sim.state.v).max() <= 1e-9
    modes = {c.mode for c in sim.collider.lasting.contacts.values()}
    assert modes == {"stick"} and len(sim.collider.lasting.contacts) == 4


@pytest.mark.parametrize("solver,tolerance", [(None, 1e-5), ("procedural", 1e-3)])
def test_a_sliding_box_stops_where_coulomb_says(solver, tolerance):
    sim, start = finished("slide", solver)
    mu, v0 = 0.3, 2.0
    distance = v0 ** 2 / (2 * mu * G)
    travelled = sim.state.x[1, 0] - start[1, 0]
    assert travelled == pytest.approx(distance, rel=tolerance)
    assert np.abs(sim.state.v[1]).max() <= 1e-9  # and stays: it sticks
    assert abs(sim.state.x[1, 1] - 0.05) <= 1e-9 and np.abs(sim.state.x[1, 2]) <= 1e-9


def _rolling(solver):
    sim = Simulation.from_file(SCENES / "roll.isaac", **({"solver": solver} if solver else {}))
    theta, r = math.radians(20), 0.05
    down = np.array([math.cos(theta), -math.sin(theta), 0.0])
    normal = np.array([math.sin(theta), math.cos(theta), 0.0])
    times, speeds, slips = [], [], []
    while sim.state.t < sim.plan.end - 1e-9:
        sim.advance_to(sim.state.t + 0.01)
        times.append(sim.state.t)
        speeds.append(sim.state.v[1] @ down)
        # the contact point's velocity: v + w x (-r n)
        slips.append(np.linalg.norm(sim.state.v[1] + np.cross(sim.state.w[1], -r * normal)))
    return np.array(times), np.array(speeds), np.array(slips)


@pytest.mark.parametrize("solver,tolerance,slip", [(None, 1e-6, 1e-8), ("procedural", 1e-6, 1e-8)])
def test_a_ball_rolls_down_an_incline_at_five_sevenths_g_sin_theta(solver, tolerance, slip):
    times, speeds, slips = _rolling(solver)
    a = 5 / 7 * G * math.sin(math.radians(20))
    assert np.polyfit(times, speeds, 1)[0] == pytest.approx(a, rel=tolerance)
    assert np.abs(speeds - a * times).max() <= tolerance * a * times[-1]
    assert slips.max() <= slip


@pytest.mark.parametrize("solver", PLANS)
def test_a_stack_of_ten_boxes_stands_still_for_ten_seconds(solver):
    sim, start = finished("tower", solver)
    assert np.abs(sim.state.x - start).max() <= 1e-6
    assert len(sim.collider.lasting.contacts) == 40 and not sim.events


@pytest.mark.parametrize("solver,when", [(None, 1e-6), ("procedural", 1e-3)])  # (its first-order fall)
def test_a_ball_falls_on_the_table_once_the_joint_that_held_it_ends(solver, when):
    sim, _ = finished("release", solver)
    assert sim.state.x[1, 1] == pytest.approx(0.05, abs=2e-3)
    assert abs(sim.state.x[1, 1] - 0.05) <= 1e-9  # (exactly, in fact)
    impacts = [e for e in sim.events if e["kind"] == "impact"]
    assert impacts and impacts[0]["time"] == pytest.approx(0.5 + math.sqrt(2 * 0.25 / G), abs=when)


def test_isaac_plan_shows_the_joined_pair_can_touch():
    plan = compile_plan(load_text((SCENES / "release.isaac").read_text()).scene)
    assert plan.collisions is not None and plan.collisions.pairs == 1


# ---- exclusion follows time -----------------------------------------------------------------------------------

WINDOWED = """scene w {
  time 0 s .. 1 s
  gravity (0, -9.81, 0) m/s2
  body table static box { size (1, 0.1, 1)  at (0, -0.05, 0) }
  body ball sphere { radius 5 cm  mass 0.2 kg  at (0, 0.05, 0) }
  exclude ball, table during 0.2 s .. 0.3 s
}"""


def test_an_exclude_with_a_window_lets_the_pair_pass_through_only_inside_it():
    sim = Simulation.from_text(WINDOWED)
    sim.advance_to(0.2)
    assert abs(sim.state.x[1, 1] - 0.05) <= 1e-12  # resting on the table
    sim.advance_to(0.3)
    # falling freely through the table for 0.1 s
    assert sim.state.x[1, 1] == pytest.approx(0.05 - 0.5 * G * 0.1 ** 2, abs=1e-9)
    assert sim.state.v[1, 1] == pytest.approx(-G * 0.1, abs=1e-9)
    sim.advance_to(1.0)
    assert sim.state.x[1, 1] == pytest.approx(0.05, abs=1e-9)  # the table holds it again


# ---- still air ------------------------------------------------------------------------------------------------

FALL = """scene fall {
  time 0 s .. 30 s
  gravity (0, -9.81, 0) m/s2
  %s
  solver dynamics { integrator rk4  step 1 ms }
  body ball sphere { radius 10 cm  mass 0.5 kg  drag 0.47  at (0, 0, 0) }
}"""


@pytest.mark.parametrize("solver", PLANS)
@pytest.mark.parametrize("air", [None, 0.9])
def test_drag_in_still_air_reaches_the_terminal_velocity(solver, air):
    text = FALL % (f"air {air} kg/m3" if air else "")
    sim = Simulation.from_text(text, **({"solver": solver} if solver else {}))
    sim.advance_to(30.0)
    rho = air or 1.2
    terminal = math.sqrt(2 * 0.5 * G / (rho * 0.47 * math.pi * 0.1 ** 2))
    assert -sim.state.v[0, 1] == pytest.approx(terminal, rel=1e-6)


def test_a_body_without_drag_falls_freely_in_still_air():
    sim = Simulation.from_text(FALL.replace("drag 0.47  ", "") % "")
    assert sim.plan.forces.wind is None  # a scene pays only for what it uses
    sim.advance_to(2.0)
    assert sim.state.v[0, 1] == pytest.approx(-2 * G, rel=1e-12)


# ---- units and warnings -----------------------------------------------------------------------------------------

SPIN = """let g = 9.81 m/s2
let L = 1 m
scene s {
  gravity (0, 0, 0) m/s2
  body top box { size (1, 1, 1)  mass 1 kg  spin (0, %s, 0) }
}"""


def test_a_spin_given_as_a_frequency_is_an_angular_velocity():
    scene = load_text(SPIN % "sqrt(g / L)").scene
    assert scene.bodies[0].angular_velocity[1] == pytest.approx(math.sqrt(9.81))


def test_a_spin_in_hertz_is_refused_with_the_factor_in_the_hint():
    from isaac_ir.diagnostics import SceneError

    with pytest.raises(SceneError) as caught:
        load_text(SPIN % "2 Hz")
    [diagnostic] = caught.value.diagnostics
    assert "Hz counts cycles" in diagnostic.message and "2 pi rad/s" in diagnostic.hint


def test_properties_that_nothing_uses_are_warnings():
    loaded = load_text("""scene u {
      air 1.0 kg/m3
      body floor static box { size (1, 1, 1)  drag 1.1 }
      body ball sphere { radius 1 cm  mass 1 g  drag 0.3  wind off }
    }""")
    text = "\n".join(loaded.warnings)
    assert "`floor` is static: the air's drag on it is not used" in text
    assert "`ball` has `wind off`: its `drag` and `area` are not used" in text
    assert "the scene's `air` (1 kg/m3) is not used" in text
