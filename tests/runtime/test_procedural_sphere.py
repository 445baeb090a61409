"""The procedural sphere (runtime/procedural_sphere.py): bouncing and rolling on static planes, no contact solve."""
from __future__ import annotations

import numpy as np
import pytest

from isaac_runtime.procedural import ProceduralSolver
from isaac_runtime.procedural_sphere import ProceduralSpheres

G = 9.81
RADIUS, MASS = 0.1, 1.0

INERTIA = 0.4 * MASS * RADIUS**2  # solid ball


def _ball(x0, normal, offset=0.0, restitution=0.0, friction=0.5, substeps=10):
    x = np.array([x0], dtype=float)
    state = {"x": x, "q": np.array([[1.0, 0.0, 0.0, 0.0]]), "v": np.zeros((1, 3)), "w": np.zeros((1, 3))}
    spheres = ProceduralSpheres([0], [RADIUS], [1.0 / MASS], [INERTIA], [normal], [offset], restitution, friction,
                                [0.0, -G, 0.0])
    solver = ProceduralSolver([], None, [1.0 / MASS], [np.eye(3) / INERTIA], substeps=substeps, contacts=spheres)
    force, torque = np.array([[0.0, -G * MASS, 0.0]]), np.zeros((1, 3))

    def step(h):
        solver.step(state["x"], state["q"], state["v"], state["w"], h, force, torque)

    return state, step, spheres


def test_bounce_heights_follow_e_squared():
    """Dropped from 1 m (bottom) onto y = 0 with e = 0.8: each apex is e^2 = 0.64 of the one before. Measured
    from the energy height y + v^2 / 2g at the top of each flight: within 2 % (the substep's O(hs) error:
    h = 1/60, 10 substeps), and the sphere never sinks into the floor."""
    state, step, spheres = _ball([0.0, 1.0 + RADIUS, 0.0], [0.0, 1.0, 0.0], restitution=0.8, friction=0.3)
    h, heights, lowest, rising = 1.0 / 60.0, [], np.inf, False
    for _ in range(int(5.0 / h)):
        step(h)
        y, vy = state["x"][0, 1] - RADIUS, state["v"][0, 1]
        lowest = min(lowest, y)
        if rising and vy <= 0.0:
            heights.append(y + vy * vy / (2 * G))
        rising = vy > 0.0
    ratios = np.array(heights[1:5]) / np.array(heights[:4])
    assert heights[0] == pytest.approx(0.64, rel=0.02)
    np.testing.assert_allclose(ratios, 0.64, rtol=0.02)
    assert lowest > -1e-12


@pytest.mark.parametrize("slope_deg", [10.0, 30.0])
def test_rolls_without_slipping_down_a_slope(slope_deg):
    """On a slope with mu = 0.5 (tan(slope) <= 3.5 mu): a = 5/7 g sin(slope), v = w r, on the surface."""
    th = np.radians(slope_deg)
    n = np.array([-np.sin(th), np.cos(th), 0.0])
    down = np.array([-np.cos(th), -np.sin(th), 0.0])
    state, step, _ = _ball(RADIUS * n, n, friction=0.5)
    for _ in range(60):
        step(1.0 / 60.0)
    v = state["v"][0] @ down
    assert v == pytest.approx(5.0 / 7.0 * G * np.sin(th) * 1.0, rel=1e-6)  # speed after 1 s
    assert np.linalg.norm(state["w"][0]) * RADIUS == pytest.approx(v, rel=1e-9)
    assert abs(state["x"][0] @ n - RADIUS) < 1e-12
    assert np.abs(state["v"][0] @ n) < 1e-9


def test_slides_when_friction_cannot_roll_it():
    """mu = 0.05 on 30 degrees (tan 30 > 3.5 mu): it slides, a = g (sin - mu cos), and spins up at the rate the
    friction torque allows, w' = mu m g cos r / I."""
    th = np.radians(30.0)
    n = np.array([-np.sin(th), np.cos(th), 0.0])
    down = np.array([-np.cos(th), -np.sin(th), 0.0])
    state, step, _ = _ball(RADIUS * n, n, friction=0.05)
    for _ in range(60):
        step(1.0 / 60.0)
    assert state["v"][0] @ down == pytest.approx(G * (np.sin(th) - 0.05 * np.cos(th)), rel=1e-6)
    spin = 0.05 * MASS * G * np.cos(th) * RADIUS / INERTIA
    assert np.linalg.norm(state["w"][0]) == pytest.approx(spin, rel=1e-6)


def test_rest_and_no_contact_solve_needed():
    """A ball set down on the floor stays put (no jitter, no creep); one thrown sideways with backspin ends up
    rolling (the slip is removed by friction, never reversed)."""
    state, step, spheres = _ball([0.0, RADIUS, 0.0], [0.0, 1.0, 0.0], restitution=0.5)
    for _ in range(120):
        step(1.0 / 60.0)
    assert np.abs(state["x"][0] - [0.0, RADIUS, 0.0]).max() < 1e-12 and np.abs(state["v"]).max() < 1e-12
    state["v"][0], state["w"][0] = [2.0, 0.0, 0.0], [0.0, 0.0, 10.0]  # backspin: w r = 1 m/s the wrong way
    for _ in range(120):
        step(1.0 / 60.0)
    vx, wz = state["v"][0, 0], state["w"][0, 2]
    assert vx > 0.0 and vx == pytest.approx(-wz * RADIUS, rel=1e-9)
    # friction acts at the contact point: the angular momentum about it, I w - m r v (z), is kept through the slide
    assert INERTIA * wz - MASS * RADIUS * vx == pytest.approx(INERTIA * 10.0 - MASS * RADIUS * 2.0, rel=1e-9)


def test_bounce_scene_with_the_procedural_sphere():
    """scenes/bounce.isaac (e = 0.5, ball dropped from 1 m) run by the procedural plan with the sphere module in
    place of the collision stage (plan.collisions = None: how the plan enables it): the first impact at
    t1 = sqrt(2 (h0 - r) / g) (within one substep), then rebound speeds of e times the impact speed, apexes e^2."""
    from pathlib import Path

    from isaac_lang.load import load_scene
    from isaac_runtime.plan import PlanOptions, compile_plan
    from isaac_runtime.procedural_sphere import ProceduralSpheres as Spheres
    from isaac_runtime.simulation import Simulation

    scene = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "bounce.isaac").scene
    plan = compile_plan(scene, PlanOptions(solver="procedural"))
    plan.collisions = None
    sim = Simulation(plan)
    spheres = sim.procedural.contacts
    assert isinstance(spheres, Spheres)
    impacts, apex, rising = [], [], False
    while sim.state.t < 2.0 - 1e-9:
        sim.step()
        impacts += [(sim.state.t, speed) for _, _, speed in spheres.take_events()]
        y, vy = sim.state.x[1, 1] - 0.05, sim.state.v[1, 1]
        if rising and vy <= 0.0:
            apex.append(y + vy * vy / (2 * G))
        rising = vy > 0.0
    t1 = np.sqrt(2 * 0.95 / G)
    assert impacts[0][0] == pytest.approx(t1, abs=0.01)  # reported at the end of the step it falls in
    assert impacts[0][1] == pytest.approx(np.sqrt(2 * G * 0.95), rel=0.01)
    assert apex[0] == pytest.approx(0.25 * 0.95, rel=0.02)
    np.testing.assert_allclose(np.array(apex[1:3]) / np.array(apex[:2]), 0.25, rtol=0.03)
