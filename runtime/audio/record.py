"""Audio stage, recording the motion: a tracer of the step loop that keeps what the sounds read.

For every step (handed on after each kernel call: Simulation.add_tracer) it stores, at the step's end time:
- hits: every new collision event of kind "impact", with its sample round((t - start) fs), the contact point
  in each body's frame at the end of the step it happened in (for the mode shapes) and the contact duration
  (excitation.py);
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

from isaac_ir import expr as E

from ..plan.kinematics import never_moving
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


class StepTable:
    """The signals sampled at every step, N steps: times (N,) s, positions (p,N,3) of the placed bodies, wind
    (w,N) speeds; each signal's samples lie together in memory (what the renderer reads). Preallocated for the
    run's steps (`reserve`), doubled if a run takes more. The record's series of these signals are its
    columns (`StepColumn`): they share its memory and its size."""

    def __init__(self, positions: int, winds: int, steps: int = 256):
        self.times = np.zeros(steps)
        self.positions = np.zeros((positions, steps, 3))
        self.wind = np.zeros((winds, steps))
        self.size = 0

    def reserve(self, steps: int) -> None:
        """Room for `steps` steps in all (the steps written so far kept, the new ones zero)."""
        if steps <= len(self.times):
            return
        self.times = _grown(self.times, 0, steps, self.size)
        self.positions = _grown(self.positions, 1, steps, self.size)
        self.wind = _grown(self.wind, 1, steps, self.size)

    def room_for(self, count: int) -> int:
        """The index of the first of `count` steps to write next (the table at least doubles when they do not
        fit); `size` counts them once written."""
        if self.size + count > len(self.times):
            self.reserve(max(2 * len(self.times), self.size + count))
        return self.size


def _grown(array: np.ndarray, axis: int, steps: int, kept: int) -> np.ndarray:
    """A zero array with `steps` along `axis`, the first `kept` of `array` copied."""
    shape = list(array.shape)
    shape[axis] = steps
    grown = np.zeros(shape)
    index = (slice(None),) * axis + (slice(0, kept),)
    grown[index] = array[index]
    return grown


class StepColumn:
    """One signal of a StepTable as a read-only Series: `data`, `size`, `view()` (what the renderer reads)."""

    def __init__(self, table: StepTable, name: str, index: int | None = None):
        self.table, self.name, self.index = table, name, index

    @property
    def data(self) -> np.ndarray:
        array = getattr(self.table, self.name)
        return array if self.index is None else array[self.index]

    @property
    def size(self) -> int:
        return self.table.size

    def view(self) -> np.ndarray:
        return self.data[: self.table.size]


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
    parts: dict = field(default_factory=dict)  # body -> the part of it struck (compound bodies only)

    def values(self) -> dict:
        """The event signals of docs/design/sound.md#section-1 at this hit (distance and wind speed are added by the
        renderer)."""
        return {"impulse": self.impulse, "speed": self.normal_speed, "normal_force": self.impulse / self.tau,
                "t": self.time}


@dataclass
class MotionRecord:
    start: float
    fs: float
    steps: StepTable  # what is sampled at every step: times, positions, wind (the columns below)
    times: StepColumn  # the steps' end times
    positions: dict = field(default_factory=dict)  # body -> StepColumn (3,), at `times`
    contacts: dict = field(default_factory=dict)  # pair -> {"times", "speed", "force", "roll": Series,
    #                                                        ("local", body): Series (3,)}, at their own times
    wind: dict = field(default_factory=dict)  # body name, or ("listener", wind) -> StepColumn, at `times`
    hits: list = field(default_factory=list)

    @property
    def until(self) -> float:
        """The time up to which the motion is known."""
        return float(self.times.data[self.times.size - 1]) if self.times.size else -math.inf


class Recorder:
    """The tracer (Simulation.add_tracer): started by AudioPlan.record(sim), fills a MotionRecord as the
    simulation steps, from the motion of its bodies at every step that each kernel call hands it."""

    def __init__(self, plan, sim):
        self.plan = plan
        self.record = new_record(plan)
        self.record.steps.reserve(_steps_of(sim.plan) + 1)
        self.index = {name: i for i, name in enumerate(sim.plan.names)}
        # the placed bodies in the run (their columns of the table) and their rows of the state
        placed = [(column, self.index[body]) for column, body in enumerate(self.record.positions)
                  if body in self.index]
        self.placed_columns = np.array([c for c, _ in placed], np.int64)
        self.placed_rows = np.array([i for _, i in placed], np.int64)
        self.air = WindField(plan.scene, sim.plan) if self.record.wind else None
        # where the wind is sampled, in the order of the record's wind columns
        self.wind_probes = WindProbes.of(self.record.wind, self.index, never_moving(sim.plan)) \
            if self.record.wind else None
        self.frames = np.asarray(sim.plan.frame_times, float)
        self.next_frame = int(np.searchsorted(self.frames, sim.state.t, side="right"))
        # the bodies whose motion the steps must hand on (each once): the placed ones first, those the wind is
        # sampled at, and those an event's point is read in (`_posed`)
        moving = self.wind_probes.moving_body if self.wind_probes is not None else np.zeros(0, np.int64)
        rows = list(dict.fromkeys([*self.placed_rows.tolist(), *moving.tolist(), *self._posed(plan)]))
        self.bodies = np.array(rows, np.int64)
        self.slot = {row: k for k, row in enumerate(rows)}  # a body's row of the state -> its column of a trace
        self.moving_slots = np.array([self.slot[b] for b in moving.tolist()], np.int64)
        self._step_state = _StepState(sim.state.x.copy(), sim.state.v.copy())  # wind speeds' state of one step
        self._last = (sim.state.t, sim.state.y[self.bodies].copy())  # the last step handed on: its time and rows
        self.seen = 0
        self._sample_start(sim)
        sim.add_tracer(self)

    def take(self, sim, times: np.ndarray, trace: np.ndarray) -> None:
        """The steps of one kernel call (Simulation.add_tracer): their end times (k,) and trace (k, b, 13), the
        state rows of self.bodies after each; then the events they brought, each read with the state of the step
        it happened in."""
        first, events = self.seen, sim.events
        self.seen = len(events)
        self._sample_steps(times, trace)
        steps = _Steps(times, trace, self._last)
        if len(times):
            self._last = (float(times[-1]), trace[-1].copy())
        if self.seen > first:  # (only the impacts become dicts, unless a sound listens to pressing pairs)
            self._hits(steps, events.impacts_from(first))
        if self.record.contacts:
            self._contacts(events[first:] if self.seen > first else NO_EVENTS, steps)

    def _sample_start(self, sim) -> None:
        """The table's first row: the state the run starts from."""
        s = sim.state
        self._sample_steps(np.array([s.t]), s.y[self.bodies][None])

    def _posed(self, plan) -> list:
        """The rows of the bodies an event's point is read in: those with modes (a hit's point in their frame
        sets how each mode is struck) and both bodies of each pair a contact sound listens to (its speeds too;
        every body when one listens to the contacts of any body, or of one body with any other)."""
        if any(len(pair) < 2 for pair in plan.needs.pairs):
            return sorted(self.index.values())
        names = {body for sp in plan.sounds for body in sp.modes} | {body for pair in plan.needs.pairs for body in pair}
        return sorted(self.index[name] for name in names if name in self.index)

    def _hits(self, steps: "_Steps", impacts: list) -> None:
        """A hit of each (index in events.json, event) of an impact, read with the state of its step."""
        for index, event in impacts:
            rows = steps.at(float(event["time"]))
            local = self.local_points(rows, event.get("point", (0.0, 0.0, 0.0)), event.get("bodies", ()))
            self.record.hits.append(make_hit(self.plan, event, local, index))

    def _sample_steps(self, times: np.ndarray, trace: np.ndarray) -> None:
        """The table's rows of these steps: time, placed bodies' positions, wind speeds (a body not in the run
        keeps position 0 and wind 0)."""
        table = self.record.steps
        count = len(times)
        k = table.room_for(count)
        table.times[k:k + count] = times
        placed = len(self.placed_rows)
        if placed:
            # (steps, placed, 3) -> the table's (placed, steps, 3)
            table.positions[self.placed_columns, k:k + count] = trace[:, :placed, :3].transpose(1, 0, 2)
        if self.wind_probes is not None:
            step, moving, slots = self._step_state, self.wind_probes.moving_body, self.moving_slots
            for i in range(count):
                step.x[moving], step.v[moving] = trace[i, slots, :3], trace[i, slots, 7:10]
                self.air.speeds(self.wind_probes, step, float(times[i]), out=table.wind[:, k + i])
        table.size = k + count

    def local_points(self, rows: np.ndarray, point, bodies) -> dict:
        """A world point in the frame of each of the bodies that is traced, from their state rows (b, 13) at
        the end of a step."""
        from ..core.rotation import quat_to_matrix

        point = np.asarray(point, float)
        out = {}
        for body in bodies:
            k = self.slot.get(self.index.get(body, -1))
            if k is not None:
                # p_local = R^T (p - x)
                out[body] = quat_to_matrix(rows[k, 3:7]).T @ (point - rows[k, :3])
        return out

    def _contacts(self, events: list, steps: "_Steps") -> None:
        """A sample per contact event of each listened pair; a zero at each frame passed without one."""
        frame_period = (self.frames[1] - self.frames[0]) if len(self.frames) > 1 else 1.0
        touched = {pair: [] for pair in self.record.contacts}
        for event in events:
            if event.get("kind") == "contact":
                for pair in touched:
                    if _of_pair(event, pair):
                        touched[pair].append(event)
        passed = []  # the frames these steps passed
        while self.next_frame < len(self.frames) and self.frames[self.next_frame] <= steps.until + 1e-12:
            passed.append(float(self.frames[self.next_frame]))
            self.next_frame += 1
        for pair, series in self.record.contacts.items():
            times = series["times"]
            last = times.view()[-1] if times.size else math.nan
            samples = [(float(event["time"]), k, event) for k, event in enumerate(touched[pair])]
            heard = np.sort([t for t, _, _ in samples])
            for t_frame in passed:
                k = int(np.searchsorted(heard, t_frame - 1e-9))
                if not (k < len(heard) and heard[k] <= t_frame + 1e-9) and not abs(last - t_frame) <= 1e-9:
                    samples.append((t_frame, len(samples), None))
            for t, _, event in sorted(samples, key=lambda sample: sample[:2]):
                # N = J / frame period (the event's impulse is summed over its frame)
                force = float(event.get("impulse", 0.0)) / frame_period if event is not None else 0.0
                self._contact_sample(pair, series, event, t, force, steps)

    def _contact_sample(self, pair, series, event, t: float, force: float, steps: "_Steps") -> None:
        speed = roll = 0.0
        local = {}
        if event is not None:
            speed = abs(float(event.get("tangential_speed", 0.0)))
            normal = np.asarray(event.get("normal", (0.0, 1.0, 0.0)), float)
            bodies = event.get("bodies", pair)
            rows = steps.at(t)
            rel = sum((sign * rows[self.slot[self.index[b]], 7:10] for sign, b in zip((1.0, -1.0), bodies)
                       if b in self.index), np.zeros(3))
            # |v_rel - n (n . v_rel)|: how fast the contact point travels over the surfaces
            roll = float(np.linalg.norm(rel - normal * np.dot(rel, normal)))
            local = self.local_points(rows, event.get("point", (0.0, 0.0, 0.0)), pair)
        series["times"].append(t)
        series["speed"].append(speed)
        series["force"].append(force)
        series["roll"].append(roll)
        for body in pair:
            points = series[("local", body)]
            points.append(local[body] if body in local else (points.view()[-1] if points.size else np.zeros(3)))


NO_EVENTS: list = []  # the new events of a step without any (never appended to)


class _Steps:
    """The traced state rows at the steps of one kernel call and at the step handed on before them."""

    def __init__(self, times: np.ndarray, trace: np.ndarray, last: tuple):
        self.times = np.concatenate([[last[0]], times])
        self.rows = np.concatenate([last[1][None], trace]) if len(times) else last[1][None]
        self.until = float(self.times[-1])

    def at(self, t: float) -> np.ndarray:
        """(b, 13) at the end of the step that time t falls in (the first ending at or after it)."""
        k = int(np.searchsorted(self.times, t - 1e-9))
        return self.rows[min(k, len(self.rows) - 1)]


@dataclass
class _StepState:
    """The state as WindField.speeds reads it, of one traced step: x, v (n, 3), the traced rows filled."""

    x: np.ndarray
    v: np.ndarray


def _of_pair(event: dict, pair: tuple) -> bool:
    bodies = tuple(event.get("bodies", ()))
    if not pair:
        return True  # contact(): any contact
    return set(bodies) == set(pair) if len(pair) > 1 else pair[0] in bodies


def make_hit(plan, event: dict, local: dict, index: int) -> Hit:
    bodies = tuple(event.get("bodies", ()))
    parts = {b: p for b, p in zip(bodies, event.get("parts") or ()) if p is not None}
    speed = abs(float(event.get("normal_speed", 0.0)))
    # a compound body's contact is its part's: its curvature and its material's stiffness
    props = [plan.contact_props.get((b, parts[b]), plan.contact_props.get(b)) if b in parts else
             plan.contact_props[b] for b in bodies if b in plan.contact_props]
    props = props or [{"mass": 1.0, "radius": math.inf, "young": None, "poisson": 0.3}]
    tau = contact_duration(props[0], props[1] if len(props) > 1 else None, speed, plan.fs)
    time = float(event["time"])
    return Hit(time, int(round((time - plan.start) * plan.fs)), bodies, float(event.get("impulse", 0.0)), speed,
               abs(float(event.get("tangential_speed", 0.0))), np.asarray(event.get("point", (0, 0, 0)), float),
               local, tau, index, parts)


def new_record(plan) -> MotionRecord:
    needs = plan.needs
    placed = list(needs.bodies)
    winds = list(needs.wind_bodies) + [("listener", wind) for wind in needs.listener_winds]
    table = StepTable(len(placed), len(winds))
    record = MotionRecord(plan.start, plan.fs, table, StepColumn(table, "times"))
    for column, body in enumerate(placed):
        record.positions[body] = StepColumn(table, "positions", column)
    for pair in needs.pairs:
        series = {"times": Series(), "speed": Series(), "force": Series(), "roll": Series()}
        for body in pair:
            series[("local", body)] = Series((3,))
        record.contacts[pair] = series
    for column, key in enumerate(winds):
        record.wind[key] = StepColumn(table, "wind", column)
    return record


def _steps_of(sim_plan) -> int:
    """At most how many steps a run takes: its span over the step, plus one per frame and per switch (a step
    is cut short at each)."""
    switches = len(sim_plan.constraints.switch_times()) if sim_plan.constraints is not None else 0
    span = max(sim_plan.end - sim_plan.start, 0.0)
    return int(math.ceil(span / sim_plan.step)) + len(sim_plan.frame_times) + switches + 1


# ---- records made by hand ---------------------------------------------------------------------------------

def synthetic_record(plan, events: list, end: float | None = None, contacts: dict | None = None,
                     wind: dict | None = None, step: float = 1e-3) -> MotionRecord:
    """A record without a simulation: `events` as the collision stage writes them; bodies stay where the
    scene puts them. contacts: pair -> (times, sliding speeds, normal forces), the rolling speed taken equal to
    the sliding one; wind: key -> (times, speeds), key a body or ("listener", wind)."""
    from ..core.rotation import quat_to_matrix

    end = plan.end if end is None else end
    record = new_record(plan)
    scene = plan.scene
    pose = {b.name: (np.asarray(E.evaluate(b.position, {"t": plan.start}), float),
                     np.asarray(E.evaluate(b.orientation, {"t": plan.start}), float)) for b in scene.bodies}
    times = np.arange(plan.start, end + step / 2, step)
    table = record.steps
    table.reserve(len(times))
    table.times[: len(times)] = times
    for column, body in enumerate(record.positions):
        table.positions[column, : len(times)] = pose[body][0] if body in pose else 0.0
    for pair, series in record.contacts.items():
        given = (contacts or {}).get(pair) or (contacts or {}).get(tuple(reversed(pair)))
        t_given, v_given, f_given = given if given is not None else ([plan.start, end], [0.0, 0.0], [0.0, 0.0])
        for t, v, f in zip(t_given, v_given, f_given):
            for name, value in (("times", t), ("speed", v), ("force", f), ("roll", v)):
                series[name].append(value)
            for body in pair:
                series[("local", body)].append(np.zeros(3))
    for column, key in enumerate(record.wind):
        t_given, u_given = (wind or {}).get(key, ([plan.start, end], [0.0, 0.0]))
        table.wind[column, : len(times)] = np.interp(times, t_given, u_given)
    table.size = len(times)
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
        self._scratch = None  # (probes, together, points, relative velocities): speeds' scratch (_points)

    def velocity(self, points: np.ndarray, t: float) -> np.ndarray:
        return self.fields.velocity(points, t)

    def listener_speed(self, name: str, t: float) -> float:
        """The speed of wind `name` at the listener."""
        u = self.fields.velocity(self.listener[None, :], t, self.fields.names.index(name))
        return float(np.linalg.norm(u[0]))

    def speeds(self, probes: "WindProbes", state, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """(len(probes.keys),) the wind speeds the record keeps at time t (into `out` if given), in one
        evaluation of the field for all the points when the scene has one wind (the listener's wind is then
        the sum at its point): |u(x_i) - v_i| at each body, |u_w(listener)| for each listener wind, 0 for a
        body not in the run. Bodies that never move (probes.still) keep their first point, and v = 0."""
        if out is None:
            out = np.zeros(len(probes.keys))
        together = bool(len(self.fields.names) == 1 and len(probes.listener_wind))
        points, rel = self._points(probes, together, state)
        if len(points):
            moving, body = probes.moving, probes.moving_body
            if len(moving):
                points[moving] = state.x[body]
            u = self.fields.velocity(points, t)
            if len(moving):
                # |u - v| at the moving bodies (u itself elsewhere: v = 0 at a body that never moves)
                rel[...] = u
                rel[moving] = u[moving] - state.v[body]
                u = rel
            out[probes.point_slot if together else probes.body_slot] = np.sqrt(np.einsum("ij,ij->i", u, u))
        if not together:
            for slot, name in zip(probes.listener_slot, probes.listener_wind):
                out[slot] = self.listener_speed(name, t)
        return out

    def _points(self, probes: "WindProbes", together: bool, state) -> tuple:
        """Scratch (p,3) twice, for these probes: the points (the bodies' centres, then with `together` the
        listener's point; those that never move filled once) and the air's velocities relative to them."""
        if self._scratch is None or self._scratch[0] is not probes or self._scratch[1] != together:
            points = np.zeros((len(probes.body) + int(together), 3))
            still = np.setdiff1d(np.arange(len(probes.body)), probes.moving)
            points[still] = state.x[probes.body[still]]
            if together:
                points[-1] = self.listener
            self._scratch = (probes, together, points, np.zeros_like(points))
        return self._scratch[2], self._scratch[3]

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
    point_slot: np.ndarray  # (b + 1,) int: body_slot, then the (first) listener wind's slot
    moving: np.ndarray  # (m,) int: which of `body` move (the others stay where they start, at rest)
    moving_body: np.ndarray  # (m,) int: body[moving]

    @classmethod
    def of(cls, wind: dict, index: dict, still: np.ndarray | None = None) -> "WindProbes":
        """still (n,) bool, optional: bodies that never move (without it, every body may)."""
        keys = list(wind)
        bodies = [(slot, index[key]) for slot, key in enumerate(keys) if not isinstance(key, tuple) and key in index]
        listeners = [(slot, key[1]) for slot, key in enumerate(keys) if isinstance(key, tuple)]
        body = np.array([i for _, i in bodies], dtype=np.int64)
        body_slot = np.array([s for s, _ in bodies], np.int64)
        moving = np.flatnonzero(~still[body]) if still is not None else np.arange(len(body))
        return cls(keys, body, body_slot, [name for _, name in listeners], [s for s, _ in listeners],
                   np.concatenate([body_slot, np.array([s for s, _ in listeners[:1]], np.int64)]), moving,
                   body[moving])


def _fields(scene, sim_plan):
    # the wind stage's own construction (runtime/wind), for winds no body feels
    from ..signals import asset_folders
    from ..wind import wind_functions
    from ..wind.fields import compile_fields

    holder = sim_plan if sim_plan is not None else _Warnings()
    folders = asset_folders(scene, getattr(sim_plan, "folder", None))
    return compile_fields(scene.winds, [wind_functions(scene, w, folders, holder) for w in scene.winds], scene.seed)


class _Warnings:
    def __init__(self):
        self.warnings = []
