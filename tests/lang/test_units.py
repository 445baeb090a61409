"""Units: conversion to SI, dimensions, and what a bare number means in each kind of slot."""
from __future__ import annotations

import math

import pytest

from isaac_ir import units as U
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text


def scene(body_props: str = "", extra: str = ""):
    text = f"scene s {{\n  body b sphere {{ radius 5 cm  mass 1 kg  {body_props} }}\n  {extra}\n}}\n"
    return load_text(text, "s.isaac").scene


def error(body_props: str = "", extra: str = "") -> str:
    with pytest.raises(SceneError) as caught:
        scene(body_props, extra)
    return caught.value.diagnostics[0].message


@pytest.mark.parametrize("unit,factor,dim", [
    ("m", 1.0, U.LENGTH), ("cm", 1e-2, U.LENGTH), ("mm", 1e-3, U.LENGTH), ("km", 1e3, U.LENGTH),
    ("g", 1e-3, U.MASS), ("kg", 1.0, U.MASS), ("ms", 1e-3, U.TIME), ("min", 60.0, U.TIME),
    ("deg", math.pi / 180, U.ANGLE), ("rad", 1.0, U.ANGLE), ("Hz", 1.0, U.FREQUENCY), ("kHz", 1e3, U.FREQUENCY),
    ("kg/m3", 1.0, U.DENSITY), ("g/cm3", 1e3, U.DENSITY), ("N*s/m", 1.0, U.DAMPING), ("N/m", 1.0, U.STIFFNESS),
    ("m/s2", 1.0, U.ACCELERATION), ("m/s^2", 1.0, U.ACCELERATION), ("m/s", 1.0, U.VELOCITY),
    ("GPa", 1e9, U.PRESSURE), ("MPa", 1e6, U.PRESSURE), ("rad/s", 1.0, U.ANGULAR_VELOCITY),
    ("deg/s", math.pi / 180, U.ANGULAR_VELOCITY), ("N*m", 1.0, U.TORQUE), ("m2", 1.0, U.AREA),
    ("kg*m2", 1.0, U.INERTIA), ("cm2", 1e-4, U.AREA),
])
def test_parse_unit(unit, factor, dim):
    got_factor, got_dim = U.parse_unit(unit)
    assert got_factor == pytest.approx(factor, rel=1e-12)
    assert got_dim == dim


@pytest.mark.parametrize("text", ["furlong", "m/", "kg**2", "m/s/", "mm m"])
def test_unreadable_units(text):
    with pytest.raises(U.UnitError):
        U.parse_unit(text)


def test_dimension_helpers():
    assert U.combine(U.LENGTH, U.TIME, -1) == U.VELOCITY
    assert U.combine(None, None, +1) is None
    assert U.scale_dim(U.AREA, 0.5) == U.LENGTH
    with pytest.raises(U.UnitError):
        U.scale_dim(U.LENGTH, 0.5)
    assert U.unify(None, U.LENGTH) == U.LENGTH
    with pytest.raises(U.UnitError, match="cannot add a length and a time"):
        U.unify(U.LENGTH, U.TIME)
    assert U.describe(U.DENSITY) == "a density"
    assert U.format_dim((1, 1, -2, 0)) == "m*kg/s2"


@pytest.mark.parametrize("written,si", [
    ("radius 5 cm", 0.05), ("radius 12 mm", 0.012), ("radius 0.3 m", 0.3), ("radius (2 + 3) cm", 0.05),
])
def test_lengths_in_si(written, si):
    text = f"scene s {{\n  body b sphere {{ {written}  mass 1 kg }}\n}}\n"
    assert load_text(text, "s.isaac").scene.body("b").shape.radius == pytest.approx(si, rel=1e-12)


def test_mass_density_and_material_units():
    assert scene().body("b").mass == 1.0
    text = ("scene s {\n  material m { density 7.8 g/cm3  young 200 GPa }\n"
            "  body b sphere { radius 10 cm  mass 500 g  material m }\n}\n")
    loaded = load_text(text, "s.isaac").scene
    assert loaded.body("b").mass == pytest.approx(0.5)
    assert loaded.materials[0].density == pytest.approx(7800.0)
    assert loaded.materials[0].young == pytest.approx(2e11)
    by_density = load_text("scene s {\n  body b sphere { radius 10 cm  density 1000 kg/m3 }\n}\n", "s.isaac").scene
    assert by_density.body("b").mass == pytest.approx(1000 * 4 / 3 * math.pi * 0.1**3)


def test_times_frequencies_and_rates():
    text = ("scene s {\n  time 0 ms .. 2500 ms\n  frames 50 Hz\n  solver dynamics { step 500 us  stabilize 2 kHz }\n"
            "  audio { rate 48 kHz }\n}\n")
    loaded = load_text(text, "s.isaac").scene
    assert (loaded.time.start, loaded.time.end, loaded.time.frame_rate) == (0.0, 2.5, 50.0)
    assert loaded.solver.step == pytest.approx(5e-4)
    assert loaded.solver.stabilize_frequency == 2000.0
    assert loaded.audio.rate == 48000.0


def test_velocities_gravity_and_spin():
    body = scene("velocity (10, 0, 0) cm/s  spin (0, 0, 90) deg/s").body("b")
    assert body.velocity == pytest.approx((0.1, 0.0, 0.0))
    assert body.angular_velocity == pytest.approx((0.0, 0.0, math.pi / 2))
    text = "scene s {\n  gravity (0, -981, 0) cm/s2\n}\n"
    assert load_text(text, "s.isaac").scene.gravity == pytest.approx((0.0, -9.81, 0.0))


def test_forces_with_compound_units():
    forces = scene(extra="force f spring(b, (0, 1, 0)) { stiffness 2 N/m  damping 0.5 N*s/m  rest 10 cm }").forces
    (spring,) = forces
    assert (spring.stiffness, spring.damping, spring.rest_length) == pytest.approx((2.0, 0.5, 0.1))
    (load,) = scene(extra="force f load(b) { force (0, 1, 0) N  torque (0, 0, 2) N*m }").forces
    assert load.torque.value == (0.0, 0.0, 2.0)


def test_vector_with_a_unit_and_with_units_per_component():
    assert scene("at (1, 2, 3) cm").body("b").position.value == pytest.approx((0.01, 0.02, 0.03))
    assert scene("at (1 m, 20 cm, 3 mm)").body("b").position.value == pytest.approx((1.0, 0.2, 0.003))


def test_bare_numbers_are_si_in_vector_slots():
    assert scene("at (1, 2, 3)").body("b").position.value == (1.0, 2.0, 3.0)
    assert scene("velocity (1, 0, 0)").body("b").velocity == (1.0, 0.0, 0.0)


def test_bare_numbers_are_an_error_in_scalar_slots_with_a_unit():
    assert error(extra="force f spring(b, (0, 1, 0)) { stiffness 2 }") == \
        "`stiffness` needs a unit: it is a stiffness"
    with pytest.raises(SceneError, match="needs a unit: it is a length"):
        load_text("scene s {\n  body b sphere { radius 5  mass 1 kg }\n}\n", "s.isaac")
    with pytest.raises(SceneError, match="needs a unit: it is a mass"):
        load_text("scene s {\n  body b sphere { radius 5 cm  mass 1 }\n}\n", "s.isaac")


def test_bare_numbers_where_they_are_allowed():
    loaded = load_text("scene s {\n  frames 30\n  camera c { fov 40 deg }\n}\n", "s.isaac").scene
    assert loaded.time.frame_rate == 30.0  # a rate: Hz
    assert loaded.cameras[0].fov == pytest.approx(math.radians(40))


def test_a_bare_angle_is_refused_like_any_other_scalar():
    with pytest.raises(SceneError, match="`fov` needs a unit: it is an angle") as caught:
        load_text("scene s {\n  camera c { fov 40 }\n}\n", "s.isaac")
    assert caught.value.diagnostics[0].hint == "write the unit after the number, e.g. `40 deg`"


def test_a_bare_vector_in_a_slot_with_a_unit_is_read_in_si_and_said_so():
    loaded = load_text("scene s {\n  body b box { size (10, 10, 10)  mass 1 kg }\n}\n", "s.isaac")
    assert loaded.scene.body("b").shape.size == (10.0, 10.0, 10.0)
    [warning] = loaded.warnings
    assert warning.startswith("s.isaac:2:21: `size` has no unit: read as (10, 10, 10) m, a length in SI")
    assert "hint: write the unit after the vector: `(10, 10, 10) m` (or `(10, 10, 10) cm`" in warning


def test_zero_needs_no_unit_and_a_range_takes_the_unit_of_its_end():
    loaded = load_text("scene s {\n  time 5 .. 20 ms\n  body b sphere { radius 5 cm  mass 1 kg  at (0, 0, 0) }"
                       "\n  constraint n nail(b, (0, 0, 0)) during 0 .. 10 ms\n}\n", "s.isaac")
    assert (loaded.scene.time.start, loaded.scene.time.end) == pytest.approx((0.005, 0.02))
    assert (loaded.scene.constraints[0].start, loaded.scene.constraints[0].end) == pytest.approx((0.0, 0.01))
    assert loaded.warnings == []


def test_a_direction_with_a_unit_gets_a_hint_that_makes_sense():
    with pytest.raises(SceneError) as caught:
        load_text("scene s {\n  body f static plane { normal (1, 0, 0) m }\n}\n", "s.isaac")
    assert "drop the unit" in caught.value.diagnostics[0].hint


def test_euler_angles_default_to_degrees():
    quarter = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)
    for written in ("orient (90, 0, 0)", "orient euler(90, 0, 0)", "orient euler(90 deg, 0, 0)",
                    "orient euler((0.5 * pi) rad, 0, 0)", "orient axis_angle((1, 0, 0), 90)",
                    "orient quat(1, 1, 0, 0)"):
        assert scene(written).body("b").orientation.value == pytest.approx(quarter, abs=1e-12), written


def test_dimension_mismatch_in_a_sum():
    assert error("at (1 m + 2 s, 0, 0)") == "cannot add a length and a time"
    assert error("at (1, 2, 3) m + (1, 2, 3) kg") == "cannot add a length and a mass"


def test_wrong_unit_for_a_slot():
    assert error("velocity (1, 0, 0) m") == "`velocity` wants a velocity, not a length"
    assert error("spin (0, 0, 1) Hz") == "`spin` wants an angular velocity: Hz counts cycles, not radians"
    assert error("spin (0, 0, 1) m") == "`spin` wants an angular velocity, not a length"
    assert error(extra="constraint c nail(b) during 0 m .. 1 m") == "a constraint's time wants a time, not a length"


def test_a_unit_on_a_value_that_has_one():
    assert error("at (1 m, 0, 0) cm") == "this value already has a unit (a length)"


def test_arithmetic_keeps_dimensions():
    text = ("let a = 2 m\nlet area = a * a\nscene s {\n"
            "  body b sphere { radius sqrt(area) / 4  mass 1 kg  wind on  area area }\n}\n")
    body = load_text(text, "s.isaac").scene.body("b")
    assert body.shape.radius == pytest.approx(0.5)
    assert body.wind.area == pytest.approx(4.0)
    with pytest.raises(SceneError, match="wants an area, not a length"):
        load_text(text.replace("area area", "area a"), "s.isaac")


def test_decibels_are_a_gain():
    text = "scene s {\n  sound s on at(0 s) { play sine(440 Hz)  gain -6 dB }\n}\n"
    (sound,) = load_text(text, "s.isaac").scene.sounds
    assert sound.gain == pytest.approx(10 ** (-6 / 20))
