"""Audio stage, scraping and rolling (texture-based, docs/design/sound.md#section-7; van den Doel, Kry, Pai 2001).

A surface has a height profile h(x): a texture file, or fractal noise with power spectrum ~ 1/k^beta.
While two bodies touch, the contact point travels x(t) = integral of v dt (v the sliding speed for
`scrape`, the rolling speed for `roll`); reading the profile's slope at x(t) at audio rate gives the force
that drives the modes of both bodies:

    f(t) = (N(t) / 1 N) * (v(t) / v_max) * s(x(t)) * (roughness / 10 um)

with s the slope h'(x) scaled to unit RMS and N the normal force. The profile is stored at the spatial step
v_max / fs, so that the top speed reads one profile sample per audio sample; the speed is clamped to v_max.
Speed and normal force come from the motion at the simulation's steps; they are interpolated to the audio
samples and smoothed over SMOOTHING seconds, so that a contact that starts or ends fades in or out over a
few milliseconds instead of clicking. The level follows v (linearly) and N; the pitch of the texture rises
with v. Rolling is the same with a smoother profile (beta 3) and the rolling speed.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .iir import PoleFilter, one_pole
from .impact import Banks
from .nodes import Node
from .noise import fractal_profile, read_periodic

# profile samples (periodic; 2^18 at v_max 10 m/s and 44.1 kHz is 59 m of surface before it repeats)
PROFILE_SAMPLES = 2**18
DEFAULT_MAX_SPEED = 10.0  # m/s
SCRAPE_BETA = 2.0  # brown: the slope is white noise, a broadband scrape
ROLL_BETA = 3.0  # smoother: a low rumble
# texture files give heights at this spatial step unless the sound says `step`
TEXTURE_STEP = 1e-4  # m
REFERENCE_ROUGHNESS = 1e-5  # m: the material default, at which the force has unit scale
SMOOTHING = 0.005  # s, one-pole time constant on speed and normal force
DIRECT_LEVEL = 0.3  # the contact's own noise, heard beside the modes it drives


class SurfaceProfile:
    """The slope of a height profile, unit RMS, stored at step dx (metres per sample)."""

    def __init__(self, slope: np.ndarray, dx: float, source: str):
        self.slope, self.dx, self.source = slope, dx, source

    @classmethod
    def fractal(cls, beta: float, dx: float, seed: int) -> "SurfaceProfile":
        heights = fractal_profile(PROFILE_SAMPLES, beta, np.random.default_rng(seed))
        return cls(_unit_slope(heights), dx, f"fractal noise, beta {beta:g}")

    @classmethod
    def from_file(cls, path: str, dx: float, step: float = TEXTURE_STEP) -> "SurfaceProfile":
        heights = read_heights(path)
        if len(heights) < 4:
            raise ValueError(f"texture `{path}` has fewer than 4 height samples")
        # resample from the file's step to dx, periodically (the texture repeats)
        length = len(heights) * step
        count = max(4, int(round(length / dx)))
        x = np.arange(count) * (length / count)
        resampled = np.interp(x, np.arange(len(heights) + 1) * step, np.append(heights, heights[0]))
        return cls(_unit_slope(resampled), length / count, f"texture {Path(path).name}")

    def read(self, position_m: np.ndarray) -> np.ndarray:
        return read_periodic(self.slope, position_m / self.dx)


def _unit_slope(heights: np.ndarray) -> np.ndarray:
    slope = np.diff(np.append(heights, heights[0]))  # periodic first difference
    rms = np.sqrt(np.mean(slope**2))
    return slope / rms if rms > 0 else slope


def read_heights(path: str) -> np.ndarray:
    """Heights of a texture file: .npy, .txt/.csv (numbers), .wav/.flac (samples, first channel), or an
    image (.png: grey levels, rows one after the other)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".npy":
        data = np.load(path, allow_pickle=False)
    elif suffix in (".txt", ".csv", ".dat"):
        data = np.loadtxt(path, delimiter="," if suffix == ".csv" else None)
    elif suffix in (".wav", ".flac", ".ogg", ".aiff"):
        import soundfile

        data, _ = soundfile.read(path, always_2d=True)
        data = data[:, 0]
    elif suffix in (".png", ".jpg", ".jpeg"):
        import matplotlib.image

        image = np.asarray(matplotlib.image.imread(path), float)
        data = image[..., :3].mean(axis=-1) if image.ndim == 3 else image
    else:
        raise ValueError(f"texture `{path}`: unknown file type (use .npy, .txt, .csv, .wav or .png)")
    data = np.asarray(data, float).ravel()
    return data - data.mean()


class Scrape(Node):
    """scrape(a, b) / roll(a, b): the profile read at the contact's travel drives both bodies' banks."""

    def __init__(self, pair: tuple, banks: list, profile: SurfaceProfile, max_speed: float, rolling: bool,
                 roughness: float, fs: float):
        self.pair, self.banks, self.profile = pair, Banks(banks, fs), profile
        self.max_speed, self.rolling = max_speed, rolling
        self.scale = roughness / REFERENCE_ROUGHNESS
        self.travel = 0.0  # m along the profile
        # y[k] = y[k-1] + c (x[k] - y[k-1]) on speed and normal force, c = 1 - exp(-1 / (T fs))
        self.smooth = PoleFilter(*one_pole(1.0 - math.exp(-1.0 / (SMOOTHING * fs))), channels=(2,))
        self.fs = fs

    def render(self, ctx):
        contact = ctx.contact(self.pair)
        raw_speed = np.clip(contact["roll" if self.rolling else "speed"], 0.0, self.max_speed)
        speed, force = self.smooth.run(np.stack([raw_speed, np.maximum(contact["force"], 0.0)]))
        speed = np.maximum(speed, 0.0)
        travel = self.travel + np.cumsum(speed) / ctx.fs
        self.travel = float(travel[-1]) % (len(self.profile.slope) * self.profile.dx)
        # f = N (v / v_max) s(x) (roughness / 10 um)
        drive = force * (speed / self.max_speed) * self.profile.read(travel) * self.scale
        gains = sum(self.banks.gains(body, contact["local"].get(body)) for body in self.banks.bodies)
        return DIRECT_LEVEL * drive + self.banks.render(ctx.start, ctx.n, [(gains, 0, drive)])

