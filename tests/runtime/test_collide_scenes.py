"""The collision scenes against their answers (in their headers): cradle, scrape, bar (motion), bounce, stack;
resting contact, tunnelling, meshes, and the procedural plan. Runs are cut short where the answer is already there;
the full-length runs are marked slow."""
from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_scene
from isaac_runtime.core.rotation import quat_rotate
from isaac_runtime.run import RunOptions, simulate
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"
ASSETS = SCENES / "assets"
G = 9.81


@functools.lru_cache(maxsize=None)
def run(name: str, until: float | None = None, solver: str | None = None):
    result = simulate(load_scene(SCENES / f"{name}.isaac").scene, RunOptions(solver=solver, until=until))
    assert result.error is None, result.error
    return result


def impacts(result):
    return [e for e in result.simulation.events if e["kind"] == "impact"]


# ---- Newton's cradle -------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def cradle_strike(solver: str | None = None):
    """Speeds of the five balls just before and just after the first strike, and the strike's events."""
    sim = Simulation.from_file(SCENES / "cradle.isaac", **({"solver": solver} if solver else {}))
    before = None
    while not sim.events:
        before = np.linalg.norm(sim.state.v, axis=1)
        sim.step()
        assert sim.state.t < 1.0, "no strike"
    after = np.linalg.norm(sim.state.v, axis=1)
    return before, after, list(sim.events), sim


@pytest.mark.parametrize("solver", [None, "procedural"])
def test_cradle_passes_the_strike_to_the_last_ball(solver):
    before, after, events, _ = cradle_strike(solver)
    assert after[4] >= 0.95 * before[0]
    assert np.all(after[1:4] < 0.05 * before[0])
    # the whole row is one strike: four impacts at one time, each with the same impulse
    assert [e["bodies"] for e in events] == [["ball0", "ball1"], ["ball1", "ball2"], ["ball2", "ball3"],
                                             ["ball3", "ball4"]]
    times = [e["time"] for e in events]
    assert max(times) - min(times) < 1e-9  # (the procedural plan's capturing path dates them to rounding)
    assert all(e["kind"] == "impact" for e in events)


def test_cradle_strike_happens_at_the_bottom_of_the_swing():
    _, _, events, sim = cradle_strike()
    # ball 0 meets ball 1 when it hangs straight down: a quarter of its (large-amplitude) period, and its speed
    # is sqrt(2 g (1 - cos 30 deg)) for the point mass plus the small spin correction (I_p = 1.001)
    speed = math.sqrt(2 * G * (1 - math.cos(math.radians(30))) / 1.001)
    assert events[0]["normal_speed"] == pytest.approx(speed, rel=1e-4)
    assert events[0]["impulse"] == pytest.approx(1.001 * speed, rel=1e-3)


def test_cradle_nails_hold():
    result = run("cradle", 0.7)
    arrays = result.recorder.arrays()
    for i in range(5):
        q = arrays["orientation"][:, i]
        held = arrays["position"][:, i] + quat_rotate(q, np.broadcast_to([0.0, 1.0, 0.0], (len(q), 3)))
        assert np.max(np.linalg.norm(held - [0.1 * i, 1.0, 0.0], axis=1)) < 1e-6
    assert len(impacts(result)) == 4  # the return strike comes at 1.5 s


@pytest.mark.slow
def test_cradle_full_run_keeps_striking_and_holds():
    result = run("cradle")
    strikes = sorted({round(e["time"], 6) for e in impacts(result)})
    assert len(strikes) >= 4
    assert result.report["max_constraint_error"] < 1e-6


# ---- scrape ----------------------------------------------------------------------------------------------------

def test_scrape_slides_with_coulomb_friction():
    result = run("scrape", 0.5)
    arrays = result.recorder.arrays()
    t, v = arrays["time"], arrays["linear_velocity"][:, 1]
    down = np.array([math.cos(math.radians(30)), -math.sin(math.radians(30)), 0.0])
    speed = v @ down
    chosen = t > 0.1
    a = np.polyfit(t[chosen], speed[chosen], 1)[0]
    assert a == pytest.approx(G * (math.sin(math.radians(30)) - 0.2 * math.cos(math.radians(30))), rel=1e-3)
    # no sinking into the slope, no tumbling
    normal = np.array([math.sin(math.radians(30)), math.cos(math.radians(30)), 0.0])
    height = arrays["position"][:, 1] @ normal
    assert np.all(np.abs(height - 0.05) < 2e-6)
    assert np.abs(arrays["angular_velocity"][:, 1]).max() < 1e-5


def test_scrape_reports_its_sliding_speed_every_frame():
    result = run("scrape", 0.5)
    contacts = [e for e in result.simulation.events if e["kind"] == "contact"]
    assert len(contacts) == 50 and not impacts(result)
    times = np.array([e["time"] for e in contacts])
    assert np.allclose(np.diff(times), 0.01)
    a = G * (math.sin(math.radians(30)) - 0.2 * math.cos(math.radians(30)))
    assert [e["tangential_speed"] for e in contacts] == pytest.approx(list(a * times), rel=1e-3)
    # a frame's normal impulse is m g cos 30 deg x the frame
    assert contacts[-1]["impulse"] == pytest.approx(G * math.cos(math.radians(30)) * 0.01, rel=1e-6)


# ---- bouncing ball -----------------------------------------------------------------------------------------------

def test_bounce_heights_follow_e_squared():
    result = run("bounce", 1.35)
    arrays = result.recorder.arrays()
    y, vy = arrays["position"][:, 1, 1], arrays["linear_velocity"][:, 1, 1]
    apex = y + vy**2 / (2 * G) - 0.05  # height of the ball's bottom at the top of its flight
    times = [e["time"] for e in impacts(result)]
    t = arrays["time"]
    heights = [apex[(t > t0 + 0.002) & (t < t1 - 0.002)].max() for t0, t1 in zip(times[:5], times[1:6])]
    ratios = np.array(heights[1:]) / np.array(heights[:-1])
    assert heights[0] == pytest.approx(0.25 * 0.95, rel=1e-3)
    assert ratios == pytest.approx([0.25] * len(ratios), rel=0.02)


def test_bounce_impacts_are_events_at_their_times():
    result = run("bounce", 1.35)
    events = impacts(result)
    t1 = math.sqrt(2 * 0.95 / G)
    v = G * t1
    expected = [t1]
    for _ in range(6):
        v *= 0.5
        expected.append(expected[-1] + 2 * v / G)
    assert [e["time"] for e in events[:7]] == pytest.approx(expected, abs=1e-6)
    assert events[0]["normal_speed"] == pytest.approx(G * t1, rel=1e-6)
    assert events[0]["impulse"] == pytest.approx(0.1 * 1.5 * G * t1, rel=1e-6)
    assert all(e["bodies"] == ["floor", "ball"] and e["normal"] == pytest.approx([0, -1, 0]) for e in events)


def test_events_json_lists_every_impact(tmp_path):
    from isaac.cli import main

    assert main(["run", str(SCENES / "bounce.isaac"), "--out", str(tmp_path), "--until", "1.2"]) == 0
    events = json.loads((tmp_path / "events.json").read_text())
    listed = [e for e in events if e["kind"] == "impact"]
    assert [round(e["time"], 4) for e in listed] == [0.4401, 0.8802, 1.1002]
    assert set(listed[0]) == {"time", "bodies", "point", "normal", "impulse", "tangential_speed", "normal_speed",
                              "kind", "parts"}
    assert listed[0]["parts"] == [None, None]  # no compound bodies


# ---- bar, stack, resting contact ---------------------------------------------------------------------------

def test_bar_lands_flat_at_its_time():
    result = run("bar", 0.4)
    first = impacts(result)[0]
    assert first["time"] == pytest.approx(math.sqrt(2 * 0.2 / G), abs=1e-7)
    assert first["point"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)  # all four corners at once
    assert np.abs(result.recorder.arrays()["angular_velocity"]).max() < 1e-9


@pytest.mark.parametrize("until", [0.5, pytest.param(3.0, marks=pytest.mark.slow)])
def test_stack_stands_still(until):
    arrays = run("stack", until).recorder.arrays()
    x = arrays["position"][:, 1:]
    assert np.abs(x - x[0]).max() < 1e-4
    # the contacts hold the boxes where they stand: not a sink, not a creep
    assert np.abs(x[-1] - x[0]).max() < 1e-9
    assert np.abs(arrays["angular_velocity"][:, 1:]).max() < 1e-9


REST = """scene rest {
  time 0 s .. 10 s
  frames 100 Hz
  material wood { friction 0.6  restitution 0.5 }
  body floor plane { material wood }
  body box box { size (0.3, 0.2, 0.1)  mass 2 kg  at (0, 0.1, 0)  orient (0, 30, 0)  material wood }
}"""


@pytest.mark.parametrize("until,solver", [(0.5, None), (0.5, "procedural"),
                                          pytest.param(10.0, None, marks=pytest.mark.slow),
                                          pytest.param(10.0, "procedural", marks=pytest.mark.slow)])
def test_a_box_resting_on_a_plane_neither_sinks_nor_jitters(until, solver):
    sim = Simulation.from_text(REST, **({"solver": solver} if solver else {}))
    x0 = sim.state.x[1].copy()
    worst = 0.0
    for k in range(1, int(until * 100) + 1):
        sim.advance_to(k / 100)
        worst = max(worst, float(np.linalg.norm(sim.state.x[1] - x0)))
    assert worst < 1e-4
    assert worst <= 1.0001e-6  # it settles by the slop and stays
    assert np.abs(sim.state.v[1]).max() < 1e-12 and np.abs(sim.state.w[1]).max() < 1e-12


# ---- tunnelling ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("solver", ["dynamics", "procedural"])
@pytest.mark.parametrize("speed,start", [(10.0, -0.4), (200.0, -0.4), (900.0, -0.4),
                                         (20.0, -0.5),  # one step ends with the centre in the board's middle
                                         (100.0, -0.5622773529176417)])  # one ends just beyond the board
def test_a_fast_small_sphere_does_not_cross_a_thin_board(solver, speed, start):
    """1 cm sphere, 1 cm board, 1 ms step: the sweep test catches it up to 64 x 1.5 cm = 0.96 m per step."""
    sim = Simulation.from_text(f"""scene tunnel {{
      time 0 s .. 0.1 s
      gravity (0, 0, 0) m/s2
      solver {solver} {{ step 1 ms }}
      material hard {{ friction 0.3  restitution 1 }}
      body board static box {{ size (1, 1, 1 cm)  material hard }}
      body bullet sphere {{ radius 1 cm  mass 10 g  at (0.1, 0.2, {start})  velocity (0, 0, {speed})  material hard }}
    }}""")
    sim.advance_to(-start / speed + 0.004)
    assert sim.state.v[1, 2] == pytest.approx(-speed)  # bounced back
    assert sim.state.x[1, 2] < -0.015
    event, = [e for e in sim.events if e["kind"] == "impact"]
    assert event["time"] == pytest.approx((-start - 0.015) / speed, abs=1e-9)


# ---- the broad phase's room ------------------------------------------------------------------------------------

def test_chimes_strikes_are_the_same_with_and_without_the_room(monkeypatch):
    """The early-out's room (pairs.py) skips the broad phase while the clapper cannot have come near a tube. A
    strike it missed, or found at another time, would change the events: they must be exactly those of the
    same run checking every step in full. The run covers the first strikes, found at their sub-step times."""
    from isaac_runtime.collide import pairs

    scene = load_scene(SCENES / "chimes.isaac").scene
    with_room = simulate(scene, RunOptions(until=4.0))
    monkeypatch.setattr(pairs.BroadPhase, "_within_room", lambda self, x, x_before: False)
    every_step = simulate(scene, RunOptions(until=4.0))
    assert len(impacts(every_step)) >= 4
    assert with_room.simulation.events == every_step.simulation.events
    assert np.array_equal(with_room.simulation.state.x, every_step.simulation.state.x)


# ---- meshes ----------------------------------------------------------------------------------------------------

# the icosahedron's first face turned down, then tilted by 4 degrees
FACE_DOWN = "quat(0.895139, -0.295173, -0.014126, 0.333765)"


@pytest.mark.parametrize("mesh,height,orient", [
    pytest.param("icosahedron.obj", 0.05 * 0.7946544722917661, FACE_DOWN, marks=pytest.mark.xfail(
        strict=True, reason="known defect: it rocks between its face's vertices (|w| ~ 0.1 rad/s after 3 s) "
                            "instead of settling; the impacts of a rocking face do not take its energy")),
    ("cube.obj", 0.05, "(2, 3, 1)")])
def test_a_convex_mesh_comes_to_rest_on_a_box(mesh, height, orient):
    """Dropped a little tilted, it settles on a face (an icosahedron's is its inradius below the centre)."""
    sim = Simulation.from_text(f"""scene m {{
      time 0 s .. 1.5 s
      material m {{ friction 0.5  restitution 0.2 }}
      body table static box {{ size (1, 0.1, 1)  at (0, -0.05, 0)  material m }}
      body rock mesh {{ file "{(ASSETS / mesh).as_posix()}"  mass 0.5 kg  inertia (1e-3, 1e-3, 1e-3) kg*m2
                       at (0.001, 0.1, 0.002)  orient {orient}  material m }}
    }}""")
    sim.advance_to(1.0)
    assert sim.state.x[1, 1] == pytest.approx(height, abs=1e-9)  # on the box, not in it
    assert np.abs(sim.state.v[1]).max() < 1e-9
    assert "python-fcl" in sim.plan.collisions.describe()


def test_a_non_convex_mesh_lands_on_a_floor():
    sim = Simulation.from_text(f"""scene m {{
      time 0 s .. 1 s
      body floor plane {{ }}
      body ell mesh {{ file "{(ASSETS / 'ell.obj').as_posix()}"  mass 0.5 kg  inertia (1e-3, 1e-3, 1e-3) kg*m2
                      at (0, 0.1, 0)  orient (5, 0, 0) }}
    }}""")
    sim.advance_to(0.6)
    assert sim.state.x[1, 1] == pytest.approx(0.02, abs=1e-9)  # lies flat on its 4 cm side
    assert np.abs(sim.state.v[1]).max() < 1e-9


# ---- the procedural plan ---------------------------------------------------------------------------------------

def test_procedural_bounce_and_scrape():
    bounce = run("bounce", 1.3, "procedural")
    speeds = [e["normal_speed"] for e in impacts(bounce)][:4]
    assert np.array(speeds[1:]) / np.array(speeds[:-1]) == pytest.approx([0.5] * 3, rel=0.01)
    assert impacts(bounce)[0]["time"] == pytest.approx(math.sqrt(2 * 0.95 / G), abs=1e-3)
    scrape = run("scrape", 1.0, "procedural")
    speed = scrape.simulation.state.v[1] @ [math.cos(math.radians(30)), -math.sin(math.radians(30)), 0.0]
    assert speed == pytest.approx(G * (math.sin(math.radians(30)) - 0.2 * math.cos(math.radians(30))), rel=1e-3)


def test_a_static_body_given_a_velocity_hits_what_is_in_its_way():
    """A static body declared with a velocity drifts with it (nothing changes that velocity). It is not one that
    never moves: the broad phase's early-out recomputes its box every step instead of keeping its first one,
    so the wall below meets the ball (with the kept box it passed through it)."""
    sim = Simulation.from_text("""scene drift {
      time 0 s .. 2 s
      gravity (0, 0, 0) m/s2
      body wall static box { size (1, 1, 1)  velocity (1, 0, 0) }
      body ball sphere { radius 0.1 m  mass 1 kg  at (2, 0, 0) }
    }""")
    sim.advance_to(2.0)
    event, = impacts_of(sim)
    # the wall's face (x = 0.5 + t) meets the ball's surface (x = 1.9) at t = 1.4 s
    assert event["time"] == pytest.approx(1.4, abs=1e-8)
    assert sim.state.v[1, 0] == pytest.approx(1.5)  # restitution 0.5 off an immovable wall moving at 1 m/s


def impacts_of(sim):
    return [e for e in sim.events if e["kind"] == "impact"]


@pytest.mark.parametrize("landing", [0.3192025, 0.319205, 0.31925, 0.3192999])
def test_a_ball_that_lands_just_before_a_steps_end_bounces(landing):
    """A ball (restitution 0.5) dropped to land at `landing`, the run stopped 0.5 ms after it (off the step grid:
    the steps of that span are shortened to share it, and the impact falls just before one's end, found less than
    a micrometre deep and not rewound). It must leave at e times its impact speed; it used to be held as a resting
    contact, its bounce taken away (v = 0), at 31 of 41 landing times in 0.3192 .. 0.3193 s."""
    g, e, r = 9.81, 0.5, 0.05
    height = r + 0.5 * g * landing**2
    text = f"""scene s {{
  time 0 s .. 0.4 s
  gravity (0, -{g}, 0) m/s2
  solver dynamics {{ integrator rk4  step 0.1 ms }}
  material m {{ restitution {e}  friction 0 }}
  body floor plane {{ material m }}
  body ball sphere {{ radius {r} m  mass 1 kg  material m  at (0, {height!r} m, 0) }}
}}"""
    sim = Simulation.from_text(text)
    sim.advance_to(landing + 0.0005)
    sim.advance_to(landing + 0.005)
    # v = e g T - g (t - T) after the bounce at T; an impact resolved at the end of its step, up to 0.25 us late,
    # gains g times that: 1.5e-6 of the speed
    assert sim.state.v[1, 1] == pytest.approx(e * g * landing - g * 0.005, rel=1e-5)
