"""Motion on the capturing path against its exact answers, in both plans (a crowd of resting spheres far away makes
the run take it from its start). A body whose velocity the step changes smoothly (no impact) moves at the mean of
its velocities before and after the step (the trapezoid, capture/loop.py `_drift`), which is exact for a constant
force:

- a body in flight follows y0 + v0 t - g t^2 / 2, to round-off (moving at v+, symplectic Euler, it was
  g h t / 2 lower);
- a block sliding at v0 stops after v0^2 / (2 sqrt(mu_a mu_b) g), within 1e-3 of it (measured 2e-4 at most, at
  v0 = 1 m/s and 4 ms; moving at v+ it stopped v0 h / 2 short: 1.1 % at v0 = 0.5 m/s and 1 ms, 3.7 % at 4 ms);
- a ball landing with slip v0 and no spin leaves rolling, at 5/7 v0, spin -5/7 v0 / r, whether it stays down
  (e = 0) or bounces (e > 0: the bounce parts in the step it lands, and the friction is its impact's, within
  mu times the impact's normal impulse: capture/solve.py `_rub`).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac.api import Simulation

PLANS = {"dynamics": "solver dynamics {{ integrator rk4  step {step} }}",
         "procedural": "solver procedural {{ step {step}  substeps 10 }}"}
STEPS = {"dynamics": ("1 ms", "4 ms"), "procedural": ("10 ms", "40 ms")}
G = 9.81
# 24 spheres resting apart on a far static slab: a heap (capture.crowded), so the run is on the capturing path from
# its start, and nothing of the exact path's own integration is in the figures
CROWD = ("  material far { density 2000 kg/m3  friction 0.6  restitution 0.3 }\n"
         "  body slab static box { size (5, 0.2, 0.4) m  material far  at (0, -0.1, -3) m }\n"
         + "".join(f"  body s{k} sphere {{ radius 5 cm  material far  at ({0.2 * k - 2.3:.1f}, 0.05, -3) m }}\n"
                   for k in range(24)))


def scene(plan: str, step: str, bodies: str, until: float) -> Simulation:
    return Simulation.from_text(
        f"scene exact {{\n  time 0 s .. {until} s\n  gravity (0, -9.81, 0) m/s2\n"
        f"  {PLANS[plan].format(step=step)}\n{CROWD}{bodies}}}\n")


def row(sim: Simulation, name: str) -> np.ndarray:
    return sim.state.y[sim.plan.names.index(name)]


@pytest.mark.parametrize("plan", PLANS)
def test_a_body_in_flight_follows_its_parabola(plan):
    for step in STEPS[plan]:
        sim = scene(plan, step, "  body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) m  velocity (1, 2, 0) m/s }\n",
                    0.4)
        sim.advance_to(0.4)
        assert sim.contact_report()["path"] == "capturing"
        t = 0.4
        assert row(sim, "ball")[:3] == pytest.approx([t, 1 + 2 * t - G * t * t / 2, 0.0], abs=1e-9)


@pytest.mark.parametrize("plan", PLANS)
@pytest.mark.parametrize("v0, mu_block, mu_floor", [(0.5, 0.9, 0.8), (1.0, 1.0, 1.0), (2.5, 0.3, 0.6)])
def test_a_sliding_block_stops_where_coulomb_says(plan, v0, mu_block, mu_floor):
    for step in STEPS[plan]:
        sim = scene(plan, step,
                    f"  material blk {{ density 8000 kg/m3  friction {mu_block}  restitution 0 }}\n"
                    f"  material fl {{ density 800 kg/m3  friction {mu_floor}  restitution 0 }}\n"
                    "  body floor plane { material fl }\n"
                    f"  body block box {{ size (5, 5, 5) cm  material blk  at (0, 0.025, 0) m  velocity ({v0}, 0, 0) m/s }}\n",
                    2.0)
        sim.advance_to(2.0)
        assert sim.contact_report()["path"] == "capturing"
        distance = v0 ** 2 / (2 * math.sqrt(mu_block * mu_floor) * G)
        assert row(sim, "block")[0] == pytest.approx(distance, rel=1e-3)
        assert np.abs(row(sim, "block")[7:13]).max() < 1e-9


@pytest.mark.parametrize("plan", PLANS)
@pytest.mark.parametrize("restitution", [0.0, 0.5, 0.8])
def test_a_ball_landing_with_slip_leaves_rolling(plan, restitution):
    v0, r = 1.0, 0.05
    sim = scene(plan, STEPS[plan][0],
                f"  material m {{ density 1000 kg/m3  friction 0.8  restitution {restitution} }}\n"
                "  body floor plane { material m }\n"
                f"  body ball sphere {{ radius {r} m  material m  at (0, 0.25, 0) m  velocity ({v0}, 0, 0) m/s }}\n",
                0.3)
    sim.advance_to(0.3)  # (lands at 0.19 s)
    assert sim.contact_report()["path"] == "capturing"
    ball = row(sim, "ball")
    assert ball[7] == pytest.approx(5 / 7 * v0, abs=1e-6)
    assert ball[12] == pytest.approx(-5 / 7 * v0 / r, abs=1e-5)


@pytest.mark.parametrize("plan", PLANS)
def test_a_ball_landing_with_little_friction_slides_through_its_impact(plan):
    # too little friction to reach rolling (5/7 v0 asks 2/7 m v0 = 0.29 m N s of it, mu (1 + e) m u_n gives 0.15 m):
    # Coulomb's disc at the impact's normal impulse takes mu (1 + e) u_n off the slip, and its torque 5/2 of that
    # over r off the spin (u_n = sqrt(2 g 0.2 m), the landing speed)
    v0, r, mu, e = 1.0, 0.05, 0.05, 0.5
    sim = scene(plan, STEPS[plan][0],
                f"  material m {{ density 1000 kg/m3  friction {mu}  restitution {e} }}\n"
                "  body floor plane { material m }\n"
                f"  body ball sphere {{ radius {r} m  material m  at (0, 0.25, 0) m  velocity ({v0}, 0, 0) m/s }}\n",
                0.3)
    sim.advance_to(0.3)
    assert sim.contact_report()["path"] == "capturing"
    taken = mu * (1 + e) * math.sqrt(2 * G * 0.2)
    ball = row(sim, "ball")
    assert ball[7] == pytest.approx(v0 - taken, rel=2e-3)
    assert ball[12] == pytest.approx(-2.5 * taken / r, rel=2e-3)
