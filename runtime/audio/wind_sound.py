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
The whistles of a mix render as one node, with arrays over the whistles (merge_whistles).
"""
from __future__ import annotations

import functools

import numpy as np

from .iir import PoleFilter
from .nodes import FRAME, Node, biquad, biquads, segment_means
from .noise import ColoredNoise, Gusts

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
# (2, ENVELOPE_STRIDE): 1 and m at the m-th sample of a group, so that (value, slope) @ _RAMP is a line through it
_RAMP = np.stack([np.ones(ENVELOPE_STRIDE), np.arange(ENVELOPE_STRIDE, dtype=float)])
# the wind's band-pass is retuned every this many samples (23 ms at 44.1 kHz; gusts are much slower; a multiple
# of iir.ROW)
WIND_CONTROL = 1024


class WindNoise(Node):
    def __init__(self, body: str | None, depth: float, gust_scale: float, fs: float, seed: int):
        self.body, self.depth = body, depth
        self.noise = ColoredNoise(1.0, fs, seed)
        self.gusts = Gusts(gust_scale, seed + 1)
        self.filter = PoleFilter(*biquad("bandpass", WIND_BASE, WIND_Q, fs))

    def render(self, ctx):
        speed = ctx.wind_speed(self.body)
        gusty = np.maximum(speed * (1.0 + self.depth * self.gusts(ctx.t)), 0.0)
        level = np.minimum((gusty / REFERENCE_SPEED) ** 2, LOUDEST)
        # f_c = 100 Hz + 60 Hz per m/s, at the mean speed over each WIND_CONTROL samples
        centre = WIND_BASE + WIND_SLOPE * segment_means(gusty, WIND_CONTROL)
        b, a = biquads("bandpass", centre, WIND_Q, ctx.fs)
        return self.filter.run_swept(self.noise.block(ctx.n), b, a, WIND_CONTROL) * level


class Whistle(Node):
    """The whistles of one or several bodies (`merge_whistles` makes a mix of whistles one node), as arrays over
    the whistles (W,): each with its body, its envelope table and where it reads it, and its phase."""

    def __init__(self, body: str, diameter: float, strouhal: float, q: float, fs: float, seed: int):
        rng = np.random.default_rng(seed)
        self.bodies = [body]
        self.hz_per_speed = np.array([strouhal / diameter])  # f = St U / d
        # the table's bandwidth is ENVELOPE_CORNER cycles per table sample; read it at the rate that makes it
        # f / 2Q hertz: (f / 2Q) / ENVELOPE_CORNER table samples per second, this many per audio sample and Hz
        self.reads_per_hz = np.array([1.0 / (2.0 * q * ENVELOPE_CORNER * fs)])
        self.table = narrow_band_table(rng)[None, :]  # (W, ENVELOPE_SAMPLES) complex
        self.read = np.array([rng.uniform(0, ENVELOPE_SAMPLES)])  # (W,) where in the table each whistle stands
        self.half_phase = np.zeros(1)  # (W,) phi / 2, modulo pi

    def join(self, other: "Whistle") -> None:
        """Take another whistle's arrays in (it is rendered here from now on)."""
        self.bodies = self.bodies + other.bodies
        for name in ("hz_per_speed", "reads_per_hz", "table", "read", "half_phase"):
            setattr(self, name, np.concatenate([getattr(self, name), getattr(other, name)]))

    def render(self, ctx):
        speed = ctx.wind_speeds(self.bodies)  # (W, n)
        # f = St U / d
        freq = speed * self.hz_per_speed[:, None]
        real, twice_imag = self._envelope(freq, ctx.start)
        half_phase = self._half_phases(freq, ctx.fs)
        level = _whistle_level(speed, freq, ctx.fs)  # (overwrites freq)
        return np.sum(_tone(real, twice_imag, half_phase, level), axis=0)

    def _half_phases(self, freq: np.ndarray, fs: float) -> np.ndarray:
        """(W, n) phi / 2 at each sample, phi = 2 pi integral f dt, from the phase carried in."""
        n = freq.shape[-1]
        half = np.empty((len(freq), n + 1))
        half[:, 0] = self.half_phase
        np.multiply(freq, np.pi / fs, out=half[:, 1:])
        np.cumsum(half, axis=1, out=half)
        self.half_phase = half[:, n] % np.pi
        return half[:, :n]

    def _envelope(self, freq: np.ndarray, start: int) -> np.ndarray:
        """(2, W, n): the real part and twice the imaginary part of the complex envelope over the block from sample
        `start`, the table read at the first and last sample of groups of ENVELOPE_STRIDE samples (the envelope is
        tens of hertz wide) and interpolated linearly between (see _groups)."""
        n = freq.shape[-1]
        rate = np.maximum(freq, LOWEST_WHISTLE)
        rate *= self.reads_per_hz[:, None]  # table samples per audio sample
        # position at a group's first sample = read + the sums of the rates of the groups before it
        sums = _group_sums(rate, ENVELOPE_STRIDE)  # (W, G)
        left = _running_sum(sums, self.read)
        self.read = (left[:, -1] + sums[:, -1]) % ENVELOPE_SAMPLES
        cut, last, span = _groups(n, start % FRAME)
        # the right end: the next group's first sample, or the group's own last sample where it is cut
        right = left + sums - rate[:, last] * cut
        ends = _read_tables(self.table, np.concatenate([left, right], axis=1))
        at_left, at_right = ends[:, :len(cut)], ends[:, len(cut):]
        # e = e_left + m (e_right - e_left) / span at the m-th sample of a group: (e_left, slope) @ (1, m)
        lines = np.empty((2,) + at_left.shape + (2,))  # (2, W, G, 2)
        lines[..., 0] = at_left.real, 2.0 * at_left.imag
        slope = (at_right - at_left) / span
        lines[..., 1] = slope.real, 2.0 * slope.imag
        envelope = lines.reshape(-1, 2) @ _RAMP
        return envelope.reshape(2, len(freq), -1)[:, :, :n]


def _whistle_level(speed: np.ndarray, freq: np.ndarray, fs: float) -> np.ndarray:
    """level = (U / U_ref)^3, at most LOUDEST, faded in over LOWEST_WHISTLE .. 2 LOWEST_WHISTLE and silent from
    0.4 fs (the fade and the cut skipped when no sample needs them: a factor 1 changes nothing). Overwrites
    freq."""
    level = speed * speed
    level *= speed
    level *= 1.0 / REFERENCE_SPEED**3
    np.minimum(level, LOUDEST, out=level)
    if freq.max() >= 0.4 * fs:
        level *= freq < 0.4 * fs
    if freq.min() < 2.0 * LOWEST_WHISTLE:
        # fade = (f - f_low) / f_low within [0, 1]
        fade = np.subtract(freq, LOWEST_WHISTLE, out=freq)
        fade *= 1.0 / LOWEST_WHISTLE
        level *= np.clip(fade, 0.0, 1.0, out=fade)
    return level


def merge_whistles(nodes: list) -> list:
    """The nodes of a mix, its whistles rendered as one node (the first whistle's place)."""
    whistles = [node for node in nodes if isinstance(node, Whistle)]
    for other in whistles[1:]:
        whistles[0].join(other)
    return [node for node in nodes if not isinstance(node, Whistle) or node is whistles[0]]


def _tone(real: np.ndarray, twice_imag: np.ndarray, half_phase: np.ndarray, level: np.ndarray) -> np.ndarray:
    """level Re((re + i im) e^{i phi}) = level (re cos(phi) - im sin(phi)), with t = tan(phi / 2):
    cos = (1 - t^2) / (1 + t^2), sin = 2 t / (1 + t^2) (see nodes.cos_sin). Overwrites half_phase and level."""
    t = np.tan(half_phase, out=half_phase)
    t2 = t * t
    out = real * t2
    np.subtract(real, out, out=out)  # re (1 - t^2)
    t *= twice_imag
    out -= t
    t2 += 1.0
    level /= t2
    out *= level
    return out


def _read_tables(tables: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(W, m): row w of the periodic tables (W, N) read at the fractional positions position[w], linearly."""
    size = tables.shape[-1]
    base = np.floor(position)
    frac = position - base
    i = base.astype(np.int64) % size
    rows = (np.arange(len(tables)) * size)[:, None]
    flat = tables.ravel()
    return flat[rows + i] * (1.0 - frac) + flat[rows + (i + 1) % size] * frac


def _running_sum(steps: np.ndarray, start) -> np.ndarray:
    """start + sum of steps[..., :k] at each k (the value before each step is taken), along the last axis."""
    out = np.empty(steps.shape)
    out[..., 0] = 0.0
    np.cumsum(steps[..., :-1], axis=-1, out=out[..., 1:])
    out += np.asarray(start)[..., None]
    return out


def _group_sums(x: np.ndarray, size: int) -> np.ndarray:
    """(W, ceil(n / size)) the sums of x (W, n) over consecutive groups of `size` samples (the last may be
    shorter)."""
    full = x.shape[-1] // size
    sums = x[:, :full * size].reshape(len(x), full, size).sum(axis=-1)
    if x.shape[-1] > full * size:
        sums = np.append(sums, x[:, full * size:].sum(axis=-1, keepdims=True), axis=1)
    return sums


@functools.lru_cache(maxsize=16)
def _groups(n: int, offset: int) -> tuple:
    """A block of n samples starting `offset` samples into a FRAME, in G = ceil(n / ENVELOPE_STRIDE) groups of
    ENVELOPE_STRIDE samples from its start. A whistle reads its envelope at every group's first sample and
    interpolates towards the next group's first, except where the group is cut, at the end of the block or of a
    frame: there it reads at the group's own last sample. Frames are fixed in the samples, so blocks made of
    whole frames read at the same samples whatever their size. Returns cut (G,) 1.0 or 0.0, the index of each
    group's last sample (G,), and the samples from each group's first sample to its right end (G,) (at least 1)."""
    first = np.arange(0, n, ENVELOPE_STRIDE)
    last = np.minimum(first + ENVELOPE_STRIDE, n) - 1
    cut = (last == n - 1) | ((offset + last + 1) % FRAME == 0)
    span = np.where(cut, np.maximum(last - first, 1), ENVELOPE_STRIDE).astype(float)
    return cut.astype(float), last, span


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
