"""Goals on a finished run (docs/goals.md): each goal's value, its error, and whether it is met.

A state goal is read at its own time exactly, not from frames: the run stops there (`run_with_goal_stops`: the
frames before it, then the step loop to the goal's time, which cuts the last piece there) and the state is kept.
An event goal is read from the run's events: the time of the first impact (`collide`) or lasting contact
(`contact`) of its pair, located inside its step by the collision stage.
"""
from __future__ import annotations

import math

import numpy as np

from isaac_ir import ir

AXES = {"x": 0, "y": 1, "z": 2}
EVENT_KINDS = {"collide": "impact", "contact": "contact"}


def goal_times(scene: ir.Scene) -> list:
    """The distinct times at which a state goal reads the state, in order."""
    return sorted({goal.time for goal in scene.goals if goal.kind == "state"})


def run_with_goal_stops(sim, frame_times, recorder, stops: list, on_frame=None) -> dict:
    """Run to the last frame, recording every frame, and stop exactly at each time of `stops` on the way:
    {time: (x (n,3), q (n,4), v (n,3)) copies}; also {"start": ...} the state the run started from. A stop after
    the last frame (a run cut short by --until) is not reached and not in the answer."""
    frame_times = np.asarray(frame_times, float)
    states = {"start": _snapshot(sim)}
    done = -math.inf
    end = float(frame_times[-1]) if len(frame_times) else sim.state.t
    for stop in stops:
        if stop > end + 1e-12:
            break
        before = frame_times[(frame_times > done) & (frame_times <= stop + 1e-12)]
        if len(before):
            sim.run_frames(before, recorder, on_frame)
        sim.advance_to(stop)  # (nothing to do when the stop is a frame's time)
        states[stop] = _snapshot(sim)
        done = float(before[-1]) if len(before) else done
    rest = frame_times[frame_times > done]
    if len(rest):
        sim.run_frames(rest, recorder, on_frame)
    return states


def _snapshot(sim) -> tuple:
    s = sim.state
    return s.x.copy(), s.q.copy(), s.v.copy()


def evaluate_goals(scene: ir.Scene, names: list, states: dict, events: list) -> list:
    """report.json's `goals`: for each goal its name, met, value, target, error and tolerance (SI; an event
    goal's value is the first event's time, null when there was none; a state goal not reached: value null)."""
    return [evaluate_goal(goal, names, states, events) for goal in scene.goals]


def evaluate_goal(goal: ir.Goal, names: list, states: dict, events: list) -> dict:
    if goal.kind == "event":
        value, target = first_event_time(goal, events), goal.time
    else:
        value, target = state_value(goal, names, states), goal.target
    error = goal_error(value, target)
    return {"name": goal.name, "kind": goal.kind, "met": error is not None and error <= goal.tolerance, "value": _plain(value),
            "target": _plain(target), "error": error, "tolerance": goal.tolerance, "source": goal.source}


def goal_error(value, target) -> float | None:
    """|value - target|, the Euclidean length for a vector; None when there is no value."""
    if value is None:
        return None
    # e = ||value - target||
    return float(np.linalg.norm(np.subtract(value, target)))


def residuals(goal_record: dict, missing: float) -> list:
    """The goal's misses in tolerances, one per component (a fit's least-squares residuals); `missing` for each
    when the goal has no value (no event, a run cut short)."""
    size = len(goal_record["target"]) if isinstance(goal_record["target"], list) else 1
    if goal_record["value"] is None:
        return [missing] * size
    # r = (value - target) / tolerance
    difference = np.subtract(goal_record["value"], goal_record["target"]) / goal_record["tolerance"]
    return [float(r) for r in np.atleast_1d(difference)]


def state_value(goal: ir.Goal, names: list, states: dict):
    """The body's centre of mass position or velocity (world), or its rotation angle from the start, at the
    goal's time; a component when the goal names one. None when the run did not reach that time."""
    state = states.get(goal.time)
    if state is None:
        return None
    x, q, v = state
    body = names.index(goal.bodies[0])
    if goal.quantity == "angle":
        return rotation_angle(states["start"][1][body], q[body])
    vector = (x if goal.quantity == "position" else v)[body]
    if goal.component is not None:
        return float(vector[AXES[goal.component]])
    return tuple(float(c) for c in vector)


def rotation_angle(q0, q) -> float:
    """The angle of the rotation that takes orientation q0 to q (quaternions w, x, y, z), in [0, pi]."""
    # q_rel = q q0*: its scalar part is the dot product of the two quaternions (up to sign)
    w = abs(float(np.dot(q0, q)) / (float(np.linalg.norm(q0)) * float(np.linalg.norm(q))))
    # angle = 2 acos(|w|)
    return 2.0 * math.acos(min(1.0, w))


def first_event_time(goal: ir.Goal, events: list) -> float | None:
    """The time of the first event of the goal's kind between its two bodies, or None."""
    kind, pair = EVENT_KINDS[goal.quantity], set(goal.bodies)
    for event in events:
        if event.get("kind") == kind and set(event.get("bodies", ())) == pair:
            return float(event["time"])
    return None


def goals_check(records: list) -> dict:
    """report.json's `checks.goals`: ok when every goal is met; the missed ones named."""
    missed = [r["name"] for r in records if not r["met"]]
    worst = max((r["error"] / r["tolerance"] for r in records if r["error"] is not None), default=0.0)
    return {"ok": not missed, "missed": missed, "value": worst, "limit": 1.0}


def describe_miss(record: dict) -> str:
    """`hit` missed by 3.2e-05 (tolerance 1e-06), or `land`: no event (tolerance ...)."""
    if record["error"] is None:
        why = "no such event in the run" if record["kind"] == "event" else "its time not reached by the run"
        return f"`{record['name']}`: {why} (tolerance {record['tolerance']:.3g})"
    return f"`{record['name']}` missed by {record['error']:.3g} (tolerance {record['tolerance']:.3g}, SI units)"


def _plain(value):
    return list(value) if isinstance(value, tuple) else value
