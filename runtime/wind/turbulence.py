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

import importlib

import numpy as np

# octaves of the fractal noise (the finest has a time scale T / 2^(OCTAVES-1))
OCTAVES = 4
# lattice cells hashed ahead for each noise element (the finest octave crosses 8 cells per gust time scale)
WINDOW = 32
# an element that leaves its window renews the windows of all elements within this many cells of their end
WINDOW_MARGIN = 8
# amplitude ratio between octaves: 0.5 gives the 1/f ("pink", fractal) spectrum
GAIN = 0.5
# m/s: how fast the gust pattern sweeps through space; a gust of time scale T is about GUST_SPEED * T across
GUST_SPEED = 2.0
# mean of (1 - S)^2 + S^2 over f in [0, 1) for the quintic fade S: the variance factor of the blend
_BLEND_VARIANCE = 181.0 / 231.0
# variance of a lattice value, uniform in [-1, 1)
_LATTICE_VARIANCE = 1.0 / 3.0

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
MIX1 = np.uint64(0xBF58476D1CE4E5B9)
MIX2 = np.uint64(0x94D049BB133111EB)


def _einsum_core():
    """np.einsum's C function: np.einsum(..., optimize=False) passes its arguments to it unchanged (the same
    result to the bit), and calling it directly skips about 1 us of dispatch, half of an einsum on one point.
    np.einsum itself where numpy does not expose it."""
    for module in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            return importlib.import_module(module).c_einsum
        except (ImportError, AttributeError):
            continue
    return np.einsum


einsum = _einsum_core()


def _splitmix(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser on uint64 arrays (wraps modulo 2^64)."""
    z = (z ^ (z >> np.uint64(30))) * MIX1
    z = (z ^ (z >> np.uint64(27))) * MIX2
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

    Called at every force evaluation with a few points, where numpy costs per call, not per number: so one
    evaluation is a fixed list of in-place operations on flat arrays of equal length (no broadcasting), one
    element per (octave o, point i, component c) in that order, in buffers kept per number of points k
    (`GustScratch`). What did not change since the last call of that size is kept: x . k / L while the points
    stay put (the recorder's probes), and the lattice values while the points stay in their cells (a cell is
    0.4 s / 2^o wide in time and the steps are a few ms). The lattice values come from windows of cells hashed
    ahead (`LatticeWindow`), so a point entering a new cell costs a gather, not a hash. The values are
    value_noise's to the bit (`gust_reference` is the slow twin)."""

    # scratch kept at once, one per number of points asked for (force stage, recorder, ...)
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
        # the directions and constants by octave and component, row 3 o + c: (3O, 3) and (3O,)
        self.row_k = np.ascontiguousarray(self.k.transpose(1, 0, 2)).reshape(3 * octaves, 3)
        self.row_constants = {name: np.broadcast_to(value, (3, octaves, 1)).transpose(1, 0, 2).reshape(-1)
                              for name, value in (("frequency", self.frequency), ("offset", self.offset),
                                                  ("amplitude", self.amplitude), ("salt_mix", self.salt_mix))}
        self._scratch: dict = {}  # k -> GustScratch

    def __call__(self, x: np.ndarray, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """(k,3) gust vectors at points x (k,3) and time t (into `out` when given, else a new array)."""
        x = np.asarray(x, dtype=float)
        scratch = self._scratch_for(len(x))
        self._octave_terms(scratch, x, t)
        # G_c = sum_o amplitude_o n_oc, the octaves added in order (as np.sum over them)
        octave = scratch.noise_of_octave
        out = np.add(octave[0], octave[1], out)
        for terms in octave[2:]:
            np.add(out, terms, out)
        return out

    def at_one_point(self, x: np.ndarray, t: float) -> tuple:
        """G at one point x (1,3), three floats: the octaves added in floats, in the same order."""
        scratch = self._scratch_for(1)
        self._octave_terms(scratch, x, t)
        terms = scratch.noise.tolist()
        g0, g1, g2 = terms[0:3]
        for o in range(3, len(terms), 3):
            g0, g1, g2 = g0 + terms[o], g1 + terms[o + 1], g2 + terms[o + 2]
        return g0, g1, g2

    def _octave_terms(self, scratch: "GustScratch", x: np.ndarray, t: float) -> None:
        """scratch.noise <- amplitude_o n(s) of every point, octave and component at time t."""
        self._phase(scratch, x, t)
        self._refresh_lattice(scratch)
        self._noise(scratch)

    def _scratch_for(self, k: int) -> "GustScratch":
        scratch = self._scratch.get(k)
        if scratch is None:
            if len(self._scratch) >= self.CACHED_SHAPES:
                self._scratch.clear()
            scratch = self._scratch[k] = GustScratch(self.row_constants, k, self.length)
        return scratch

    def _phase(self, scratch: "GustScratch", x: np.ndarray, t: float) -> None:
        """scratch.s <- s = 2^o (t / T + x_i . k_oc / L) + offset_o, and scratch.cell <- floor(s)."""
        key = x.tobytes()
        if key != scratch.points_key:
            # x . k / L, kept while the points stay put (x . k by point, then / L into the octave-major layout)
            einsum("fj,ij->if", self.row_k, x, out=scratch.dot)
            np.divide(scratch.dot_by_point, scratch.length, scratch.along_by_point)
            scratch.points_key = key
        s = scratch.s
        np.add(scratch.along, t / self.time_scale, s)
        np.multiply(s, scratch.frequency, s)
        np.add(s, scratch.offset, s)
        np.floor(s, scratch.cell)

    def _refresh_lattice(self, scratch: "GustScratch") -> None:
        """scratch.a, scratch.rise <- the lattice value a at floor(s) and b - a, b the value one above (from
        the window of hashed cells; nothing to do while no point changed cell)."""
        key = scratch.cell.tobytes()
        if key != scratch.cell_key:
            scratch.window.look_up(scratch.cell, scratch.a, scratch.rise)
            scratch.cell_key = key

    def _noise(self, scratch: "GustScratch") -> None:
        """scratch.noise <- amplitude_o n(s), n(s) = a + (b - a) S(f) with f = s - floor(s)."""
        f, f_f, six_f, pair, poly, cube, noise = (scratch.f, scratch.f_f, scratch.six_f, scratch.pair, scratch.poly,
                                                  scratch.cube, scratch.noise)
        np.subtract(scratch.s, scratch.cell, f)
        scratch.f_again[...] = f
        # S(f) = f f f (f (6 f - 15) + 10), each product as value_noise takes it, two at a time where they pair up:
        np.multiply(f_f, six_f, pair)  # (6 f, f f)
        np.subtract(poly, scratch.fifteen, poly)  # (6 f - 15, f f)
        np.multiply(pair, f_f, pair)  # (f (6 f - 15), f f f)
        np.add(poly, scratch.ten, poly)  # (f (6 f - 15) + 10, f f f)
        np.multiply(cube, poly, noise)
        # n = a + (b - a) S(f), times the octave's amplitude
        np.multiply(scratch.rise, noise, noise)
        np.add(scratch.a, noise, noise)
        np.multiply(scratch.amplitude, noise, noise)


class GustScratch:
    """A GustField's working memory for k points: flat arrays of O k 3 elements, element (o, i, c) (octave, point,
    component) at (o k + i) 3 + c, so that an octave's terms are one contiguous (k,3) block; the field's
    constants spread to that length; what the last call of this size left to reuse (the points' x . k / L and
    their bytes, the cells' lattice values and their bytes)."""

    def __init__(self, row_constants: dict, k: int, length: float):
        octaves = len(row_constants["frequency"]) // 3
        size = octaves * k * 3

        def spread(row):  # (3O,) by row 3 o + c -> (O k 3,)
            return np.broadcast_to(row.reshape(octaves, 1, 3), (octaves, k, 3)).reshape(-1)

        self.frequency, self.offset, self.amplitude = (spread(row_constants[name])
                                                       for name in ("frequency", "offset", "amplitude"))
        self.window = LatticeWindow(spread(row_constants["salt_mix"]))
        self.fifteen, self.ten = np.full(size, 15.0), np.full(size, 10.0)
        self.points_key = None  # bytes of the last points
        self.dot = np.empty((k, 3 * octaves))  # x_i . k_oc by point (the einsum's layout)
        self.dot_by_point = self.dot.reshape(k, octaves, 3)
        self.length = np.full((k, octaves, 3), length)  # L
        self.along = np.empty(size)  # x_i . k_oc / L at those points
        self.along_by_point = self.along.reshape(octaves, k, 3).transpose(1, 0, 2)  # (k, O, 3) view
        self.s = np.empty(size)  # the noise coordinate s
        self.cell = np.empty(size)  # floor(s)
        self.cell_key = None  # bytes of `cell` when `a` and `rise` were brought up to date
        self.a = np.empty(size)  # lattice value at floor(s)
        self.rise = np.empty(size)  # b - a, b the lattice value at floor(s) + 1
        # f beside 6 and beside itself, [6 | f | f]: (f, f) times (6, f) is one call; and the polynomial's two
        # factors side by side, [f (6 f - 15) + 10 | f^3]
        six_f_f = np.empty(3 * size)
        six_f_f[:size] = 6.0
        self.f, self.f_again = six_f_f[size:2 * size], six_f_f[2 * size:]
        self.f_f, self.six_f = six_f_f[size:], six_f_f[:2 * size]
        self.pair = np.empty(2 * size)
        self.poly, self.cube = self.pair[:size], self.pair[size:]
        self.noise = np.empty(size)
        self.noise_of_octave = list(self.noise.reshape(octaves, k, 3))  # (k,3) block of each octave


class LatticeWindow:
    """The lattice values of WINDOW consecutive cells ahead of each of m noise elements (each with its salt),
    hashed in advance: as time goes on an element walks up its cells one at a time, and a look-up is a gather;
    an element that walks out of its window gets a new one, starting a cell below where it is."""

    def __init__(self, salt_mix: np.ndarray):
        m = len(salt_mix)
        self.salt_mix = salt_mix[:, None]  # (m,1) salt * GOLDEN of each element
        self.first = np.zeros(m)  # (m,) the window's first cell
        self.value = np.empty((m, WINDOW))  # value at cell first + j
        self.rise = np.empty((m, WINDOW))  # value at first + j + 1 minus value at first + j
        self.row_start = np.arange(m) * WINDOW  # where each element's window starts in the flat tables
        self.step = np.empty(m, np.int64)  # scratch: cell - first, then its index in the flat tables
        self.step_unsigned = self.step.view(np.uint64)
        self.fresh = False  # no window hashed yet

    def look_up(self, cell: np.ndarray, value_out: np.ndarray, rise_out: np.ndarray) -> None:
        """value_out, rise_out (m,) <- the lattice value at each element's cell (integers, as floats) and the
        rise to the next; re-hashes the windows of the elements outside theirs."""
        if not self.fresh:
            self._hash(slice(None), cell)
            self.fresh = True
        # j = cell - first, outside [0, WINDOW) for the elements that left their window (a negative j is a huge
        # unsigned one)
        j = np.subtract(cell, self.first, self.step, casting="unsafe")
        if self.step_unsigned.max() >= WINDOW:
            # new windows for those, and for the elements near the end of theirs (fewer, larger hashings)
            renew = np.flatnonzero(self.step_unsigned >= WINDOW - WINDOW_MARGIN)
            self._hash(renew, cell[renew])
            j[renew] = 1
        np.add(j, self.row_start, j)
        # ("clip": a cell that is not a number (a blown-up run) reads some value rather than raising)
        self.value.take(j, out=value_out, mode="clip")
        self.rise.take(j, out=rise_out, mode="clip")

    def _hash(self, rows, cell: np.ndarray) -> None:
        """New windows for the elements `rows`, starting a cell below `cell`: lattice values, as lattice()."""
        first = cell - 1.0
        self.first[rows] = first
        cells = first[:, None] + np.arange(WINDOW + 1.0)
        # z = i + salt * GOLDEN, modulo 2^64 (as lattice() hashes; arrays wrap without a warning)
        z = cells.astype(np.int64).view(np.uint64) + self.salt_mix[rows]
        values = _unit(_splitmix(z))
        self.value[rows] = values[:, :-1]
        # rise = b - a, b the value one cell above a
        self.rise[rows] = values[:, 1:] - values[:, :-1]


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
