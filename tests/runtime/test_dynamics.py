"""The dynamics plan on small inline scenes with exact answers, over every integrator where it matters."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.core.rotation import quat_rotate, quat_to_matrix
from isaac_runtime.run import RunOptions, simulate
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"
G = 9.81
INTEGRATORS = ("rk4", "midpoint", "euler")


def scene(body: str, integrator="rk4", step="1 ms", time="1 s", extra="") -> str:
    return f"""
scene test {{
  time 0 s .. {time}
  frames 100 Hz
  solver dynamics {{ integrator {integrator}  step {step} {extra} }}
{body}
}}"""


def run(text: str, **options):
    result = simulate(load_text(text).scene, RunOptions(**options))
    assert result.error is None, result.error
    return result.recorder.arrays(), result


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_free_fall(integrator):
    arrays, _ = run(scene("body b sphere { radius 1 cm  mass 2 kg  at (0, 10, 0)  velocity (1, 0, 0) }", integrator))
    t = arrays["time"]
    expected_y = 10 - 0.5 * G * t**2
    # RK4 and midpoint integrate a constant acceleration exactly; semi-implicit Euler is off by g h t / 2
    tolerance = 1e-9 if integrator != "euler" else 0.5 * G * 1e-3 * t[-1] + 1e-9
    assert np.max(np.abs(arrays["position"][:, 0, 1] - expected_y)) <= tolerance
    assert np.allclose(arrays["position"][:, 0, 0], t, atol=1e-12)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_spring_period(integrator):
    # a 0.5 kg ball on a 200 N/m spring to a world point, no gravity: x(t) = A cos(w t), w = sqrt(k/m) = 20 rad/s
    body = """
  gravity (0, 0, 0)
  body b sphere { radius 1 cm  mass 0.5 kg  at (0.1, 0, 0) }
  force s spring(b @ (0, 0, 0), (0, 0, 0)) { stiffness 200 N/m  rest 0 m }"""
    arrays, _ = run(scene(body, integrator, step="0.5 ms"))
    t = arrays["time"]
    error = np.max(np.abs(arrays["position"][:, 0, 0] - 0.1 * np.cos(20 * t)))
    assert error < {"rk4": 1e-9, "midpoint": 2e-4, "euler": 2e-3}[integrator]


def test_load_follows_a_function_of_time():
    # F = (2 sin t, 0, 0) N on 2 kg, no gravity: x = t - sin t (from rest)
    body = """
  gravity (0, 0, 0)
  body b sphere { radius 1 cm  mass 2 kg }
  force push load(b) { force (2 * sin(t), 0, 0) N }"""
    arrays, _ = run(scene(body, time="2 s"))
    t = arrays["time"]
    assert np.max(np.abs(arrays["position"][:, 0, 0] - (t - np.sin(t)))) < 1e-10


def test_torque_free_rotation_keeps_angular_momentum_and_energy():
    # an asymmetric box spinning about a tilted axis: the gyroscopic term must keep L = I w and E constant
    body = """
  gravity (0, 0, 0)
  body b box { size (0.3, 0.2, 0.1) m  mass 1 kg  spin (1, 5, 0.5) rad/s }"""
    arrays, result = run(scene(body, time="2 s", step="0.5 ms"))
    R = quat_to_matrix(arrays["orientation"][:, 0])
    inertia_body = np.diag([(0.2**2 + 0.1**2) / 12, (0.3**2 + 0.1**2) / 12, (0.3**2 + 0.2**2) / 12])
    momentum = np.einsum("tij,jk,tlk,tl->ti", R, inertia_body, R, arrays["angular_velocity"][:, 0])
    assert np.max(np.abs(momentum - momentum[0])) < 1e-9
    assert np.max(np.abs(arrays["energy"] - arrays["energy"][0])) < 1e-9


def test_euler_keeps_a_whirling_rod_on_its_circle_with_its_energy():
    # a rod spinning at 20 rad/s about a nail at its end, no gravity: a uniform turn. Semi-implicit Euler's step takes
    # the nail's correction as an impulse and projects the velocities at the corrected pose (dynamics/projection.py,
    # h > 0); with the multipliers of the step's start and the step's own M^-1 J^T instead, the rod gained 8 % of its
    # energy in 0.25 s and ran away at 3.4 s
    body = """
  gravity (0, 0, 0)
  body rod box { size (0.2, 2 cm, 2 cm)  mass 0.5 kg  at (0.1, 0, 0)  velocity (0, 2, 0)  spin (0, 0, 20) rad/s }
  constraint anchor nail(rod @ (-0.1, 0, 0), (0, 0, 0))"""
    arrays, _ = run(scene(body, "euler", time="4 s"))
    energy, t, x = arrays["energy"], arrays["time"], arrays["position"][:, 0]
    assert np.max(np.abs(energy - energy[0])) <= 1e-12 * energy[0]
    assert np.max(np.abs(np.hypot(x[:, 0], x[:, 1]) - 0.1)) <= 1e-12
    # first order in its phase only: 20 t to 4e-3 rad after 80 rad
    assert np.max(np.abs(np.unwrap(np.arctan2(x[:, 1], x[:, 0])) - 20 * t)) <= 5e-3


@pytest.mark.parametrize("step, bound", [("1 ms", 4e-3), ("0.5 ms", 1e-3)])
def test_euler_chain_keeps_its_energy_bounded(step, bound):
    # the shipped 10-link chain with semi-implicit Euler for its 10 s: it ran away at 2.8 s (1 ms), 3.9 s (0.5 ms);
    # now its energy error stays bounded and shrinks with the step (measured 1.9e-3 and 4.2e-4 of m g extent)
    text = (SCENES / "chain.isaac").read_text().replace("integrator rk4  step 0.5 ms", f"integrator euler  step {step}")
    assert f"integrator euler  step {step}" in text
    result = simulate(load_text(text, name="chain.isaac", folder=SCENES).scene, RunOptions())
    assert result.error is None, result.error
    assert result.report["energy_drift_relative"] <= bound


def test_moving_nail_drags_the_point_along_its_path():
    # a nail moving on a circle carries the bob's point exactly (point on path); the bob starts with the
    # nail's velocity, so there is nothing for the stabilization to pull in
    body = """
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0)  velocity (0, 2, 0) }
  constraint ride nail(bob @ (0, 0.5, 0), (cos(2 * t), 0.5 + sin(2 * t), 0))"""
    arrays, _ = run(scene(body, time="2 s"))
    t = arrays["time"]
    point = arrays["position"][:, 0] + quat_rotate(arrays["orientation"][:, 0], np.tile([0, 0.5, 0], (len(t), 1)))
    path = np.stack([np.cos(2 * t), 0.5 + np.sin(2 * t), 0 * t], axis=1)
    assert np.max(np.linalg.norm(point - path, axis=1)) < 1e-6


def test_point_on_inclined_plane_slides_with_g_sin_theta():
    # a bead held on a frictionless plane tilted 30 degrees: a = g sin 30 along the slope
    body = """
  body bead sphere { radius 1 cm  mass 1 kg }
  constraint slope plane(bead @ (0, 0, 0), (0, 0, 0), (-sin(30 deg), cos(30 deg), 0)) + tz(bead)"""
    arrays, _ = run(scene(body, time="1 s"))
    t = arrays["time"]
    travelled = np.linalg.norm(arrays["position"][:, 0], axis=1)
    assert np.max(np.abs(travelled - 0.5 * G * math.sin(math.radians(30)) * t**2)) < 1e-8


def test_weld_minus_rz_leaves_only_the_turn_about_z():
    # element rows fix the centre of mass and the orientation; removing rz leaves the spin about z free
    body = """
  body post static box { size (0.1, 0.1, 0.1) m  at (0, 0, 0) }
  body rod box { size (1, 0.02, 0.02) m  mass 1 kg  at (0.5, 0, 0)  spin (0.3, -0.2, 3) rad/s }
  constraint hinge weld(rod, post) - rz"""
    arrays, _ = run(scene(body, time="1 s"))
    w = arrays["angular_velocity"][:, 1]
    # the x and y spin start violating the rows: they are removed as the rows assemble (critically damped at the
    # default 10 Hz: (1 + w t) exp(-w t) is 1e-12 by 0.5 s), then stay zero
    assert np.max(np.abs(w[50:, :2])) < 1e-9
    assert np.max(np.abs(arrays["position"][:, 1] - [0.5, 0, 0])) < 1e-6
    assert np.all(np.abs(w[50:, 2]) > 2.0)


def test_redundant_rows_stay_finite_and_are_reported():
    # a windmill joint with a third, redundant orientation row: J M^-1 J^T is singular
    body = """
  body tower static box { size (0.2, 2, 0.2) m  at (0, -1.2, -0.2) }
  body blade box { size (2, 0.2, 0.05) m  mass 3 kg  at (0.5, 0, 0) }
  constraint joint point(blade @ (-0.5, 0, 0), tower @ (0, 1.2, 0.2)) + orient(blade.z, x) + orient(blade.z, y) + orient(blade.x, z)"""
    arrays, result = run(scene(body, time="1 s"))
    assert np.isfinite(arrays["position"]).all()
    assert result.report["max_constraint_error"] < 1e-6
    assert any("redundant" in w for w in result.report["warnings"])


def test_switch_lands_exactly_on_the_time():
    sim = Simulation.from_text(scene("""
  body a sphere { radius 5 cm  mass 1 kg  at (-0.2, 0, 0) }
  body b sphere { radius 5 cm  mass 1 kg  at (0.2, 0, 0) }
  constraint late point(a @ (0.05, 0, 0), b @ (-0.05, 0, 0)) from 0.3337 s""", extra="", time="1 s")
                               .replace("frames 100 Hz", "frames 100 Hz\n  gravity (0, 0, 0)"))
    sim.advance_to(0.3337)
    assert sim.state.t == 0.3337
    assert np.all(sim.state.v == 0)  # nothing moved before the switch
    sim.step()
    assert np.any(sim.state.v != 0)


def test_blow_up_names_time_step_and_culprit():
    text = scene("""
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) }
  constraint hang nail(bob @ (-0.9, 0, 0), (0, 0, 0))""", step="20 ms", time="5 s",
                 extra="stabilize 200 Hz  tolerance 0")  # (the error control would take it in substeps)
    result = simulate(load_text(text).scene)
    assert result.error is not None
    message = str(result.error)
    assert "numerical blow-up at t =" in message and "step" in message
    assert "`hang`" in message or "`bob`" in message
    assert result.recorder.count >= 1  # frames before the blow-up were kept
