"""Audio stage, noise: white, pink and brown noise in blocks, and fractal (1/f^beta) profiles.

Every generator owns a numpy Generator seeded from the scene's seed and where it stands in the scene, so
that a run is reproducible and removing one event does not change the noise of another.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np

# pink (1/f) filter: a 3-pole / 3-zero fit to a -3 dB/octave slope within +-0.3 dB over 9 octaves
# (J. O. Smith, "Spectral Audio Signal Processing", the pink-noise example)
PINK_B = np.array([0.049922035, -0.095993537, 0.050612699, -0.004408786])
PINK_A = np.array([1.0, -2.494956002, 2.017265875, -0.522189400])
# brown (1/f^2) noise: a leaky integrator whose corner is this low, so that it does not wander off
BROWN_CORNER = 20.0  # Hz
COLORS = {"white": 0.0, "pink": 1.0, "brown": 2.0, "red": 2.0}


def seed_for(*parts) -> int:
    """A stable 64-bit seed from any printable parts (scene seed, sound name, node path, event sample)."""
    digest = hashlib.blake2b(repr(parts).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little")


class ColoredNoise:
    """Noise with spectrum ~ 1/f^beta for beta 0 (white), 1 (pink), 2 (brown), streamed in blocks at
    about unit RMS."""

    def __init__(self, beta: float, fs: float, seed: int):
        from .iir import PoleFilter

        self.rng = np.random.default_rng(seed)
        self.beta = beta
        if beta == 0.0:
            self.b = self.a = None
        elif beta == 1.0:
            self.b, self.a, self.scale = PINK_B, PINK_A, 1.0 / 0.086  # output RMS 0.086 for unit white input
        elif beta == 2.0:
            pole = np.exp(-2.0 * np.pi * BROWN_CORNER / fs)
            # y[k] = pole y[k-1] + (1 - pole) x[k], RMS sqrt((1 - pole) / (1 + pole)) for unit white x
            self.b, self.a = np.array([1.0 - pole]), np.array([1.0, -pole])
            self.scale = np.sqrt((1.0 + pole) / (1.0 - pole))
        else:
            raise ValueError(f"noise colour beta={beta}: use 0 (white), 1 (pink) or 2 (brown)")
        self.filter = PoleFilter(self.b, self.a) if self.b is not None else None

    def block(self, n: int) -> np.ndarray:
        white = self.rng.standard_normal(n)
        if self.filter is None:
            return white
        return self.filter.run(white) * self.scale


def fractal_profile(n: int, beta: float, rng: np.random.Generator) -> np.ndarray:
    """A periodic random signal of n samples with |H(k)| ~ k^(-beta/2) (power ~ 1/k^beta), zero mean and
    unit RMS. Synthesised in the frequency domain, so it wraps around without a seam."""
    spectrum = rng.standard_normal(n // 2 + 1) + 1j * rng.standard_normal(n // 2 + 1)
    k = np.arange(n // 2 + 1, dtype=float)
    k[0] = 1.0
    spectrum *= k ** (-beta / 2.0)
    spectrum[0] = 0.0
    profile = np.fft.irfft(spectrum, n)
    return profile / np.sqrt(np.mean(profile**2))


def read_periodic(profile: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Linear interpolation of a periodic profile at fractional sample positions. Positions within a stretch of
    the profile not much longer than their count (a block read at a speed up to one profile sample per sample)
    go through np.interp over that stretch, unrolled."""
    n = len(profile)
    position = np.asarray(position, float)
    if position.size == 0:
        return np.zeros(position.shape)
    first, last = math.floor(position.min()), math.floor(position.max()) + 1
    if last - first <= 2 * position.size + 2:
        stretch = np.arange(first, last + 1)
        return np.interp(position, stretch, profile[stretch % n])
    base = np.floor(position)
    frac = position - base
    i = base.astype(np.int64) % n
    return profile[i] * (1.0 - frac) + profile[(i + 1) % n] * frac


class Gusts:
    """A slow fractal modulation g(t) (brown, unit RMS, smooth at the time scale `scale`), periodic over
    4096 * scale / 16 seconds: gusts of wind, or any slow wobble."""

    STEPS_PER_SCALE = 16

    def __init__(self, scale: float, seed: int, beta: float = 2.0):
        self.scale = scale
        self.profile = fractal_profile(4096, beta, np.random.default_rng(seed))

    def __call__(self, t) -> np.ndarray:
        return read_periodic(self.profile, np.asarray(t, float) / self.scale * self.STEPS_PER_SCALE)
