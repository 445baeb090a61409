"""Bodies that start touching and approaching: the first instant is an impact, with Newton's restitution and the
momentum kept, in both plans. Found 2026-12-07: the exact path took such a pair as a lasting contact, and the
row, or the pair, moved off together (a striker placed against three balls at 2 m/s: all four at 0.5 m/s; two
boxes on a floor, one pushed against the other: both stopped within 10 ms, their momentum lost).

Exact answers: two spheres of equal mass, one at v against one at rest, restitution e: (1 - e) v / 2 and
(1 + e) v / 2. A striker against a touching row with e = 1: the striker and the row stop, the last ball leaves at
v (the momentum handed along, as Newton's cradle does). A ball touching a floor and moving down at u with
restitution e: it leaves at e u and rises (e u)^2 / (2 g)."""
from __future__ import annotations

import numpy as np
import pytest

from isaac.api import Simulation

PLANS = {"dynamics": "solver dynamics { integrator rk4  step 1 ms }",
         "procedural": "solver procedural { step 10 ms  substeps 10 }"}
G = 9.81


def run(plan: str, bodies: str, restitution: float, gravity: float, until: float = 0.3) -> Simulation:
    text = (f"scene start {{\n  time 0 s .. {until} s\n  gravity (0, {-gravity}, 0) m/s2\n  {PLANS[plan]}\n"
            f"  material m {{ density 7800 kg/m3  friction 0.3  restitution {restitution} }}\n{bodies}\n}}\n")
    sim = Simulation.from_text(text)
    sim.advance_to(until)
    return sim


def velocity(sim: Simulation, name: str) -> np.ndarray:
    return sim.state.y[sim.plan.names.index(name), 7:10]


@pytest.mark.parametrize("plan", PLANS)
@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_a_sphere_that_starts_against_another_strikes_it(plan, e):
    bodies = ("  body striker sphere { radius 5 cm  material m  at (-0.1, 0, 0) m  velocity (1.6, 0, 0) m/s }\n"
              "  body struck sphere { radius 5 cm  material m  at (0, 0, 0) m }")
    sim = run(plan, bodies, e, 0.0)
    assert velocity(sim, "striker")[0] == pytest.approx((1 - e) * 0.8, abs=1e-9)
    assert velocity(sim, "struck")[0] == pytest.approx((1 + e) * 0.8, abs=1e-9)
    impacts = [event for event in sim.events if event["kind"] == "impact"]
    assert impacts and impacts[0]["time"] == 0.0


@pytest.mark.parametrize("plan", PLANS)
def test_a_striker_against_a_touching_row_hands_its_momentum_to_the_last_ball(plan):
    row = "\n".join(f"  body b{k} sphere {{ radius 5 cm  material m  at ({0.1 * k}, 0, 0) m }}" for k in range(4))
    bodies = "  body striker sphere { radius 5 cm  material m  at (-0.1, 0, 0) m  velocity (2, 0, 0) m/s }\n" + row
    sim = run(plan, bodies, 1.0, 0.0)
    for name in ("striker", "b0", "b1", "b2"):
        assert np.linalg.norm(velocity(sim, name)) < 1e-9
    assert velocity(sim, "b3") == pytest.approx([2.0, 0.0, 0.0], abs=1e-9)


@pytest.mark.parametrize("plan", PLANS)
def test_a_ball_that_starts_on_the_floor_moving_down_bounces(plan):
    e, u = 0.5, 1.0
    bodies = ("  body floor plane { material m }\n"
              "  body ball sphere { radius 5 cm  material m  at (0, 0.05, 0) m  velocity (0, -1, 0) m/s }")
    sim = Simulation.from_text(
        f"scene start {{\n  time 0 s .. 0.3 s\n  frames 1000 Hz\n  gravity (0, -9.81, 0) m/s2\n  {PLANS[plan]}\n"
        f"  material m {{ density 7800 kg/m3  friction 0.3  restitution {e} }}\n{bodies}\n}}\n")
    top = 0.0
    for k in range(1, 101):
        sim.advance_to(k * 1e-3)
        top = max(top, sim.state.y[sim.plan.names.index("ball"), 1] - 0.05)
    # (e u)^2 / (2 g) = 12.74 mm; the peak at t = e u / g = 51 ms, sampled every 1 ms (g (1 ms)^2 / 8 = 1.2 um
    # low at most); the procedural plan's flight in substeps of 1 ms peaks 25 um low
    assert top == pytest.approx((e * u) ** 2 / (2 * G), abs=2e-6 if plan == "dynamics" else 4e-5)
