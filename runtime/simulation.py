"""Stage 5, the step loop: a Simulation steps a plan and exposes its state.

    sim = Simulation(compile_plan(scene, PlanOptions()))   # (isaac.api builds one from a scene file or text)
    sim.advance_to(2.0)
    sim.state.x[sim.body("bob")]

The steps themselves run in compiled kernels (runtime/core, runtime/dynamics, runtime/procedural), many per call;
Python runs only between calls: at constraint switches (a step never crosses one: time is cut into pieces at
switches and frames, and each piece takes equal steps no longer than the plan's), at recorded frames when a
caller needs them one by one, at the collision stage's looks, and after each step while an observer listens. A
tracer (the audio stage) is handed the state of its bodies at every step of a call, after the call. A run steps
alike, bit for bit, whether a call covers one frame or many (`_steps_of`, `step_times`): a live run calls once a
frame.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .blowup import NumericalError, constraint_failure, failure
from .outputs.events import EventList
from .core import data as D
from .core.bodies import RUNAWAY_SPEED  # noqa: F401 (callers of the step loop import it from here)
from .core.bodies import place_kinematic
from .core.build import CompiledPlan
from .core import model as M
from .core.entries import measure, row_errors, state_constraint_error, state_energy
from .core.jit import CompileNotice
from .core.record import RUNAWAY_CONSTRAINT_ERROR, Frames
from .core.record import CONTACT, DONE, RUNAWAY_BODY
from .plan.kinematics import on_path, window_switches
from .plan import Plan

# a run that hands its frames to a caller one by one (watch, live) steps at most this many steps per kernel call
ON_FRAME_STEPS = 2000
# a call traced for a tracer holds at most this many numbers of the motion (8 bytes each: 16 MB)
TRACE_CELLS = 1 << 21


@dataclass
class State:
    """The mutable part: time and the struct-of-arrays state of every body.

    x, q, v, w are views of y (n+1, 13), each body's state packed in one row [x q v w] and the last row the world,
    which the kernels advance in place; write them in place (x[...] = ...), never rebind them."""

    t: float
    x: np.ndarray  # (n,3) centre of mass, m
    q: np.ndarray  # (n,4) orientation (w, x, y, z)
    v: np.ndarray  # (n,3) m/s
    w: np.ndarray  # (n,3) world angular velocity, rad/s
    steps: int = 0
    y: np.ndarray | None = None  # (n+1,13)

    @classmethod
    def initial(cls, plan: Plan) -> "State":
        y = D.initial_state(plan)
        n = plan.n
        return cls(plan.start, y[:n, D.X], y[:n, D.Q], y[:n, D.V], y[:n, D.W], y=y)


def _steps_of(span: float, h: float) -> tuple:
    """(count, length) of the steps of an interval of `span`: the fewest of equal length no longer than h, and h
    itself when their length is h to rounding (frames a whole number of steps apart then step alike, whether a
    kernel call covers one frame or many)."""
    count = max(1, math.ceil(span / h - 1e-9))
    length = span / count
    return count, (h if abs(length - h) <= 1e-12 * h else length)


def step_times(t0: float, ends: list, count: int, h: float) -> np.ndarray:
    """The times of the step boundaries of intervals of `count` steps of h from t0 to each of `ends` in turn:
    each interval's steps counted from its start, its last ending at its end. A kernel call covering several
    intervals (frames) steps at the times that a call per interval does, bit for bit."""
    starts = np.array([t0] + list(ends[:-1]))
    times = np.empty(count * len(ends) + 1)
    times[:-1] = (starts[:, None] + h * np.arange(count)).ravel()
    times[-1] = ends[-1]
    return times


class _FrameSink:
    """Where a run of frames goes: the Recorder (or nothing), and the frame times still to record."""

    def __init__(self, times, recorder, on_frame):
        self.times = np.asarray(times, float)
        self.recorder, self.on_frame = recorder, on_frame
        self.next = 0


class Simulation:
    def __init__(self, plan: Plan):
        self.plan = plan
        self.state = State.initial(plan)
        self.events = EventList()  # (a list of the event dicts of collide/events.py)
        self.compile_seconds = 0.0  # spent compiling the core (a first run on a machine), apart from the run
        # the notice names the entries the run will call: a heap's starts on the capturing path and never calls the
        # exact stepper's (which, never compiled, made every run of a heap announce a compile it did not do)
        exact = () if self._starts_capturing(plan) else self._stepper_class(plan).entries
        self._compile_notice = CompileNotice.begin(measure, *exact)
        self.compiled = CompiledPlan(plan)
        self.stepper = self._stepper_class(plan)(self.compiled, plan)
        switches = list(plan.constraints.switch_times()) if plan.constraints else []
        if plan.collisions is not None:
            switches += plan.collisions.window_switches()
        switches += window_switches(plan.kinematics)
        self._switches = np.unique(np.array(switches, float))
        # a body with `kinematic A .. B`: the mass properties it has off its path (the plan's are changed in place
        # while it is on it, for the stages that read them)
        self._off_path = (plan.dynamic.copy(), plan.inv_mass.copy(), plan.inv_inertia_body.copy())
        self._act = None  # the Active rows of the epoch the state is in (active_rows; `rows_now` reads it)
        self._frame_now = False  # a frame is due at the state's time (recorded before the next step)
        self._epoch_in = ()  # the epoch (and windowed exclusions and `collide`s) the collision stage was told of
        self._status = np.zeros(4, np.int64)
        self._initial = self.state.y.copy()  # the state the run started from (a blow-up's diagnosis reads it)
        self._last_delivered = None  # (time, packed state) of the last frame handed on (likewise)
        # collisions (runtime.collide): contact rows in the step, impacts and changes of contact when it stops;
        # built only when the plan has them
        self.collider = None  # (built below, once the bodies are placed: _start_contacts)
        # observers called after every step (the kernel then takes one step per call: a probe, a test's oracle)
        self.observers: list = []
        # tracers (add_tracer): the audio stage's recorder, handed the state of its bodies at every step after each
        # kernel call
        self.tracers: list = []
        self._traced = np.zeros(0, np.int64)  # their bodies, one after another (Frames.traced)
        self._follow_paths()
        self._place_kinematic()
        if plan.collisions is not None:
            self._start_contacts()

    # -- construction -------------------------------------------------------------------------------------

    @staticmethod
    def _stepper_class(plan):
        if plan.solver == "procedural":
            from .procedural import ProceduralStepper

            return ProceduralStepper
        from .dynamics import DynamicsStepper

        return DynamicsStepper

    # -- queries ------------------------------------------------------------------------------------------

    def body(self, name: str) -> int:
        return self.plan.names.index(name)

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy of the dynamic bodies, J."""
        c = self.compiled
        return float(state_energy(c.model, c.scratch, self.state.y))

    def constraint_errors(self) -> tuple:
        """(max |C| over active position rows, global index of that row or -1) at the current state."""
        if self.plan.constraints is None:
            return 0.0, -1
        act = self.active_rows()
        c, s = self.compiled, self.state
        error, row = state_constraint_error(c.model, act, c.scratch, s.y, c.table.evaluate(s.t, 0.0, 1))
        return float(error), int(row)

    def check_constraints(self) -> float:
        """Constraint error now; a runaway error stops the run naming the constraint."""
        error, row = self.constraint_errors()
        if not np.isfinite(error) or error > RUNAWAY_CONSTRAINT_ERROR:
            raise constraint_failure(self, row, error)
        return error

    def rank_deficient(self) -> bool:
        """Whether a solve found redundant constraints (J M^-1 J^T singular) so far."""
        return bool(self.compiled.scratch.counters[D.COUNTER_RANK])

    def steps_at_rest(self) -> int:
        """Steps that found the scene at rest and left its state as it was (core/rest.py)."""
        return int(self.compiled.scratch.counters[D.COUNTER_RESTING])

    def error_control(self) -> dict:
        """RK4's error control so far (dynamics/integrate.py): steps taken again in substeps, the substeps they
        took, and steps whose estimated error stayed above the tolerance."""
        c = self.compiled.scratch.counters
        return {"steps_refined": int(c[D.COUNTER_REFINED]), "substeps": int(c[D.COUNTER_SUBSTEPS]),
                "steps_over_tolerance": int(c[D.COUNTER_OVER])}

    def constraint_residuals(self) -> tuple:
        """({global row: |C|} of the active position rows, [rows the last solve dropped as dependent]) at the
        current state (runtime/checks.py names the constraints that cannot all hold from them)."""
        if self.plan.constraints is None:
            return {}, []
        self.constraint_errors()  # evaluates C of every active row into the scratch
        act, c = self.active_rows(), self.compiled
        rows = act.rows.tolist()
        residuals = {r: abs(float(c.scratch.C[r])) for r in rows if not c.model.constraints.velocity_only[r]}
        return residuals, [r for i, r in enumerate(rows) if c.scratch.dropped[i]]

    # -- live inputs --------------------------------------------------------------------------------------

    def set_pose(self, name: str, position, orientation=(1.0, 0.0, 0.0, 0.0)) -> None:
        """Drive a kinematic body from outside (a mouse, a tracker) until `release_pose`."""
        index = self.body(name)
        paths = self.plan.kinematics
        if paths is None or index not in paths.index:
            raise ValueError(f"body `{name}` is not kinematic; declare it `kinematic` to drive it")
        quat = np.asarray(orientation, float)
        self.compiled.table.poses[index] = (np.asarray(position, float), quat / np.linalg.norm(quat))
        self._place_kinematic()

    def release_pose(self, name: str) -> None:
        self.compiled.table.poses.pop(self.body(name), None)

    def pull(self, name: str, point, target, stiffness: float, damping: float) -> None:
        """Pull a point of a body (its frame) toward a world point with a spring of rest length 0, until
        `release_pull` (a mouse dragging the body, as MuJoCo's perturbation): one more row of the compiled springs
        after the scene's, the world at its far end; a new target rewrites that row, read at the next kernel call."""
        springs, row = self.compiled.model.springs, self._scene_springs()
        if len(springs.stiffness) == row:
            springs = M.Springs(*(np.concatenate((a, np.zeros((1,) + a.shape[1:], a.dtype))) for a in springs))
            self.compiled.model = self.compiled.model._replace(springs=springs)
        springs.body[row] = (self.body(name), -1)
        springs.point[row, 0], springs.point[row, 1] = point, target
        springs.stiffness[row], springs.rest[row], springs.damping[row] = stiffness, 0.0, damping
        self._model_changed()

    def release_pull(self) -> None:
        springs, row = self.compiled.model.springs, self._scene_springs()
        if len(springs.stiffness) > row:
            self.compiled.model = self.compiled.model._replace(springs=M.Springs(*(a[:row] for a in springs)))
            self._model_changed()

    def _model_changed(self) -> None:
        """The model was changed between kernel calls (a pull, a body onto or off its path): the next call
        evaluates its first slope afresh rather than keep the last call's (dynamics/integrate.py run)."""
        self.compiled.scratch.counters[D.COUNTER_SLOPE] = 0

    def _scene_springs(self) -> int:
        springs = self.plan.forces.springs
        return 0 if springs is None else len(springs.stiffness)

    def carry_on(self, plan: Plan) -> None:
        """Go on with another plan of the same scene (a parameter changed, the scene re-planned by the caller):
        every dynamic body that still exists keeps its state, and time and steps go on."""
        before, names = self.state, list(self.plan.names)
        Simulation.__init__(self, plan)  # (the engine's state only: what a subclass adds stays)
        old = {name: i for i, name in enumerate(names)}
        for j, body in enumerate(plan.names):
            if body in old and plan.dynamic[j]:
                self.state.y[j] = before.y[old[body]]
        self.state.t, self.state.steps = before.t, before.steps

    # -- stepping -----------------------------------------------------------------------------------------

    def add_tracer(self, tracer) -> None:
        """A stage that reads the state of tracer.bodies ((b,) int) at every step: tracer.take(simulation,
        times (k,), trace (k, b, 13) their state rows x, q, v, w) is called after each kernel call with its steps
        (their end times), after the collision stage and the frames of those steps; an event of those steps is
        read with the state of the step it happened in (a call may cover many frames)."""
        self.tracers.append(tracer)
        self._traced = np.concatenate([np.asarray(t.bodies, np.int64) for t in self.tracers])

    def advance_to(self, t_target: float) -> None:
        """Step until time t_target, landing exactly on every constraint switch on the way."""
        self._advance(t_target, None)

    def step(self, h: float | None = None) -> None:
        """One step of the plan's size (or h), not crossing a switch."""
        self.advance_to(self.state.t + (h or self.plan.step))

    def integrate(self, tau: float) -> None:
        """One step of length tau from the live state at its time, with the plan's own step (the collision stage
        re-runs part of a step with it); the time and step count are the caller's to update."""
        s = self.state
        taken = self.stepper.run(self.active_rows(), s.y, s.t, tau, 1, np.zeros(0, np.int64), self._frame_buffer(0),
                                 self._status)
        if self._status[0] not in (DONE, CONTACT):  # (a change of contact is the caller's to look at)
            s.t += taken * tau
            raise self._failure()

    def joint_rows(self, rows: np.ndarray, t: float) -> tuple:
        """(J (m,2,6), ct (m,)) of the given global constraint rows at the live state and time t."""
        c = self.compiled
        cons = c.model.constraints
        instances = np.unique(cons.row_instance[rows])
        row_errors(c.model, instances, c.scratch, self.state.y, c.table.evaluate(t, 0.0, 1))
        return c.scratch.J[rows].copy(), c.scratch.ct[rows].copy()

    def run_frames(self, frame_times, recorder, on_frame=None) -> None:
        """Advance to the last of frame_times, recording every one of them into `recorder` (the kernels record;
        with on_frame, each frame is also handed to on_frame(simulation, recorder) as it is recorded)."""
        sink = _FrameSink(frame_times, recorder, on_frame)
        if len(sink.times):
            self._advance(float(sink.times[-1]), sink)

    def _advance(self, t_target: float, sink) -> None:
        s = self.state
        while True:
            self.active_rows()
            # a frame at the start, or at a switch: recorded here, in the epoch that begins
            if sink is not None and sink.next < len(sink.times) and sink.times[sink.next] <= s.t + 1e-12:
                self._record_now(sink)
            if s.t >= t_target - 1e-12:
                break
            ahead = self._switches[self._switches > s.t + 1e-12]
            boundary = min(t_target, float(ahead[0])) if ahead.size else t_target
            cuts = [(boundary, False)] if sink is None else self._cuts(sink, boundary, boundary < t_target - 1e-12)
            self._run_pieces(cuts, sink)
            s.t = boundary  # no drift from summing h

    def _cuts(self, sink, boundary: float, switch: bool) -> list:
        """[(time, is a frame)]: the frame times up to the boundary (not one on a switch: that one belongs to the
        next epoch), then the boundary."""
        frames = sink.times[sink.next:]
        frames = frames[frames <= boundary + (-1e-12 if switch else 1e-12)]
        cuts = [(float(t), True) for t in frames]
        if not cuts or cuts[-1][0] < boundary - 1e-12:
            cuts.append((boundary, False))
        return cuts

    def _run_pieces(self, cuts: list, sink) -> None:
        """Step through the cut points [(time, is a frame)]: consecutive intervals with the same number and length
        of steps go to the kernel in one call, which records the frames among them."""
        s, h = self.state, self.plan.step
        i = 0
        per_call = self.compiled.table.steps_per_call(self.stepper.grid)
        if sink is not None and sink.on_frame is not None:
            per_call = min(per_call, ON_FRAME_STEPS)  # the caller hears of the frames (and can stop) every so often
        if self.observers:
            per_call = 1  # stages still in Python need the state after every step
        if self.tracers:
            per_call = min(per_call, max(1, TRACE_CELLS // max(len(self._traced) * D.PACKED, 1)))
        while i < len(cuts):
            count, h_piece = _steps_of(cuts[i][0] - s.t, h)
            intervals = 1
            while (i + intervals < len(cuts) and count * intervals < per_call
                   and _steps_of(cuts[i + intervals][0] - cuts[i + intervals - 1][0], h) == (count, h_piece)):
                intervals += 1
            piece = cuts[i:i + intervals]
            self._run_steps(h_piece, count, piece, sink, per_call)
            s.t = piece[-1][0]
            i += intervals

    def _run_steps(self, h: float, count: int, ends: list, sink, per_call: int) -> None:
        """count steps of h per interval, over the intervals ending at ends [(time, is a frame)], recording the
        frames among them (in the kernel; or here, after the stages that still run in Python). The Active rows
        are the epoch's as the collision stage last left them (self._act)."""
        s = self.state
        is_frame = [frame for _, frame in ends]
        total = count * len(is_frame)
        clock = step_times(s.t, [t for t, _ in ends], count, h)
        frame_ends = {(k + 1) * count for k in range(len(is_frame)) if is_frame[k]}
        if self._frame_now:  # the frame at the start of these steps (see _advance)
            frame_ends.add(0)
            self._frame_now = False
        in_python = self._python_stages()
        done = 0
        while done < total:
            steps = min(per_call, total - done)
            frame_step = np.array(sorted(end - done for end in frame_ends if (done < end or end == 0)
                                         and end <= done + steps and not in_python), np.int64)
            frames = self._frame_buffer(len(frame_step), steps)
            taken = self.stepper.run(self._act, s.y, clock[done:done + steps + 1], h, steps, frame_step, frames,
                                     self._status)
            self._end_compile_notice()
            first = done
            done += taken
            s.steps += taken
            s.t = float(clock[done])
            stopped = self._status[0] == CONTACT
            # a stop for the collision stage, or a body that ran away, ends the call before the frames of that step
            # are recorded (core/record.py after_step): only the frames the kernel recorded go on (a frame buffer is
            # zeros until recorded: a blow-up on a frame time once wrote a frame of zero positions and quaternions)
            self._deliver(frames, frame_step, taken - (self._status[0] in (CONTACT, RUNAWAY_BODY)), sink)
            if self._status[0] not in (DONE, CONTACT):
                raise self._failure()
            if stopped:  # the collision stage looks at the step that just ended
                self.collider.on_stop(int(self._status[3]), int(self._status[2]), h, self._epoch(s.t - 0.5 * h))
                if getattr(self.collider, "wants_capture", None) is None:
                    self._count_look()
                if getattr(self.collider, "wants_capture", None):
                    self.switch_to_capture(self.collider.wants_capture, float(clock[done]))
                self.active_rows()
            if in_python:
                self._after_step(h)
            if (in_python or stopped) and done in frame_ends and sink is not None:
                self._record_now(sink)
            if self.tracers:
                self._hand_trace(frames.trace[:taken], clock[first + 1:done + 1].copy(), stopped)

    def _hand_trace(self, trace: np.ndarray, times: np.ndarray, stopped: bool) -> None:
        """The steps of a kernel call to each tracer (add_tracer); the last one as the collision stage left it
        when it looked at that step (it may have taken the step again)."""
        if stopped:
            s = self.state
            times[-1] = s.t
            trace[-1] = s.y[self._traced]
        first = 0
        for tracer in self.tracers:
            count = len(tracer.bodies)
            tracer.take(self, times, trace[:, first:first + count])
            first += count

    def _python_stages(self) -> bool:
        """Whether a stage still runs in Python after every step (observers)."""
        return bool(self.observers)

    def _epoch(self, t: float | None = None):
        c = self.plan.constraints
        return c.epoch_at(self.state.t if t is None else t) if c is not None else None

    def _after_step(self, h: float) -> None:
        for observe in self.observers:
            observe(self, h)

    # -- frames ---------------------------------------------------------------------------------------------

    def _frame_buffer(self, count: int, steps: int = 0) -> Frames:
        """Room for `count` frames, and for the traced motion of `steps` steps when a tracer listens."""
        n1 = self.plan.n + 1
        K = len(self.compiled.model.constraints.family)
        traced = self._traced
        return Frames(np.zeros((count, n1, D.PACKED)), np.zeros(count), np.zeros(count), np.zeros(count, np.int64),
                      np.zeros((count, K, 8)), traced,
                      np.zeros((steps if self.tracers else 0, len(traced), D.PACKED)))

    def _deliver(self, frames: Frames, frame_step, recorded: int, sink) -> None:
        """Hand on the frames the kernel recorded: those after steps 0..recorded (a frame at step 0 is recorded
        whenever the call ran)."""
        if sink is None:
            return
        n = self.plan.n
        for f in range(len(frame_step)):
            if frame_step[f] > max(recorded, 0):
                break
            if sink.recorder is not None:
                sink.recorder.record_packed(frames.y[f, :n], float(frames.error[f]), float(frames.energy[f]),
                                            int(frames.worst[f]))
            self._last_delivered = (float(sink.times[sink.next]), frames.y[f])
            if self.collider is not None:
                self.collider.frame_events(float(sink.times[sink.next]), frames.contact[f])
            sink.next += 1
            if sink.on_frame is not None:
                sink.on_frame(self, sink.recorder)

    def _record_now(self, sink) -> None:
        if sink.recorder is not None:
            sink.recorder.record(self.state, self.check_constraints(), self.energy())
        self._last_delivered = (float(sink.times[sink.next]), self.state.y.copy())
        if self.collider is not None:
            self.collider.frame_events(float(sink.times[sink.next]), None)
        sink.next += 1
        if sink.on_frame is not None:
            sink.on_frame(self, sink.recorder)

    # -- epochs and failures ----------------------------------------------------------------------------------

    def _follow_paths(self) -> None:
        """Bodies with a `kinematic A .. B` window onto their path when it begins (placed on it: the path's pose
        and velocities replace the state), off it when it ends (dynamic from the path's state there)."""
        paths = self.plan.kinematics
        if paths is None or np.isinf(paths.windows).all():
            return
        on = on_path(paths, self.state.t + 1e-12)
        windowed = np.isfinite(paths.windows).any(axis=1)
        changed = np.flatnonzero(windowed & (on != self.compiled.model.kinematic.on))
        if not len(changed):
            return
        dynamic, inv_mass, inv_inertia = self._off_path
        for k in changed.tolist():
            self.compiled.set_on_path(k, bool(on[k]))
            b = int(paths.index[k])
            self.plan.dynamic[b] = dynamic[b] and not on[k]
            self.plan.inv_mass[b] = 0.0 if on[k] else inv_mass[b]
            self.plan.inv_inertia_body[b] = 0.0 if on[k] else inv_inertia[b]
        self._model_changed()
        self._place_kinematic()

    @property
    def rows_now(self):
        """The Active rows the last step ran with (None before the first), as they were: a blow-up's diagnosis
        and the collision stage's frame contacts read them without bringing them up to date."""
        return self._act

    def active_rows(self):
        """The Active rows of the epoch the state is in, brought up to date: kinematic windows followed, the
        collision stage told of a new epoch or phase, the stepper told of a new set. The collision stage calls it
        after it changes the contacts."""
        self._follow_paths()
        c = self.plan.constraints
        epoch = c.epoch_at(self.state.t + 1e-12) if c is not None else None
        if self.collider is not None:
            phase = (id(epoch), self.plan.collisions.phase(self.state.t + 1e-12))
            if phase != self._epoch_in:
                self._epoch_in = phase
                self.collider.on_epoch(epoch, self.state.t + 1e-12)
        lasting = self.collider.lasting if self.collider is not None else None
        act = self.compiled.active(epoch, self.state.y, self.state.t,
                                   lasting.active_rows() if lasting is not None else None,
                                   lasting.version if lasting is not None else 0)
        if act is not self._act:
            if self._act is not None:
                self.compiled.leave(self._act)
            self._act = act
            self.stepper.enter(act, self.state.y, self.state.t)
        return act

    # -- the contact path -----------------------------------------------------------------------------------

    def _start_contacts(self) -> None:
        """A heap starts on the capturing path (runtime/capture); other scenes on the exact one (runtime/collide),
        until it asks to change: an impact between two moving bodies (`collider.wants_capture`), or, with joints,
        contacts that change at most steps (`_count_look`)."""
        from . import capture

        plan = self.plan
        self.capture_refused = capture.eligible(plan)
        self._looks = [] if self.capture_refused is None else None  # the steps at which the exact path looked
        if self._starts_capturing(plan):
            n = int(np.count_nonzero(plan.dynamic[plan.collisions.collidable]))
            self.switch_to_capture(f"a heap: {n} moving bodies collide")
            return
        self.collider = plan.collisions.start(self)
        self.collider.may_capture = self.capture_refused is None and (plan.solver == "procedural"
                                                                      or not capture.jointed(plan))
        # the procedural plan's exact contacts gain energy when a jointed body strikes (a chain landing): it hands
        # over at the first impact of one, whatever it strikes (Collider.on_epoch marks them)
        self.collider.jointed_strike = plan.solver == "procedural" and self.capture_refused is None
        self.active_rows()
        self.collider.start(self._epoch())
        if self.collider.wants_capture:
            self.switch_to_capture(self.collider.wants_capture)

    @staticmethod
    def _starts_capturing(plan) -> bool:
        """Whether the run starts on the capturing path: a heap (enough moving bodies collide) that may take it."""
        from . import capture

        return plan.collisions is not None and capture.eligible(plan) is None and capture.crowded(plan)

    def _count_look(self) -> None:
        """A look of the exact path: LOOKS of them within STEPS steps ask for the capturing path."""
        from .capture import LOOKS, STEPS

        if self._looks is None:
            return
        self._looks = self._looks[-(LOOKS - 1):] + [self.state.steps]
        if len(self._looks) == LOOKS and self._looks[-1] - self._looks[0] < STEPS:
            self.collider.wants_capture = f"the contacts changed {LOOKS} times within {STEPS} steps"

    def _end_compile_notice(self) -> None:
        """The compile notice's last line, and its time counted apart from the run's."""
        started = self._compile_notice.started
        if started:
            self.compile_seconds += time.perf_counter() - started
        self._compile_notice.end()

    def switch_to_capture(self, why: str, t_end: float | None = None) -> None:
        """From now on contacts are solved in the capturing loop (runtime/capture), which keeps them itself; the
        live state, at an impact inside a step that ends at t_end, is taken to t_end by it."""
        from .capture import CaptureStage, CaptureStepper

        stage = CaptureStage(self, self.events, why)
        self.collider, self.stepper = stage, CaptureStepper(self.compiled, self.plan, stage)
        self._compile_notice = CompileNotice.begin(*self.stepper.entries)
        self._epoch_in = ()
        act = self.active_rows()
        s = self.state
        if t_end is not None and t_end - s.t > 1e-12:
            self.stepper.run(act, s.y, s.t, t_end - s.t, 1, np.zeros(0, np.int64), self._frame_buffer(0), self._status)
            if self._status[0] != DONE:
                raise self._failure()
            s.t = t_end

    def contact_report(self) -> dict | None:
        """report.json `contact`: which contact path ran and why, and the capturing path's checks."""
        if self.collider is None:
            return None
        report = getattr(self.collider, "report", None)
        if report is not None:
            return report()
        from .capture import LOOKS, STEPS, jointed

        quiet = (f"its contacts never changed {LOOKS} times within {STEPS} steps" if jointed(self.plan)
                 else "no impact between moving bodies")
        return {"path": "exact", "why": self.capture_refused or quiet}

    def _failure(self) -> NumericalError:
        return failure(self)

    def _place_kinematic(self) -> None:
        """The bodies on their paths now at their paths' pose and velocity: the compiled kernel's own code
        (core/bodies.py place_kinematic), run as Python on the time table's row of now."""
        kin = self.compiled.model.kinematic
        if len(kin.body):
            place_kinematic.py_func(kin, self.compiled.table.evaluate(self.state.t, 0.0, 1), 0, self.state.y)

