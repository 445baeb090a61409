"""Heavy bodies on light ones, on the capturing path, in both plans: a slab on a cube 360 times lighter, and a
stack of cubes whose densities alternate between 100 and 8000 kg/m3, and a steel capsule lying across a light cube,
must stand still at their exact heights (within the position pass's slop of 0.1 mm, and 0.05 mm more), with no
contact deeper than that, and gain no energy.

Found 2026-12-07: projected Gauss-Seidel passes a heavy body's weight down through a light one a fraction
m_light / (m_heavy + m_light) per sweep, so in 16 sweeps the slab sank through the cube by 1.5 to 12 mm (exit 3),
and a stack of 8 such cubes beside a far impact drifted 2.1 mm (exit 0). Now an island that the sweeps leave
unsolved has its velocities solved whole by Newton's method (capture/newton.py): the slab and the stack rest. (The
first version solved the impulses of the rows that hold instead; on the stack they asked for negative normal
impulses, the solve was put back, and the stack sank 1.3 mm.) The capsule rocked on the one axis point nearest the
cube and sank 14 mm into it in 0.5 s; it now rests on the two sides of the face it lies across (capture/boxes.py)."""
from __future__ import annotations

import numpy as np
import pytest

from isaac.api import Simulation

from .test_capture_jointed_bounce import largest_rise

PLANS = {"dynamics 1 ms": "solver dynamics { integrator rk4  step 1 ms }",
         "dynamics 4 ms": "solver dynamics { integrator rk4  step 4 ms }",
         "procedural 4 ms": "solver procedural { step 8 ms  substeps 2 }"}


def _scene(plan: str, bodies: str, materials: str, seconds: float) -> str:
    return (f"scene ratio {{\n  time 0 s .. {seconds} s\n  frames 100 Hz\n  gravity (0, -9.81, 0) m/s2\n  {PLANS[plan]}\n"
            f"  material floor {{ density 800 kg/m3  friction 0.5  restitution 0 }}\n{materials}"
            f"  body floor plane {{ material floor }}\n{bodies}}}\n")


def _run(text: str, seconds: float):
    sim = Simulation.from_text(text)
    energy = [sim.energy()]
    for k in range(1, int(round(seconds * 100)) + 1):
        sim.advance_to(k * 0.01)
        energy.append(sim.energy())
    return sim, np.array(energy)


# the position pass leaves a contact up to its slop (0.1 mm) deep; a body rests within this of its exact height
HEIGHT = 1.5e-4


def _rests(plan: str, bodies: str, materials: str, heights: dict) -> None:
    """The scene's 1.5 s on the capturing path: no contact deeper than HEIGHT, energy never rising by 1 %, and each
    body named in heights at rest with its centre there ((x, y, z), m) within HEIGHT."""
    sim, energy = _run(_scene(plan, bodies, materials, 1.5), 1.5)
    report = sim.contact_report()
    assert report["path"] == "capturing"
    assert report["deepest"] < HEIGHT
    assert largest_rise(energy) < 0.01
    for name, centre in heights.items():
        state = sim.state.y[sim.plan.names.index(name)]
        assert np.abs(state[7:13]).max() < 1e-3, name
        assert np.abs(state[:3] - centre).max() < HEIGHT, name


# what falls on a 0.1 kg cube (10 cm, 100 kg/m3), and the height of its centre at rest: a 36 kg slab (0.3 x 0.05 x
# 0.3 m, 8000 kg/m3) of clay (e = 0) from 2 cm, and a 10.2 kg steel capsule (r 4 cm, 20 cm between its end centres,
# e = 0.3) lying across the cube from 1 cm, its ends 5 cm beyond the cube's sides. Either lands on a moving body, so
# the run takes the capturing path
HEAVY = {"slab": (0.0, "box { size (0.3, 0.05, 0.3) m  material heavy  at (0, 0.145, 0) m }", 0.125),
         "capsule": (0.3, "capsule { radius 0.04 m  length 0.2 m  material heavy  at (0, 0.15, 0) m  orient (0, 90, 0) }",
                     0.14)}


@pytest.mark.parametrize("plan", PLANS)
@pytest.mark.parametrize("top", HEAVY)
def test_a_heavy_body_dropped_on_a_light_cube_rests_on_it(plan, top):
    restitution, shape, height = HEAVY[top]
    materials = (f"  material light {{ density 100 kg/m3  friction 0.5  restitution {restitution} }}\n"
                 f"  material heavy {{ density 8000 kg/m3  friction 0.5  restitution {restitution} }}\n")
    bodies = f"  body cube box {{ size (0.1, 0.1, 0.1) m  material light  at (0, 0.05, 0) m }}\n  body top {shape}\n"
    _rests(plan, bodies, materials, {"cube": (0, 0.05, 0), "top": (0, height, 0)})


@pytest.mark.parametrize("plan", PLANS)
def test_a_stack_of_alternating_densities_stands_still_beside_an_impact(plan):
    # 8 cubes of 10 cm, 100 and 8000 kg/m3 in turn, each resting on the one below (touching bodies whose masses
    # differ 10 times or more: the run takes the capturing path from the start); far away a ball strikes a ball
    densities = (100, 8000, 300, 5000, 600, 2500, 1000, 8000)
    materials = "".join(f"  material m{i} {{ density {rho} kg/m3  friction 0.5  restitution 0 }}\n"
                        for i, rho in enumerate(densities))
    materials += "  material ball { density 1000 kg/m3  friction 0.1  restitution 0.5 }\n"
    bodies = "".join(f"  body b{i} box {{ size (0.1, 0.1, 0.1) m  material m{i}  at ({0.01 * (i % 3 - 1)}, "
                     f"{0.05 + 0.1 * i:.2f}, 0) m }}\n" for i in range(len(densities)))
    bodies += ("  body striker sphere { radius 0.05 m  material ball  at (1.0, 0.05, 0) m  velocity (1, 0, 0) m/s }\n"
               "  body struck sphere { radius 0.05 m  material ball  at (1.2, 0.05, 0) m }\n")
    _rests(plan, bodies, materials, {f"b{i}": (0.01 * (i % 3 - 1), 0.05 + 0.1 * i, 0) for i in range(len(densities))})


@pytest.mark.parametrize("plan", PLANS)
def test_a_heavy_block_sliding_on_a_light_board_stops_at_coulombs_distance(plan):
    """An 8 kg steel block (10 cm) sliding at 1 m/s along a 0.18 kg board lying on a floor: friction 0.3 between
    them, and sqrt(0.3 x 1) = 0.55 between the board and the floor, which holds the board (0.55 x 8.18 g > 0.3 x 8 g).
    The block stops after v0^2 / (2 mu g) = 0.16990 m, within 1 %, the board does not move (0.1 mm), nothing turns,
    and no energy is gained. Before, the exact path blew up at 0.05 s in the procedural plan, and at 4 ms in the
    dynamics plan the block turned about the vertical and stopped 2 % short."""
    materials = ("  material board { density 30 kg/m3  friction 0.3  restitution 0 }\n"
                 "  material steel { density 8000 kg/m3  friction 0.3  restitution 0 }\n")
    bodies = ("  body board box { size (1.0, 0.02, 0.3) m  material board  at (0, 0.01, 0) m }\n"
              "  body block box { size (0.1, 0.1, 0.1) m  material steel  at (-0.3, 0.07, 0) m  velocity (1, 0, 0) m/s }\n")
    text = _scene(plan, bodies, materials, 1.0).replace("friction 0.5  restitution 0 }", "friction 1.0  restitution 0 }", 1)
    sim, energy = _run(text, 1.0)
    assert sim.contact_report()["path"] == "capturing"
    assert largest_rise(energy) < 0.01
    board, block = (sim.state.y[sim.plan.names.index(name)] for name in ("board", "block"))
    distance = 1.0 ** 2 / (2 * 0.3 * 9.81)
    assert abs(block[0] + 0.3 - distance) < 0.01 * distance
    assert np.abs(block[7:13]).max() < 1e-3 and np.abs(block[1:3] - (0.07, 0.0)).max() < HEIGHT
    assert np.abs(board[:3] - (0.0, 0.01, 0.0)).max() < 1e-4 and np.abs(board[7:13]).max() < 1e-3


def _wall(plan: str) -> str:
    """A wall of 6 x 4 bricks (0.15 x 0.08 x 0.08 m, 600 kg/m3, 0.58 kg), each course half a brick along, struck
    at 4 m/s by an aluminium ball (r 8 cm, 5.79 kg: 10.05 times a brick, so islands of both are solved whole)."""
    bricks = "".join(f"  body br{j}_{i} box {{ size (0.15, 0.08, 0.08) m  material brick  at (0, {0.04 + 0.08 * j:.2f}, "
                     f"{0.15 * (i - 2.5) + 0.075 * (j % 2):.4f}) m  orient (0, 90, 0) }}\n"
                     for j in range(4) for i in range(6))
    return ("scene wall {\n  time 0 s .. 0.4 s\n  frames 100 Hz\n  gravity (0, -9.81, 0) m/s2\n"
            f"  {plan}\n"
            "  material floor { density 800 kg/m3  friction 0.4  restitution 0.5 }\n"
            "  material brick { density 600 kg/m3  friction 0.4  restitution 0.5 }\n"
            "  material aluminium { density 2700 kg/m3  friction 0.3  restitution 0.5 }\n"
            "  body floor plane { material floor }\n" + bricks +
            "  body ball sphere { radius 0.08 m  material aluminium  at (-0.6, 0.08, 0) m  velocity (4, 0, 0) m/s }\n"
            "}\n")


@pytest.mark.parametrize("plan", ["solver dynamics { integrator rk4  step 1 ms }", "solver procedural { step 4 ms }"])
def test_a_light_wall_struck_by_a_heavy_ball_gains_no_energy(plan):
    """Found 2026-12-07: at one step the warm start (the impulses of the step before) raised the bricks' energy
    from 44 J to 2234 J, and the sweeps took back all but 12 J (4.6 J in the dynamics plan): exit 0, a rise of 10
    to 24 % of the energy available. A solve whose impulses create energy is now taken again with only so much
    of the warm start as lowers the energy (capture/loop.py `_warm_again`)."""
    sim, energy = _run(_wall(plan), 0.4)
    report = sim.contact_report()
    assert report["path"] == "capturing"
    assert report["steps_creating_energy"] == 0 and report["deepest"] < 1e-3
    assert largest_rise(energy) < 0.01
