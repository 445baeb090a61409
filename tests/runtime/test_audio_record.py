"""runtime/audio/record.py: the recorder keeps, at every step, the time, the placed bodies' positions and the wind
speeds in one preallocated table (StepTable), whose columns are the record's series; records made by hand fill
the same table."""
from __future__ import annotations

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.audio.record import StepColumn, StepTable, WindField, WindProbes
from isaac_runtime.run import RunOptions, simulate
from isaac_runtime.simulation import Simulation

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


def test_the_table_is_sized_for_the_run_and_grows_past_it():
    """Preallocated for the run's steps: no copy while it runs. A run longer than that (a live run driven past
    its end) still keeps every step, the earlier ones untouched."""
    result = simulate(load_text(BREEZE).scene, RunOptions())
    table = result.audio.record.steps
    assert table.size == result.simulation.state.steps + 1 <= len(table.times)
    table = StepTable(positions=1, winds=2, steps=4)
    columns = StepColumn(table, "times"), StepColumn(table, "positions", 0), StepColumn(table, "wind", 1)
    for k in range(11):
        row = table.next_step()
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
    from isaac_runtime.audio.record import _never_moving

    result = simulate(load_text(BREEZE).scene, RunOptions(until=0.1))
    sim = result.simulation
    index = {name: i for i, name in enumerate(sim.plan.names)}
    still = _never_moving(sim.plan)
    assert still[index["pole"]] and not still[index["bob"]]
    fast = WindProbes.of(result.audio.record.wind, index, still)
    every = WindProbes.of(result.audio.record.wind, index)
    field = WindField(sim.plan.scene, sim.plan)
    for t in (0.1, 0.37, 1.5):
        assert np.array_equal(field.speeds(fast, sim.state, t), field.speeds(every, sim.state, t))
