"""Live stage, the loop: one frame of simulation at a time, held to the wall clock, while the page watches and acts.

Each frame: take what the page asked for (a drag, a parameter), wait until the frame's start is due, latch the
breath, run the steps to the frame (Simulation.run_frames over one frame: the compiled core steps the whole frame
in one call), render the sound the new motion allows, send the poses (and the sound) to the page, and note the
lag. It ends at the last frame (`--until`, or the scene's end) or on Ctrl-C, and hands back what happened.
"""
from __future__ import annotations

import base64
import signal
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from isaac_ir.diagnostics import SceneError

from ..outputs import Recorder
from ..simulation import NumericalError
from .audio import LiveAudio
from .clock import Pacer
from .drag import Drag


class LiveRecorder(Recorder):
    """The trajectory of what happened live, in the bodies the run began with: after a re-plan that changed the
    bodies, one that is gone stays NaN and a new one is not recorded."""

    def __init__(self, frame_times, names):
        super().__init__(frame_times, names)
        self.rows = None  # the state's row of each recorded body (-1: gone), None while they are the same

    def follow(self, names: list) -> bool:
        """The simulation's bodies are now `names`; whether they are the ones recorded."""
        index = {name: i for i, name in enumerate(names)}
        rows = np.array([index.get(str(n), -1) for n in self.bodies], np.int64)
        same = len(names) == len(rows) and bool((rows == np.arange(len(rows))).all())
        self.rows = None if same else rows
        return same

    def _mapped(self, y: np.ndarray) -> np.ndarray:
        out = np.full((len(self.rows), y.shape[1]), np.nan)
        have = self.rows >= 0
        out[have] = y[self.rows[have]]
        return out

    def record_packed(self, y, *rest) -> None:
        super().record_packed(y if self.rows is None else self._mapped(y), *rest)

    def record(self, state, *rest) -> None:
        if self.rows is None:
            super().record(state, *rest)
            return
        packed = self._mapped(np.concatenate([state.x, state.q, state.v, state.w], axis=1))
        super().record_packed(packed, *rest)


@dataclass
class LiveResult:
    simulation: object
    recorder: LiveRecorder
    events: list
    error: NumericalError | None
    audio: LiveAudio | None
    wall: float  # s: from the clock's start to the end of the loop
    interrupted: bool
    pacer: Pacer
    replans: list = field(default_factory=list)
    notices: list = field(default_factory=list)
    drags: int = 0


class LiveSession:
    """The loop (module docstring). publish(kind, data) sends to the page; say(text) to the terminal."""

    def __init__(self, simulation, frame_times, breath, publish, commands, say, describe_scene,
                 parameters: dict, clock=time.monotonic, sleep=time.sleep, replan=None, overrides=None):
        self.sim = simulation
        self.replan = replan  # overrides -> the scene's plan with them (a slider's change; the application's)
        self.overrides = dict(overrides or {})
        self.frames = np.asarray(frame_times, float)
        self.breath = breath
        self.publish, self.commands, self.say = publish, commands, say
        self.describe_scene = describe_scene  # () -> the page's drawing data of the scene now
        self.parameters = parameters  # name -> the text the value is written in (sliders)
        self.clock = clock
        self.pacer = Pacer(self.frames[0], self._frame_period(), clock, sleep, self._notice)
        self.recorder = LiveRecorder(self.frames, simulation.plan.names)
        self.audio = LiveAudio.start(simulation)
        self.drag = Drag()
        self.events: list = []  # the events of the simulations before the last re-plan
        self.replans: list = []
        self.notices: list = []
        self.version = 0  # of the scene the page draws
        self.frame = 0
        self.stop = threading.Event()

    def _frame_period(self) -> float:
        return float(self.frames[1] - self.frames[0]) if len(self.frames) > 1 else 1.0

    def _notice(self, text: str, level: str = "info") -> None:
        self.notices.append(text)
        self.say(text)
        self.publish("notice", {"text": text, "level": level})

    # -- the loop ------------------------------------------------------------------------------------------------

    def run(self) -> LiveResult:
        # the first frame and the steps to the second before the clock starts: they load the compiled core from
        # its cache (or compile it, on a new machine), which a paced frame could not afford
        self.sim.run_frames(self.frames[:min(2, len(self.frames))], self.recorder)
        self._send_frame(min(1, len(self.frames) - 1))
        error, started = None, None
        with _ctrl_c_stops(self.stop):
            started = self.pacer.begin() - (self.frames[min(1, len(self.frames) - 1)] - self.frames[0])
            self.pacer.origin = started  # the second frame is now
            if self.breath is not None:
                self.breath.start(started)
            try:
                for k in range(2, len(self.frames)):
                    if self.stop.is_set():
                        break
                    self.pacer.wait_until(self.frames[k - 1])
                    if self.stop.is_set():
                        break
                    self._take_commands()
                    self._step(k)
            except NumericalError as failure:
                error = failure
        wall = self.clock() - started  # (from scene time start, as the clock counts it)
        if self.breath is not None:
            self.breath.close()
        self._flush_audio()
        self.publish("end", {"t": float(self.sim.state.t), "interrupted": self.stop.is_set(),
                             "error": str(error) if error else None})
        return LiveResult(self.sim, self.recorder, self.events + list(self.sim.events), error, self.audio, wall,
                          self.stop.is_set(), self.pacer, self.replans, self.notices, self.drag.count)

    def _step(self, k: int) -> None:
        if self.breath is not None:
            self.breath.latch()
        began = self.clock()
        self.sim.run_frames(self.frames[k:k + 1], self.recorder)
        work = self.clock() - began
        if self.breath is not None:
            self.breath.stepped()
        if self.audio is not None:
            for first, block in self.audio.pump():
                self.publish("audio", self.audio.message(first, block))
        self.pacer.done(self.frames[k], work)
        self._send_frame(k)

    def _send_frame(self, k: int) -> None:
        self.frame = k
        y = self.sim.state.y[:self.sim.plan.n]
        data = {"k": k, "t": float(self.frames[k]), "version": self.version,
                "p": _b64(y[:, 0:3]), "q": _b64(y[:, 3:7]), "lag_ms": self.pacer.lag * 1e3,
                "breath": self.breath.display_level() if self.breath is not None else None,
                "wind": self._winds(), "drag": self.drag.overlay()}
        self.publish("frame", data)

    def _winds(self) -> list:
        wind = self.sim.plan.forces.wind
        if wind is None:
            return []
        from ..wind import wind_intensity

        t = float(self.sim.state.t)
        return [{"name": name, "speed": float(wind_intensity(wind, name, t))} for name in wind.fields.names]

    def _flush_audio(self) -> None:
        if self.audio is not None:
            for first, block in self.audio.flush():
                self.publish("audio", self.audio.message(first, block))

    # -- what the page asks for ------------------------------------------------------------------------------------

    def _take_commands(self) -> None:
        changed, drag, parameters = self.commands.take()
        for name, value in parameters:
            self._set_parameter(name, value)
        if changed:  # (only the newest state of the mouse counts)
            self.drag.apply(self.sim, drag)

    def _set_parameter(self, name: str, value: str) -> None:
        if name not in self.parameters:
            self._notice(f"no parameter `{name}` to change (the sliders are: {', '.join(self.parameters)})", "error")
            return
        began = self.clock()
        sim, old_events, old_names = self.sim, list(self.sim.events), list(self.sim.plan.names)
        overrides = {**self.overrides, name: value}
        try:
            sim.carry_on(self.replan(overrides))
        except SceneError as error:
            self._notice(f"{name} = {value}: {error.diagnostics[0].message if error.diagnostics else error}", "error")
            self.pacer.forgive(began)
            return
        self.events += old_events
        same = self.recorder.follow(sim.plan.names)
        if self.audio is not None:
            self.audio.follow(sim, same and sim.plan.names == old_names)
        self.drag.follow(sim)
        self.parameters[name] = value
        self.overrides = overrides
        seconds = self.clock() - began
        self.replans.append({"t": float(sim.state.t), "name": name, "value": value, "seconds": seconds})
        if not same:
            self.version += 1
            self.publish("scene", dict(self.describe_scene(), version=self.version))
        self._notice(f"{name} = {value} (re-planned in {seconds * 1e3:.0f} ms at t = {sim.state.t:.2f} s)")
        self.pacer.forgive(began)


class _ctrl_c_stops:
    """While the loop runs, Ctrl-C asks it to stop after the frame in hand (a second one interrupts at once)."""

    def __init__(self, stop: threading.Event):
        self.stop, self.previous = stop, None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame):
        if self.stop.is_set():
            raise KeyboardInterrupt
        self.stop.set()

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False


def _b64(array: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype="<f4").tobytes()).decode("ascii")
