"""Audio stage, wind: fractal wind noise shaped by the wind speed, and aeolian whistles of bodies in it.

wind_noise([body]): pink (1/f, "fractal") noise shaped by the wind speed U at the listener (or at a body):
    U_g(t) = U(t) (1 + depth * g(t))          g: slow brown-noise gusts, unit RMS, time scale `gust`
    level  = (U_g / 10 m/s)^2, at most 4      (aerodynamic noise rises steeply with speed)
    band-pass centre f_c = 100 Hz + 60 Hz * U_g / (1 m/s), Q 1   (the whoosh rises with the wind)
(Farnell, "Designing Sound", builds wind the same way.)

whistle(body, st = 0.2, q = 30, diameter = ...): the aeolian tone of a body in the wind, f = St U / d with
St the Strouhal number, U the wind speed relative to the body, d its cross dimension (2 r for spheres,
cylinders and capsules; the smallest edge of a box). A narrow band of noise around f: complex white noise
low-passed to the bandwidth f / Q and shifted to f by multiplying with exp(i phi), phi = 2 pi integral f dt
(the same signal as a band-pass of Q on noise, without a filter that must be retuned as f glides; the
envelope is read from a table of noise at the speed that gives it the bandwidth f / Q).
level = (U / 10 m/s)^3 (a dipole's pressure ~ U^3), faded out below 20 Hz and above 0.4 fs.
"""
from __future__ import annotations

import functools

import numpy as np

from .iir import PoleFilter
from .nodes import Node, biquad
from .noise import ColoredNoise, Gusts, read_periodic

REFERENCE_SPEED = 10.0  # m/s: the speed at which wind and whistle have unit level
LOUDEST = 4.0  # wind level limit
WIND_BASE, WIND_SLOPE, WIND_Q = 100.0, 60.0, 1.0  # f_c = WIND_BASE + WIND_SLOPE * U
STROUHAL = 0.2
WHISTLE_Q = 30.0
LOWEST_WHISTLE = 20.0  # Hz
# the whistle's envelope: a periodic table of noise with a one-pole spectrum, corner ENVELOPE_CORNER cycles per
# table sample, read faster or slower so that its bandwidth is f / Q (time-scaling noise scales its bandwidth)
ENVELOPE_SAMPLES = 2**15
ENVELOPE_CORNER = 1.0 / 16.0
ENVELOPE_STRIDE = 32  # samples between envelope reads (1.4 kHz at 44.1 kHz, far above f / 2Q)
# the wind's band-pass is retuned every this many samples (23 ms at 44.1 kHz; gusts are much slower)
WIND_CONTROL = 1024


class WindNoise(Node):
    def __init__(self, body: str | None, depth: float, gust_scale: float, fs: float, seed: int):
        self.body, self.depth = body, depth
        self.noise = ColoredNoise(1.0, fs, seed)
        self.gusts = Gusts(gust_scale, seed + 1)
        self.filter = None

    def render(self, ctx):
        speed = ctx.wind_speed(self.body)
        gusty = np.maximum(speed * (1.0 + self.depth * self.gusts(ctx.t)), 0.0)
        level = np.minimum((gusty / REFERENCE_SPEED) ** 2, LOUDEST)
        x = self.noise.block(ctx.n)
        y = np.empty(ctx.n)
        for lo in range(0, ctx.n, WIND_CONTROL):
            hi = min(lo + WIND_CONTROL, ctx.n)
            # f_c = 100 Hz + 60 Hz per m/s
            coefficients = biquad("bandpass", WIND_BASE + WIND_SLOPE * float(np.mean(gusty[lo:hi])), WIND_Q, ctx.fs)
            if self.filter is None:
                self.filter = PoleFilter(*coefficients)
            else:
                self.filter.set(*coefficients)
            y[lo:hi] = self.filter.run(x[lo:hi])
        return y * level


class Whistle(Node):
    def __init__(self, body: str, diameter: float, strouhal: float, q: float, fs: float, seed: int):
        self.body, self.diameter, self.strouhal, self.q = body, diameter, strouhal, q
        rng = np.random.default_rng(seed)
        self.envelope = narrow_band_table(rng)
        self.read = float(rng.uniform(0, ENVELOPE_SAMPLES))  # where in the table this whistle starts
        self.phase = 0.0

    def render(self, ctx):
        speed = ctx.wind_speed(self.body)
        n, fs = ctx.n, ctx.fs
        # f = St U / d
        freq = speed * (self.strouhal / self.diameter)
        # phi = 2 pi integral f dt: the phase at each sample, from the phase carried in
        phases = _running_sum(freq * (2.0 * np.pi / fs), self.phase)
        self.phase = float(phases[-1] + freq[-1] * (2.0 * np.pi / fs)) % (2.0 * np.pi)
        # the table's bandwidth is ENVELOPE_CORNER cycles per table sample; read it at the rate that makes it
        # f / 2Q hertz: (f / 2Q) / ENVELOPE_CORNER table samples per second. The envelope (tens of hertz wide)
        # is read every ENVELOPE_STRIDE samples and interpolated between.
        rate = np.maximum(freq, LOWEST_WHISTLE) * (1.0 / (2.0 * self.q * ENVELOPE_CORNER * fs))
        where = _running_sum(rate, self.read)
        self.read = float(where[-1] + rate[-1]) % ENVELOPE_SAMPLES
        samples, picks = _picks(n)
        envelope = np.interp(samples, picks, read_periodic(self.envelope, where[picks]))  # complex: re + i im
        # Re(e(t) e^{i phi}) = re cos(phi) - im sin(phi): unit RMS when re and im have it
        tone = envelope.real * np.cos(phases) - envelope.imag * np.sin(phases)
        audible = np.clip((freq - LOWEST_WHISTLE) * (1.0 / LOWEST_WHISTLE), 0.0, 1.0) * (freq < 0.4 * fs)
        # level = (U / U_ref)^3, at most LOUDEST
        level = np.minimum(speed * speed * speed * (1.0 / REFERENCE_SPEED**3), LOUDEST) * audible
        return tone * level


def _running_sum(steps: np.ndarray, start: float) -> np.ndarray:
    """start + sum of steps[:k] at each k (the value before each step is taken)."""
    out = np.empty(len(steps))
    out[0] = 0.0
    np.cumsum(steps[:-1], out=out[1:])
    out += start
    return out


@functools.lru_cache(maxsize=8)
def _picks(n: int) -> tuple:
    """(arange(n), the samples where a whistle reads its envelope: every ENVELOPE_STRIDE-th and the last)."""
    return np.arange(n), np.append(np.arange(0, n, ENVELOPE_STRIDE), n - 1)


def narrow_band_table(rng) -> np.ndarray:
    """(ENVELOPE_SAMPLES,) complex periodic noise, real and imaginary parts of unit RMS with a one-pole
    (Lorentzian) spectrum of corner ENVELOPE_CORNER cycles per sample: the complex envelope of a band of noise,
    to be read at any speed."""
    k = np.fft.rfftfreq(ENVELOPE_SAMPLES)
    shape = 1.0 / np.sqrt(1.0 + (k / ENVELOPE_CORNER) ** 2)
    rows = []
    for _ in range(2):
        spectrum = (rng.standard_normal(len(k)) + 1j * rng.standard_normal(len(k))) * shape
        spectrum[0] = 0.0
        row = np.fft.irfft(spectrum, ENVELOPE_SAMPLES)
        rows.append(row / np.sqrt(np.mean(row**2)))
    return rows[0] + 1j * rows[1]


def cross_dimension(shape) -> float | None:
    """d of the Strouhal relation: the body's width across the wind."""
    if shape.type in ("sphere", "cylinder", "capsule"):
        return 2.0 * shape.radius
    if shape.type == "box":
        return float(min(shape.size))
    return None
