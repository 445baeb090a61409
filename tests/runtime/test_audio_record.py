"""runtime/audio/record.py: the recorder keeps, at every step, the time, the placed bodies' positions and the wind
speeds in one preallocated table (StepTable), whose columns are the record's series; records made by hand fill
the same table."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.audio.record import StepColumn, StepTable, WindField, WindProbes
from isaac_runtime.run import RunOptions, simulate
from isaac.api import Simulation

BREEZE = """scene breeze {
  time 0 s .. 0.3 s
  audio { rate 22050 Hz }
  listener { at (0.3, 1, 2) }
  body pole static cylinder { radius 2 mm  length 1 m  at (0.5, 1, 0) }
  body bob sphere { radius 5 cm  mass 10 g  at (0, 1, 0)  velocity (0.5, 2, 0)  wind on }
  wind gale { direction (1, 0, 0.3)  speed 6 m/s + 1 m/s * sin(t / 1 s)  turbulence 0.5  gust 0.3 s }
  sound air on wind(gale) { play wind_noise() + whistle(pole) + whistle(bob) }
  sound knock on collide(bob) { play impact() }
}"""


def test_the_record_holds_every_step_as_the_simulation_went():
    """Times, positions and wind speeds of the record, step by step, against the state each step left (seen by
    an observer after the recorder's) and the wind field asked point by point."""
    sim = Simulation.from_text(BREEZE)
    run = sim.plan.audio.record(sim)
    seen = []
    sim.observers.append(lambda s, h: seen.append((s.state.t, s.state.x.copy(), s.state.v.copy())))
    sim.advance_to(0.3)
    record = run.record
    field = WindField(sim.plan.scene, sim.plan)
    times = record.times.view()
    assert len(times) == len(seen) + 1 and times[0] == 0.0  # the start, then every step
    assert np.array_equal(times[1:], [t for t, _, _ in seen])
    bob, pole = sim.plan.names.index("bob"), sim.plan.names.index("pole")
    assert np.array_equal(record.positions["bob"].view()[1:], [x[bob] for _, x, _ in seen])
    for k, (t, x, v) in enumerate(seen, start=1):
        for body, i in (("bob", bob), ("pole", pole)):
            expected = np.linalg.norm(field.velocity(x[i][None, :], t)[0] - v[i])
            assert record.wind[body].view()[k] == pytest.approx(expected, rel=1e-14, abs=1e-14)
        listener = field.listener_speed("gale", t)
        assert record.wind[("listener", "gale")].view()[k] == pytest.approx(listener, rel=1e-14, abs=1e-14)


SCENES = Path(__file__).resolve().parents[2] / "scenes"
LANDING = BREEZE.replace("time 0 s .. 0.3 s", "time 0 s .. 1 s\n  frames 100 Hz\n  body floor plane { }")


def _recorded(make, one_step_per_call: bool):
    """(record, kernel calls) of a whole run of frames of make(), the kernel taking many steps per call (the
    recorder is handed each call's steps) or, with an observer listening, one."""
    from isaac_runtime.outputs import Recorder as FrameRecorder

    sim = make()
    run = sim.plan.audio.record(sim)
    if one_step_per_call:
        sim.observers.append(lambda s, h: None)
    calls, stepper_run = [], sim.stepper.run
    sim.stepper.run = lambda *args: calls.append(args[4]) or stepper_run(*args)
    sim.run_frames(sim.plan.frame_times, FrameRecorder(sim.plan.frame_times, sim.plan.names))
    return run.record, len(calls)


@pytest.mark.parametrize("make", [lambda: Simulation.from_text(LANDING),
                                  lambda: Simulation.from_file(SCENES / "scrape.isaac", until=0.6)],
                         ids=["landing", "scrape"])
def test_a_call_of_many_steps_records_what_calls_of_one_step_do(make):
    """The kernel hands the recorder the state of every step of a call (Simulation.add_tracer), a call covering
    many frames: the same table, hits (their points in the bodies' frames at the step each happened in) and
    contact samples as stepping one step per call, in a fraction of the calls (1 ms steps, 100 Hz frames)."""
    many, calls = _recorded(make, False)
    one, one_calls = _recorded(make, True)
    assert len(many.hits) == len(one.hits)
    for a, b in zip(many.hits, one.hits):
        assert (a.sample, a.bodies) == (b.sample, b.bodies) and a.impulse == pytest.approx(b.impulse, rel=1e-9)
        assert a.local.keys() == b.local.keys()
        for body in a.local:
            assert np.allclose(a.local[body], b.local[body], rtol=0, atol=1e-12)
    assert np.array_equal(many.times.view(), one.times.view())
    for key in many.positions:
        assert np.allclose(many.positions[key].view(), one.positions[key].view(), rtol=0, atol=1e-12)
    for key in many.wind:
        assert np.allclose(many.wind[key].view(), one.wind[key].view(), rtol=1e-12, atol=1e-12)
    assert many.contacts.keys() == one.contacts.keys()
    for pair, series in many.contacts.items():
        for name, column in series.items():
            assert np.allclose(column.view(), one.contacts[pair][name].view(), rtol=1e-9, atol=1e-12), (pair, name)
    assert one_calls >= len(one.times.view()) - 1 and calls <= one_calls / 5


def test_the_table_is_sized_for_the_run_and_grows_past_it():
    """Preallocated for the run's steps: no copy while it runs. A run longer than that (a live run driven past
    its end) still keeps every step, the earlier ones untouched."""
    result = simulate(load_text(BREEZE).scene, RunOptions())
    table = result.audio.record.steps
    assert table.size == result.simulation.state.steps + 1 <= len(table.times)
    table = StepTable(positions=1, winds=2, steps=4)
    columns = StepColumn(table, "times"), StepColumn(table, "positions", 0), StepColumn(table, "wind", 1)
    for k in range(11):
        row = table.room_for(1)
        table.times[row], table.positions[0, row], table.wind[:, row] = 0.1 * k, (k, 2 * k, 3 * k), (-k, k)
        table.size = row + 1
    assert len(table.times) == 16 and all(column.size == 11 for column in columns)
    assert np.array_equal(columns[0].view(), 0.1 * np.arange(11))
    assert np.array_equal(columns[1].view(), np.outer(np.arange(11), [1, 2, 3]))
    assert np.array_equal(columns[2].view(), np.arange(11))


def test_a_record_made_by_hand_fills_the_same_columns():
    plan = simulate(load_text(BREEZE).scene, RunOptions(until=0.01)).simulation.plan.audio
    record = plan.synthetic_record([], end=0.2, wind={"pole": ([0.0, 0.2], [1.0, 3.0])}, step=0.01)
    times = record.times.view()
    assert np.allclose(times, np.arange(21) * 0.01) and record.until == times[-1]
    assert np.array_equal(record.wind["pole"].view(), np.interp(times, [0.0, 0.2], [1.0, 3.0]))
    assert np.array_equal(record.wind["bob"].view(), np.zeros(21))  # not given: still air
    assert np.array_equal(record.positions["bob"].view(), np.tile([0.0, 1.0, 0.0], (21, 1)))


def test_wind_speeds_go_into_the_given_row():
    """`speeds(..., out=)` writes the record's column of one step in place, the same numbers as returned."""
    result = simulate(load_text(BREEZE).scene, RunOptions(until=0.05))
    sim = result.simulation
    index = {name: i for i, name in enumerate(sim.plan.names)}
    field = WindField(sim.plan.scene, sim.plan)
    probes = WindProbes.of(result.audio.record.wind, index)
    table = np.full((len(probes.keys), 3), -1.0)
    field.speeds(probes, sim.state, 0.37, out=table[:, 1])
    assert np.array_equal(table[:, 1], field.speeds(probes, sim.state, 0.37))
    assert np.all(table[:, [0, 2]] == -1.0)


def test_bodies_that_never_move_keep_their_point():
    """The recorder tells WindProbes which bodies never move (static, at rest): their points are filled once,
    their velocity taken as 0. The same speeds, to the last bit, as reading every body from the state."""
    from isaac_runtime.plan.kinematics import never_moving

    result = simulate(load_text(BREEZE).scene, RunOptions(until=0.1))
    sim = result.simulation
    index = {name: i for i, name in enumerate(sim.plan.names)}
    still = never_moving(sim.plan)
    assert still[index["pole"]] and not still[index["bob"]]
    fast = WindProbes.of(result.audio.record.wind, index, still)
    every = WindProbes.of(result.audio.record.wind, index)
    field = WindField(sim.plan.scene, sim.plan)
    for t in (0.1, 0.37, 1.5):
        assert np.array_equal(field.speeds(fast, sim.state, t), field.speeds(every, sim.state, t))


def test_a_sound_on_the_contacts_of_one_body_hears_each_frame_of_them():
    """`contact(block)`: any body the block touches, so every body's state is traced. The block slides down the
    30 degree slope from rest at a = g (sin 30 deg - 0.2 cos 30 deg) = 3.2058 m/s2 (scenes/scrape.isaac): the
    sliding and the rolling speed both read a t at each frame (it slides without turning)."""
    text = (SCENES / "scrape.isaac").read_text().replace(
        "on contact(block, slope) { play lowpass(scrape(), 4 kHz) * 0.1 }",
        "on contact(block) { play sine(440 Hz) * speed * 0.1 }")
    sim = Simulation.from_text(text, folder=SCENES)
    run = sim.plan.audio.record(sim)
    from isaac_runtime.outputs import Recorder as FrameRecorder

    frames = sim.plan.frame_times[sim.plan.frame_times <= 0.5 + 1e-9]
    sim.run_frames(frames, FrameRecorder(frames, sim.plan.names))
    (pair, series), = run.record.contacts.items()
    assert pair == ("block",) and series["times"].size == len(frames) - 1
    a = 9.81 * (np.sin(np.radians(30)) - 0.2 * np.cos(np.radians(30)))
    times = series["times"].view()
    assert np.allclose(series["speed"].view(), a * times, rtol=1e-3, atol=1e-3)
    assert np.allclose(series["roll"].view(), series["speed"].view(), rtol=1e-9, atol=1e-12)
