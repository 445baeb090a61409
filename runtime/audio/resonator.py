"""Audio stage, the resonator bank: M two-pole resonators rendered block by block, state kept across hits.

SOUND.md's resonator, per mode n (r = exp(-d/fs), w = 2 pi f / fs):

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

from .iir import convolve

# a bank whose state has fallen below this (relative to the largest it has had) is silent: skipped
SILENCE = 1e-7


class ResonatorBank:
    """Modes (freq, decay, gain) at rate fs, rendered in blocks of at most `block` samples."""

    def __init__(self, freq, decay, gain, fs: float, block: int):
        freq, decay, gain = (np.asarray(v, float) for v in (freq, decay, gain))
        self.fs, self.block, self.size = fs, block, len(freq)
        w = 2.0 * np.pi * freq / fs
        r = np.exp(-decay / fs)
        self.pole = r * np.exp(1j * w)  # (M,)
        self.out = gain * np.exp(1j * w)  # (M,) c_n
        powers = self.pole[:, None] ** np.arange(block + 1)[None, :]  # (M, N+1) p^k
        self.q_re = np.ascontiguousarray(powers.real)
        self.q_im = np.ascontiguousarray(powers.imag)
        self.pole_block = self.pole**block
        self.state = np.zeros(self.size, complex)  # z_n after the last rendered sample
        self.loudest = 0.0

    def render(self, n: int, inputs=()) -> np.ndarray:
        """The next n samples (n <= block). inputs: (gains (M,), k0, x) with x starting at sample k0 of this
        block and len(x) <= n - k0; an input longer than the block must be split by the caller."""
        y = np.zeros(n)
        if self.size == 0:
            return y
        z = self.state
        ringing = bool(np.any(z))
        if ringing:
            cz = self.out * z
            # Im(c z p^(k+1)) = Re(cz) Im(p^(k+1)) + Im(cz) Re(p^(k+1))
            y += cz.real @ self.q_im[:, 1:n + 1] + cz.imag @ self.q_re[:, 1:n + 1]
            z = z * (self.pole_block if n == self.block else self.pole**n)
        for gains, k0, x in inputs:
            z = z + self._add_input(y, np.asarray(gains, float), int(k0), np.asarray(x, float), n)
        self.state = z
        self._check_silence()
        return y

    def _add_input(self, y, gains, k0: int, x, n: int) -> np.ndarray:
        """Add the response to input x at k0 into y; return the input's contribution to the end state."""
        span = n - k0
        cg = self.out * gains
        h = cg.real @ self.q_im[:, :span] + cg.imag @ self.q_re[:, :span]  # bank impulse response, (span,)
        y[k0:] += convolve(x, h, span)
        # z_n += g_n sum_j x[j] p_n^(span-1-j): exponents span-len(x) .. span-1, reversed against x
        lo = span - len(x)
        back = np.ascontiguousarray(x[::-1])
        return gains * (self.q_re[:, lo:span] @ back + 1j * (self.q_im[:, lo:span] @ back))

    def _check_silence(self) -> None:
        level = float(np.max(np.abs(self.state)))
        self.loudest = max(self.loudest, level)
        if level < SILENCE * self.loudest:
            self.state[:] = 0.0
            self.loudest = 0.0

    @property
    def silent(self) -> bool:
        return not np.any(self.state)


def two_pole_reference(freq, decay, gain, fs: float, inputs) -> np.ndarray:
    """SOUND.md's recursion, per mode and per sample. inputs: (N, M) array, the input of each mode."""
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
