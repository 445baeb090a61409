"""A wind that moves (issue 15): a direction and a source point that follow t, against an independent integration
of the drag law with the closed-form air velocity (scipy's adaptive RK45 at rtol 1e-11: an oracle, not our
kernels), in both plans; and a clear error for a direction that passes through zero."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac.api import Simulation

RADIUS, MASS, CD, RHO = 0.05, 0.01, 0.47, 1.2
# F = 1/2 rho Cd A |u - v| (u - v), A = pi r^2: dv/dt = K |u - v| (u - v)
K = 0.5 * RHO * CD * math.pi * RADIUS**2 / MASS

BALL = f"body ball sphere {{ radius {RADIUS} m  mass {MASS} kg  drag {CD} }}"

TURNING = """scene fan {
  time 0 s .. 4 s
  gravity (0, 0, 0) m/s2
  BALL
  wind turning { direction (cos(1 rad/s * t), 0, sin(1 rad/s * t))  speed 2 m/s }
}""".replace("BALL", BALL)

# a source that follows the ball along x, its wind falling off as 1 / r^2 from 1 m
WALKING = """scene walker {
  time 0 s .. 2 s
  gravity (0, 0, 0) m/s2
  BALL
  wind puff { from (-1 m + 0.25 m/s * t, 0 m, 0 m)  toward (1, 0, 0)  speed 3 m/s  falloff inverse_square
              distance 1 m  spread 90 deg }
}""".replace("BALL", BALL)


def turning_air(t, x):
    return 2.0 * np.array([math.cos(t), 0.0, math.sin(t)])


def walking_air(t, x):
    r = x - np.array([-1.0 + 0.25 * t, 0.0, 0.0])
    distance = math.sqrt(r @ r)
    return 3.0 * (1.0 / distance) ** 2 * r / distance


def oracle(air, end: float) -> np.ndarray:
    """(x, v) of the ball at `end` by the drag law integrated with the air velocity in closed form."""
    def slope(t, y):
        x, v = y[:3], y[3:]
        rel = air(t, x) - v
        return np.concatenate((v, K * math.sqrt(rel @ rel) * rel))

    return solve_ivp(slope, (0.0, end), np.zeros(6), rtol=1e-11, atol=1e-13, method="RK45").y[:, -1]


CASES = pytest.mark.parametrize("scene,air,end", [(TURNING, turning_air, 4.0), (WALKING, walking_air, 2.0)],
                                ids=["turning direction", "moving source"])


def relative_error(scene, air, end, **options) -> float:
    sim = Simulation.from_text(scene, **options)
    sim.advance_to(end)
    expected = oracle(air, end)
    got = np.concatenate((sim.state.x[0], sim.state.v[0]))
    return float(np.abs(got - expected).max() / np.abs(expected).max())


@CASES
def test_a_moving_wind_pushes_as_its_closed_form_says(scene, air, end):
    assert relative_error(scene, air, end, solver="dynamics") <= 1e-8
    # and the wind's motion matters: a wind held at its t = 0 pose pushes the ball elsewhere
    moving, still = oracle(air, end), oracle(lambda t, x: air(0.0, x), end)
    assert np.abs(still - moving).max() > 1e-3 * np.abs(moving).max()


@CASES
def test_the_procedural_plan_follows_a_moving_wind_to_first_order(scene, air, end):
    # its drag is relaxed over the step (first order in h): 4x the step, 4x the error, and small at 1 ms
    coarse = relative_error(scene, air, end, solver="procedural", step=4e-3)
    fine = relative_error(scene, air, end, solver="procedural", step=1e-3)
    assert fine <= 1e-3 and 3.0 <= coarse / fine <= 5.0, (coarse, fine)


def test_a_direction_that_passes_through_zero_is_refused_at_its_position():
    text = TURNING.replace("(cos(1 rad/s * t), 0, sin(1 rad/s * t))", "(1 - t / 1 s, 0, 0)")
    with pytest.raises(SceneError) as caught:
        load_text(text)
    [diagnostic] = caught.value.diagnostics
    assert "zero vector" in diagnostic.message and "t = 1 s" in diagnostic.message
    assert (diagnostic.pos.line, diagnostic.pos.col) == (5, 28)  # at the value
