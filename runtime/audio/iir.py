"""Audio stage, recursive filters in blocks, with numpy only (scipy.signal costs seconds to import, more than
rendering a whole scene).

Any filter H(z) = B(z) / A(z) with distinct poles splits into partial fractions (`residuez`):

    H(z) = k + sum_p r_p / (1 - p z^-1)

so the output is y[n] = k x[n] + Re(sum_p r_p z_p[n]) with one complex one-pole state per pole,
z_p[n] = p z_p[n-1] + x[n], and impulse response h[0] = k + Re(sum_p r_p), h[m] = Re(sum_p r_p p^m).
A block is cut into rows of L = ROW samples (the last one padded with zeros); row r, sample i:

    y[rL + i] = sum_{j<=i} h[i-j] x[rL + j] + Re(sum_p r_p s_p[r] p^(i+1))
    s_p[r+1] = p^L s_p[r] + u_p[r],   u_p[r] = sum_j x[rL + j] p^(L-1-j)      (s_p[0]: the state carried in)

the response inside the row from zero (one product with an L x L Toeplitz table of h) plus the ringing of the
state at the row's start. The states of all rows come at once from the same recursion unrolled,
s_p[r] = p^(Lr) s_p[0] + sum_{q<r} p^(L(r-1-q)) u_p[q]: an R x R Toeplitz product per pole. Every table holds
powers p^m with |p| < 1 (no growing term), and depends on L and R only, not on the block's length.

A swept filter (`run_swept`) takes new coefficients every `period` samples, a whole number of rows: the block
is cut into segments of R = period / L rows, each with its own tables (built for all segments at once), and
the state at each segment's start carries over from the end of the one before,
s[start of segment g+1] = p_g^(LR) s[start of g] + (the segment's own input, from a zero state).
The one-pole states stay across changes of the coefficients: a swept filter glides without clicks.
"""
from __future__ import annotations

import cmath
import functools

import numpy as np

# below this many samples a direct convolution beats the FFT
DIRECT = 64
# samples per row of PoleFilter's block method (measured: 64 beats 32 and 128 on blocks of 1024 to 4096)
ROW = 64
# rows of one pass (longer inputs are cut): the carry table has MOST_ROWS^2 entries per pole
MOST_ROWS = 64
# poles closer than this are split apart (residuez)
SPLIT = 1e-4
# powers and states below this are 0: far below any sound, and subnormal numbers are a hundred times slower
TINY = 1e-150


def residuez(b, a) -> tuple:
    """(poles, residues, k) of B(z)/A(z) in powers of z^-1, len(b) <= len(a), a[0] = 1, distinct poles.
    Coincident poles (a critically damped biquad) are split into a conjugate pair SPLIT apart: the response
    changes by about SPLIT^2 relative, far below hearing, and the residues stay well scaled.
    Orders 1 and 2 (one-poles, biquads: retuned every few milliseconds) in closed form."""
    b = [float(v) for v in b]
    a = [float(v) for v in a]
    b += [0.0] * (len(a) - len(b))
    order = len(a) - 1
    k = b[-1] / a[-1] if a[-1] != 0.0 else 0.0
    # B - k A has no z^-order term: a proper remainder
    rest = [bi - k * ai for bi, ai in zip(b, a)]
    if order == 1:
        # H = k + r / (1 - p z^-1), p = -a1, r = b0 - k
        return np.array([-a[1] + 0j]), np.array([rest[0] + 0j]), k
    if order == 2:
        # poles: roots of z^2 + a1 z + a2
        root = cmath.sqrt(a[1] * a[1] - 4.0 * a[2])
        p1, p2 = (-a[1] + root) / 2.0, (-a[1] - root) / 2.0
        if abs(p1 - p2) < SPLIT:
            middle = 0.5 * (p1 + p2).real
            p1, p2 = middle + 0.5j * SPLIT, middle - 0.5j * SPLIT
        # r_i = (rest0 + rest1 / p_i) / (1 - p_j / p_i)
        r1 = (rest[0] + rest[1] / p1) / (1.0 - p2 / p1)
        r2 = (rest[0] + rest[1] / p2) / (1.0 - p1 / p2)
        return np.array([p1, p2]), np.array([r1, r2]), k
    poles = np.roots(a).astype(complex)  # roots of z^order + a1 z^(order-1) + ...
    for i in range(order):
        for j in range(i):
            if abs(poles[i] - poles[j]) < SPLIT:
                middle = 0.5 * (poles[i] + poles[j]).real
                poles[i], poles[j] = middle + 0.5j * SPLIT, middle - 0.5j * SPLIT
    residues = np.empty(order, complex)
    for i, p in enumerate(poles):
        # r_i = [(B - kA)(z) / prod_{j != i} (1 - p_j z^-1)] at z = p_i
        u = 1.0 / p
        num = np.polyval(np.asarray(rest)[::-1], u)  # sum_n rest[n] u^n
        den = np.prod([1.0 - q * u for j, q in enumerate(poles) if j != i])
        residues[i] = num / den
    return poles, residues, k


def residuez_biquads(b: np.ndarray, a: np.ndarray) -> tuple:
    """residuez of S biquads at once: b, a (S, 3) -> poles (S, 2), residues (S, 2), k (S,) (the closed form of
    order 2 above, coincident poles split alike)."""
    b, a = np.asarray(b, float), np.asarray(a, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(a[:, 2] != 0.0, b[:, 2] / a[:, 2], 0.0)
    rest0, rest1 = b[:, 0] - k * a[:, 0], b[:, 1] - k * a[:, 1]
    # poles: roots of z^2 + a1 z + a2
    root = np.sqrt(a[:, 1] * a[:, 1] - 4.0 * a[:, 2] + 0j)
    p1, p2 = (-a[:, 1] + root) / 2.0, (-a[:, 1] - root) / 2.0
    close = np.abs(p1 - p2) < SPLIT
    middle = 0.5 * (p1 + p2).real
    p1, p2 = np.where(close, middle + 0.5j * SPLIT, p1), np.where(close, middle - 0.5j * SPLIT, p2)
    # r_i = (rest0 + rest1 / p_i) / (1 - p_j / p_i)
    r1 = (rest0 + rest1 / p1) / (1.0 - p2 / p1)
    r2 = (rest0 + rest1 / p2) / (1.0 - p1 / p2)
    return np.stack([p1, p2], axis=1), np.stack([r1, r2], axis=1), k


def convolve(x: np.ndarray, h: np.ndarray, n: int) -> np.ndarray:
    """The first n samples of x * h (x, h real, along the last axis; h one-dimensional)."""
    if x.shape[-1] <= DIRECT or len(h) <= DIRECT:
        if x.ndim == 1:
            return np.convolve(x, h)[:n]
        return np.stack([np.convolve(row, h)[:n] for row in x])
    size = 1 << int(np.ceil(np.log2(x.shape[-1] + len(h) - 1)))
    return np.fft.irfft(np.fft.rfft(x, size) * np.fft.rfft(h, size), size)[..., :n]


class PoleFilter:
    """A recursive filter run block by block; `channels` leading shape of the blocks (() mono, (2,) stereo)."""

    def __init__(self, b, a, channels: tuple = ()):
        self.channels = channels
        self.set(b, a)
        self.state = np.zeros(channels + (len(self.poles),), complex)

    def set(self, b, a) -> None:
        self.poles, self.residues, self.k = residuez(b, a)
        self.tables = RowTables(self.poles[None], self.residues[None], np.array([self.k]))

    def run(self, x: np.ndarray) -> np.ndarray:
        """y (..., n) of x (..., n) with the current coefficients."""
        x = self._take(x)
        n = x.shape[-1]
        if n <= MOST_ROWS * ROW:
            return self._rows(x, -(-n // ROW))
        # the carry table grows as the square of the rows: long inputs go a piece at a time
        return np.concatenate([self._rows(x[..., lo:lo + MOST_ROWS * ROW], MOST_ROWS)
                               for lo in range(0, n, MOST_ROWS * ROW)], axis=-1)

    def run_swept(self, x: np.ndarray, b: np.ndarray, a: np.ndarray, period: int) -> np.ndarray:
        """y (..., n) of x (..., n) through biquads b, a (S, 3), each for `period` samples (a multiple of ROW,
        S = ceil(n / period)); the filter keeps the last coefficients."""
        if period % ROW:
            raise ValueError(f"period {period}: a multiple of {ROW} samples")
        x = self._take(x)
        self.poles, self.residues, self.k = residuez_biquads(b, a)
        self.tables = RowTables(self.poles, self.residues, self.k)
        self.poles, self.residues, self.k = self.poles[-1], self.residues[-1], float(self.k[-1])
        return self._rows(x, period // ROW)

    def _take(self, x) -> np.ndarray:
        x = np.asarray(x, float)
        if x.shape[:-1] != self.state.shape[:-1]:  # a mono filter meeting stereo: give each channel a state
            self.state = np.broadcast_to(self.state, x.shape[:-1] + self.state.shape[-1:]).copy()
        return x

    def _rows(self, x: np.ndarray, rows: int) -> np.ndarray:
        """y of x (..., n) by the row method (module docstring), with the tables' S segments of `rows` rows
        (n <= S rows ROW); updates the state."""
        lead, n = x.shape[:-1], x.shape[-1]
        if n == 0:
            return np.zeros(x.shape)
        tables = self.tables
        total = len(tables.k) * rows * ROW
        padded = x
        if n < total:
            padded = np.zeros(lead + (total,))
            padded[..., :n] = x
        rows_x = padded.reshape(lead + (len(tables.k), rows, ROW))  # (..., S, R, L)
        # each row's response from a zero state: y[rL + i] = sum_{j<=i} h[i-j] x[rL + j]
        y = rows_x @ tables.toeplitz
        # u[r] = sum_j x[rL + j] p^(L-1-j), each row's input to the state at its end
        u = (rows_x @ tables.back).view(complex)  # (..., S, R, P)
        starts = self._starts(u, rows)
        # ringing of each row's starting state: Re(sum_p r_p s_p[r] p^(i+1))
        c = np.multiply(starts, tables.residues[:, None, :], order="C")
        y += c.view(float) @ tables.ahead
        self._end_state(rows_x, starts, n, rows)
        return y.reshape(lead + (total,))[..., :n]

    def _starts(self, u: np.ndarray, rows: int) -> np.ndarray:
        """(..., S, R, P) the state at each row's start: s[r] = a^r z_g + sum_{q<r} a^(r-1-q) u[q] in segment g,
        a = p^L, z_g the state at the segment's start (z_0 the state carried in)."""
        lower, rising, whole = self.tables.carry(rows)
        # sum_{q<r} a^(r-1-q) u[q]: per segment and pole, (R, R) @ (R, C) with the channels as the C columns, by
        # einsum: OpenBLAS runs complex products of this size on threads, and on a busy machine each call then
        # waits for a scheduler slice (milliseconds)
        columns = np.transpose(u.reshape((-1,) + u.shape[-3:]), (1, 3, 2, 0))  # (S, P, R, C)
        own = np.einsum("sprq,spqc->sprc", lower, columns)
        own = np.transpose(own, (3, 0, 2, 1)).reshape(u.shape)  # (..., S, R, P)
        # z_{g+1} = a^R z_g + a own[R-1] + u[R-1], the state after the segment's last row
        ends = self.tables.row_power * own[..., -1, :] + u[..., -1, :]  # (..., S, P)
        z, carried = self.state, []
        for g in range(ends.shape[-2]):
            carried.append(z)
            z = whole[g] * z + ends[..., g, :]
        return own + np.swapaxes(rising, -1, -2) * np.stack(carried, axis=-2)[..., None, :]

    def _end_state(self, rows_x: np.ndarray, starts: np.ndarray, n: int, rows: int) -> None:
        """The state after sample n - 1: z <- p^t s[row of n - 1] + sum_{j<t} x[row start + j] p^(t-1-j), t its
        samples in that row."""
        last = (n - 1) // ROW
        g, r, t = last // rows, last % rows, n - last * ROW
        tables = self.tables
        fed = (rows_x[..., g, r, :t] @ tables.back[g, ROW - t:]).view(complex)
        self.state = tables.powers[g, :, t] * starts[..., g, r, :] + fed
        self.state[np.abs(self.state) < TINY] = 0.0


class RowTables:
    """The tables of the row method for S sets of coefficients (one per segment; see the module docstring),
    L = ROW, as real arrays (numpy multiplies those with BLAS): toeplitz (S, L, L) [j, i] = h[i - j] (0 for
    j > i); back (S, L, 2P) [j] = p^(L-1-j) as (re, im) pairs, so that x @ back viewed as complex is
    sum_j x[j] p^(L-1-j); ahead (S, 2P, L) [:, i] = p^(i+1) as (re, -im) pairs, so that c viewed as (re, im)
    pairs @ ahead is Re(sum_p c_p p^(i+1)); powers p^m (S, P, L+1) and row_power p^L (S, P), complex; carry(R)."""

    def __init__(self, poles: np.ndarray, residues: np.ndarray, k: np.ndarray):
        self.residues, self.k = residues, k
        self.powers = _powers(poles, ROW + 1)  # (S, P, L+1) p^m
        h = np.einsum("sp,spm->sm", residues, self.powers[:, :, :ROW]).real
        h[:, 0] += k
        self.toeplitz = _toeplitz(h, upper=True)  # [j, i] = h[i - j]
        segments, poles_count = poles.shape
        back = np.swapaxes(self.powers[:, :, ROW - 1::-1], 1, 2)  # (S, L, P) row j: p^(L-1-j)
        self.back = np.ascontiguousarray(back).view(float)  # (S, L, 2P)
        ahead = np.empty((segments, poles_count, 2, ROW))
        ahead[:, :, 0], ahead[:, :, 1] = self.powers[:, :, 1:].real, -self.powers[:, :, 1:].imag
        self.ahead = ahead.reshape(segments, 2 * poles_count, ROW)
        self.row_power = self.powers[:, :, ROW]
        self._carry: dict = {}

    def carry(self, rows: int) -> tuple:
        """For segments of R rows, a = p^L: lower (S, P, R, R) [r, q] = a^(r-1-q) for q < r, else 0;
        rising a^r (S, P, R); whole a^R (S, P)."""
        if rows not in self._carry:
            steps = _powers(self.row_power, rows + 1)  # (S, P, R+1) a^m
            shifted = np.zeros(steps.shape[:2] + (rows,), complex)
            shifted[:, :, 1:] = steps[:, :, :rows - 1]  # a^(m-1) at m: 0 on the diagonal
            self._carry[rows] = (_toeplitz(shifted, upper=False), steps[:, :, :rows], steps[:, :, rows])
        return self._carry[rows]


def _powers(base: np.ndarray, count: int) -> np.ndarray:
    """(..., count) base^m for m < count, those below TINY set to 0."""
    m = np.arange(count)
    if np.all(base != 0):
        out = np.exp(np.log(base)[..., None] * m)
    else:
        out = base[..., None] ** m
    out[np.abs(out) < TINY] = 0.0
    return out


def _toeplitz(column: np.ndarray, upper: bool) -> np.ndarray:
    """(..., m, m) the triangular Toeplitz matrices of (..., m): lower [r, q] = column[r - q] for q <= r, or its
    transpose, upper [j, i] = column[i - j] for j <= i; 0 elsewhere."""
    m = column.shape[-1]
    padded = np.concatenate([column, np.zeros(column.shape[:-1] + (1,), column.dtype)], axis=-1)
    return np.take(padded, _toeplitz_index(m, upper), axis=-1)


@functools.lru_cache(maxsize=16)
def _toeplitz_index(m: int, upper: bool) -> np.ndarray:
    """(m, m) the lags of _toeplitz, m (the index of the zero appended to the column) off the triangle."""
    lag = np.arange(m)[:, None] - np.arange(m)[None, :]
    lag = -lag if upper else lag
    return np.where(lag >= 0, lag, m)


def one_pole(c: float) -> tuple:
    """y[n] = y[n-1] + c (x[n] - y[n-1]) as (b, a)."""
    return [c], [1.0, c - 1.0]
