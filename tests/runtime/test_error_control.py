"""RK4's error control (dynamics/integrate.py): the embedded third-order estimate from the slope at a step's end, and
the steps over the solver's tolerance taken again in substeps. Smooth motion is never refined and gives the plain
RK4 run to the bit; a chain's whips are, and its energy holds; refined steps are RK4 substeps; inputs that change
within a step are counted, not refined."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from isaac_ir import ir
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_scene, load_text
from isaac_runtime.dynamics.integrate import MAX_SUBSTEPS
from isaac_runtime.run import RunOptions, simulate
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"

# a pendulum of a 1 m massless rod released at theta0 from the vertical, a step and a tolerance
SWING = """scene swing {
  time 0 s .. %(end)s s
  frames %(frames)s Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step %(step)s ms  tolerance %(tolerance)s %(extra)s }
  body bob sphere { radius 1 cm  mass 1 kg  at (sin(150 deg), -cos(150 deg), 0) m  collide off }
  constraint rod nail(bob @ (-sin(150 deg), cos(150 deg), 0) m, (0, 0, 0))
  %(more)s
}"""


def swing(step=1, tolerance="3e-6", end=2, frames=100, extra="", more=""):
    return Simulation.from_text(SWING % dict(step=step, tolerance=tolerance, end=end, frames=frames, extra=extra,
                                             more=more))


def run_to_end(sim):
    sim.advance_to(sim.plan.end)
    return sim


def chain(tolerance: float, until: float, step: float):
    scene = load_scene(SCENES / "chain.isaac").scene
    scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, tolerance=tolerance))
    return simulate(scene, RunOptions(step=step, until=until))


def test_the_default_tolerance_is_in_the_ir():
    scene = load_text("scene s { solver dynamics { step 1 ms } }", "s.isaac").scene
    assert scene.solver.tolerance == ir.SolverOptions.tolerance == 3e-6
    assert load_text("scene s { solver dynamics { tolerance 0 } }", "s.isaac").scene.solver.tolerance == 0.0


@pytest.mark.parametrize("value", ["-1e-6", "1 m"])
def test_a_tolerance_that_is_no_tolerance_is_a_positioned_error(value):
    with pytest.raises(SceneError) as raised:
        load_text("scene s {\n  solver dynamics { tolerance %s }\n}\n" % value, "s.isaac")
    diagnostic = raised.value.diagnostics[0]
    assert diagnostic.pos.line == 2 and "tolerance" in diagnostic.message + (diagnostic.hint or "")


def test_smooth_motion_is_never_refined_and_is_the_plain_rk4_run_to_the_bit():
    controlled, plain = run_to_end(swing()), run_to_end(swing(tolerance=0))
    assert controlled.error_control() == {"steps_refined": 0, "substeps": 0, "steps_over_tolerance": 0}
    np.testing.assert_array_equal(controlled.state.y, plain.state.y)


def test_a_refined_step_is_rk4_in_substeps():
    """A tolerance no step meets takes every step of 8 ms in the most substeps: the run of 0.5 ms steps."""
    refined = run_to_end(swing(step=8, tolerance="1e-30", end=1, frames=125))
    fine = run_to_end(swing(step=8 / MAX_SUBSTEPS, tolerance=0, end=1, frames=125))
    counts = refined.error_control()
    assert counts["steps_refined"] == refined.state.steps == 125
    assert counts["substeps"] == MAX_SUBSTEPS * 125 and counts["steps_over_tolerance"] == 125
    np.testing.assert_allclose(refined.state.y, fine.state.y, rtol=0, atol=1e-12)


def test_a_chains_whips_are_refined_and_its_energy_holds():
    """The 10-link chain at RK4 1 ms for 10 s: its free end whips at up to 100 rad/s, where RK4's local error at
    1 ms is some 1e4 times that of smooth motion. Without the control the energy drifts 1.2e-4 of its scale,
    with the default tolerance 7e-7 (measured), at 5190 substeps for 2106 of its 10000 steps."""
    plain, controlled = chain(0.0, 10.0, 1e-3), chain(ir.SolverOptions.tolerance, 10.0, 1e-3)
    assert plain.error is None and controlled.error is None
    assert plain.report["energy_drift_relative"] > 3e-5
    assert controlled.report["energy_drift_relative"] < 1e-6
    assert 0 < controlled.report["steps_refined"] < 0.3 * controlled.report["steps"]
    assert controlled.report["steps_over_tolerance"] == 0
    assert controlled.report["max_constraint_error"] < 1e-9


# a nail 0.1 m from where it holds the bob, closed at 200 Hz: far too stiff for a 20 ms step (tests/runtime/test_run.py)
STIFF = """scene stiff {
  time 0 s .. 2 s
  frames 50 Hz
  solver dynamics { step 20 ms  stabilize 200 Hz  tolerance %s }
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) }
  constraint hang nail(bob @ (-0.9, 0, 0), (0, 0, 0))
}"""


def test_a_stabilization_too_stiff_for_its_step_is_taken_in_substeps():
    """RK4 blows up within a few steps (h w = 25 for w = 2 pi 200 Hz; its limit is 2.8); the control takes the
    steps while the nail closes in substeps, and the bob hangs on it."""
    assert simulate(load_text(STIFF % "0").scene).error is not None
    result = simulate(load_text(STIFF % "3e-6").scene)
    assert result.error is None and result.report["steps_refined"] > 0
    assert result.report["steps"] == 100 and result.report["max_constraint_error"] < 0.1 + 1e-9
    assert result.simulation.check_constraints() < 1e-9


def test_inputs_that_change_within_a_step_are_counted_not_refined():
    """A load of t: substeps would read the table's row of the step's start, so the step is kept and counted."""
    sim = run_to_end(swing(tolerance="1e-30", end=0.5, more="force push load(bob) { force (sin(10 * t), 0, 0) N }"))
    counts = sim.error_control()
    assert counts["steps_refined"] == 0 and counts["steps_over_tolerance"] == sim.state.steps == 500


def test_the_report_says_what_the_control_did():
    result = chain(ir.SolverOptions.tolerance, 2.0, 1e-3)
    report = result.report
    assert report["tolerance"] == 3e-6 and report["steps_refined"] > 0
    assert report["substeps"] >= 2 * report["steps_refined"]
    text = SWING % dict(step=1, tolerance="3e-6", end=0.1, frames=100, extra="", more="")
    euler = simulate(load_text(text.replace("rk4", "euler")).scene)
    assert euler.report["tolerance"] is None and euler.report["steps_refined"] == 0
    assert math.isfinite(result.report["energy_drift_relative"])
