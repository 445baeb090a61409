"""Audio stage, recursive filters in blocks, with numpy only (scipy.signal costs seconds to import, more than
rendering a whole scene).

Any filter H(z) = B(z) / A(z) with distinct poles splits into partial fractions (`residuez`):

    H(z) = k + sum_p r_p / (1 - p z^-1)

so the output is y[n] = k x[n] + Re(sum_p r_p z_p[n]) with one complex one-pole state per pole,
z_p[n] = p z_p[n-1] + x[n]. Over a block of N samples that is (the same split as resonator.py):

    y = k x + conv(x, g)[:N] + Re(sum_p r_p z_p p^(n+1)),    g[m] = Re(sum_p r_p p^m)
    z_p <- p^N z_p + sum_j x[j] p^(N-1-j)

Changing the coefficients between blocks keeps the one-pole states: a swept filter glides without clicks.
"""
from __future__ import annotations

import cmath

import numpy as np

# below this many samples a direct convolution beats the FFT
DIRECT = 64
# poles closer than this are split apart (residuez)
SPLIT = 1e-4


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
        self._tables = {}  # n -> (p^m for m = 0..n, g): reused while the coefficients stay

    def _table(self, n: int) -> tuple:
        """For blocks of n: g (n,), p^(m+1) for m < n as real and imaginary parts (P, n), p^(n-1-j) for j < n
        as real and imaginary parts (n, P) reversed, p^n (P,). Real arrays: numpy multiplies those with BLAS,
        complex slices it does not."""
        if n not in self._tables:
            m = np.arange(n + 1)[None, :]
            if np.all(self.poles != 0):
                powers = np.exp(np.log(self.poles)[:, None] * m)  # (P, n+1) p^m
            else:
                powers = self.poles[:, None] ** m
            g = (self.residues @ powers[:, :n]).real
            ahead = powers[:, 1:]
            back = powers[:, n - 1::-1].T  # row j: p^(n-1-j)
            self._tables[n] = (g, np.ascontiguousarray(ahead.real), np.ascontiguousarray(ahead.imag),
                               np.ascontiguousarray(back.real), np.ascontiguousarray(back.imag), powers[:, n])
        return self._tables[n]

    def run(self, x: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(x, float)
        n = x.shape[-1]
        if x.shape[:-1] != self.state.shape[:-1]:  # a mono filter meeting stereo: give each channel a state
            self.state = np.broadcast_to(self.state, x.shape[:-1] + self.state.shape[-1:]).copy()
        g, ahead_re, ahead_im, back_re, back_im, last = self._table(n)
        # free ringing of the state carried in: Re(sum_p c_p p^(m+1)), c_p = r_p z_p
        c = self.state * self.residues
        free = c.real @ ahead_re - c.imag @ ahead_im
        y = self.k * x + convolve(x, g, n) + free
        # z_p <- p^n z_p + sum_j x[j] p^(n-1-j)
        self.state = self.state * last + (x @ back_re + 1j * (x @ back_im))
        return y


def one_pole(c: float) -> tuple:
    """y[n] = y[n-1] + c (x[n] - y[n-1]) as (b, a)."""
    return [c], [1.0, c - 1.0]
