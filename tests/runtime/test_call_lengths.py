"""A run steps alike, bit for bit, whatever number of steps each kernel call covers (runtime/simulation.py): a live
run calls once a frame, `isaac run` once for many frames (with sound too), and both must give the same motion.

What used to make them differ, each checked by a scene below: a frame's steps took the length span / count, which
rounds differently from frame to frame where one call took the first frame's for all (`_steps_of`); the times of a
call's steps were counted from the call's start (`step_times`); the factorization kept between evaluations was
dropped at every call's start (the stack); RK4's slope at a call's start was computed again rather than kept
(a sliding block: its friction iterations start from the multipliers of the last evaluation)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isaac.api import Simulation
from isaac_runtime.core.timetable import TimeTable
from isaac_runtime.outputs import Recorder
from isaac_runtime.simulation import _steps_of, step_times

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def _frames(monkeypatch, scene: str, until: float, solver: str, steps_per_call: int | None) -> np.ndarray:
    """Every frame's state (positions, orientations, velocities) of a run whose calls cover at most
    steps_per_call steps (None: as many as the time table allows), its sounds recorded as `isaac run` does."""
    if steps_per_call is not None:
        monkeypatch.setattr(TimeTable, "steps_per_call", lambda self, grid: steps_per_call)
    sim = Simulation.from_file(SCENES / scene, until=until, solver=solver)
    if sim.plan.audio is not None:
        sim.plan.audio.record(sim)
    recorder = Recorder(sim.plan.frame_times, sim.plan.names)
    sim.run_frames(sim.plan.frame_times, recorder)
    monkeypatch.undo()
    return np.concatenate([recorder.position, recorder.orientation, recorder.linear_velocity,
                           recorder.angular_velocity], axis=2)


@pytest.mark.parametrize("solver", ["dynamics", "procedural"])
@pytest.mark.parametrize("scene, until", [("slide.isaac", 0.5), ("stack.isaac", 0.5), ("chimes.isaac", 1.0),
                                          ("dominoes.isaac", 0.3), ("scrape.isaac", 0.5)])
def test_calls_of_any_length_step_alike(monkeypatch, scene, until, solver):
    whole = _frames(monkeypatch, scene, until, solver, None)
    assert np.isfinite(whole).all()
    for steps in (1, 7):
        assert np.array_equal(_frames(monkeypatch, scene, until, solver, steps), whole), steps


def test_a_frame_of_steps_is_the_plans_step_to_rounding():
    """Frames 1/200 s apart at 1 ms: five steps of exactly 1 ms each, whatever the rounding of the frame times;
    an interval that is not a whole number of steps is cut into equal steps no longer than the plan's."""
    frames = np.arange(1, 400) / 200.0
    assert {_steps_of(b - a, 1e-3) for a, b in zip(frames[:-1], frames[1:])} == {(5, 1e-3)}
    assert _steps_of(0.0025, 1e-3) == (3, 0.0025 / 3)


def test_step_times_count_each_frames_steps_from_the_frame():
    times = step_times(0.1, [0.105, 0.11], 5, 1e-3)
    assert len(times) == 11 and times[0] == 0.1 and times[5] == 0.105 and times[10] == 0.11
    assert np.array_equal(times[5:10], 0.105 + 1e-3 * np.arange(5))
