"""Regressions of the contact-fixes branch:

1. a body's friction depends on its own contacts only: a block sliding to rest stops where Coulomb says in both
   plans, with or without other bodies moving elsewhere on the floor (the procedural plan's friction impulses once
   left the block turning about its corners at a step's end; a look of the collision stage called for by another
   body then dropped the trailing corners, and the block stopped at 0.62 m instead of 0.75 m);
2. a blow-up whose step ends on a frame time writes no frame it did not compute (it once wrote one of zero
   positions and zero quaternions);
3. a blow-up's message says what was measured, with units, names the body and what acted on it, and its hint
   follows from the measurements.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac.cli import main
from isaac.api import Simulation

G = 9.81
PLANS = ["dynamics", "procedural"]

# the others: a ball rolling without slipping 1.5 m to the side, a block of another material sliding 1.5 m to the
# other side (it stops later and farther than the block watched)
OTHERS = {
    "ball": "  body ball sphere { radius 5 cm  mass 0.5 kg  material rubber  at (0, 0.05, 1.5)  "
            "velocity (1, 0, 0)  spin (0, 0, -20) rad/s }\n",
    "block2": "  body block2 box { size (10 cm, 10 cm, 10 cm)  mass 1 kg  material ice  at (0, 0.05, -1.5)  "
              "velocity (3, 0, 0) }\n",
}


def sliding(v0: float, mu_block: float, mu_floor: float, others: tuple) -> str:
    return f"""scene s {{
  time 0 s .. 2 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  material floor_m {{ friction {mu_floor}  restitution 0 }}
  material block_m {{ friction {mu_block}  restitution 0 }}
  material rubber {{ friction 0.9  restitution 0 }}
  material ice {{ friction 0.1  restitution 0 }}
  body floor plane {{ material floor_m }}
  body block box {{ size (10 cm, 10 cm, 10 cm)  mass 2 kg  material block_m  at (0, 0.05, 0)  velocity ({v0}, 0, 0) }}
{''.join(OTHERS[o] for o in others)}}}"""


@pytest.mark.parametrize("solver", PLANS)
@pytest.mark.parametrize("v0,mu_block,mu_floor", [(2.5, 0.3, 0.6), (1.5, 0.5, 0.2), (3.0, 0.8, 0.4)])
@pytest.mark.parametrize("others", [(), ("ball",), ("block2",), ("ball", "block2")])
def test_a_block_stops_where_its_own_friction_says_whatever_moves_elsewhere(solver, v0, mu_block, mu_floor, others):
    sim = Simulation.from_text(sliding(v0, mu_block, mu_floor, others), solver=solver)
    block = sim.body("block")
    start = sim.state.x[block].copy()
    sim.advance_to(sim.plan.end)
    mu = math.sqrt(mu_block * mu_floor)
    travelled = sim.state.x[block, 0] - start[0]
    assert travelled == pytest.approx(v0 ** 2 / (2 * mu * G), rel=0.01)
    assert np.abs(sim.state.v[block]).max() <= 1e-9 and np.abs(sim.state.w[block]).max() <= 1e-9
    assert abs(sim.state.x[block, 1] - 0.05) <= 1e-9 and abs(sim.state.x[block, 2]) <= 1e-9
    if "ball" in others:  # (the ball rolled on all the while: the block's fix did not stop it)
        assert sim.state.v[sim.body("ball"), 0] == pytest.approx(1.0, rel=1e-6)


# ---- a blow-up writes no frame it did not compute --------------------------------------------------------------

# a body too fast from the start: it runs away in the first step, which ends on the frame at 10 ms
TOO_FAST = """scene s {
  time 0 s .. 0.1 s
  frames 100 Hz
  solver %s { step 10 ms }
  body ball sphere { radius 5 cm  mass 1 kg  velocity (1e300, 0, 0) m/s }
  body other sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) m }
}
"""

# a stabilization far too stiff for its step, without the error control: it blows up in its first step, which ends
# on the frame at 20 ms (tests/runtime/test_run.py BLOWS_UP, at 50 frames/s)
TOO_STIFF = """scene bad {
  time 0 s .. 5 s
  frames 50 Hz
  solver dynamics { step 20 ms  stabilize 200 Hz  tolerance 0 }
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) m }
  constraint hang nail(bob @ (-0.9, 0, 0) m, (0, 0, 0))
}
"""

SPINS_AWAY = """scene s {
  time 0 s .. 0.1 s
  frames 100 Hz
  solver dynamics { step 10 ms }
  body top box { size (10 cm, 10 cm, 10 cm)  mass 1 kg  spin (0, 3e6, 0) rad/s }
}
"""


def _run(tmp_path, text: str, capsys) -> tuple:
    scene = tmp_path / "s.isaac"
    scene.write_text(text)
    out = tmp_path / "out"
    code = main(["run", str(scene), "--out", str(out), "--no-viewer", "-q"])
    return code, capsys.readouterr().err, out, scene


@pytest.mark.parametrize("text", [TOO_FAST % "dynamics", TOO_FAST % "procedural", TOO_STIFF],
                         ids=["fast-dynamics", "fast-procedural", "stiff"])
def test_a_blow_up_on_a_frame_writes_only_the_frames_it_computed(tmp_path, capsys, text):
    code, err, out, _ = _run(tmp_path, text, capsys)
    assert code == 2, err
    with np.load(out / "trajectory.npz") as data:
        q = data["orientation"]
        # the outputs of a blow-up are kept (docs/outputs.md), with the frames before it: here the first only
        assert len(data["time"]) == 1 and data["time"][0] == 0.0
        assert np.allclose(np.linalg.norm(q, axis=-1), 1.0)  # no frame of zero quaternions
        assert np.all(np.isfinite(data["position"]))


# ---- a blow-up says what it measured -------------------------------------------------------------------------


def error_and_hint(err: str) -> tuple:
    """The error's first line and its hint line (the source line and its caret stand between them)."""
    lines = err.strip().splitlines()
    return lines[0], next(line for line in lines if line.startswith("hint: "))


def test_a_runaway_speed_is_said_in_m_per_s_with_a_hint_from_the_start(tmp_path, capsys):
    code, err, _, scene = _run(tmp_path, TOO_FAST % "dynamics", capsys)
    assert code == 2
    first, hint = error_and_hint(err)
    assert first.startswith(f"{scene}:5:3: error: numerical blow-up at t = 0.01 s (step 1): body `ball`"), first
    assert "its speed passed 1e+06 m/s (|v| = 1e+300 m/s)" in first
    assert hint.startswith("hint: `ball` starts at |v| = 1e+300 m/s") and "slower `velocity`" in hint, hint
    assert "smaller step" not in err and "procedural" not in err


def test_a_runaway_spin_is_said_in_rad_per_s(tmp_path, capsys):
    code, err, _, scene = _run(tmp_path, SPINS_AWAY, capsys)
    assert code == 2
    first, hint = error_and_hint(err)
    assert first.startswith(f"{scene}:5:3: error: numerical blow-up at t = "), first
    assert "body `top`" in first and "its angular speed passed 1e+06 rad/s (|w| = " in first, first
    assert "m/s" not in first and "`spin`" in hint, hint


def test_a_stabilization_too_stiff_for_the_step_is_measured_and_named(tmp_path, capsys):
    code, err, _, scene = _run(tmp_path, TOO_STIFF, capsys)
    assert code == 2
    first, hint = error_and_hint(err)
    assert first.startswith(f"{scene}:5:3: error: numerical blow-up at t = 0.02 s (step 1): body `bob`"), first
    assert "m/s" in first and "acting on it: constraint `hang`" in first, first
    # omega = 2 pi 200 Hz = 1257 rad/s; omega h = 25 at 20 ms, beyond the 2 RK4 holds: 15 Hz or a 1.5 ms step
    assert "constraint `hang` assembles at 200 Hz (omega = 1.26e+03 rad/s): omega h = 25.1 at the 20 ms step" in hint
    assert "`tolerance 0`" in hint and "`stabilize 15 Hz` or less" in hint and "1.5 ms or less" in hint, hint
    assert "smaller step" not in hint and "procedural" not in hint


@pytest.mark.parametrize("change", [("stabilize 200 Hz", "stabilize 15 Hz"), ("step 20 ms", "step 1.5 ms")])
def test_what_the_stiffness_hint_says_runs(change):
    from isaac_lang.load import load_text
    from isaac_runtime.run import simulate

    result = simulate(load_text(TOO_STIFF.replace(*change)).scene)
    assert result.error is None and result.report["max_constraint_error"] <= 0.1 + 1e-9


def test_a_turned_box_that_bounces_off_one_corner_onto_another_within_a_step_gains_no_energy():
    # procedural plan, 10 ms: the box strikes the floor with one corner (e 0.3) and, turning, comes down on a second
    # within the same step. The step's look located the first and, the pair then holding no lasting contact,
    # looked for the second among nothing: it was resolved 3.9 mm deep at the step's end, and the projection threw
    # the box up with 2.6 J more than the 1.4 J it had (the features touching at the located time count as the
    # pair's known ones since). Energy never rises by more than 1 % of what the fall makes available
    text = """scene corner {
  time 0 s .. 0.6 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  material m { density 2500 kg/m3  friction 0.59  restitution 0.3 }
  body floor plane { material m }
  body box box { size (0.1, 0.1, 0.1) m  material m  at (0, 0.1, -0.0768) m  orient (13, 29, 7) }
}"""
    sim = Simulation.from_text(text, solver="procedural")
    energies = []
    for k in range(1, 61):
        sim.advance_to(0.01 * k)
        energies.append(sim.energy())
    energies = np.array(energies)
    available = energies[0] - energies.min()
    assert available > 1.0
    assert np.diff(energies).max() < 0.01 * available
    assert sim.state.y[sim.body("box"), 1] > 0.0499  # on the floor, not in it (half of 10 cm, less 0.1 mm)


# turned boxes dropped onto a floor, restitution 0: the fall is all the energy there is, and contact only takes it
# away. The procedural plan's exact path still gains energy on two of them (found 2026-12-08 by a red-team sweep):
# a strike located inside its 10 ms step leaves another point of the box deep at the step's end with no impact
# found for it, and the projection turns that depth into speed (+70.9 % and +3.8 % of the energy available)
DROPS = {"48 mm": ("(0.048, 0.036, 0.0432) m", "(0, 0.0384, -0.0768) m", "(26, 58, 14)"),
         "20 cm": ("(0.2, 0.15, 0.18) m", "(0, 0.16, -0.0768) m", "(13, 29, 7)")}
KNOWN_GAIN = pytest.mark.xfail(strict=True, reason="procedural exact path: a point left deep at a step's end "
                                                   "(docs/collisions.md, Not done)")


@pytest.mark.parametrize("solver", ["dynamics", pytest.param("procedural", marks=KNOWN_GAIN)])
@pytest.mark.parametrize("drop", list(DROPS))
def test_a_turned_box_dropped_onto_a_floor_gains_no_energy(solver, drop):
    size, at, orient = DROPS[drop]
    text = f"""scene drop {{
  time 0 s .. 1 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  material m {{ density 100 kg/m3  friction 0.59  restitution 0 }}
  body floor plane {{ material m }}
  body box box {{ size {size}  material m  at {at}  orient {orient} }}
}}"""
    sim = Simulation.from_text(text, solver=solver)
    energies = []
    for k in range(1, 101):
        sim.advance_to(0.01 * k)
        energies.append(sim.energy())
    energies = np.array(energies)
    assert np.diff(energies).max() < 0.01 * (energies[0] - energies.min())
