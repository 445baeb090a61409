"""Audio stage, recording the motion: an observer of the step loop that keeps what the sounds read.

After every step (Simulation.observers) it stores, at the step's end time:
- hits: every new collision event of kind "impact", with its sample round((t - start) fs), the contact point
  in each body's frame (for the mode shapes) and the contact duration (excitation.py);
- for each body pair a sound listens to (contact sounds, scrape, roll), at the time of each of the pair's
  "contact" events (one per output frame while they touch, runtime/collide/events.py): the sliding speed
  (the event's tangential speed), the normal force (its impulse over the frame, / the frame period), the
  rolling speed (the relative velocity of the two centres, tangential to the contact normal) and the contact
  point in each body's frame; and a zero at every frame time the pair does not touch;
- positions of the bodies the sounds are placed at; wind speeds at bodies (relative to them) and at the
  listener.
The renderer interpolates these to the audio samples, so a signal is read at sample-accurate times.
A record can also be made by hand (`synthetic_record`) from a list of event dicts: tests and benchmarks
render sounds without running the simulation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
import numpy as np

from isaac_lang import expr as E

from .excitation import contact_duration


class Series:
    """A growable array of samples (each of shape `item`), appended one step at a time."""

    def __init__(self, item: tuple = ()):
        self.data = np.zeros((256,) + item)
        self.size = 0

    def append(self, value) -> None:
        if self.size == len(self.data):
            self.data = np.concatenate([self.data, np.zeros_like(self.data)])
        self.data[self.size] = value
        self.size += 1

    def view(self) -> np.ndarray:
        return self.data[: self.size]


@dataclass
class Hit:
    """One collision, as the sounds hear it."""

    time: float
    sample: int  # round((time - start) * fs)
    bodies: tuple  # names (a static body or the world may be None)
    impulse: float  # N s
    normal_speed: float  # m/s
    tangential_speed: float  # m/s
    point: np.ndarray  # (3,) world
    local: dict  # body -> (3,) contact point in the body's frame
    tau: float  # s, contact duration
    index: int  # position in events.json

    def values(self) -> dict:
        """The event signals of SOUND.md at this hit (distance and wind speed are added by the renderer)."""
        return {"impulse": self.impulse, "speed": self.normal_speed, "normal_force": self.impulse / self.tau,
                "t": self.time}


@dataclass
class MotionRecord:
    start: float
    fs: float
    times: Series = field(default_factory=Series)  # the steps' end times
    positions: dict = field(default_factory=dict)  # body -> Series (3,), at `times`
    contacts: dict = field(default_factory=dict)  # pair -> {"times", "speed", "force", "roll": Series,
    #                                                        ("local", body): Series (3,)}, at their own times
    wind: dict = field(default_factory=dict)  # body name, or ("listener", wind) -> Series, at `times`
    hits: list = field(default_factory=list)

    @property
    def until(self) -> float:
        """The time up to which the motion is known."""
        return float(self.times.data[self.times.size - 1]) if self.times.size else -math.inf


class Recorder:
    """The observer: started by AudioPlan.record(sim), fills a MotionRecord as the simulation steps."""

    def __init__(self, plan, sim):
        self.plan = plan
        self.record = new_record(plan)
        self.index = {name: i for i, name in enumerate(sim.plan.names)}
        self.air = WindField(plan.scene, sim.plan) if self.record.wind else None
        # the record's wind series, in the order WindField.speeds gives their values
        self.wind_probes = WindProbes.of(self.record.wind, self.index) if self.record.wind else None
        self.wind_series = [self.record.wind[key] for key in self.wind_probes.keys] if self.record.wind else []
        self.frames = np.asarray(sim.plan.frame_times, float)
        self.next_frame = int(np.searchsorted(self.frames, sim.state.t, side="right"))
        self.seen = 0
        self._sample(sim, [], 0)
        sim.observers.append(self.observe)

    def observe(self, sim, h: float) -> None:
        first = self.seen
        new = sim.events[first:]
        self.seen = first + len(new)
        self._sample(sim, new, first)

    def _sample(self, sim, new_events: list, first: int) -> None:
        state, record, plan = sim.state, self.record, self.plan
        t = state.t
        for k, event in enumerate(new_events):
            if event.get("kind", "impact") != "contact":
                local = self.local_points(state, event.get("point", (0.0, 0.0, 0.0)), event.get("bodies", ()))
                record.hits.append(make_hit(plan, event, local, first + k))
        record.times.append(t)
        for body, series in record.positions.items():
            series.append(state.x[self.index[body]] if body in self.index else 0.0)
        if record.contacts:
            self._contacts(new_events, state)
        if record.wind:
            for series, value in zip(self.wind_series, self.air.speeds(self.wind_probes, state, t)):
                series.append(value)

    def local_points(self, state, point, bodies) -> dict:
        """A world point in the frame of each of the bodies, from the state at the end of the step."""
        from ..rotation import quat_to_matrix

        point = np.asarray(point, float)
        out = {}
        for body in bodies:
            if body in self.index:
                i = self.index[body]
                # p_local = R^T (p - x)
                out[body] = quat_to_matrix(state.q[i]).T @ (point - state.x[i])
        return out

    def _contacts(self, events: list, state) -> None:
        """A sample per contact event of each listened pair; a zero at each frame passed without one."""
        frame_period = (self.frames[1] - self.frames[0]) if len(self.frames) > 1 else 1.0
        touched = {pair: [] for pair in self.record.contacts}
        for event in events:
            if event.get("kind") == "contact":
                for pair in touched:
                    if _of_pair(event, pair):
                        touched[pair].append(event)
        for pair, series in self.record.contacts.items():
            for event in touched[pair]:
                # N = J / frame period (the event's impulse is summed over its frame)
                self._contact_sample(pair, series, event, float(event["time"]),
                                     float(event.get("impulse", 0.0)) / frame_period, state)
        while self.next_frame < len(self.frames) and self.frames[self.next_frame] <= state.t + 1e-12:
            t_frame = float(self.frames[self.next_frame])
            for pair, series in self.record.contacts.items():
                times = series["times"]
                if not times.size or abs(times.view()[-1] - t_frame) > 1e-9:
                    self._contact_sample(pair, series, None, t_frame, 0.0, state)
            self.next_frame += 1

    def _contact_sample(self, pair, series, event, t: float, force: float, state) -> None:
        speed = roll = 0.0
        local = {}
        if event is not None:
            speed = abs(float(event.get("tangential_speed", 0.0)))
            normal = np.asarray(event.get("normal", (0.0, 1.0, 0.0)), float)
            bodies = event.get("bodies", pair)
            rel = sum((sign * state.v[self.index[b]] for sign, b in zip((1.0, -1.0), bodies) if b in self.index),
                      np.zeros(3))
            # |v_rel - n (n . v_rel)|: how fast the contact point travels over the surfaces
            roll = float(np.linalg.norm(rel - normal * np.dot(rel, normal)))
            local = self.local_points(state, event.get("point", (0.0, 0.0, 0.0)), pair)
        series["times"].append(t)
        series["speed"].append(speed)
        series["force"].append(force)
        series["roll"].append(roll)
        for body in pair:
            points = series[("local", body)]
            points.append(local[body] if body in local else (points.view()[-1] if points.size else np.zeros(3)))


def _of_pair(event: dict, pair: tuple) -> bool:
    bodies = tuple(event.get("bodies", ()))
    if not pair:
        return True  # contact(): any contact
    return set(bodies) == set(pair) if len(pair) > 1 else pair[0] in bodies


def make_hit(plan, event: dict, local: dict, index: int) -> Hit:
    bodies = tuple(event.get("bodies", ()))
    speed = abs(float(event.get("normal_speed", 0.0)))
    props = [plan.contact_props[b] for b in bodies if b in plan.contact_props]
    props = props or [{"mass": 1.0, "radius": math.inf, "young": None, "poisson": 0.3}]
    tau = contact_duration(props[0], props[1] if len(props) > 1 else None, speed, plan.fs)
    time = float(event["time"])
    return Hit(time, int(round((time - plan.start) * plan.fs)), bodies, float(event.get("impulse", 0.0)), speed,
               abs(float(event.get("tangential_speed", 0.0))), np.asarray(event.get("point", (0, 0, 0)), float),
               local, tau, index)


def new_record(plan) -> MotionRecord:
    needs = plan.needs
    record = MotionRecord(plan.start, plan.fs)
    for body in needs.bodies:
        record.positions[body] = Series((3,))
    for pair in needs.pairs:
        series = {"times": Series(), "speed": Series(), "force": Series(), "roll": Series()}
        for body in pair:
            series[("local", body)] = Series((3,))
        record.contacts[pair] = series
    for body in needs.wind_bodies:
        record.wind[body] = Series()
    for wind in needs.listener_winds:
        record.wind[("listener", wind)] = Series()
    return record


# ---- records made by hand ---------------------------------------------------------------------------------

def synthetic_record(plan, events: list, end: float | None = None, contacts: dict | None = None,
                     wind: dict | None = None, step: float = 1e-3) -> MotionRecord:
    """A record without a simulation: `events` as the collision stage writes them; bodies stay where the
    scene puts them. contacts: pair -> (times, sliding speeds, normal forces), the rolling speed taken equal to
    the sliding one; wind: key -> (times, speeds), key a body or ("listener", wind)."""
    from ..rotation import quat_to_matrix

    end = plan.end if end is None else end
    record = new_record(plan)
    scene = plan.scene
    pose = {b.name: (np.asarray(E.evaluate(b.position, {"t": plan.start}), float),
                     np.asarray(E.evaluate(b.orientation, {"t": plan.start}), float)) for b in scene.bodies}
    times = np.arange(plan.start, end + step / 2, step)
    for t in times:
        record.times.append(t)
    for body, series in record.positions.items():
        for _ in times:
            series.append(pose[body][0] if body in pose else 0.0)
    for pair, series in record.contacts.items():
        given = (contacts or {}).get(pair) or (contacts or {}).get(tuple(reversed(pair)))
        t_given, v_given, f_given = given if given is not None else ([plan.start, end], [0.0, 0.0], [0.0, 0.0])
        for t, v, f in zip(t_given, v_given, f_given):
            for name, value in (("times", t), ("speed", v), ("force", f), ("roll", v)):
                series[name].append(value)
            for body in pair:
                series[("local", body)].append(np.zeros(3))
    for key, series in record.wind.items():
        t_given, u_given = (wind or {}).get(key, ([plan.start, end], [0.0, 0.0]))
        for v in np.interp(times, t_given, u_given):
            series.append(v)
    for index, event in sorted(enumerate(events), key=lambda pair: pair[1]["time"]):
        if event.get("kind", "impact") == "contact":
            continue
        local = {}
        for body in event.get("bodies", ()):
            if body in pose:
                x, q = pose[body]
                local[body] = quat_to_matrix(q / np.linalg.norm(q)).T @ (np.asarray(event.get("point", x), float) - x)
        record.hits.append(make_hit(plan, event, local, index))
    return record


# ---- the wind -----------------------------------------------------------------------------------------------

class WindField:
    """Air velocity at points, and each wind's speed at the listener: the wind stage's fields when the run has
    one (so that a sound hears the wind that moves the bodies), else the same fields built for the sound alone
    (a scene whose winds move no body)."""

    def __init__(self, scene, sim_plan=None):
        stage = getattr(getattr(sim_plan, "forces", None), "wind", None)
        self.fields = stage.fields if stage is not None else _fields(scene, sim_plan)
        self.listener = np.asarray(scene.listener.position, float)

    def velocity(self, points: np.ndarray, t: float) -> np.ndarray:
        return self.fields.velocity(points, t)

    def listener_speed(self, name: str, t: float) -> float:
        """The speed of wind `name` at the listener."""
        u = self.fields.velocity(self.listener[None, :], t, self.fields.names.index(name))
        return float(np.linalg.norm(u[0]))

    def speeds(self, probes: "WindProbes", state, t: float) -> np.ndarray:
        """(len(probes.keys),) the wind speeds the record keeps at time t, in one evaluation of the field for
        all the points when the scene has one wind (the listener's wind is then the sum at its point):
        |u(x_i) - v_i| at each body, |u_w(listener)| for each listener wind, 0 for a body not in the run."""
        out = np.zeros(len(probes.keys))
        nb = len(probes.body)
        points = state.x[probes.body]
        together = len(self.fields.names) == 1 and len(probes.listener_wind)
        if together:
            points = np.concatenate([points, self.listener[None, :]])
        if len(points):
            u = self.fields.velocity(points, t)
            # |u - v| at the bodies
            rel = u[:nb] - state.v[probes.body]
            out[probes.body_slot] = np.sqrt(np.einsum("ij,ij->i", rel, rel))
            if together:
                out[probes.listener_slot] = np.sqrt(u[nb] @ u[nb])
        if not together:
            for slot, name in zip(probes.listener_slot, probes.listener_wind):
                out[slot] = self.listener_speed(name, t)
        return out


@dataclass
class WindProbes:
    """Where the record samples the wind (plan, built once): keys in record order; the bodies (indices into
    the state, with their slots in that order) and the listener's winds (names, with their slots). Keys of
    bodies that are not in the run keep a 0."""

    keys: list
    body: np.ndarray  # (b,) int
    body_slot: np.ndarray  # (b,) int
    listener_wind: list  # (l,) names
    listener_slot: list  # (l,) int

    @classmethod
    def of(cls, wind: dict, index: dict) -> "WindProbes":
        keys = list(wind)
        bodies = [(slot, index[key]) for slot, key in enumerate(keys) if not isinstance(key, tuple) and key in index]
        listeners = [(slot, key[1]) for slot, key in enumerate(keys) if isinstance(key, tuple)]
        return cls(keys, np.array([i for _, i in bodies], dtype=np.int64), np.array([s for s, _ in bodies], np.int64),
                   [name for _, name in listeners], [s for s, _ in listeners])


def _fields(scene, sim_plan):
    # the wind stage's own construction (runtime/wind), for winds no body feels
    from ..signals import asset_folders
    from ..wind import _functions
    from ..wind.fields import compile_fields

    holder = sim_plan if sim_plan is not None else _Warnings()
    folders = asset_folders(scene, getattr(sim_plan, "folder", None))
    return compile_fields(scene.winds, [_functions(scene, w, folders, holder) for w in scene.winds], scene.seed)


class _Warnings:
    def __init__(self):
        self.warnings = []
