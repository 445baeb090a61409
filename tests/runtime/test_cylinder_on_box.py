"""A cylinder lying on its side on a box rests there: its centre one radius above the face, still, in both plans.

Found 2026-12-07: the exact path tests a cylinder against a box with python-fcl, which gives one point of deepest
contact. A cylinder dropped on its side 2 to 4 cm off the centre of a static box settled, then rolled off by
itself after 0.8 s (its spin growing tenfold every 0.16 s) and sank to its axis, 28 to 50 mm deep, exit 0. The
capturing path tests the pair in closed form, with a point at each end of the line it rests on: the exact path
now hands such a pair over to it when they touch (collide/collider.py `_one_point_only`)."""
from __future__ import annotations

import numpy as np
import pytest

from isaac.api import Simulation

PLANS = {"dynamics": "solver dynamics { integrator rk4  step 1 ms }",
         "procedural": "solver procedural { step 10 ms  substeps 10 }"}
TOP = 0.1  # the box's top face (m)


@pytest.mark.parametrize("plan", PLANS)
@pytest.mark.parametrize("radius, offset, restitution", [(0.028, -0.023, 0.6), (0.05, -0.04, 0.0)])
def test_a_cylinder_on_its_side_rests_on_a_box(plan, radius, offset, restitution):
    sim = Simulation.from_text(
        f"scene rest {{\n  time 0 s .. 2 s\n  frames 100 Hz\n  gravity (0, -9.81, 0) m/s2\n  {PLANS[plan]}\n"
        f"  material m {{ density 300 kg/m3  friction 1.0  restitution {restitution} }}\n"
        "  body floor plane { material m }\n"
        "  body base static box { size (0.3, 0.1, 0.3) m  material m  at (0, 0.05, 0) m }\n"
        f"  body can cylinder {{ radius {radius} m  length 0.08 m  material m  at ({offset}, {TOP + radius + 0.04}, 0) m }}\n}}\n")
    can = sim.plan.names.index("can")
    lowest = np.inf
    for k in range(1, 21):
        sim.advance_to(0.1 * k)
        if k >= 5:  # (landed by 0.1 s; bounced and settled by 0.5 s)
            lowest = min(lowest, sim.state.y[can, 1])
    assert lowest == pytest.approx(TOP + radius, abs=1e-4)
    assert np.abs(sim.state.y[can, 7:13]).max() < 1e-3
    assert sim.state.y[can, 0] == pytest.approx(offset, abs=1e-3)
    report = sim.contact_report()
    assert report["path"] == "capturing" and "closed form" in report["why"]
