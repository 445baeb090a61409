"""The pendulum's period against the elliptic integral, RK4 at 1 ms (issue 13): fourth order and drift-free, the
projection keeping the nail to round-off instead of a stabilization tied to the step."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipk

from isaac_runtime.outputs import Recorder
from isaac.api import Simulation

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "pendulum.isaac"
G, LENGTH, RADIUS = 9.81, 1.0, 0.05


def exact_period(theta0: float) -> float:
    """A solid sphere on a massless rod: the physical pendulum's L_eff = L + 2 r^2 / (5 L), T = 4 sqrt(L_eff / g)
    K(sin^2(theta0 / 2)) (K of the parameter m = k^2, as scipy takes it)."""
    effective = LENGTH + 2.0 * RADIUS ** 2 / (5.0 * LENGTH)
    return 4.0 * math.sqrt(effective / G) * ellipk(math.sin(theta0 / 2.0) ** 2)


def measured_period(theta0_deg: float, until: float) -> tuple:
    """(period from the upward zero crossings of x, largest nail gap), each crossing found to round-off by a
    cubic Hermite interpolation of the steps' ends (positions and velocities, recorded at every step)."""
    sim = Simulation.from_file(SCENE, {"theta0": f"{theta0_deg} deg"}, until=until)
    times = np.arange(0.0, until + 1e-12, sim.plan.step)
    recorder = Recorder(times, sim.plan.names)
    sim.run_frames(times, recorder)
    a = recorder.arrays()
    x, v = a["position"][:, 0, 0], a["linear_velocity"][:, 0, 0]
    gap = float(np.abs(np.linalg.norm(a["position"][:, 0] - [0.0, LENGTH, 0.0], axis=1) - LENGTH).max())
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    crossings = [_hermite_root(times[i], times[i + 1], x[i], x[i + 1], v[i], v[i + 1]) for i in up]
    return float(np.mean(np.diff(crossings))), gap


def _hermite_root(t0, t1, x0, x1, v0, v1) -> float:
    h = t1 - t0
    s = x0 / (x0 - x1)
    for _ in range(50):  # Newton on the Hermite cubic p(s)
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        p = h00 * x0 + h10 * h * v0 + h01 * x1 + h11 * h * v1
        d = (6 * s**2 - 6 * s) * x0 + (3 * s**2 - 4 * s + 1) * h * v0 + (-6 * s**2 + 6 * s) * x1 \
            + (3 * s**2 - 2 * s) * h * v1
        step = p / d
        s -= step
        if abs(step) < 1e-15:
            break
    return t0 + s * h


@pytest.mark.parametrize("theta0", [10.0, 90.0, 150.0])
def test_period_matches_the_elliptic_integral_to_1e_9(theta0):
    period, gap = measured_period(theta0, until=10.0)
    assert abs(period / exact_period(math.radians(theta0)) - 1.0) <= 1e-9
    assert gap <= 1e-9
