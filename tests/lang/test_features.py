"""The language end to end: tests/lang/data/features.isaac (every construct), includes, parts, loops, kinds,
combination and subtraction, time windows, keys, moving bodies, winds, sounds, exclusions, through the IR."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from isaac_ir import expr as E
from isaac_ir.derivative import derivative
from isaac_ir import ir
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_scene, load_text

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="module")
def features() -> ir.Scene:
    return load_scene(DATA / "features.isaac", assets=False).scene  # it names a breath.wav it does not ship


def constraint(scene: ir.Scene, name: str) -> ir.Constraint:
    (found,) = [c for c in scene.constraints if c.name == name]
    return found


def summary(c: ir.Constraint):
    return [(t.family, t.bodies, t.rows) for t in c.terms]


def test_the_features_scene_prints(features):
    data = json.loads(ir.to_json(features))
    assert data["name"] == "features" and data["file"] == "features.isaac"
    assert len(data["bodies"]) == 13 and len(data["constraints"]) == 10


def test_scene_settings(features):
    assert (features.time.start, features.time.end, features.time.frame_rate) == (0.0, 2.0, 50.0)
    assert features.gravity == (0.0, -9.81, 0.0) and features.seed == 7
    solver = features.solver
    assert (solver.plan, solver.substeps, solver.iterations, solver.compliance) == ("procedural", 4, 2, 0.001)
    assert solver.step is None  # the runtime picks one and says which
    assert features.listener == ir.Listener((0.0, 1.0, 2.0), 0.5, True)
    assert features.audio == ir.Audio(48000.0, 2)
    (camera,) = features.cameras
    assert camera.fov == pytest.approx(math.radians(40))
    sun, bulb = features.lights
    assert (sun.type, sun.position, sun.color) == ("distant", (-1.0, 2.0, 3.0), (1.0, 0.9, 0.8))
    assert (bulb.type, bulb.position, bulb.intensity) == ("point", (0.0, 3.0, 0.0), 1.0)


def test_defaults_are_explicit():
    scene = load_text("scene s {\n}\n", "s.isaac").scene
    assert (scene.time.start, scene.time.end, scene.time.frame_rate) == (0.0, 10.0, 60.0)
    assert scene.gravity == (0.0, -9.81, 0.0)
    assert (scene.solver.plan, scene.solver.integrator, scene.solver.damping_ratio) == ("auto", "rk4", 1.0)
    assert dict(scene.parameters) == {}


def test_includes_resolve_relative_to_the_including_file():
    scene = load_scene(DATA / "includes.isaac").scene
    ball = scene.body("ball")
    assert ball.shape.radius == pytest.approx(0.02)  # `let` from lib/shapes.isaac, included by lib/materials.isaac
    assert ball.material == "steel" and ball.mass == pytest.approx(7800 * 4 / 3 * math.pi * 0.02**3)
    # `kind hinge(b) = nail(b) - tz` from the innermost include
    assert summary(constraint(scene, "hold")) == [("nail", ("ball",), ("tx", "ty"))]
    assert scene.materials[0].source == "lib/materials.isaac:4:1"


def test_parts_with_body_parameters_and_instance_names():
    scene = load_scene(DATA / "parts.isaac").scene
    assert [b.name for b in scene.bodies] == ["beam", "left.bob", "right.bob", "twin.upper.bob", "twin.lower.bob"]
    assert scene.body("left.bob").position.value == (0.0, -2.0, 0.0)  # length = 2 m
    assert scene.body("right.bob").position.value == (0.0, -1.0, 0.0)  # the default, 1 m
    assert (scene.body("left.bob").mass, scene.body("right.bob").mass) == (1.0, 2.0)
    assert summary(constraint(scene, "left.rod")) == [("point", ("left.bob", "beam"), ("tx", "ty", "tz"))]
    # a part inside a part: the lower pendulum hangs from the upper one's bob, named from inside the part
    assert summary(constraint(scene, "twin.lower.rod")) == [
        ("point", ("twin.lower.bob", "twin.upper.bob"), ("tx", "ty", "tz"))]
    assert scene.body("left.bob").source == "parts.isaac:3:3"  # where the part writes it


def test_instance_bodies_by_their_full_name(features):
    assert summary(constraint(features, "tether")) == [("point", ("left.shade", "right.shade"), ("tx", "ty", "tz"))]
    assert features.exclusions[1].bodies == ("left.shade", "right.shade")
    hook = constraint(features, "right.hook").terms[0]
    assert hook.bodies == ("right.shade", "post")
    assert hook.param("point_b") == pytest.approx((0.0, 1.1, 0.0))  # world (0, 2.1, 0) in the post's frame


def test_loops_and_interpolated_names(features):
    assert [b.name for b in features.bodies if b.name.startswith("bead")] == ["bead0", "bead1", "bead2"]
    assert features.body("bead2").position.value == pytest.approx((0.2, 0.5, 1.0))
    assert summary(constraint(features, "link1")) == [("point", ("bead1", "bead2"), ("tx", "ty", "tz"))]
    chain = load_scene(ROOT / "scenes" / "chain.isaac").scene
    assert [b.name for b in chain.bodies] == [f"link{i}" for i in range(10)]
    assert [c.name for c in chain.constraints] == ["anchor"] + [f"joint{i}" for i in range(9)]


def test_named_kinds_and_combination(features):
    axle = constraint(features, "axle")
    assert summary(axle) == [("point", ("wheel", "post"), ("tx", "ty", "tz")),
                             ("orient", ("wheel", "post"), ("orient",)), ("orient", ("wheel", "post"), ("orient",))]
    assert axle.terms[1].param("axis_a") == (0.0, 0.0, 1.0) and axle.terms[1].param("axis_b") == (1.0, 0.0, 0.0)
    windmill = load_scene(ROOT / "scenes" / "windmill.isaac").scene
    assert [t.family for t in windmill.constraints[0].terms] == ["point", "orient", "orient"]


def test_subtraction_of_element_rows(features):
    rows = [t.rows for t in constraint(features, "glue").terms]
    assert rows == [("tx",), ("ty",), ("tz",), ("rx",), ("ry",)]  # weld minus rz: a hinge about z
    assert [t.rows for t in constraint(features, "rail").terms] == [("ty",), ("tz",), ("rx",), ("ry",), ("rz",)]
    scene = load_text("scene s {\n  body a sphere { radius 1 cm  mass 1 kg }\n"
                      "  constraint c nail(a) - ty - tz\n}\n", "s.isaac").scene
    assert summary(scene.constraints[0]) == [("nail", ("a",), ("tx",))]


def test_time_windows_and_constraint_settings(features):
    assert (constraint(features, "axle").start, constraint(features, "axle").end) == (0.0, 1.5)
    rail = constraint(features, "rail")
    assert (rail.start, rail.end, rail.stabilize_frequency, rail.damping_ratio) == (0.5, math.inf, 5.0, 0.7)
    assert (constraint(features, "glue").start, constraint(features, "glue").end) == (0.0, 1.0)
    assert (constraint(features, "pin").start, constraint(features, "pin").end) == (0.0, math.inf)
    assert json.loads(ir.to_json(features))["constraints"][5]["end"] == "inf"


def test_a_moving_nail(features):
    target = constraint(features, "pin").terms[0].param("target")
    np.testing.assert_allclose(E.evaluate(target, {"t": np.array([0.0, 1.0])}),
                               [[0.0, 0.5, 1.0], [0.0, 0.5 + 0.1 * math.sin(1.0), 1.0]])


def test_kinematic_bodies(features):
    driver = features.body("driver")
    assert driver.motion == "kinematic" and driver.mass is None
    times = np.array([0.0, 0.25, 0.6])
    expected = np.stack([np.sin(2 * np.pi * times), 2 + 0 * times, 0 * times], axis=1)
    np.testing.assert_allclose(E.evaluate(driver.position, {"t": times}), expected, atol=1e-15)
    velocity = E.evaluate(derivative(driver.position), {"t": 0.25})
    np.testing.assert_allclose(velocity, [2 * np.pi * np.cos(np.pi / 2), 0, 0], atol=1e-12)
    glider = features.body("glider").position
    assert isinstance(glider, E.Keys) and glider.interp == "cubic"
    np.testing.assert_allclose(E.evaluate(glider, {"t": 1.0}), [1.0, 0.5, 0.0])


def test_bodies_shapes_and_motions(features):
    assert features.body("floor").motion == "static" and features.body("floor").shape.normal == (0.0, 1.0, 0.0)
    assert features.body("post").motion == "static"
    wheel = features.body("wheel")
    assert wheel.mass == pytest.approx(600 * math.pi * 0.3**2 * 0.05)
    assert wheel.angular_velocity == (0.0, 0.0, 2.0)
    r, h = 0.3, 0.05
    side, axial = wheel.mass * (3 * r * r + h * h) / 12, wheel.mass * r * r / 2
    assert np.diag(wheel.inertia) == pytest.approx([side, side, axial])
    slab = features.body("slab")
    assert slab.material == "wood" and slab.mass == pytest.approx(600 * 0.2 * 0.1 * 0.05)
    assert slab.orientation.value == pytest.approx((math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)))
    cart = features.body("cart")
    assert cart.collide is False and cart.velocity == (1.0, 0.0, 0.0)
    kite = features.body("kite").wind
    assert (kite.enabled, kite.drag, kite.area) == (True, 0.5, pytest.approx(0.1))


def test_forces(features):
    spring, push = features.forces
    assert (spring.type, spring.bodies, spring.stiffness, spring.rest_length, spring.damping) == \
        ("spring", ("kite", "post"), 50.0, 1.0, 0.1)
    assert spring.points == ((0.0, -0.2, 0.0), (0.0, 1.0, 0.0))  # `post @ world (0, 2, 0)`: post is at (0, 1, 0)
    assert push.type == "load" and push.bodies == ("cart",)
    np.testing.assert_allclose(E.evaluate(push.force, {"t": 0.5}), [1.0, 0.0, 0.0])


def test_winds(features):
    breeze, breath = features.winds
    assert (breeze.type, breeze.direction, breeze.falloff, breeze.turbulence) == \
        ("uniform", (1.0, 0.0, 0.0), "none", 0.2)
    assert E.evaluate(breeze.speed, {"t": 0.0}) == pytest.approx(3.0)
    assert (breath.type, breath.origin, breath.direction, breath.falloff) == \
        ("source", (0.0, 1.0, 3.0), (0.0, 0.0, -1.0), "inverse")
    assert breath.speed == E.Op("mul", (E.Call("envelope", (E.Str("breath.wav"),)), E.Const(4.0)))


def test_sounds_and_triggers(features):
    clank, chime, hiss = features.sounds
    assert (clank.trigger, clank.bodies, clank.gain) == ("collide", ("wheel", "floor"), pytest.approx(10 ** -0.3))
    assert clank.graph == E.Op("mul", (E.Call("modal", (E.Str("wheel"),)), E.Var("impulse")))
    assert (chime.trigger, chime.time, chime.graph) == ("time", 0.5, E.Call("sine", (E.Const(440.0),)))
    assert (hiss.trigger, hiss.wind) == ("wind", "breath")


def test_exclusions(features):
    assert features.exclusions[0].bodies == ("wheel", "post")


def test_parameters_are_the_top_level_lets(features):
    assert dict(features.parameters) == {"ball_radius": 0.02, "n": 3.0, "spin_rate": 2.0}
    spun = load_scene(DATA / "features.isaac", overrides={"spin_rate": "3 rad/s", "n": "4"}, assets=False).scene
    assert spun.body("wheel").angular_velocity == (0.0, 0.0, 3.0)
    assert len([b for b in spun.bodies if b.name.startswith("bead")]) == 4


def test_gears_and_ropes():
    scene = load_scene(ROOT / "scenes" / "gears.isaac").scene
    mesh = constraint(scene, "mesh").terms[0]
    assert (mesh.family, mesh.bodies, mesh.param("radius_a"), mesh.param("radius_b")) == \
        ("gear", ("drive", "wheel"), 0.1, 0.3)
    rope = constraint(scene, "rope").terms[0]
    assert (rope.family, rope.param("arm"), rope.param("direction")) == ("rope", (-0.1, 0.0, 0.0), (0.0, -1.0, 0.0))


def test_directions_and_anchors():
    text = ("scene s {\n  body a sphere { radius 1 cm  mass 1 kg  at (1, 0, 0)  orient (0, 0, 90) }\n"
            "  body b static box { size (1, 1, 1) m }\n"
            "  constraint o orient(a.x, -b.y)\n"
            "  constraint w point(a @ world (1, 1, 0), b @ (0, 1, 0))\n"
            "  constraint p plane(a @ (0, 0, 0), b @ (0, 0, 0), b.z)\n}\n")
    scene = load_text(text, "s.isaac").scene
    o = scene.constraints[0].terms[0]
    assert (o.bodies, o.param("axis_a"), o.param("axis_b")) == (("a", "b"), (1.0, 0.0, 0.0), (0.0, -1.0, 0.0))
    w = scene.constraints[1].terms[0]
    # world (1, 1, 0) is one metre along world y from a's centre; a is turned 90 degrees about z, so world y
    # is a's x
    np.testing.assert_allclose(w.param("point_a"), (1.0, 0.0, 0.0), atol=1e-12)
    p = scene.constraints[2].terms[0]
    assert (p.family, p.bodies, p.param("normal")) == ("plane", ("a", "b"), (0.0, 0.0, 1.0))


def test_comments_free_layout_and_trailing_commas():
    text = ("// a comment\nscene s { # another\n  body b sphere { radius 5 cm mass 1 kg at (1, 2, 3,) }"
            "  constraint c nail(b @ (0, 0, 0),) body c sphere {\nradius\n5 cm\nmass 1 kg } }")
    scene = load_text(text, "s.isaac").scene
    assert scene.body("b").position.value == (1.0, 2.0, 3.0)
    assert [b.name for b in scene.bodies] == ["b", "c"]


def test_declaration_order_does_not_matter():
    text = ("scene s {\n  constraint c nail(b)\n  body b sphere { radius 5 cm  material m }\n"
            "  material m { density 1000 kg/m3 }\n}\n")
    scene = load_text(text, "s.isaac").scene
    assert scene.constraints[0].terms[0].bodies == ("b",)


def test_a_dotted_name_that_is_not_a_body():
    with pytest.raises(SceneError, match="unknown body `left.bob`"):
        load_text("scene s {\n  body b sphere { radius 5 cm  mass 1 kg }\n  exclude b, left.bob\n}\n", "s.isaac")


def test_modes_are_a_table_of_rows():
    text = "scene s {\n  body bar box { size (30, 2, 1) cm  mass 100 g  modes ((440, 3, 1), (1210, 8, 0.5)) }\n}\n"
    assert load_text(text, "s.isaac").scene.body("bar").modes == ((440.0, 3.0, 1.0), (1210.0, 8.0, 0.5))
    with pytest.raises(SceneError, match="`at` wants a 3-vector"):
        load_text("scene s {\n  body b sphere { radius 1 m  mass 1 kg  at ((1, 2, 3), (4, 5, 6), (7, 8, 9)) }\n}\n",
                  "s.isaac")


def test_other_shapes_triggers_and_constraint_forms():
    text = ("scene s {\n  body a sphere { radius 1 cm  mass 1 kg }\n  body b static box { size (1, 1, 1) m }\n"
            "  body m mesh { file \"assets/rock.obj\"  scale 0.5  mass 2 kg  inertia (0.1, 0.2, 0.3) kg*m2 }\n"
            "  body c capsule { radius 1 cm  length 10 cm  mass 1 kg }\n"
            "  sound s1 on always { play noise() * 0.1 }\n  sound s2 on contact(a, b) { play scrape(a) * speed }\n"
            "  constraint o3 orient(a, x, y)\n  constraint o4 orient(a, x, b, y)\n"
            "  constraint e tx(a, b) + ry(a)\n  constraint r rope(a, (0, 1 cm, 0), c, -y)\n}\n")
    scene = load_text(text, "s.isaac", assets=False).scene  # the IR of a mesh body; the file is not read
    assert scene.body("m").shape.file == "assets/rock.obj" and scene.body("m").inertia[2][2] == 0.3
    assert [(s.trigger, s.bodies) for s in scene.sounds] == [("always", ()), ("contact", ("a", "b"))]
    assert summary(constraint(scene, "o4")) == [("orient", ("a", "b"), ("orient",))]
    assert summary(constraint(scene, "e")) == [("element", ("a", "b"), ("tx",)), ("element", ("a",), ("ry",))]
    rope = constraint(scene, "r").terms[0]
    assert rope.bodies == ("a", "c") and rope.param("arm") == (0.0, 0.01, 0.0)
