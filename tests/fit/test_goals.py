"""Goals (docs/goals.md): the language's `vary` and `goal`, `isaac run` checking them, `isaac fit` meeting them.

Every fit here has an exact answer: free flight x(t) = x0 + v0 t + g t^2 / 2; a Coulomb slide to rest
d = v0^2 / (2 mu g), mu the pair's combined friction sqrt(mu_a mu_b) (docs/collisions.md); a drop's first impact
at t = sqrt(2 (h - r) / g).
"""
from __future__ import annotations

import json
import math

import pytest

from isaac.cli import main
from isaac_ir import ir
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text

G = 9.81

THROW = """
let vx = 1 m/s
let vy = 1 m/s
scene throw {{
  time 0 s .. 1 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics {{ integrator rk4  step 1 ms }}
  body ball sphere {{ radius 5 cm  mass 0.1 kg  at (0.2, 0.1, 0) m  velocity (vx, vy, 0) }}
  vary vx in 0 m/s .. 10 m/s
  vary vy in 0 m/s .. 10 m/s
  goal through: ball.position at {t} s = ({x}, {y}, 0) m within 1 um
}}
"""

SLIDE = """
let mu = 0.5
scene slide {{
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics {{ integrator rk4  step 1 ms }}
  material floor_stuff {{ friction 0.64  restitution 0 }}
  material block_stuff {{ friction mu  restitution 0 }}
  body floor plane {{ material floor_stuff }}
  body block box {{ size (10 cm, 10 cm, 10 cm)  mass 1 kg  material block_stuff  at (0, 0.05, 0)
                   velocity ({v0}, 0, 0) m/s }}
  vary mu in {low} .. {high}
  goal mark: block.position.x at 2 s = {d} m within 0.01 mm
}}
"""

DROP = """
let height = 1 m
scene drop {{
  time 0 s .. 1.5 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics {{ integrator rk4  step 1 ms }}
  material rubber {{ friction 0.8  restitution 0.5 }}
  body floor plane {{ material rubber }}
  body ball sphere {{ radius 4 cm  mass 0.1 kg  at (0, height, 0)  material rubber }}
  vary height in 10 cm .. 3 m
  goal beat: first collide(ball, floor) at {t} s within 0.01 ms
}}
"""


def fit(tmp_path, text: str, *more) -> tuple:
    scene = tmp_path / "scene.isaac"
    scene.write_text(text)
    out = tmp_path / "out"
    code = main(["-q", "fit", str(scene), "--out", str(out), *more])
    document = json.loads((out / "fit.json").read_text()) if (out / "fit.json").exists() else None
    return code, document


# -- the language ---------------------------------------------------------------------------------------------

def test_varies_and_goals_are_in_the_ir():
    scene = load_text(THROW.format(t=0.5, x=1, y=0.5)).scene
    assert [(v.name, v.low, v.high, v.unit) for v in scene.varies] == [("vx", 0.0, 10.0, "m/s"),
                                                                       ("vy", 0.0, 10.0, "m/s")]
    (goal,) = scene.goals
    assert (goal.kind, goal.bodies, goal.quantity, goal.time, goal.target, goal.tolerance) == (
        "state", ("ball",), "position", 0.5, (1.0, 0.5, 0.0), 1e-6)
    data = ir.to_data(scene)
    assert data["goals"][0]["name"] == "through" and data["varies"][1]["name"] == "vy"


def test_a_scene_without_goals_serializes_as_before():
    data = ir.to_data(load_text("scene s { body b sphere { radius 1 cm  mass 1 kg } }").scene)
    assert "goals" not in data and "varies" not in data


def test_an_event_goal_and_components():
    scene = load_text(DROP.format(t=0.3)).scene
    (goal,) = scene.goals
    assert (goal.kind, goal.bodies, goal.quantity, goal.time, goal.tolerance) == (
        "event", ("ball", "floor"), "collide", 0.3, pytest.approx(1e-5))
    text = THROW.format(t=0.5, x=1, y=0.5).replace("goal through: ball.position at 0.5 s = (1, 0.5, 0) m",
                                                   "goal through: ball.velocity.y at 0.5 s = -1 m/s")
    (goal,) = load_text(text.replace("within 1 um", "within 1 mm/s")).scene.goals
    assert (goal.quantity, goal.component, goal.target) == ("velocity", "y", -1.0)


@pytest.mark.parametrize("change, message, line", [
    ("goal through: ball.position", "goal through: bal.position", "unknown body `bal`"),
    ("at 0.5 s =", "at 3 s =", "outside the scene's time"),
    ("vary vy in", "vary vz in", "no top-level `let vz`"),
    ("vary vx in 0 m/s .. 10 m/s", "vary vx in 0 m .. 10 m", "wants a velocity"),
    ("(1, 0.5, 0) m within", "(1, 0.5, 0) m/s within", "wants a length"),
    ("ball.position at", "ball.spin at", "not a quantity a goal can ask for"),
])
def test_goals_that_cannot_be_evaluated_are_positioned_errors(change, message, line):
    text = THROW.format(t=0.5, x=1, y=0.5)
    assert change in text
    with pytest.raises(SceneError) as raised:
        load_text(text.replace(change, message), "throw.isaac")
    (diagnostic,) = raised.value.diagnostics
    assert line in diagnostic.message and diagnostic.pos is not None and diagnostic.pos.line > 1


def test_a_goal_error_on_the_command_line_is_exit_2_with_a_caret(tmp_path, capsys):
    scene = tmp_path / "bad.isaac"
    scene.write_text(THROW.format(t=0.5, x=1, y=0.5).replace("ball.position at", "bal.position at"))
    assert main(["fit", str(scene), "--out", str(tmp_path / "out")]) == 2
    said = capsys.readouterr().err
    assert "bad.isaac:11:17: error: unknown body `bal`" in said and "^" in said


# -- isaac run checks the goals -------------------------------------------------------------------------------

@pytest.mark.parametrize("vx, code", [(2.0, 0), (2.1, 3)])
def test_isaac_run_reports_goals_and_exits_3_on_a_miss(tmp_path, vx, code):
    # x(0.5) = 0.2 + 2 * 0.5 = 1.2 m; y(0.5) = 0.1 + 3 * 0.5 - 9.81 * 0.25 / 2 = 0.37375 m
    scene = tmp_path / "throw.isaac"
    scene.write_text(THROW.format(t=0.5, x=1.2, y=0.37375))
    out = tmp_path / "out"
    assert main(["-q", "run", str(scene), "--out", str(out), "--set", f"vx={vx} m/s", "--set", "vy=3 m/s",
                 "--no-viewer"]) == code
    (goal,) = json.loads((out / "report.json").read_text())["goals"]
    assert goal["name"] == "through" and goal["met"] is (code == 0) and goal["tolerance"] == 1e-6
    assert goal["error"] == pytest.approx(abs(vx - 2.0) * 0.5, abs=1e-12)
    assert goal["target"] == [1.2, 0.37375, 0.0] and goal["value"][0] == pytest.approx(0.2 + vx * 0.5, abs=1e-12)


# -- isaac fit ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("t, x, y", [(0.5, 1.2, 0.37375), (0.73, 3.1, 1.25)])
def test_fit_free_flight_through_a_point(tmp_path, t, x, y):
    code, found = fit(tmp_path, THROW.format(t=t, x=x, y=y))
    assert code == 0 and found["goals"][0]["met"]
    # x(t) = x0 + vx t;  y(t) = y0 + vy t - g t^2 / 2
    assert found["parameters"]["vx"] == pytest.approx((x - 0.2) / t, abs=1e-6)
    assert found["parameters"]["vy"] == pytest.approx((y - 0.1 + G * t * t / 2) / t, abs=1e-6)
    assert found["runs"] < 60


def test_fit_speed_and_angle_of_the_shipped_throw(tmp_path):
    from pathlib import Path

    scene = Path(__file__).resolve().parents[2] / "scenes" / "throw.isaac"
    out = tmp_path / "out"
    assert main(["-q", "fit", str(scene), "--set", "speed=4 m/s", "--set", "angle=30 deg", "--out", str(out)]) == 0
    found = json.loads((out / "fit.json").read_text())
    vx, vy = 2.5 / 0.8, (1.3 + G * 0.64 / 2) / 0.8
    assert found["parameters"]["speed"] == pytest.approx(math.hypot(vx, vy), abs=1e-6)
    assert found["parameters"]["angle"] == pytest.approx(math.atan2(vy, vx), abs=1e-6)


@pytest.mark.parametrize("v0, d", [(2.0, 0.5), (1.5, 0.2)])
def test_fit_friction_to_slide_to_rest_on_a_mark(tmp_path, v0, d):
    code, found = fit(tmp_path, SLIDE.format(v0=v0, d=d, low=0.1, high=1.5))
    assert code == 0
    # d = v0^2 / (2 mu g), mu = sqrt(0.64 mu_block)  ->  mu_block = (v0^2 / (2 d g))^2 / 0.64
    combined = v0 * v0 / (2 * d * G)
    assert found["parameters"]["mu"] == pytest.approx(combined * combined / 0.64, abs=1e-4)


@pytest.mark.parametrize("t", [0.3, 0.45])
def test_fit_a_drop_to_its_first_impact(tmp_path, t):
    code, found = fit(tmp_path, DROP.format(t=t))
    assert code == 0
    # t = sqrt(2 (h - r) / g)  ->  h = r + g t^2 / 2
    assert found["parameters"]["height"] == pytest.approx(0.04 + G * t * t / 2, abs=1e-4)


def test_a_goal_out_of_reach_exits_3_naming_it(tmp_path, capsys):
    # the mark at 0.2 m needs mu_block = 0.514; the range stops at 0.45
    code, found = fit(tmp_path, SLIDE.format(v0=1.5, d=0.2, low=0.1, high=0.45))
    assert code == 3 and not found["goals"][0]["met"]
    assert "`mark` missed by" in capsys.readouterr().err


# -- docs/goals.md ----------------------------------------------------------------------------------------------

def _doc_examples():
    from ..doc_examples import scene_examples

    return [e for e in scene_examples() if e.doc == "docs/goals.md"]


DOC_ANSWERS = {  # the closed forms the page gives
    "throw": {"vx": 2.5 / 0.8, "vy": (1.3 + G * 0.64 / 2) / 0.8},
    "slide_to_mark": {"mu": 4.0 / (2 * 0.5 * G)},
    "drop_on_the_beat": {"drop": 0.05 + G * 0.16 / 2},
}


@pytest.mark.parametrize("example", _doc_examples(), ids=lambda e: e.name)
def test_every_example_of_docs_goals_fits_to_its_closed_form(tmp_path, example):
    code, found = fit(tmp_path, example.text)
    assert code == 0
    for name, answer in DOC_ANSWERS[example.name].items():
        assert found["parameters"][name] == pytest.approx(answer, abs=1e-4)
