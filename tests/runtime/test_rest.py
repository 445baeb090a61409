"""Steps at rest (core/rest.py): once every body has stood still for a few steps with constant inputs, the step
loops stop integrating, and the run is the one that integrating every step gives, to the bounds of rest; anything
that moves, or an input that changes, integrates as before."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from isaac_runtime.core.data import COUNTER_RESTING
from isaac_runtime.core.rest import REST_ACCELERATION, REST_SPEED, REST_STEPS
from isaac_runtime.dynamics import DynamicsStepper
from isaac_runtime.procedural import ProceduralStepper
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"
G = 9.81

# a box on a floor, pushed from t = 1 s by 5 N against friction 0.5: at rest, then x = (F / m - mu g) (t - 1)^2 / 2
PUSHED = """scene pushed {
  time 0 s .. 2 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  material wood { friction 0.5  restitution 0 }
  body floor plane { material wood }
  body box box { size (20 cm, 20 cm, 20 cm)  mass 1 kg  material wood  at (0, 10 cm, 0) }
  force push load(box) { force (5 * step(1 s, t), 0, 0) N }
}"""

PENDULUM = """scene hanging {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  body bob sphere { radius 2 cm  mass 1 kg  at (%s, %s, 0) m  collide off }
  constraint nail nail(bob @ (%s, %s, 0) m, (0, 0, 0))
}"""


def resting(sim) -> int:
    return int(sim.compiled.scratch.counters[COUNTER_RESTING])


def run(monkeypatch, rest: bool, path=None, text=None, frames=False, **options):
    """The scene run to its end, in one advance or (`frames`) one frame at a time (a call of the loop each, as the
    audio stage and the live mode step)."""
    for stepper in (DynamicsStepper, ProceduralStepper):
        monkeypatch.setattr(stepper, "rest_after", REST_STEPS if rest else 0)
    sim = Simulation.from_file(path, **options) if path is not None else Simulation.from_text(text, **options)
    for t in (sim.plan.frame_times[1:] if frames else [sim.plan.end]):
        sim.advance_to(float(t))
    monkeypatch.undo()
    return sim


@pytest.mark.parametrize("solver", ["dynamics", "procedural"])
def test_a_tower_at_rest_is_left_standing_as_integrating_it_leaves_it(monkeypatch, solver):
    at_rest = run(monkeypatch, True, SCENES / "tower.isaac", solver=solver)
    stepped = run(monkeypatch, False, SCENES / "tower.isaac", solver=solver)
    steps = at_rest.state.steps
    assert resting(stepped) == 0 and resting(at_rest) >= steps - 3 * REST_STEPS  # (each call finds rest afresh)
    T = at_rest.plan.end
    # a body left standing moves at most REST_SPEED T + REST_ACCELERATION T^2 / 2 less than an integrated one
    bound = REST_SPEED * T + 0.5 * REST_ACCELERATION * T * T
    assert np.abs(at_rest.state.x - stepped.state.x).max() <= bound
    assert np.abs(at_rest.state.v - stepped.state.v).max() <= REST_SPEED
    # the contact events (one a frame for each pressing pair) are the same, with the same impulses
    ours, theirs = at_rest.events, stepped.events
    assert [(e["time"], e["bodies"]) for e in ours] == [(e["time"], e["bodies"]) for e in theirs]
    assert np.allclose([e["impulse"] for e in ours], [e["impulse"] for e in theirs], rtol=1e-9, atol=0)


def test_a_push_that_starts_later_wakes_the_box_on_time(monkeypatch):
    at_rest = run(monkeypatch, True, text=PUSHED)
    stepped = run(monkeypatch, False, text=PUSHED)
    assert 1000 - 2 * REST_STEPS <= resting(at_rest) < 1000  # still until the push, then integrated
    assert np.abs(at_rest.state.x - stepped.state.x).max() <= 1e-12
    assert np.abs(at_rest.state.v - stepped.state.v).max() <= 1e-12
    # it slides from 1 s on: x = (F / m - mu g) (t - 1)^2 / 2 = 4.75 cm at 2 s, but for the RK4 stage at 1 s that
    # sees the push a step early (F h / 6 = 0.83 mN s more: 0.83 mm more by 2 s)
    moved = at_rest.state.x[1, 0] - Simulation.from_text(PUSHED).state.x[1, 0]
    assert moved == pytest.approx(0.5 * (5.0 - 0.5 * G) + 5.0 * 1e-3 / 6, rel=1e-3)


def test_a_pendulum_rests_only_where_it_hangs_at_rest(monkeypatch):
    hanging = run(monkeypatch, True, text=PENDULUM % (0, -1, 0, 1))
    assert resting(hanging) == hanging.state.steps - REST_STEPS  # an equilibrium from the start
    swinging = run(monkeypatch, True, text=PENDULUM % (1, 0, -1, 0))  # at rest at its turning points, never still
    assert resting(swinging) == 0


def test_a_scene_in_the_wind_is_never_left_at_rest():
    # (the gusts are functions of time computed inside the kernel: constant table rows do not make them constant)
    sim = Simulation.from_file(SCENES / "mobile.isaac", until=1.0)
    sim.advance_to(1.0)
    assert resting(sim) == 0


# a ball held still above a table by a constraint until 0.5 s, run a frame (a call of the loop) at a time, as the
# audio stage steps a scene with sound: rest is carried from call to call; the release must drop it on time
RELEASED = """scene released {
  time 0 s .. 1 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  solver %s
  material felt { friction 0.5  restitution 0 }
  body table static box { size (1, 0.1, 1)  at (0, -0.05, 0)  material felt }
  body ball sphere { radius 5 cm  mass 0.2 kg  at (0, 30 cm, 0)  material felt }
  constraint hold point(ball @ (0, 0, 0), table @ (0, 0.35, 0)) until 0.5 s
}"""


@pytest.mark.parametrize("solver", ["dynamics { integrator rk4  step 1 ms }", "procedural { step 1 ms }"])
def test_rest_is_carried_from_call_to_call_and_a_release_drops_the_ball_on_time(monkeypatch, solver):
    text = RELEASED % solver
    at_rest = run(monkeypatch, True, text=text, frames=True)
    stepped = run(monkeypatch, False, text=text, frames=True)
    # held still until 0.5 s: nearly every step of it at rest, though each call is a frame of 10 steps
    assert 500 - 3 * REST_STEPS <= resting(at_rest) <= 1000
    impact = [e["time"] for e in at_rest.events if e["kind"] == "impact"]
    # released at 0.5 s from 25 cm above the table: it lands sqrt(2 0.25 / g) later
    assert impact and impact[0] == pytest.approx(0.5 + math.sqrt(2 * 0.25 / G), abs=2e-3)
    assert impact[0] == pytest.approx([e["time"] for e in stepped.events if e["kind"] == "impact"][0], abs=1e-9)
    assert np.abs(at_rest.state.x - stepped.state.x).max() <= 1e-9
