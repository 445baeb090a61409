"""Audio stage, the nodes of the graph (timbre tree): sources, filters, envelopes, arithmetic and mixing.

A node renders one block at a time: `render(ctx)` returns a float (a constant), an (n,) mono block or a
(2, n) stereo block; numpy broadcasting mixes them. `ctx` is the sound's view of the block (render.SoundBlock):
its sample times `t`, the hits that start in it, the envelope triggers, and the motion signals.
A node keeps its own state (phase, filter memory, envelope level) from block to block, so a graph renders
the same samples whatever the block size. Exciters (modal, impact) live in impact.py, scraping in scrape.py,
wind in wind_sound.py, the listener in listener.py.
"""
from __future__ import annotations

import math

import numpy as np

from isaac_ir import expr as E

from ..signals import follow_envelope
from .iir import PoleFilter
from .modal import LN1000
from .noise import ColoredNoise

# a time-varying filter recomputes its coefficients every this many samples (1.5 ms at 44.1 kHz)
CONTROL_PERIOD = 64
# samples: a grid fixed in the render's samples, on which nodes take the decisions that would otherwise fall at
# the edges of blocks (a whistle reads its envelope at the end of each frame, a bank tests for silence), so that
# the samples do not depend on the block size
FRAME = 2048
# filter frequencies are kept inside [LOWEST_FILTER, HIGHEST_FILTER * fs]
LOWEST_FILTER = 10.0
HIGHEST_FILTER = 0.45


def as_block(value, n: int) -> np.ndarray:
    """A node's output as an array of n samples (a constant is repeated)."""
    if np.ndim(value) == 0:
        return np.full(n, float(value))
    return value


def is_constant(value) -> bool:
    return np.ndim(value) == 0


def cos_sin(angle: np.ndarray) -> tuple:
    """cos and sin of an array of angles from t = tan(angle / 2): cos = (1 - t^2) / (1 + t^2), sin = 2 t / (1 + t^2)
    (one transcendental function instead of two; numpy vectorizes tan, not cos and sin)."""
    t = np.tan(0.5 * angle)
    t2 = t * t
    scale = 1.0 / (1.0 + t2)
    return (1.0 - t2) * scale, 2.0 * t * scale


class Node:
    """Base of the nodes; `stereo` says whether the output has two channels."""

    stereo = False

    def render(self, ctx):
        raise NotImplementedError

    def children(self) -> tuple:
        return ()

    def walk(self):
        yield self
        for child in self.children():
            yield from child.walk()


# ---- leaves ---------------------------------------------------------------------------------------------

class Constant(Node):
    def __init__(self, value: float):
        self.value = float(value)

    def render(self, ctx):
        return self.value


class Control(Node):
    """An expression without audio nodes (a function of t and of motion signals), evaluated per block."""

    def __init__(self, expr: E.Expr):
        self.expr = expr
        self.names = sorted(E.free_vars(expr))

    def render(self, ctx):
        env = {name: ctx.signal(name) for name in self.names}
        env.setdefault("t", ctx.t)
        return E.evaluate(self.expr, env)


class Held(Node):
    """An expression of event values (impulse, speed, ...) evaluated at each hit and held until the next."""

    def __init__(self, expr: E.Expr):
        self.expr = expr

    def render(self, ctx):
        return ctx.held(self.expr)


# ---- arithmetic and mixing ------------------------------------------------------------------------------

_BINARY = {"add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide, "pow": np.power}


class Binary(Node):
    def __init__(self, op: str, a: Node, b: Node):
        self.op, self.a, self.b = op, a, b
        self.fn = _BINARY[op]
        self.stereo = a.stereo or b.stereo

    def children(self):
        return (self.a, self.b)

    def render(self, ctx):
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.fn(self.a.render(ctx), self.b.render(ctx))


class Negate(Node):
    def __init__(self, a: Node):
        self.a = a
        self.stereo = a.stereo

    def children(self):
        return (self.a,)

    def render(self, ctx):
        return -self.a.render(ctx)


class Function(Node):
    """sin, exp, clamp, ... of signals, element-wise."""

    def __init__(self, fn: str, args: list):
        self.fn, self.args = E.SCALAR_FUNCTIONS[fn], args
        self.stereo = any(a.stereo for a in args)

    def children(self):
        return tuple(self.args)

    def render(self, ctx):
        with np.errstate(all="ignore"):
            return self.fn(*[a.render(ctx) for a in self.args])


class Mix(Node):
    """mix(a, b, ...): the sum of its inputs."""

    def __init__(self, inputs: list):
        self.inputs = inputs
        self.stereo = any(i.stereo for i in inputs)

    def children(self):
        return tuple(self.inputs)

    def render(self, ctx):
        total = 0.0
        for node in self.inputs:
            total = total + node.render(ctx)
        return total


class Gain(Node):
    """gain(x, g): x times g (linear; gain(x, db = -6) in decibels)."""

    def __init__(self, x: Node, g: Node, decibels: bool = False):
        self.x, self.g, self.decibels = x, g, decibels
        self.stereo = x.stereo

    def children(self):
        return (self.x, self.g)

    def render(self, ctx):
        g = self.g.render(ctx)
        if self.decibels:
            g = 10.0 ** (np.asarray(g) / 20.0)
        return self.x.render(ctx) * g


# ---- sources --------------------------------------------------------------------------------------------

class Sine(Node):
    """sine(freq, phase = 0): an oscillator whose frequency may follow a signal (phase integrated)."""

    def __init__(self, freq: Node, phase: float = 0.0):
        self.freq = freq
        self.phase = phase

    def children(self):
        return (self.freq,)

    def render(self, ctx):
        f = self.freq.render(ctx)
        # phi[k] = phi0 + 2 pi sum_{j<k} f[j] / fs
        steps = 2.0 * np.pi * as_block(f, ctx.n) / ctx.fs
        phases = self.phase + np.concatenate(([0.0], np.cumsum(steps[:-1])))
        self.phase = float((phases[-1] + steps[-1]) % (2.0 * np.pi))
        return np.sin(phases)


class Noise(Node):
    """noise(colour): white (default), pink or brown noise at about unit RMS."""

    def __init__(self, beta: float, fs: float, seed: int):
        self.source = ColoredNoise(beta, fs, seed)

    def render(self, ctx):
        return self.source.block(ctx.n)


# ---- filters --------------------------------------------------------------------------------------------

def biquad(kind: str, freq: float, q: float, fs: float) -> tuple:
    """RBJ Audio-EQ-Cookbook coefficients (b, a), normalised so that a[0] = 1."""
    f = min(max(freq, LOWEST_FILTER), HIGHEST_FILTER * fs)
    w0 = 2.0 * math.pi * f / fs
    cos, alpha = math.cos(w0), math.sin(w0) / (2.0 * max(q, 1e-3))
    if kind == "lowpass":
        b = ((1 - cos) / 2, 1 - cos, (1 - cos) / 2)
    elif kind == "highpass":
        b = ((1 + cos) / 2, -(1 + cos), (1 + cos) / 2)
    elif kind == "bandpass":  # constant 0 dB peak gain
        b = (alpha, 0.0, -alpha)
    else:
        raise ValueError(kind)
    a0 = 1 + alpha
    return np.array(b) / a0, np.array((1.0, -2 * cos / a0, (1 - alpha) / a0))


def biquads(kind: str, freq: np.ndarray, q, fs: float) -> tuple:
    """biquad of S frequencies (S,) and Q (S,) or one, at once: b, a (S, 3)."""
    f = np.clip(freq, LOWEST_FILTER, HIGHEST_FILTER * fs)
    w0 = 2.0 * math.pi * f / fs
    cos, alpha = np.cos(w0), np.sin(w0) / (2.0 * np.maximum(q, 1e-3))
    one, zero = np.ones_like(cos), np.zeros_like(cos)
    if kind == "lowpass":
        b = ((1 - cos) / 2, 1 - cos, (1 - cos) / 2)
    elif kind == "highpass":
        b = ((1 + cos) / 2, -(1 + cos), (1 + cos) / 2)
    elif kind == "bandpass":  # constant 0 dB peak gain
        b = (alpha, zero, -alpha)
    else:
        raise ValueError(kind)
    a0 = 1 + alpha
    return np.stack(b, axis=1) / a0[:, None], np.stack((one, -2 * cos / a0, (1 - alpha) / a0), axis=1)


def segment_means(x: np.ndarray, period: int) -> np.ndarray:
    """(S,) the mean of x (n,) over each stretch of `period` samples (the last may be shorter), S = ceil(n / period)."""
    full = len(x) // period
    means = x[:full * period].reshape(full, period).mean(axis=1)
    return np.append(means, x[full * period:].mean()) if len(x) > full * period else means


class Filter(Node):
    """lowpass(x, freq, q), highpass(x, freq, q), bandpass(x, freq, q): biquads whose frequency and Q may
    follow signals (coefficients recomputed every CONTROL_PERIOD samples, memory carried across)."""

    def __init__(self, kind: str, x: Node, freq: Node, q: Node):
        self.kind, self.x, self.freq, self.q = kind, x, freq, q
        self.stereo = x.stereo
        self.filter = None

    def children(self):
        return (self.x, self.freq, self.q)

    def render(self, ctx):
        x = as_block(self.x.render(ctx), ctx.n)
        f, q = self.freq.render(ctx), self.q.render(ctx)
        if is_constant(f) and is_constant(q):
            coefficients = biquad(self.kind, float(f), float(q), ctx.fs)
            if self.filter is None:
                self.filter = PoleFilter(*coefficients, channels=x.shape[:-1])
            else:
                self.filter.set(*coefficients)
            return self.filter.run(x)
        # one biquad per CONTROL_PERIOD samples, at the means of f and Q over them
        f, q = segment_means(as_block(f, ctx.n), CONTROL_PERIOD), segment_means(as_block(q, ctx.n), CONTROL_PERIOD)
        b, a = biquads(self.kind, f, q, ctx.fs)
        if self.filter is None:
            self.filter = PoleFilter(b[0], a[0], channels=x.shape[:-1])
        return self.filter.run_swept(x, b, a, CONTROL_PERIOD)


# ---- envelopes ------------------------------------------------------------------------------------------

class Decay(Node):
    """decay(x, t60): x times an exponential that restarts at 1 at every trigger (a hit, the `at` time, the
    start of an `always` sound) and falls by 60 dB in t60 seconds. Silent before the first trigger."""

    def __init__(self, x: Node, t60: Node):
        self.x, self.t60 = x, t60
        self.stereo = x.stereo
        self.since = math.inf  # seconds since the last trigger, at the first sample of the next block

    def children(self):
        return (self.x, self.t60)

    def render(self, ctx):
        x = self.x.render(ctx)
        t60 = self.t60.render(ctx)
        since = self.since + np.arange(ctx.n) / ctx.fs
        for k0 in ctx.triggers:
            since[k0:] = np.arange(ctx.n - k0) / ctx.fs
        self.since = float(since[-1] + 1.0 / ctx.fs)
        # e = exp(-ln(1000) (t - t_trigger) / t60)
        with np.errstate(over="ignore"):
            envelope = np.where(np.isfinite(since), np.exp(-LN1000 * np.minimum(since, 1e9) / t60), 0.0)
        return x * envelope


class ADSR(Node):
    """adsr(x, attack, decay, sustain, release): x times a linear attack to 1, a linear decay to the
    sustain level while the gate is open, and an exponential release (-60 dB in `release`) after it closes.
    The gate: open while in contact (contact sounds), for attack + decay after each hit (collisions), from
    the trigger on (at, always, wind)."""

    def __init__(self, x: Node, attack: float, decay: float, sustain: float, release: float):
        self.x = x
        self.attack, self.decay, self.sustain, self.release = max(attack, 1e-6), max(decay, 1e-6), sustain, release
        self.stereo = x.stereo
        self.level = 0.0  # envelope level at the end of the last block
        self.open_for = math.inf  # seconds the gate has been open (inf: closed)
        self.start_level = 0.0  # level when the gate last opened
        self.closed_level = 0.0  # level when the gate last closed
        self.closed_for = math.inf

    def children(self):
        return (self.x,)

    def render(self, ctx):
        x = self.x.render(ctx)
        gate = ctx.adsr_gate(self.attack + self.decay)
        env = np.empty(ctx.n)
        k = 0
        while k < ctx.n:
            end = k + 1
            while end < ctx.n and gate[end] == gate[k]:
                end += 1
            env[k:end] = self._segment(bool(gate[k]), end - k, ctx.fs)
            k = end
        return x * env

    def _segment(self, open_: bool, n: int, fs: float) -> np.ndarray:
        if open_:
            if self.open_for == math.inf:  # the gate opens: attack from the current level
                self.open_for, self.start_level = 0.0, self.level
            s = self.open_for + np.arange(n) / fs
            attack = self.start_level + (1.0 - self.start_level) * s / self.attack
            decay = 1.0 + (self.sustain - 1.0) * np.minimum((s - self.attack) / self.decay, 1.0)
            env = np.where(s < self.attack, attack, decay)
            self.open_for += n / fs
        else:
            if self.open_for != math.inf:  # the gate closes: release from the current level
                self.open_for, self.closed_for, self.closed_level = math.inf, 0.0, self.level
            s = self.closed_for + np.arange(n) / fs
            env = self.closed_level * np.exp(-LN1000 * s / max(self.release, 1e-6))
            self.closed_for += n / fs
        self.level = float(env[-1])
        return env


class Follower(Node):
    """envelope(x, attack = 10 ms, release = 100 ms): the envelope of an audio signal (a one-pole on |x| with
    separate attack and release time constants, runtime/signals.py)."""

    def __init__(self, x: Node, attack: float, release: float):
        self.x, self.attack, self.release = x, attack, release
        self.level = 0.0

    def children(self):
        return (self.x,)

    def render(self, ctx):
        x = as_block(self.x.render(ctx), ctx.n)
        if x.ndim > 1:
            x = np.max(np.abs(x), axis=0)
        env = follow_envelope(x, ctx.fs, self.attack, self.release, self.level)
        self.level = float(env[-1])
        return env


class FileEnvelope(Node):
    """envelope("breath.wav", attack, release): the envelope of a recording (runtime/signals.py), as a
    control signal: time 0 of the file at the scene's start, 0 after its end."""

    def __init__(self, envelope):
        self.envelope = envelope

    def render(self, ctx):
        return self.envelope.at(ctx.t)


# ---- time and space -------------------------------------------------------------------------------------

class DelayLine(Node):
    """delay(x, time, max = 2 s): x delayed by a time that may vary (linear interpolation between samples;
    a varying delay bends the pitch, as a moving source does)."""

    def __init__(self, x: Node, time: Node, longest: float, fs: float):
        self.x, self.time = x, time
        self.stereo = x.stereo
        self.keep = int(math.ceil(longest * fs)) + 2
        self.history = None

    def children(self):
        return (self.x, self.time)

    def render(self, ctx):
        x = as_block(self.x.render(ctx), ctx.n)
        if self.history is None:
            self.history = np.zeros(x.shape[:-1] + (self.keep,))
        delay = np.clip(as_block(self.time.render(ctx), ctx.n) * ctx.fs, 0.0, self.keep - 2)
        line = np.concatenate([self.history, x], axis=-1)
        position = self.keep + np.arange(ctx.n) - delay
        base = np.floor(position).astype(np.int64)
        frac = position - base
        y = line[..., base] * (1.0 - frac) + line[..., np.minimum(base + 1, line.shape[-1] - 1)] * frac
        self.history = line[..., -self.keep:]
        return y


class Pan(Node):
    """pan(x, position): mono to stereo, equal power; position -1 (left) .. 1 (right)."""

    stereo = True

    def __init__(self, x: Node, position: Node):
        self.x, self.position = x, position

    def children(self):
        return (self.x, self.position)

    def render(self, ctx):
        x = as_block(self.x.render(ctx), ctx.n)
        if x.ndim > 1:
            x = x.mean(axis=0)
        p = np.clip(self.position.render(ctx), -1.0, 1.0)
        cos, sin = cos_sin((p + 1.0) * np.pi / 4.0)
        return np.stack([x * cos, x * sin])
