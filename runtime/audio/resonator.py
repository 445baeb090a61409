"""Audio stage, the resonator bank: M two-pole resonators rendered block by block, state kept across hits.

docs/design/sound.md's resonator, per mode n (r = exp(-d/fs), w = 2 pi f / fs):

    y[k] = 2 r cos(w) y[k-1] - r^2 y[k-2] + b x[k]

Its impulse response is b r^k sin(w (k+1)) / sin(w). With b = a sin(w) it is a r^k sin(w (k+1)): the modal
impulse response a exp(-d t) sin(2 pi f t) read one sample ahead, so a hit at sample k0 sounds at k0 itself.
`two_pole_reference` is that recursion, sample by sample: slow and obvious, the oracle of the tests.

The fast path writes the same filter as a complex one-pole per mode (p = r e^{iw}):

    z[k] = p z[k-1] + g x[k],     y[k] = sum_n Im(c_n z_n[k]),   c_n = a_n e^{i w_n}

since Im(e^{iw} p^m) / r^0 = r^m sin(w (m+1)). A block is linear in the state and the inputs, so it splits
into the ringing of the state carried in, plus the response to each input inside the block:

    free:   y[k] = Im(sum_n c_n z_n p_n^(k+1))                  (one matrix-vector product, M x N)
    input:  y[k0 + m] = sum_j x[j] h[m - j],  h[m] = Im(sum_n c_n g_n p_n^m)   (the bank's impulse response)
    state:  z_n <- p_n^N z_n + g_n sum_j x[j] p_n^(N-1-k0-j)

All three are products with one precomputed table Q[n, k] = p_n^k (k = 0..N), kept as real and imaginary
parts (BLAS is much faster on real arrays). A hit costs O(M N), ringing O(M N) per block, with no Python
loop over samples or modes.
"""
from __future__ import annotations

import numpy as np

from .iir import TINY, convolve

# a bank whose state has fallen below this (relative to the largest it has had) is silent: skipped
SILENCE = 1e-7
# products of a vector with more than this many table entries go a few modes at a time: OpenBLAS runs bigger ones
# on threads, and on a busy machine each call then waits for a scheduler slice (milliseconds)
BLAS_PIECE = 1 << 17


class ResonatorBank:
    """Modes (freq, decay, gain) at rate fs, rendered a frame of at most `frame` samples at a time. Frames are fixed
    in the render's samples (frame k covers samples k frame .. (k+1) frame - 1): a block is cut at their edges,
    and the bank tests for silence at the end of each, so that the samples do not depend on the block size.
    `groups`: the sizes of consecutive groups of modes (the bodies of one exciter) tested for silence apart."""

    def __init__(self, freq, decay, gain, fs: float, frame: int, groups=None):
        freq, decay, gain = (np.asarray(v, float) for v in (freq, decay, gain))
        self.fs, self.frame, self.size = fs, frame, len(freq)
        self.groups = np.asarray(groups if groups is not None else [self.size], int)
        self.group_starts = np.cumsum(self.groups) - self.groups
        w = 2.0 * np.pi * freq / fs
        r = np.exp(-decay / fs)
        self.pole = r * np.exp(1j * w)  # (M,)
        self.out = gain * np.exp(1j * w)  # (M,) c_n
        powers = self.pole[:, None] ** np.arange(frame + 1)[None, :]  # (M, N+1) p^k
        powers[np.abs(powers) < TINY] = 0.0  # subnormal numbers are a hundred times slower
        self.q_re = np.ascontiguousarray(powers.real)
        self.q_im = np.ascontiguousarray(powers.imag)
        self.pole_frame = self.pole**frame
        self.state = np.zeros(self.size, complex)  # z_n after the last rendered sample
        self.loudest = np.zeros(len(self.groups))  # per group, the largest |z_n| since it last fell silent

    def render(self, n: int, inputs=(), start: int = 0) -> np.ndarray:
        """The n samples from sample `start` of the render. inputs: (gains (M,), k0, x) with x starting at
        sample k0 of this block and len(x) <= n - k0; an input longer than the block must be split by the caller."""
        if self.size == 0:
            return np.zeros(n)
        pieces, lo = [], 0
        while lo < n:
            hi = min(n, lo + self.frame - (start + lo) % self.frame)  # the end of this block's part of a frame
            pieces.append(self._piece(hi - lo, _inputs_between(inputs, lo, hi), (start + hi) % self.frame == 0))
            lo = hi
        return pieces[0] if len(pieces) == 1 else np.concatenate(pieces)

    def _piece(self, n: int, inputs, frame_ends: bool) -> np.ndarray:
        """n samples within one frame; at the frame's end, the test for silence. Products run over the modes
        from the first to the last one ringing (or fed), so that the silent bodies of a bank cost nothing."""
        y = np.zeros(n)
        z = self.state
        modes = _extent(z)
        if modes.stop:
            self._ring(y, modes, z)
            z = z * (self.pole_frame if n == self.frame else self.pole**n)
        else:
            z = z.copy()
        for gains, k0, x in inputs:
            gains = np.asarray(gains, float)
            modes = _extent(gains)
            if modes.stop > modes.start:
                z[modes] += self._add_input(y, gains[modes], modes, int(k0), np.asarray(x, float), n)
        self.state = z
        if frame_ends:
            self._check_silence()
        return y

    def _ring(self, y: np.ndarray, modes: slice, z: np.ndarray) -> None:
        """Add to y (n,) the free ringing of states z of `modes`: Im(c z p^(k+1)) = Re(cz) Im(p^(k+1)) +
        Im(cz) Re(p^(k+1)), a few modes at a time when they are many (BLAS_PIECE)."""
        n = len(y)
        for rows in _pieces(modes, n):
            cz = self.out[rows] * z[rows]
            y += cz.real @ self.q_im[rows, 1:n + 1] + cz.imag @ self.q_re[rows, 1:n + 1]

    def _add_input(self, y, gains, modes: slice, k0: int, x, n: int) -> np.ndarray:
        """Add the response of `modes` to input x at k0 into y; return the input's contribution to their end
        state."""
        span = n - k0
        cg = self.out[modes] * gains
        h = np.zeros(span)  # the modes' impulse response
        for rows in _pieces(modes, span):
            part = cg[rows.start - modes.start:rows.stop - modes.start]
            h += part.real @ self.q_im[rows, :span] + part.imag @ self.q_re[rows, :span]
        y[k0:] += convolve(x, h, span)
        # z_n += g_n sum_j x[j] p_n^(span-1-j): exponents span-len(x) .. span-1, reversed against x
        lo = span - len(x)
        back = np.ascontiguousarray(x[::-1])
        fed = np.concatenate([self.q_re[rows, lo:span] @ back + 1j * (self.q_im[rows, lo:span] @ back)
                              for rows in _pieces(modes, len(x))])
        return gains * fed

    def _check_silence(self) -> None:
        """A group whose largest |z_n| has fallen below SILENCE of the largest it has had is set to silence."""
        level = np.maximum.reduceat(np.abs(self.state), self.group_starts)
        np.maximum(self.loudest, level, out=self.loudest)
        quiet = level < SILENCE * self.loudest
        if quiet.any():
            self.state[np.repeat(quiet, self.groups)] = 0.0
            self.loudest[quiet] = 0.0

    @property
    def silent(self) -> bool:
        return not np.any(self.state)


def _pieces(modes: slice, n: int):
    """The modes in slices small enough that a product with n table entries each stays within BLAS_PIECE."""
    step = max(1, BLAS_PIECE // max(n, 1))
    for lo in range(modes.start, modes.stop, step):
        yield slice(lo, min(lo + step, modes.stop))


def _extent(values: np.ndarray) -> slice:
    """The indices from the first non-zero value to the last (slice(0, 0) when all are zero)."""
    nonzero = np.flatnonzero(values)
    return slice(nonzero[0], nonzero[-1] + 1) if len(nonzero) else slice(0, 0)


def _inputs_between(inputs, lo: int, hi: int) -> list:
    """The parts of inputs (gains, k0, x) that fall in samples lo .. hi - 1 of the block, as inputs of that part."""
    parts = []
    for gains, k0, x in inputs:
        first, last = max(k0, lo), min(k0 + len(x), hi)
        if first < last:
            parts.append((gains, first - lo, x[first - k0:last - k0]))
    return parts


def two_pole_reference(freq, decay, gain, fs: float, inputs) -> np.ndarray:
    """docs/design/sound.md's recursion, per mode and per sample. inputs: (N, M) array, the input of each mode."""
    freq, decay, gain = (np.asarray(v, float) for v in (freq, decay, gain))
    inputs = np.asarray(inputs, float)
    out = np.zeros(inputs.shape[0])
    for n in range(len(freq)):
        w = 2.0 * np.pi * freq[n] / fs
        r = np.exp(-decay[n] / fs)
        b = gain[n] * np.sin(w)
        y1 = y2 = 0.0
        for k in range(inputs.shape[0]):
            # y[k] = 2 r cos(w) y[k-1] - r^2 y[k-2] + b x[k]
            y0 = 2.0 * r * np.cos(w) * y1 - r * r * y2 + b * inputs[k, n]
            out[k] += y0
            y1, y2 = y0, y1
    return out
