"""Wind stage, turbulence: seeded fractal (1/f) noise in time and space, and the `noise()` / `gust()` signals.

Value noise on an integer lattice: a lattice value is a hash of (lattice index, salt), uniform in [-1, 1), and
the noise between two lattice points blends them with the quintic fade S(f) = 6f^5 - 15f^4 + 10f^3 (C2).
Fractal noise sums octaves o = 0..O-1 at frequency 2^o and amplitude GAIN^o, divided by its RMS so that
`fbm` has unit RMS whatever the number of octaves. Nothing is drawn from a global random state: the same seed,
time and place give the same value in every run, on every machine (integer hashing, no platform RNG).

Gusts of a wind (`turbulence I`, `gust T`): u' = I |u_mean(x, t)| G(x, t), G a 3-vector of independent fractal
noises, each octave read at s = 2^o (t / T + x . k / (GUST_SPEED T)) with k a seeded unit vector per component
and octave: a pattern of gusts about GUST_SPEED * T across that sweeps through space. I is then the turbulence
intensity sigma_u / |u_mean| of wind engineering.
"""
from __future__ import annotations

import numpy as np

# octaves of the fractal noise (the finest has a time scale T / 2^(OCTAVES-1))
OCTAVES = 4
# amplitude ratio between octaves: 0.5 gives the 1/f ("pink", fractal) spectrum
GAIN = 0.5
# m/s: how fast the gust pattern sweeps through space; a gust of time scale T is about GUST_SPEED * T across
GUST_SPEED = 2.0
# mean of (1 - S)^2 + S^2 over f in [0, 1) for the quintic fade S: the variance factor of the blend
_BLEND_VARIANCE = 181.0 / 231.0
# variance of a lattice value, uniform in [-1, 1)
_LATTICE_VARIANCE = 1.0 / 3.0

_MASK64 = np.uint64(0xFFFFFFFFFFFFFFFF)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)


def _splitmix(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser on uint64 arrays (wraps modulo 2^64)."""
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


def lattice(index: np.ndarray, salt) -> np.ndarray:
    """Values in [-1, 1) at integer lattice points; salt (int or uint64 array broadcasting with index)."""
    with np.errstate(over="ignore"):
        z = index.astype(np.int64).view(np.uint64) + np.asarray(salt, dtype=np.uint64) * _GOLDEN
        z = _splitmix(z)
    return _unit(z)


def _unit(z: np.ndarray) -> np.ndarray:
    """Hashes (uint64) to values in [-1, 1): the top 53 bits as a float in [0, 1), then to [-1, 1)."""
    return (z >> np.uint64(11)).astype(np.float64) * (2.0 / 2.0**53) - 1.0


def value_noise(s, salt) -> np.ndarray:
    """Smooth noise of s (any shape): n(s) = a + (b - a) S(f), a, b the lattice values around s."""
    s = np.asarray(s, dtype=float)
    i0 = np.floor(s)
    f = s - i0
    i0 = i0.astype(np.int64)
    a, b = lattice(np.stack([i0, i0 + 1]), salt)
    fade = f * f * f * (f * (6.0 * f - 15.0) + 10.0)
    return a + (b - a) * fade


def fbm_norm(octaves: int = OCTAVES, gain: float = GAIN) -> float:
    """RMS of the raw octave sum: sqrt(var_lattice * blend * sum gain^(2o))."""
    return float(np.sqrt(_LATTICE_VARIANCE * _BLEND_VARIANCE * np.sum(gain ** (2.0 * np.arange(octaves)))))


def fbm(s, salt: int, octaves: int = OCTAVES, gain: float = GAIN) -> np.ndarray:
    """Fractal noise of s with unit RMS: sum_o gain^o n(2^o s + o * 0.37, salt + o) / norm."""
    s = np.asarray(s, dtype=float)
    total = np.zeros_like(s)
    for o in range(octaves):
        # the offset keeps the lattice points of different octaves apart
        total += gain**o * value_noise(2.0**o * s + 0.37 * o, np.uint64(salt + o))
    return total / fbm_norm(octaves, gain)


class GustField:
    """G(x, t): three independent unit-RMS fractal noises in time and space for one wind.

    Called at every force evaluation with a few points, so the lattice values are cached: a lattice cell is
    0.4 s / 2^o wide in time and the steps are a few ms, so the points mostly stay in the cells of the last
    call; the hash runs again only when one of them leaves its cell (the values are the same either way)."""

    # lattice caches kept at once, one per shape of the points asked for (force stage, recorder, ...)
    CACHED_SHAPES = 8

    def __init__(self, seed: int, time_scale: float, octaves: int = OCTAVES):
        rng = np.random.default_rng(np.random.SeedSequence([seed & 0xFFFFFFFF, 0x9057]))
        k = rng.normal(size=(3, octaves, 3))
        self.k = k / np.linalg.norm(k, axis=2, keepdims=True)  # (3 components, octaves, 3) unit directions
        self.time_scale = float(time_scale)
        self.length = GUST_SPEED * self.time_scale
        frequency = 2.0 ** np.arange(octaves)
        self.frequency = frequency[None, :, None]  # (1, O, 1)
        self.amplitude = (GAIN ** np.arange(octaves))[None, :, None] / fbm_norm(octaves)
        self.offset = (0.37 * np.arange(octaves))[None, :, None]
        salts = (np.uint64(seed & 0xFFFFFFFF) * np.uint64(7919) + np.arange(3 * octaves, dtype=np.uint64))
        self.salt = salts.reshape(3, octaves, 1)
        with np.errstate(over="ignore"):
            self.salt_mix = self.salt * _GOLDEN  # (3, O, 1) the salt's part of the lattice hash, modulo 2^64
        self._cells: dict = {}  # shape -> (floor(s), a, b): the lattice cells of the last call of that shape

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """(k,3) gust vectors at points x (k,3) and time t."""
        # s[c, o, i] = 2^o (t / T + x_i . k_co / L) + offset_o
        phase = t / self.time_scale + np.einsum("coj,ij->coi", self.k, x) / self.length
        s = self.frequency * phase + self.offset
        # value noise n(s) = a + (b - a) S(f), a and b the lattice values at floor(s) and floor(s) + 1
        cell = np.floor(s)
        a, b = self._lattice_pair(cell)
        f = s - cell
        fade = f * f * f * (f * (6.0 * f - 15.0) + 10.0)
        noise = a + (b - a) * fade
        return np.add.reduce(self.amplitude * noise, axis=1).T  # sum over the octaves

    def _lattice_pair(self, cell: np.ndarray) -> tuple:
        """Lattice values (a, b) at the integer points floor(s) (cell, (3, O, k) floats) and one above, with
        this field's salts: lattice([i0, i0 + 1], salt), from the cache when no point changed cell."""
        cached = self._cells.get(cell.shape)
        if cached is not None and (cached[0] == cell).all():
            return cached[1], cached[2]
        z = np.empty((2,) + cell.shape, np.uint64)
        with np.errstate(over="ignore"):
            # z = i0 + salt * GOLDEN and z + 1 = (i0 + 1) + salt * GOLDEN, modulo 2^64 (as lattice() hashes)
            np.add(cell.astype(np.int64).view(np.uint64), self.salt_mix, out=z[0])
            np.add(z[0], np.uint64(1), out=z[1])
            values = _unit(_splitmix(z))
        if len(self._cells) >= self.CACHED_SHAPES:
            self._cells.clear()
        self._cells[cell.shape] = (cell, values[0], values[1])
        return values[0], values[1]


def gust_reference(field: GustField, point, t: float) -> np.ndarray:
    """The same G at one point, one component and octave at a time (the slow, obvious twin of __call__)."""
    out = np.zeros(3)
    for c in range(3):
        for o in range(field.k.shape[1]):
            s = 2.0**o * (t / field.time_scale + np.dot(field.k[c, o], point) / field.length) + 0.37 * o
            out[c] += GAIN**o * float(value_noise(np.array([s]), field.salt[c, o, 0])[0])
    return out / fbm_norm(field.k.shape[1])


# ---- the noise() and gust() signals of a wind's speed --------------------------------------------------------

def signal_functions(seed: int, default_time_scale: float) -> dict:
    """`noise(T)`: zero-mean fractal noise of t with unit RMS and time scale T (default: the wind's `gust`).
    `gust(T, depth = 0.5)`: a gust factor max(0, 1 + depth * noise(T)), mean about 1, to multiply a speed.
    Both take `seed = n` to decorrelate two calls in one wind; otherwise they follow the wind's seed."""

    def noise(env, time_scale=None, seed=0.0, octaves=float(OCTAVES)):
        scale = default_time_scale if time_scale is None else float(time_scale)
        if scale <= 0:
            raise ValueError("noise(T): the time scale T must be positive")
        return _scalar_like(env["t"], fbm(np.asarray(env["t"], float) / scale, _salt(seed), int(octaves)))

    def gust(env, time_scale=None, depth=0.5, seed=0.0, octaves=float(OCTAVES)):
        value = noise(env, time_scale, seed + 101.0, octaves)
        return np.maximum(0.0, 1.0 + depth * np.asarray(value))

    def _salt(extra) -> int:
        return (seed * 1_000_003 + int(round(float(extra))) * 7_919) & 0xFFFFFFFF

    return {"noise": noise, "gust": gust}


def _scalar_like(t, value):
    return float(value) if np.ndim(t) == 0 else value
