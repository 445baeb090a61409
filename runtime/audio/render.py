"""Audio stage, render: the sounds' graphs played block by block over the recorded motion, and the WAV file.

For every block of samples [s, s + n) and every sound (a Voice: its own copy of the graph, its listener
stage, its held event values), the renderer gives the graph a SoundBlock: the sample times, the hits of
the sound's trigger that start in the block with their offsets (a hit at time t starts at sample
round((t - start) fs)), the envelope triggers and gates, and the motion signals interpolated at the samples.
The voices' outputs pass through the listener and are summed. A block can be rendered as soon as the
motion has been recorded past its end, so a live run can stream; `isaac run` renders after the simulation,
OFFLINE_BLOCKS blocks at a time (the nodes keep the decisions that would fall at block edges on a fixed grid of
frames, nodes.FRAME, so the samples do not depend on the block size). soundfile is imported only to write the file.
"""
from __future__ import annotations

import copy
import functools
import io
import math

import numpy as np

from isaac_ir import expr as E

from .excitation import rule_duration
from .listener import ListenerStage
from .record import Hit

BLOCK = 2048  # samples per block (46 ms at 44.1 kHz: the latency of a stream, well under the 125 ms of ITU-R BT.1359)
# a render of motion already recorded (nothing waits for it) goes this many blocks at a time: the nodes' work per
# block is spread over more samples (scenes/chimes: 0.32 s of CPU instead of 0.6 s), and the samples are the same
OFFLINE_BLOCKS = 8
EVENT_HELD = ("impulse", "speed", "normal_force")  # event signals held from one hit to the next


class Voice:
    """One sound being played: its graph's state, its hits still to come, its held values."""

    def __init__(self, sound_plan, plan, record):
        self.sp, self.plan, self.record = sound_plan, plan, record
        self.sound = sound_plan.sound
        self.root = copy.deepcopy(sound_plan.root)
        self.listener = ListenerStage(plan.scene.listener, plan.fs, plan.channels)
        self.pending: list = []
        self.seen = 0
        self.held_values: dict = {}  # expression -> its value at the latest hit
        self.gate_until = -1  # sample until which an adsr gate opened by a hit stays open
        self.last_force = 0.0
        self.last_point = np.asarray(plan.scene.listener.position, float)
        self.started = False
        if self.sound.trigger == "time":
            self.pending.append(self._timed_hit())

    def _timed_hit(self) -> Hit:
        sound, plan = self.sound, self.plan
        anchor = self.sp.anchor
        props = plan.contact_props.get(anchor) if anchor else None
        tau = max(rule_duration(props["mass"]) if props and props["mass"] < math.inf else 1e-3, 1.0 / plan.fs)
        return Hit(sound.time, int(round((sound.time - plan.start) * plan.fs)), (anchor,) if anchor else (), 1.0,
                   0.0, 0.0, self.last_point.copy(), {}, tau, -1)

    def hears(self, hit: Hit) -> bool:
        bodies = self.sp.hit_bodies
        if bodies is None:
            return True
        if not bodies:
            return False
        return set(hit.bodies) == set(bodies) if len(bodies) > 1 else bodies[0] in hit.bodies

    def render(self, block: "BlockTime", out: np.ndarray) -> None:
        """Add the sound's block, as the listener hears it, to out (channels, n)."""
        start, n = block.start, block.n
        hits = self.record.hits
        self.pending.extend(h for h in hits[self.seen:] if self.hears(h))
        self.seen = len(hits)
        now = sorted((h for h in self.pending if h.sample < start + n), key=lambda h: h.sample)
        self.pending = [h for h in self.pending if h.sample >= start + n]
        ctx = SoundBlock(self, block, now)
        sound = self.root.render(ctx)
        sound = np.broadcast_to(sound, (n,)) if np.ndim(sound) == 0 else sound
        if self.sound.trigger == "time":  # silent before its time
            quiet = int(np.clip(round((self.sound.time - self.plan.start) * self.plan.fs) - start, 0, n))
            if quiet:
                sound = np.array(sound, copy=True)
                sound[..., :quiet] = 0.0
        self.listener.render(sound, ctx.source, ctx.source_distance(), out)


class SoundBlock:
    """What a sound's graph sees of one block (the `ctx` of nodes.py)."""

    def __init__(self, voice: Voice, block: "BlockTime", hits: list):
        start, n = block.start, block.n
        self.voice, self.block, self.start, self.n, self.fs, self.t = voice, block, start, n, voice.plan.fs, block.t
        self.hits = [(min(max(h.sample - start, 0), n - 1), h) for h in hits]
        self._cache: dict = {}
        trigger = voice.sound.trigger
        self.triggers = [k0 for k0, _ in self.hits]
        if trigger in ("always", "wind") and not voice.started:
            self.triggers.insert(0, 0)
        if trigger == "contact":
            self.triggers = sorted(set(self.triggers) | set(self._contact_onsets()))
        voice.started = True
        self.source = self._source_positions()

    # -- motion signals -----------------------------------------------------------------------------------

    def _interp(self, series) -> np.ndarray:
        times = self.voice.record.times.view()
        values = series.view()
        if values.ndim == 1:
            return np.interp(self.t, times, values)
        return np.stack([np.interp(self.t, times, values[:, i]) for i in range(values.shape[1])], axis=-1)

    def position(self, body: str) -> np.ndarray:
        key = ("position", body)
        if key not in self._cache:
            self._cache[key] = self._interp(self.voice.record.positions[body])
        return self._cache[key]

    def contact(self, pair: tuple) -> dict:
        """Sliding speed, normal force, rolling speed (n,) and the latest contact point of each body."""
        key = ("contact", pair)
        if key not in self._cache:
            series = self.voice.record.contacts[pair]
            times = series["times"].view()
            if not len(times):
                zero = np.zeros(self.n)
                self._cache[key] = {"speed": zero, "force": zero, "roll": zero, "local": {}}
            else:
                at = lambda name: np.interp(self.t, times, series[name].view())
                self._cache[key] = {"speed": at("speed"), "force": at("force"), "roll": at("roll"),
                                    "local": {b: _value_at(series[("local", b)], times, self.t[-1]) for b in pair}}
        return self._cache[key]

    def wind_speed(self, body: str | None) -> np.ndarray:
        key = ("wind", body)
        if key not in self._cache:
            wind = self.voice.record.wind
            if body is not None:
                value = self._interp(wind[body])
            else:
                value = np.zeros(self.n)
                for name in self.voice.sp.winds:
                    if ("listener", name) in wind:
                        value = value + self._interp(wind[("listener", name)])
            self._cache[key] = value
        return self._cache[key]

    def wind_speeds(self, bodies: list) -> np.ndarray:
        """(len(bodies), n) the relative wind speed at each body."""
        return np.stack([self.wind_speed(body) for body in bodies])

    def source_distance(self) -> np.ndarray:
        """Distances from the source to the listener: (n,), or (1,) for a source that stays put."""
        if "distance" not in self._cache:
            self._cache["distance"] = self.voice.listener.distance(self.source)
        return self._cache["distance"]

    def signal(self, name: str) -> np.ndarray:
        if name == "t":
            return self.t
        key = ("signal", name)
        if key in self._cache:
            return self._cache[key]
        voice, trigger = self.voice, self.voice.sound.trigger
        if name == "distance":
            value = np.broadcast_to(self.source_distance(), (self.n,)).copy()
        elif name == "wind_speed":
            anchor = voice.sp.anchor
            value = self.wind_speed(anchor if anchor in voice.record.wind and trigger != "wind" else None)
        elif trigger == "contact" and name in ("speed", "normal_force"):
            c = self.contact(tuple(voice.sound.bodies))
            value = c["speed"] if name == "speed" else c["force"]
        elif trigger == "wind" and name == "speed":
            value = self.wind_speed(None)
        elif name in EVENT_HELD:
            value = self.held(E.Var(name))
        else:
            value = np.zeros(self.n)
        self._cache[key] = value
        return value

    # -- hits ---------------------------------------------------------------------------------------------

    def hit_env(self, k0: int, hit: Hit) -> dict:
        env = hit.values()
        env["distance"] = float(self.signal("distance")[k0])
        env["wind_speed"] = float(self.signal("wind_speed")[k0])
        return env

    def strength(self, expr, hit: Hit) -> float:
        if expr is None:
            return 1.0
        k0 = min(max(hit.sample - self.start, 0), self.n - 1)
        return float(E.evaluate(expr, self.hit_env(k0, hit)))

    def held(self, expr) -> np.ndarray:
        """expr evaluated at each hit, held from its sample until the next hit (0 before the first)."""
        values = self.voice.held_values
        out = np.full(self.n, values.get(expr, 0.0))
        for k0, hit in self.hits:
            value = float(E.evaluate(expr, self.hit_env(k0, hit)))
            out[k0:] = value
            values[expr] = value
        return out

    def adsr_gate(self, hold: float) -> np.ndarray:
        voice, trigger = self.voice, self.voice.sound.trigger
        if trigger == "contact":
            return self.contact(tuple(voice.sound.bodies))["force"] > 0.0
        if trigger in ("always", "wind"):
            return np.ones(self.n, bool)
        # open for `hold` after each hit; an opening carried over from an earlier block stays open
        gate = np.zeros(self.n, bool)
        until = voice.gate_until - self.start  # end of the open stretch, relative to this block
        gate[:max(0, min(until, self.n))] = True
        hold_samples = int(round(hold * self.fs))
        for k0, _ in self.hits:
            gate[k0:min(k0 + hold_samples, self.n)] = True
            until = max(until, k0 + hold_samples)
        voice.gate_until = self.start + until
        return gate

    def _contact_onsets(self) -> list:
        force = self.contact(tuple(self.voice.sound.bodies))["force"]
        before = np.concatenate(([self.voice.last_force], force[:-1]))
        self.voice.last_force = float(force[-1])
        return list(np.flatnonzero((before <= 0.0) & (force > 0.0)))

    def _source_positions(self) -> np.ndarray:
        """(n, 3) where the sound comes from at each sample, or (1, 3) when it stays put over the block."""
        voice = self.voice
        anchor = voice.sp.anchor
        if anchor is not None and anchor in voice.record.positions:
            still = self._still(voice.record.positions[anchor])
            return still if still is not None else self.position(anchor)
        moves = [(k0, hit) for k0, hit in self.hits if hit.index >= 0]
        if not moves:
            return voice.last_point[None, :]
        out = np.tile(voice.last_point, (self.n, 1))
        for k0, hit in moves:
            out[k0:] = hit.point
            voice.last_point = np.asarray(hit.point, float)
        return out

    def _still(self, series) -> np.ndarray | None:
        """The value (1, ...) of a series recorded at the steps when it does not change over the block (its
        interpolation is that value at every sample), else None."""
        window = series.view()[self.block.steps]
        return window[:1] if (window == window[0]).all() else None


class BlockTime:
    """One block of samples [start, start + n): their times t (n,), and the record's steps around them."""

    def __init__(self, start: int, t: np.ndarray, record_times: np.ndarray):
        self.start, self.n, self.t = start, len(t), t
        self.record_times = record_times

    @functools.cached_property
    def steps(self) -> slice:
        """The recorded steps whose values the block's samples interpolate (np.interp's), from the last at or
        before the first sample to the first after the last."""
        times, t = self.record_times, self.t
        first = max(int(np.searchsorted(times, t[0], side="right")) - 1, 0)
        return slice(first, int(np.searchsorted(times, t[-1], side="right")) + 1)


def _value_at(series, times: np.ndarray, t: float) -> np.ndarray:
    values = series.view()
    if not len(values):
        return np.zeros(3)
    i = int(np.searchsorted(times, t, side="right")) - 1
    return values[max(0, min(i, len(values) - 1))]


class Renderer:
    """Renders a plan's sounds over a record, block by block."""

    def __init__(self, plan, record, block: int = BLOCK):
        self.plan, self.record, self.block = plan, record, block
        self.voices = [Voice(sp, plan, record) for sp in plan.sounds]
        self.position = 0

    def ready(self) -> int:
        """Samples whose motion is known (all of them once the simulation has finished)."""
        known = int(math.floor((self.record.until - self.plan.start) * self.plan.fs + 1e-9)) + 1
        return min(self.plan.samples, max(known, 0))

    def next_block(self, final: bool = False, size: int | None = None) -> np.ndarray | None:
        """The next (channels, n) block of `size` samples (the plan's block), or None when the motion is not known
        far enough yet."""
        size = size or self.block
        limit = self.plan.samples if final else self.ready()
        n = min(size, limit - self.position)
        if n <= 0 or (not final and n < size and limit < self.plan.samples):
            return None
        out = np.zeros((self.plan.channels, n))
        t = self.plan.start + (self.position + np.arange(n)) / self.plan.fs
        block = BlockTime(self.position, t, self.record.times.view())
        for voice in self.voices:
            voice.render(block, out)
        self.position += n
        return out

    def render(self) -> np.ndarray:
        """Every remaining sample, as (frames, channels), OFFLINE_BLOCKS blocks at a time."""
        first = self.position
        out = np.empty((self.plan.channels, max(self.plan.samples - first, 0)))
        while self.position < self.plan.samples:
            lo = self.position - first
            block = self.next_block(final=True, size=self.block * OFFLINE_BLOCKS)
            out[:, lo:lo + block.shape[1]] = block
        return out.T


def wav_bytes(samples: np.ndarray, rate: int) -> bytes:
    """A 24-bit PCM WAV of (frames, channels) samples: every reader takes it (the standard library's `wave`,
    scipy, browsers), and its step, 1.2e-7 of full scale, is far below anything a test measures. Samples past
    +-1 are clipped (the report warns when the peak passes 1)."""
    import soundfile

    buffer = io.BytesIO()
    soundfile.write(buffer, np.clip(samples, -1.0, 1.0), rate, format="WAV", subtype="PCM_24")
    return buffer.getvalue()
