"""The audio stage: sounds whose parameters come from the motion (docs/design/sound.md#section-1, docs/sound.md).

Imported only for scenes that have sounds (runtime/plan/__init__.py). Its passes, one module each:

    compile   graph.py     a sound's `play` expression -> a tree of nodes (nodes.py, impact.py, scrape.py,
                           wind_sound.py; modes from modal.py, resonators from resonator.py)
    record    record.py    an observer of the step loop keeps hits, contact and wind signals, positions
    render    render.py    the graphs played block by block over the record, through the listener
                           (listener.py); written as audio.wav (soundfile, imported only then)

    plan = compile_audio(scene, sim_plan)       # in compile_plan, as plan.audio
    run = plan.audio.record(simulation)         # before stepping: registers the observer
    ... simulation ...
    report = run.write(out / "audio.wav")       # render, write atomically, figures for report.json
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .graph import Needs, SoundCompiler, contact_properties
from .render import BLOCK, Renderer, wav_bytes


@dataclass
class AudioPlan:
    scene: object  # ir.Scene
    fs: float
    channels: int
    block: int
    start: float
    end: float
    sounds: list  # SoundPlan
    needs: Needs
    contact_props: dict  # body -> what excitation.contact_duration needs
    warnings: list = field(default_factory=list)

    @property
    def samples(self) -> int:
        return int(round((self.end - self.start) * self.fs))

    @property
    def mode_count(self) -> int:
        return sum(len(m) for sp in self.sounds for m in sp.modes.values())

    def record(self, sim) -> "AudioRun":
        """Start recording a simulation's motion (before it steps)."""
        return AudioRun(self, sim)

    def describe(self) -> str:
        lines = [f"audio: {len(self.sounds)} sounds at {self.fs:g} Hz, {self.channels} channel(s), "
                 f"blocks of {self.block}, {self.mode_count} modes"]
        for sp in self.sounds:
            s = sp.sound
            on = {"collide": f"collide({', '.join(s.bodies) or 'any'})",
                  "contact": f"contact({', '.join(s.bodies) or 'any'})", "wind": f"wind({s.wind})",
                  "time": f"at({s.time} s)", "always": "always"}[s.trigger]
            modes = ", ".join(f"{b}: {len(m)} modes ({m.model}, {m.freq[0]:.0f} Hz ..)" for b, m in sp.modes.items()
                              if len(m))
            lines.append(f"  sound {s.name} on {on}" + (f"; {modes}" if modes else ""))
        return "\n".join(lines)

    def render(self, record, block: int | None = None) -> np.ndarray:
        """(frames, channels) of the whole scene over a record (from a run, or record.synthetic_record)."""
        return Renderer(self, record, block or self.block).render()

    def synthetic_record(self, events: list, **kwargs):
        from .record import synthetic_record

        return synthetic_record(self, events, **kwargs)


def compile_audio(scene, plan=None, block: int = BLOCK) -> AudioPlan:
    """Compile the scene's sounds (plan: the simulation plan, for its time span; None: the scene's)."""
    fs = float(scene.audio.rate)
    needs, warnings = Needs(), []
    folder = getattr(plan, "folder", None)
    sounds = [SoundCompiler(scene, sound, fs, needs, warnings, folder).compile() for sound in scene.sounds]
    start = plan.start if plan is not None else scene.time.start
    end = plan.end if plan is not None else scene.time.end
    channels = max(1, min(2, int(scene.audio.channels)))
    audio = AudioPlan(scene, fs, channels, block, start, end, sounds, needs, contact_properties(scene), warnings)
    if plan is not None:
        plan.warnings.extend(warnings)
    return audio


class AudioRun:
    """The audio of one simulation: records while it steps, renders and writes when asked."""

    def __init__(self, plan: AudioPlan, sim):
        from .record import Recorder

        self.plan = plan
        self.recorder = Recorder(plan, sim)
        self.render_time = 0.0

    @property
    def record(self):
        return self.recorder.record

    def render(self) -> np.ndarray:
        started = time.perf_counter()
        samples = self.plan.render(self.record)
        self.render_time = time.perf_counter() - started
        return samples

    def write(self, path, simulation_time: float | None = None) -> dict:
        """Render, write the WAV atomically, and return the audio part of report.json."""
        from ..outputs import write_atomic

        samples = self.render()
        write_atomic(path, wav_bytes(samples, int(round(self.plan.fs))))
        seconds = len(samples) / self.plan.fs
        peak = float(np.max(np.abs(samples))) if samples.size else 0.0
        report = {
            "file": path.name, "rate": self.plan.fs, "channels": self.plan.channels, "seconds": seconds,
            "sounds": len(self.plan.sounds), "hits": len(self.record.hits), "modes": self.plan.mode_count,
            "render_time": self.render_time,
            "real_time_factor": _ratio(seconds, self.render_time),
            "peak": peak, "warnings": list(self.plan.warnings),
        }
        if simulation_time is not None:
            report["real_time_factor_with_simulation"] = _ratio(seconds, self.render_time + simulation_time)
        if peak > 1.0:
            report["warnings"].append(f"audio peak {peak:.2f} > 1: lower a sound's `gain` or the listener's")
        return report


def _ratio(a: float, b: float) -> float | None:
    return a / b if b > 0 else None  # JSON has no infinity
