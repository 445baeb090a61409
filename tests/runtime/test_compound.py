"""Compound bodies in the runtime (docs/compound.md): collisions part by part, against the closed forms of a free
fall and of an impulse's lever arm; events that name the part struck; and the sound of one body of two materials
(the dissertation's heterogeneous object), which depends on the part struck."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.audio import compile_audio
from isaac_runtime.collide.collider import TOI_LOCATE
from isaac.api import Simulation

G = 9.81
E = 0.5  # restitution of the scenes below

DUMBBELL = """
scene s {{
  time 0 s .. 1 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics {{ integrator rk4  step 0.1 ms }}
  material steel {{ density 7800 kg/m3  friction 0  restitution {e} }}
  body floor plane {{ material steel }}
  body bell compound {{
    material steel
    part left sphere {{ radius 2 cm  at (-20, 0, 0) cm }}
    part right sphere {{ radius 2 cm  at (20, 0, 0) cm }}
    part rod cylinder {{ radius 2 mm  length 36 cm  orient (0, 90, 0) }}
    at (0, {height} m + 2 cm, 0)
    orient (0, 0, {tilt})
  }}
}}
"""


def simulation(text: str) -> Simulation:
    return Simulation.from_text(text)


def state_of(sim: Simulation, name: str) -> tuple:
    """(x, v, w) of a body: the packed state's rows [x q v w]."""
    y = sim.state.y[sim.body(name)]
    return y[0:3].copy(), y[7:10].copy(), y[10:13].copy()


STEP = 1e-4  # the scenes' step


def on_the_grid(t: float) -> float:
    """The first time of the scenes' step grid at or after t (a run stopped there takes whole steps only)."""
    return math.ceil(t / STEP - 1e-9) * STEP


def fall_time(height: float) -> float:
    # y = h - g t^2 / 2 = 0
    return math.sqrt(2.0 * height / G)


def test_a_dumbbell_dropped_flat_lands_on_both_balls_at_the_free_fall_time():
    h = 1.0
    sim = simulation(DUMBBELL.format(e=E, height=h, tilt=0))
    t_hit = fall_time(h)
    stop = on_the_grid(t_hit + 0.002)
    sim.advance_to(stop)
    first = sim.events[0]
    # located to TOI_LOCATE in distance, approached at g t
    assert first["time"] == pytest.approx(t_hit, abs=TOI_LOCATE / (G * t_hit) + 1e-12)
    assert first["kind"] == "impact" and first["parts"][0] is None and first["parts"][1] in ("left", "right")
    # both balls took the impulse: its point is midway between them, and the body bounces without turning
    assert abs(first["point"][0]) < 1e-9
    _, v, w = state_of(sim, "bell")
    assert np.abs(w).max() < 1e-9
    # Newton's restitution at both contacts alike: v+ = e v-, less what gravity took since
    t = first["time"]
    assert v[1] == pytest.approx(E * G * t - G * (stop - t), rel=1e-9)
    assert len(sim.events) == 1


def test_a_tilted_dumbbell_lands_on_its_lower_ball_first_and_the_event_names_it():
    h = 1.0
    tilt = 2.0  # degrees: the right ball is 20 cm sin(2 deg) = 7 mm lower than the centre
    sim = simulation(DUMBBELL.format(e=0, height=h, tilt=-tilt))
    drop = h - 0.2 * math.sin(math.radians(tilt))
    sim.advance_to(fall_time(h) + 0.05)
    impacts = [e for e in sim.events if e["kind"] == "impact"]
    assert impacts[0]["parts"] == [None, "right"]
    assert impacts[0]["time"] == pytest.approx(fall_time(drop), abs=TOI_LOCATE / (G * fall_time(drop)) + 1e-12)
    assert impacts[0]["point"][0] == pytest.approx(0.2 * math.cos(math.radians(tilt)), abs=1e-6)
    assert any(e["parts"] == [None, "left"] for e in impacts[1:]), impacts


KEY = """
scene s {
  time 0 s .. 1 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 0.1 ms }
  material slick { density 1000 kg/m3  friction 0  restitution 0.5 }
  body floor plane { material slick }
  body key compound {
    material slick
    part bar box { size (40, 2, 2) cm }
    part knob sphere { radius 1 cm  at (15, -2, 0) cm }
    at (0, 53, 0) cm
  }
}
"""


def knob_impulse(t_impact: float) -> tuple:
    """(j, dw per unit impulse (3,), m) of the key's knob landing at t_impact (it falls 0.5 m). A frictionless
    impulse j n at r from the centre of mass, with restitution e:
        j = (1 + e) u / (1/m + n . ((I^-1 (r x n)) x r)),   dv = j n / m,   dw = I^-1 (r x j n)."""
    body = load_text(KEY, "s.isaac").scene.body("key")
    m, inertia = body.mass, np.asarray(body.inertia, float)
    # the contact: the knob's lowest point, (15, 0, 0) cm from the written origin, which is now at the floor
    centre = np.asarray(body.position.value, float) - (0.0, 0.5, 0.0)  # it fell 0.5 m
    r = np.array([0.15, 0.0, 0.0]) - centre
    n = np.array([0.0, 1.0, 0.0])
    u = G * t_impact  # the approach speed at the located time of impact
    arm = np.linalg.solve(inertia, np.cross(r, n))
    return (1 + E) * u / (1 / m + n @ np.cross(arm, r)), arm, m


def test_a_part_off_the_centre_turns_the_body_as_the_impulses_lever_arm_says():
    """The knob, 15 cm out, lands first, and the body turns as the impulse's lever arm says (knob_impulse)."""
    sim = Simulation.from_text(KEY)
    t_hit = fall_time(0.5)
    stop = on_the_grid(t_hit + 0.001)
    sim.advance_to(stop)
    first = sim.events[0]
    assert first["parts"] == [None, "knob"]
    assert first["time"] == pytest.approx(t_hit, abs=TOI_LOCATE / (G * t_hit) + 1e-12)
    j, arm, m = knob_impulse(first["time"])
    assert first["impulse"] == pytest.approx(j, rel=1e-9)
    _, v, w = state_of(sim, "key")
    # the turn is about z, a principal axis (the parts lie in z = 0), so w stays what the impulse made it
    np.testing.assert_allclose(w, j * arm, rtol=1e-9, atol=1e-12)
    assert w[2] > 10.0  # rad/s: the lever arm is real, not rounding
    assert v[1] == pytest.approx(-G * first["time"] + j / m - G * (stop - first["time"]), rel=1e-9)


def test_a_bounce_found_at_the_end_of_a_step_keeps_its_restitution():
    """The knob's impact of the test above, with the run stopped 1 ms after it, off the step grid: the steps are
    then a little shorter (advance_to shares the span equally), and the impact falls 7e-8 s before a step's end,
    found 1e-7 .. 1e-6 m deep (not rewound). Its point parts faster than a resting contact and is out within a
    step: it is let go (runtime/collide/contacts.py update), not held as a contact whose row takes the bounce."""
    sim = Simulation.from_text(KEY)
    sim.advance_to(fall_time(0.5) + 0.001)
    j, arm, _ = knob_impulse(sim.events[0]["time"])
    _, v, w = state_of(sim, "key")
    np.testing.assert_allclose(w, j * arm, rtol=1e-6, atol=1e-9)


def test_the_compound_as_a_whole_falls_like_a_point_mass():
    """Before it touches anything, a body made of parts is one rigid body: its centre of mass falls by g t^2 / 2
    from where `at` and the parts put it."""
    sim = Simulation.from_text(KEY)
    body = load_text(KEY, "s.isaac").scene.body("key")
    sim.advance_to(0.2)
    x, v, w = state_of(sim, "key")
    start = np.asarray(body.position.value, float)
    np.testing.assert_allclose(x, start - (0, 0.5 * G * 0.04, 0), atol=1e-12)
    assert np.abs(w).max() == 0.0


# ---- one body, two materials: the sound depends on the part struck ------------------------------------------

FS = 22050
PAIR = """
scene s {{
  time 0 s .. 1 s
  audio {{ rate 22050 Hz  channels 1 }}
  listener {{ at (0, 0, 1) }}
  solver dynamics {{ integrator rk4  step 0.1 ms }}
  material steel {{ density 7850 kg/m3  young 200 GPa  poisson 0.29  loss 0.0002 }}
  material oak {{ density 700 kg/m3  young 11 GPa  poisson 0.3  loss 0.01 }}
  body pair static compound {{
    part iron box {{ size (30, 1, 3) cm  at (0, 0, -3) cm  material steel }}
    part wood box {{ size (30, 1, 3) cm  at (0, 0, 3) cm  material oak }}
  }}
  body ball sphere {{ radius 5 mm  material steel  at ({x}, 10.5, {z}) cm }}
  sound knock on collide(ball, pair) {{ play impact(pair) * impulse }}
}}
"""


# cos(beta L) cosh(beta L) = 1: the free-free bar's first three roots
BETA_L = (4.730040745, 7.853204624, 10.995607838)


def bar_modes(young: float, density: float, length: float, thickness: float) -> np.ndarray:
    """The first free-free bending modes of a bar across its thickness h:
    f_n = (beta_n L)^2 / (2 pi L^2) (h / sqrt 12) sqrt(E / rho)."""
    return np.array([b**2 / (2 * math.pi * length**2) * thickness / math.sqrt(12) * math.sqrt(young / density)
                     for b in BETA_L])


STEEL = bar_modes(200e9, 7850, 0.30, 0.01)  # 576.5, 1589, 3116 Hz
OAK = bar_modes(11e9, 700, 0.30, 0.01)  # 452.8, 1248, 2447 Hz


def spectrum(samples, start: float = 0.0) -> tuple:
    """(frequencies, |FFT|, samples) of the audio from `start` s on."""
    x = np.asarray(samples, float).reshape(-1)[int(start * FS):]
    return np.fft.rfftfreq(len(x), 1 / FS), np.abs(np.fft.rfft(x)), x


def lines(freq, power, modes) -> float:
    """The strongest of the spectrum's lines within 2 Hz of the given modes."""
    return max(power[np.abs(freq - f) <= 2.0].max() for f in modes)


def heard(samples) -> dict:
    """What a listener can tell of one hit: the loudest line, the steel and oak lines' strengths, and how much
    of the sound is left half a second after the hit (at 0.1 s)."""
    freq, power, x = spectrum(samples)
    late = np.sqrt(np.mean(x[int(0.6 * FS):] ** 2)) / np.sqrt(np.mean(x**2))
    return {"loudest": freq[np.argmax(power)], "steel": lines(freq, power, STEEL), "oak": lines(freq, power, OAK),
            "late": late}


def synthetic_hit(part: str | None, z: float) -> dict:
    return {"time": 0.1, "bodies": ["ball", "pair"], "point": [0.07, 0.005, z], "normal": [0.0, 1.0, 0.0],
            "impulse": 0.01, "tangential_speed": 0.0, "normal_speed": 1.0, "kind": "impact", "parts": [None, part]}


@pytest.fixture(scope="module")
def pair_audio():
    return compile_audio(load_text(PAIR.format(x=7, z=-3), "s.isaac").scene)


def hit_on(pair_audio, part, z) -> dict:
    return heard(pair_audio.render(pair_audio.synthetic_record([synthetic_hit(part, z)])))


def test_each_part_rings_with_its_own_materials_modes(pair_audio):
    described = pair_audio.describe()
    assert "pair.iron" in described and "pair.wood" in described
    iron, wood = hit_on(pair_audio, "iron", -0.03), hit_on(pair_audio, "wood", 0.03)
    # the loudest line is one of the struck part's bending modes (1 Hz bins over 1 s), and the other part is
    # silent: a body that ignored its parts would ring the same both times
    assert np.abs(STEEL - iron["loudest"]).min() <= 1.0
    assert np.abs(OAK - wood["loudest"]).min() <= 1.0
    assert iron["steel"] > 100 * iron["oak"]
    assert wood["oak"] > 100 * wood["steel"]
    # steel (loss 2e-4) still rings half a second on; oak (1e-2: d = pi f loss = 14 /s at 453 Hz) is gone
    assert iron["late"] > 0.3
    assert wood["late"] < 1e-2


def test_a_hit_that_names_no_part_rings_every_part(pair_audio):
    both = hit_on(pair_audio, None, 0.0)
    iron = hit_on(pair_audio, "iron", -0.03)
    assert both["oak"] > 10 * iron["oak"] and both["steel"] > 0.5 * iron["steel"]


@pytest.mark.parametrize("z,part,modes", [(-3, "iron", STEEL), (3, "wood", OAK)])
def test_a_ball_dropped_on_each_part_of_one_body_sounds_of_that_part(z, part, modes):
    """The whole path: the ball falls 10 cm onto the part (its events name it), and audio.wav's loudest line is
    one of that part's modes."""
    from isaac_runtime.run import RunOptions, simulate

    scene = load_text(PAIR.format(x=7, z=z), "s.isaac").scene
    result = simulate(scene, RunOptions(until=1.0))
    assert result.error is None
    impacts = [e for e in result.simulation.events if e["kind"] == "impact"]
    assert impacts and impacts[0]["parts"] == [part, None]
    assert impacts[0]["time"] == pytest.approx(fall_time(0.105 - 0.005 - 0.005), abs=1e-6)
    sound = heard(result.audio.render())
    assert np.abs(modes - sound["loudest"]).min() <= 1.0
    other = "oak" if part == "iron" else "steel"
    assert sound["steel" if part == "iron" else "oak"] > 100 * sound[other]


def test_a_compound_on_a_compound_names_both_parts():
    """The dumbbell dropped flat across a static table of two slabs: its left ball lands on the west slab and its
    right ball on the east one, 1 m below, at the free fall time."""
    text = DUMBBELL.format(e=0, height=1.0, tilt=0).replace(
        "body floor plane { material steel }",
        "body table static compound {\n    material steel\n"
        "    part west box { size (20, 10, 10) cm  at (-20, -5, 0) cm }\n"
        "    part east box { size (20, 10, 10) cm  at (20, -5, 0) cm }\n  }")
    sim = simulation(text)
    t_hit = fall_time(1.0)
    sim.advance_to(on_the_grid(t_hit + 0.001))
    first = sim.events[0]
    assert first["bodies"] == ["table", "bell"]  # in the order of declaration
    assert first["time"] == pytest.approx(t_hit, abs=TOI_LOCATE / (G * t_hit) + 1e-12)
    assert first["parts"] in (["west", "left"], ["east", "right"])
    _, v, w = state_of(sim, "bell")
    assert np.abs(w).max() < 1e-9 and abs(v[1]) < 1e-9  # restitution 0: both balls stopped alike


def test_the_exports_draw_each_part_in_its_place():
    """The hammer of docs/compound.md tessellated in its body frame (origin at the centre of mass c = 29.27 cm up
    the handle): the handle's foot at -c, the head's flat ends at x = +-5 cm, its top at 34 cm - c."""
    from isaac_runtime.export.geometry import tessellate

    text = """
scene s {
  material oak { density 700 kg/m3 }
  material steel { density 7850 kg/m3 }
  body hammer compound {
    material oak
    part handle box { size (3, 30, 3) cm  at (0, 15, 0) cm }
    part head cylinder { radius 2 cm  length 10 cm  at (0, 32, 0) cm  orient (0, 90, 0)  material steel }
  }
}
"""
    shape = load_text(text, "s.isaac").scene.body("hammer").shape
    handle, head = 700 * 0.03 * 0.3 * 0.03, 7850 * math.pi * 0.02**2 * 0.1
    c = (0.15 * handle + 0.32 * head) / (handle + head)
    points = tessellate(shape).positions
    np.testing.assert_allclose(points.min(axis=0)[:2], (-0.05, -c), atol=1e-12)
    np.testing.assert_allclose(points.max(axis=0)[:2], (0.05, 0.34 - c), atol=1e-12)


def test_a_mesh_part_lands_on_its_lowest_vertex_at_the_free_fall_time():
    """A compound of an icosahedron mesh (python-fcl against the table) and a ball: the mesh's lowest vertex,
    4.25325404 cm below its origin, falls 0.6 m less that and lands first, and the event names the mesh part."""
    from pathlib import Path

    scenes = Path(__file__).resolve().parents[2] / "scenes"
    text = """
scene s {
  time 0 s .. 1 s
  solver dynamics { integrator rk4  step 0.5 ms }
  material m { density 1000 kg/m3  restitution 0.3  friction 0.5 }
  body table static box { size (1, 0.1, 1) m  at (0, -0.05, 0)  material m }
  body thing compound {
    material m
    part rock mesh { file "assets/icosahedron.obj"  at (-0.1, 0, 0) m }
    part ball sphere { radius 3 cm  at (0.1, 0.02, 0) m }
    at (0, 0.6, 0)
  }
}
"""
    sim = Simulation.from_text(text, folder=scenes)
    drop = 0.6 - 0.0425325404
    sim.advance_to(fall_time(drop) + 0.01)
    first = sim.events[0]
    assert first["parts"] == [None, "rock"]
    assert first["time"] == pytest.approx(fall_time(drop), abs=TOI_LOCATE / (G * fall_time(drop)) + 1e-12)


def test_a_kinematic_compound_carries_its_written_origin_on_the_path():
    """`at` and `orient` of a kinematic compound follow t; its centre of mass, c = (0.1, 0, 0) m from the written
    origin, is at(t) + R(t) c: at t = 0.5 s, (sin 0.5 + 0.1 cos 45 deg, 0.1 sin 45 deg, 0)."""
    sim = Simulation.from_text("""
scene s {
  time 0 s .. 1 s
  body arm kinematic compound {
    part a sphere { radius 1 cm  mass 1 kg  at (0.3, 0, 0) m }
    part b sphere { radius 1 cm  mass 2 kg }
    at (sin(t / 1 s) * 1 m, 0 m, 0 m)
    orient euler(0, 0, (90 * t / 1 s) deg)
  }
}""")
    sim.advance_to(0.5)
    x, _, _ = state_of(sim, "arm")
    turn = math.radians(45)
    np.testing.assert_allclose(x, (math.sin(0.5) + 0.1 * math.cos(turn), 0.1 * math.sin(turn), 0.0), atol=1e-12)


BELLS = """
scene s {{
  time 0 s .. 1 s
  audio {{ rate 22050 Hz  channels 1 }}
  body bells static compound {{
    {modes}
    part low sphere {{ radius 1 cm  at (-5, 0, 0) cm  modes ((440, 3, 1), (2200, 30, 0.1)) }}
    part high sphere {{ radius 1 cm  at (5, 0, 0) cm  modes ((1000, 3, 1), (5000, 30, 0.1)) }}
  }}
  body ball sphere {{ radius 5 mm  mass 10 g  at (0, 5, 0) cm }}
  sound ding on collide(ball, bells) {{ play modal(bells) * impulse }}
}}
"""


def test_a_parts_own_modes_table_rings_when_it_is_struck():
    audio = compile_audio(load_text(BELLS.format(modes=""), "s.isaac").scene)
    for part, x, f in (("low", -0.05, 440.0), ("high", 0.05, 1000.0)):
        hit = synthetic_hit(part, 0.0) | {"bodies": ["ball", "bells"], "point": [x, 0.01, 0.0]}
        freq, power, _ = spectrum(audio.render(audio.synthetic_record([hit])))
        assert freq[np.argmax(power)] == pytest.approx(f, abs=1.0)


def test_a_modes_table_on_the_body_rings_it_as_one():
    audio = compile_audio(load_text(BELLS.format(modes="modes ((700, 3, 1), (3500, 30, 0.1))"), "s.isaac").scene)
    hit = synthetic_hit("low", 0.0) | {"bodies": ["ball", "bells"], "point": [-0.05, 0.01, 0.0]}
    freq, power, _ = spectrum(audio.render(audio.synthetic_record([hit])))
    assert freq[np.argmax(power)] == pytest.approx(700.0, abs=1.0)
