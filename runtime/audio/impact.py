"""Audio stage, collision sounds: the exciters `modal`, `impact` and `pulse`.

An exciter turns each hit (a collision event, or the time of an `at` sound) into sound, starting at the
hit's sample, round((t - start) * fs). Its strength is the hit's value of the event factors that multiply it
in the sound's expression (`modal(bar) * impulse` excites the bar with each hit's impulse; the compiler moves
such factors onto the exciter, see graph.py), so that a new hit adds to the ringing of the old ones instead of
rescaling them.

- modal(body, [input]): the body's modes (modal.py) in a resonator bank kept across hits (resonator.py),
  each hit a half-sine force pulse of the contact's duration (excitation.py) weighted per mode by |phi_n(p)|
  at the contact point. A second argument drives the bank with any signal as well.
- impact([a, b]): the collision sound of two bodies, homogeneous or not, chosen from both materials:
  the modal bank of each body that has modes, plus the contact itself: a click (the force pulse, the
  "acceleration noise" of the bodies) and a burst of noise band-passed at 1 / tau whose level rises as the
  materials ring less (wood, plastic: a thud; metal, glass: a ring with a small tick).
- pulse([duration]): the bare force pulse (unit peak), for graphs that build their own sound from it.
"""
from __future__ import annotations

import math

import numpy as np

from .excitation import half_sine
from .nodes import FRAME, Node, as_block
from .noise import seed_for
from .resonator import ResonatorBank

# ringing of a material, rho = exp(-loss / RING_LOSS): ~1 for metal and glass (loss 1e-4), ~0 for wood (1e-2)
RING_LOSS = 3e-3
# level of the click (force pulse) in an impact, and of its noise burst when neither body rings
CLICK_LEVEL = 0.25
BURST_LEVEL = 1.0
# the burst's tail decays with this many contact durations as time constant
BURST_TAIL = 2.0
# band-pass of the burst: centre 1 / tau kept in [BURST_LOWEST, 0.4 fs], Q
BURST_LOWEST = 200.0
BURST_Q = 0.8


class BodyBank:
    """A body's modes, as the compiler hands them to an exciter; or one part's of a compound body (the
    dissertation's heterogeneous object: each part rings with its own shape and material): `part` its name, `pose`
    (where its origin sits in the body frame (3,), its axes R (3,3)), so that a hit's body-frame point can be read
    in the part's frame."""

    def __init__(self, body: str, modes, part: str | None = None, pose: tuple | None = None):
        self.body, self.modes, self.part, self.pose = body, modes, part, pose

    def excitation(self, local_point) -> np.ndarray:
        if self.pose is not None and local_point is not None:
            origin, R = self.pose
            local_point = R.T @ (np.asarray(local_point, float) - origin)  # p_part = R^T (p_body - o)
        return self.modes.excitation(local_point)


class Banks:
    """The resonator banks of an exciter's bodies (or their parts) as one ResonatorBank, their modes side by side
    (each bank tested for silence on its own), with the parts of pulses that run past the end of a block."""

    def __init__(self, bodies: list, fs: float):
        self.bodies = list(dict.fromkeys(b.body for b in bodies))
        self.banks = bodies
        sizes = [len(b.modes) for b in bodies]
        edges = np.cumsum([0] + sizes)
        self.slices = [slice(lo, hi) for lo, hi in zip(edges[:-1], edges[1:])]
        freq, decay, gain = (np.concatenate([getattr(b.modes, name) for b in bodies] or [np.zeros(0)])
                             for name in ("freq", "decay", "gain"))
        self.bank = ResonatorBank(freq, decay, gain, fs, FRAME, groups=sizes or None)
        self.pending = []  # (gains, samples still to feed from the start of the next block)

    def has(self, body: str) -> bool:
        return body in self.bodies

    def gains(self, body: str, local_point, part: str | None = None) -> np.ndarray:
        """(M,) the input gains of a hit on `body` at a body-frame point: its modes' excitation, 0 elsewhere; a
        compound body's hit rings the part struck (every part when the hit names none)."""
        out = np.zeros(self.bank.size)
        for bank, where in zip(self.banks, self.slices):
            if bank.body == body and (bank.part is None or part is None or bank.part == part):
                out[where] = bank.excitation(local_point)
        return out

    def render(self, start: int, n: int, inputs: list) -> np.ndarray:
        """The block of n samples from sample `start`. inputs: (gains (M,), k0, x) with x of any length; what
        does not fit in this block waits."""
        fitted, pending = [], []
        for gains, x in self.pending:
            fitted.append((gains, 0, x[:n]))
            if len(x) > n:
                pending.append((gains, x[n:]))
        for gains, k0, x in inputs:
            room = n - k0
            fitted.append((gains, k0, x[:room]))
            if len(x) > room:
                pending.append((gains, x[room:]))
        self.pending = pending
        if not fitted and self.bank.silent:
            return np.zeros(n)
        return self.bank.render(n, fitted, start)


class Exciter(Node):
    """Base of the nodes that sound at hits. `strength`: the expression of event values multiplying it."""

    def __init__(self, strength):
        self.strength = strength
        self._pulses: dict = {}
        self._tails: list = []  # finite signals still sounding: the parts past the last block, from its end on

    def _block_with_tails(self, n: int) -> np.ndarray:
        """A new block of n samples holding what the earlier blocks' signals still had to play."""
        out = np.zeros(n)
        for x in self._tails:
            out[: min(len(x), n)] += x[:n]
        self._tails = [x[n:] for x in self._tails if len(x) > n]
        return out

    def _add_signal(self, out: np.ndarray, k0: int, x: np.ndarray) -> None:
        """out[k0:] += x, the part of x beyond the block kept for the next ones."""
        room = len(out) - k0
        out[k0:k0 + min(room, len(x))] += x[:room]
        if len(x) > room:
            self._tails.append(x[room:])

    def pulse(self, tau: float, fs: float, area: bool = True) -> np.ndarray:
        key = (max(1, int(round(tau * fs))), area)
        if key not in self._pulses:
            self._pulses[key] = half_sine(tau, fs, area)
        return self._pulses[key]


class Modal(Exciter):
    """modal(body, ...): see the module docstring."""

    def __init__(self, banks: list, strength, fs: float, drive: Node | None = None, tau: float | None = None):
        super().__init__(strength)
        self.banks, self.drive, self.tau = Banks(banks, fs), drive, tau

    def children(self):
        return (self.drive,) if self.drive is not None else ()

    def render(self, ctx):
        inputs = []
        for k0, hit in ctx.hits:
            s = ctx.strength(self.strength, hit)
            if s == 0.0:
                continue
            x = self.pulse(self.tau or hit.tau, ctx.fs)
            touched = [body for body in self.banks.bodies if body in hit.bodies] or self.banks.bodies
            for body in touched:
                inputs.append((s * self.banks.gains(body, hit.local.get(body), hit.parts.get(body)), k0, x))
        if self.drive is not None:
            x = as_block(self.drive.render(ctx), ctx.n)
            x = x.mean(axis=0) if x.ndim > 1 else x
            inputs.append((np.ones(self.banks.bank.size), 0, x))
        return self.banks.render(ctx.start, ctx.n, inputs)


class Impact(Exciter):
    """impact(a, b): the modal banks of the bodies hit, plus a click and a noise burst set by the materials.
    `ringing`: (body, part or None) -> rho in [0, 1] (0 for a body without modes): of the part struck."""

    def __init__(self, banks: list, ringing: dict, strength, seed: tuple, fs: float, tau: float | None = None):
        super().__init__(strength)
        self.banks, self.ringing, self.seed, self.tau = Banks(banks, fs), ringing, seed, tau

    def render(self, ctx):
        inputs = []
        out = self._block_with_tails(ctx.n)
        for k0, hit in ctx.hits:
            s = ctx.strength(self.strength, hit)
            if s == 0.0:
                continue
            tau = self.tau or hit.tau
            for name in hit.bodies:
                if self.banks.has(name):
                    inputs.append((s * self.banks.gains(name, hit.local.get(name), hit.parts.get(name)), k0,
                                   self.pulse(tau, ctx.fs)))
            rho = max((self._ringing(name, hit.parts.get(name)) for name in hit.bodies), default=0.0)
            self._add_signal(out, k0, s * self._contact_sound(tau, rho, ctx.fs, hit))
        return out + self.banks.render(ctx.start, ctx.n, inputs)

    def _ringing(self, body: str, part: str | None) -> float:
        """rho of the part struck (of the body; a compound hit at no part: its most ringing part)."""
        if (body, part) in self.ringing:
            return self.ringing[(body, part)]
        return max((rho for (b, p), rho in self.ringing.items() if b == body and (part is None or p is None)),
                   default=0.0)

    def _contact_sound(self, tau: float, rho: float, fs: float, hit) -> np.ndarray:
        """The click (force pulse, unit peak) and the noise burst of one contact, as one finite signal."""
        from .iir import PoleFilter
        from .nodes import biquad

        click = self.pulse(tau, fs, area=False)
        peak = len(click) // 2
        tail = int(math.ceil(6.0 * BURST_TAIL * tau * fs))  # six time constants: -52 dB
        fall = click[peak] * np.exp(-np.arange(1, tail) / (BURST_TAIL * tau * fs))
        envelope = np.concatenate([click[:peak + 1], fall])
        envelope[0] = 0.0  # the burst follows the click by a sample: no chance of cancelling it at the onset
        rng = np.random.default_rng(seed_for(*self.seed, hit.sample, hit.bodies))
        band = PoleFilter(*biquad("bandpass", max(BURST_LOWEST, 1.0 / tau), BURST_Q, fs))
        burst = band.run(rng.standard_normal(len(envelope)) * envelope)
        out = BURST_LEVEL * (1.0 - 0.8 * rho) * burst
        out[: len(click)] += CLICK_LEVEL * click
        return out


class Pulse(Exciter):
    """pulse([duration]): a half-sine of unit peak at every hit (its contact duration unless given)."""

    def __init__(self, strength, duration: float | None = None):
        super().__init__(strength)
        self.duration = duration

    def render(self, ctx):
        out = self._block_with_tails(ctx.n)
        for k0, hit in ctx.hits:
            s = ctx.strength(self.strength, hit)
            self._add_signal(out, k0, s * self.pulse(self.duration or hit.tau, ctx.fs, area=False))
        return out


def ringing_of(material) -> float:
    """rho = exp(-loss / RING_LOSS) of a material's internal friction (Rayleigh: at 1 kHz)."""
    from .modal import DEFAULT_LOSS

    if material is None:
        return 0.0
    if material.rayleigh is not None:
        alpha, beta = material.rayleigh
        w = 2.0 * math.pi * 1000.0
        loss = (alpha + beta * w * w) / 2.0 / (math.pi * 1000.0)  # d = pi f loss at 1 kHz
    else:
        loss = material.loss if material.loss is not None else DEFAULT_LOSS
    return math.exp(-loss / RING_LOSS)
