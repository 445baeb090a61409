"""Live stage, sound: the scene's sounds rendered block by block as the motion is recorded, for the page to play
and for audio.wav.

    audio = LiveAudio.start(simulation)      # None for a scene without sounds
    for start, block in audio.pump(): ...    # after each frame: the blocks whose motion is now known
    audio.write(path, wall)                  # at the end: audio.wav of what was played, report.json's figures

The audio stage's recorder observes the steps (runtime/audio/record.py) and its renderer gives a block as soon as
the motion is recorded past the block's end (runtime/audio/render.py `Renderer.next_block`): the same samples an
offline render of the same motion gives. A block travels to the page as 16-bit PCM in base64.
"""
from __future__ import annotations

import base64
import time

import numpy as np


class LiveAudio:
    def __init__(self, plan, run):
        from ..audio.render import Renderer

        self.plan, self.run = plan, run
        self.renderer = Renderer(plan, run.record)
        self.blocks: list = []  # (channels, n) every block rendered, in order
        self.render_time = 0.0
        self.stopped = None  # why the sound stopped before the run did (a re-plan changed the bodies)

    @classmethod
    def start(cls, simulation):
        audio = simulation.plan.audio
        return None if audio is None else cls(audio, audio.record(simulation))

    @property
    def rate(self) -> float:
        return self.plan.fs

    def follow(self, simulation, same_bodies: bool) -> None:
        """A re-plan made a new simulation: the recorder observes it from now on (its events start again), when
        it has the same bodies; else the sound stops here."""
        recorder = self.run.recorder
        if not same_bodies:
            self.stopped = "a parameter changed the scene's bodies: the sound stopped there"
            return
        recorder.seen = 0
        simulation.add_tracer(recorder)

    def pump(self) -> list:
        """[(first sample, (channels, n) block)] of every block the motion now allows."""
        if self.stopped:
            return []
        out = []
        started = time.perf_counter()
        while True:
            first = self.renderer.position
            block = self.renderer.next_block()
            if block is None:
                break
            self.blocks.append(block)
            out.append((first, block))
        self.render_time += time.perf_counter() - started
        return out

    def flush(self) -> list:
        """At the end: the last, shorter block of the samples whose motion is known."""
        out = self.pump()
        renderer = self.renderer
        known = renderer.ready()
        if not self.stopped and known > renderer.position:
            first = renderer.position
            block = renderer.next_block(final=True, size=known - first)
            if block is not None:
                self.blocks.append(block)
                out.append((first, block))
        return out

    def message(self, first: int, block: np.ndarray) -> dict:
        pcm = np.clip(np.round(block.T * 32767.0), -32768, 32767).astype("<i2")
        return {"first": first, "rate": self.rate, "channels": int(block.shape[0]),
                "time": self.plan.start + first / self.rate, "pcm": base64.b64encode(pcm.tobytes()).decode()}

    def samples(self) -> np.ndarray:
        """(frames, channels) of what was rendered."""
        if not self.blocks:
            return np.zeros((0, self.plan.channels))
        return np.concatenate(self.blocks, axis=1).T

    def write(self, path, simulation_time: float | None = None) -> dict:
        """audio.wav of the blocks rendered live (atomically), and the `audio` part of report.json."""
        from ..audio.render import wav_bytes
        from ..outputs import write_atomic

        samples = self.samples()
        write_atomic(path, wav_bytes(samples, int(round(self.rate))))
        seconds = len(samples) / self.rate
        peak = float(np.max(np.abs(samples))) if samples.size else 0.0
        report = {"file": path.name, "rate": self.rate, "channels": self.plan.channels, "seconds": seconds,
                  "sounds": len(self.plan.sounds), "hits": len(self.run.record.hits), "modes": self.plan.mode_count,
                  "render_time": self.render_time, "streamed": True,
                  "real_time_factor": seconds / self.render_time if self.render_time > 0 else None,
                  "peak": peak, "warnings": list(self.plan.warnings) + ([self.stopped] if self.stopped else [])}
        if peak > 1.0:
            report["warnings"].append(f"audio peak {peak:.2f} > 1: lower a sound's `gain` or the listener's")
        return report
