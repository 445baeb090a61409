"""Audio stage, the listener: what a sound becomes by the time it reaches the ears.

Per sound, from its source position (the first body of its trigger, the point of its latest hit, or the
listener itself) to the listener's position:
- gain by distance: g = listener.gain * d_ref / max(d, d_ref), d_ref = 1 m (spherical spreading, no gain
  closer than a metre);
- delay by distance, when the scene asks (`listener { delay on }`): d / 343 m/s, a varying fractional delay
  (a moving source bends its pitch, Doppler); without it an event at t sounds at sample round(t fs) exactly;
- stereo pan (two channels): the listener faces -z with +x to its right; p = (x_source - x_listener) / d,
  equal-power gains cos((p + 1) pi / 4), sin((p + 1) pi / 4). A sound already panned by `pan(...)` keeps its
  own placement.
"""
from __future__ import annotations

import math

import numpy as np

from .nodes import cos_sin

SPEED_OF_SOUND = 343.0  # m/s, air at 20 C
REFERENCE_DISTANCE = 1.0  # m
# longest delay a listener delay line keeps: sources farther than this many metres arrive late by at most this
FARTHEST = 343.0  # m (one second)


class ListenerStage:
    def __init__(self, listener, fs: float, channels: int):
        self.position = np.asarray(listener.position, float)
        self.gain = float(listener.gain)
        self.delayed = bool(listener.delay)
        self.fs, self.channels = fs, channels
        self.keep = int(math.ceil(FARTHEST / SPEED_OF_SOUND * fs)) + 2
        self.history = None

    def distance(self, source: np.ndarray) -> np.ndarray:
        """(n,) distances from (n, 3) source positions."""
        offset = source - self.position
        return np.sqrt(np.einsum("ij,ij->i", offset, offset))

    def render(self, x: np.ndarray, source: np.ndarray, distance: np.ndarray, out: np.ndarray) -> None:
        """Add to out (channels, n) a sound's block x ((n,) or (2, n)) from source positions (n, 3) at distances
        (n,); a source that stays put over the block may come as (1, 3) and (1,)."""
        n = x.shape[-1]
        if n and len(source) > 1 and (source[0] == source).all():
            # a source that stays put over the block (a hit's point, a body at rest): one gain, one pan
            source, distance = source[:1], distance[:1]
        # g = gain d_ref / max(d, d_ref)
        gain = self.gain * REFERENCE_DISTANCE / np.maximum(distance, REFERENCE_DISTANCE)
        if self.delayed:
            x, gain = self._delay(x * gain, distance / SPEED_OF_SOUND * self.fs), 1.0
        if self.channels == 1:
            out[0] += (x.mean(axis=0) if x.ndim > 1 else x) * gain
        elif x.ndim > 1:
            out += x * gain
        else:
            offset = source[:, 0] - self.position[0]
            p = np.where(distance > 1e-9, np.clip(offset / np.maximum(distance, 1e-9), -1.0, 1.0), 0.0)
            cos, sin = cos_sin((p + 1.0) * np.pi / 4.0)
            out[0] += x * (gain * cos)
            out[1] += x * (gain * sin)

    def _delay(self, x: np.ndarray, delay: np.ndarray) -> np.ndarray:
        n = x.shape[-1]
        if self.history is None:
            self.history = np.zeros(x.shape[:-1] + (self.keep,))
        if self.history.shape[:-1] != x.shape[:-1]:  # a mono history meeting a stereo block
            self.history = np.broadcast_to(self.history, x.shape[:-1] + (self.keep,)).copy()
        line = np.concatenate([self.history, x], axis=-1)
        position = self.keep + np.arange(n) - np.clip(delay, 0.0, self.keep - 2)
        base = np.floor(position).astype(np.int64)
        frac = position - base
        y = line[..., base] * (1.0 - frac) + line[..., np.minimum(base + 1, line.shape[-1] - 1)] * frac
        self.history = line[..., -self.keep:]
        return y
