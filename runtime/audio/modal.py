"""Audio stage, modal models: the modes (frequency, decay, gain) of a homogeneous body from its shape and
material, the damping models, and where a hit excites each mode.

Every model gives `Modes`: frequencies f_n (Hz), decay rates d_n (1/s, amplitude ~ exp(-d_n t)), gains a_n,
and optionally `shape(local_point)` -> (M,) excitation weights |phi_n(p)| of a hit at a body-frame point.
The formulas, and where each holds (docs/sound.md has the same table):

- free-free Euler-Bernoulli bar (box with one long edge, long cylinder or tube):
      f_n = (beta_n L)^2 / (2 pi L^2) * r_g * sqrt(E / rho),  cos(beta L) cosh(beta L) = 1,
  r_g the radius of gyration of the section: h / sqrt(12) (rectangle, bending across the thin edge h),
  R / 2 (solid rod), sqrt(R^2 + R_i^2) / 2 (tube). For a rectangle this is docs/design/sound.md's
  (beta_n L)^2 h / (2 pi L^2) sqrt(E / (12 rho)). Valid for slender bars (L / h > ~10: shear and rotary
  inertia add under 1 % to the first modes, more to high ones); bending across the thin edge only.
- free rectangular thin plate (box with one thin edge): Kirchhoff plate, Rayleigh-Ritz with products of
  free-free beam functions (Leissa 1973): omega^2 from K c = omega^2 M c, D = E h^3 / (12 (1 - nu^2)).
  Valid for h < ~ b / 10.
- free circular thin plate (short cylinder): the exact Kirchhoff frequency equation in Bessel functions
  J_n, I_n (Leissa, "Vibration of Plates", 1969), omega = lambda^2 / a^2 sqrt(D / (rho h)). Valid for h < a / 5.
- free elastic sphere (sphere, and compact solids as the sphere of equal volume): spheroidal modes from
  Lamb's (1882) frequency equation in spherical Bessel functions, eta = omega a / c_T. Exact for a sphere;
  for a cube or a thick cylinder it is a rough estimate (within ~20 % of the lowest mode).

Damping (docs/design/sound.md#section-3): Rayleigh d_n = (alpha + beta w_n^2) / 2; internal friction d_n = pi f_n
tan(phi); a per-mode RT60, d = 6.91 / RT60 (ln 1000 = 6.91: -60 dB).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

# internal friction tan(phi) of a material that gives neither `loss` nor `rayleigh`
DEFAULT_LOSS = 2e-3
# modes at or above this fraction of Nyquist are switched off (a resonator there aliases and rings wrong)
NYQUIST_MARGIN = 0.9
# modes below this are inaudible and would only cost time
LOWEST_FREQUENCY = 20.0
# most modes a model keeps (the lowest ones), unless a sound asks for `count`
DEFAULT_COUNT = 24
# the part of a hit's excitation that ignores where it lands: w_n = u + (1 - u) |phi_n(p)|. A real contact is
# a patch, not a point, and a real landing is never perfectly symmetric; a pure |phi_n(p)| would silence every
# antisymmetric mode of a bar that lands flat (one event at the centre of its four corners).
EXCITATION_UNIFORM = 0.5
# ln(1000): an amplitude decaying at d falls by 60 dB in 6.91 / d seconds
LN1000 = math.log(1000.0)
# slenderness above which a box or cylinder is a bar, and thinness below which it is a plate
BAR_SLENDERNESS = 4.0
PLATE_THINNESS = 0.2


@dataclass
class Modes:
    freq: np.ndarray  # (M,) Hz
    decay: np.ndarray  # (M,) 1/s
    gain: np.ndarray  # (M,) relative amplitudes
    model: str  # what made them, for `isaac plan` and the report
    shape: Callable | None = None  # body-frame point (3,) -> (M,) excitation weights in [EXCITATION_UNIFORM, 1]

    def __len__(self) -> int:
        return len(self.freq)

    def excitation(self, local_point) -> np.ndarray:
        if self.shape is None or local_point is None:
            return np.ones(len(self.freq))
        return self.shape(np.asarray(local_point, float))

    def audible(self, fs: float, count: int | None = None) -> "Modes":
        """The modes a resonator bank at rate fs can play: below NYQUIST_MARGIN * fs / 2, above 20 Hz,
        the lowest `count`; gains normalised so that they sum to 1 (a unit hit rings at about unit level)."""
        keep = (self.freq < NYQUIST_MARGIN * 0.5 * fs) & (self.freq >= LOWEST_FREQUENCY) & (self.gain != 0)
        index = np.flatnonzero(keep)
        index = index[np.argsort(self.freq[index], kind="stable")][: count or len(index)]
        gain = self.gain[index]
        total = np.sum(np.abs(gain))
        shape = self.shape
        sub = None if shape is None else (lambda p, shape=shape, index=index: shape(p)[index])
        return Modes(self.freq[index], self.decay[index], gain / total if total > 0 else gain, self.model, sub)


# ---- damping -------------------------------------------------------------------------------------------

def rayleigh_decay(freq, alpha: float, beta: float) -> np.ndarray:
    w = 2.0 * np.pi * np.asarray(freq, float)
    # d_n = (alpha + beta w_n^2) / 2
    return 0.5 * (alpha + beta * w * w)


def loss_decay(freq, loss: float) -> np.ndarray:
    # d_n = pi f_n tan(phi)
    return np.pi * np.asarray(freq, float) * loss


def rt60_decay(rt60) -> np.ndarray:
    # d = ln(1000) / RT60
    return LN1000 / np.asarray(rt60, float)


def material_decay(freq, material) -> tuple:
    """(decays, description) from a material's damping: Rayleigh if given, else internal friction."""
    if material is not None and material.rayleigh is not None:
        alpha, beta = material.rayleigh
        return rayleigh_decay(freq, alpha, beta), f"rayleigh ({alpha:g}, {beta:g})"
    loss = material.loss if material is not None and material.loss is not None else DEFAULT_LOSS
    return loss_decay(freq, loss), f"loss {loss:g}"


# ---- the free-free bar ---------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def free_free_roots(count: int) -> tuple:
    """beta_n L: roots of cos x cosh x = 1 (x > 0): 4.7300, 7.8532, 10.9956, 14.1372, 17.2788, ..."""
    roots = []
    for n in range(1, count + 1):
        # Newton on f(x) = cos x - 1 / cosh x (well scaled for large x), from (n + 1/2) pi, where root n lies
        x = (n + 0.5) * math.pi
        for _ in range(50):
            step = (math.cos(x) - 1.0 / math.cosh(x)) / (-math.sin(x) + math.tanh(x) / math.cosh(x))
            x -= step
            if abs(step) < 1e-15 * x:
                break
        roots.append(x)
    return tuple(roots)


def beam_function(x, length: float, root: float, derivative: int = 0) -> np.ndarray:
    """Free-free beam mode shape (or its 1st/2nd derivative) at x in [0, L], equal to 2 at the ends.

    phi(x) = cosh(bx) + cos(bx) - s (sinh(bx) + sin(bx)),  s = (cosh bL - cos bL) / (sinh bL - sin bL).
    The hyperbolic parts are rewritten with exponentials so that high modes do not cancel catastrophically:
    cosh(bx) - s sinh(bx) = ((1 - s) e^{bx} + (1 + s) e^{-bx}) / 2, with
    1 - s = (cos bL - sin bL - e^{-bL}) / (sinh bL - sin bL).
    """
    x = np.asarray(x, float)
    if np.ndim(root):  # several roots (x a point): the modes side by side
        one_minus, one_plus, s = _end_terms_of(tuple(np.asarray(root, float)))
        b = np.asarray(root, float) / length
    else:
        one_minus, one_plus, s = _end_terms(root)
        b = root / length
    grow, fall = np.exp(b * x), np.exp(-b * x)
    even_h = 0.5 * (one_minus * grow + one_plus * fall)  # cosh - s sinh
    odd_h = 0.5 * (one_minus * grow - one_plus * fall)  # sinh - s cosh
    c, sn = np.cos(b * x), np.sin(b * x)
    if derivative == 0:
        return even_h + c - s * sn
    if derivative == 1:
        return b * (odd_h - sn - s * c)
    return b * b * (even_h - c + s * sn)


def _end_terms(bl: float) -> tuple:
    """1 - s, 1 + s and s of beam_function for the root bl."""
    denom = math.sinh(bl) - math.sin(bl)
    one_minus = (math.cos(bl) - math.sin(bl) - math.exp(-bl)) / denom
    return one_minus, 2.0 - one_minus, 1.0 - one_minus


@functools.lru_cache(maxsize=64)
def _end_terms_of(roots: tuple) -> tuple:
    """_end_terms of several roots, as three arrays."""
    return tuple(np.array(v) for v in zip(*(_end_terms(r) for r in roots)))


def bar_modes(length: float, gyration: float, young: float, density: float, count: int = DEFAULT_COUNT,
              axis: int = 0) -> Modes:
    """Free-free Euler-Bernoulli bar along body axis `axis` (centred on the body origin)."""
    roots = np.array(free_free_roots(count))
    # f_n = (beta_n L)^2 / (2 pi L^2) * r_g * sqrt(E / rho)
    freq = roots**2 / (2.0 * np.pi * length**2) * gyration * math.sqrt(young / density)

    def shape(point, roots=roots, length=length, axis=axis):
        x = np.clip(point[axis] + 0.5 * length, 0.0, length)
        phi = beam_function(x, length, roots) * 0.5  # 1 at the free ends
        return EXCITATION_UNIFORM + (1.0 - EXCITATION_UNIFORM) * np.abs(phi)

    return Modes(freq, np.zeros(count), np.ones(count), "free-free bar", shape)


# ---- the free rectangular plate (Rayleigh-Ritz) ---------------------------------------------------------

RITZ_TERMS = 7  # beam functions per direction (2 rigid + 5 flexural): first ~15 plate modes within ~1 %
_GAUSS_POINTS = 160


def _trial_functions(length: float, terms: int) -> tuple:
    """Values and derivatives (0, 1, 2) of the trial functions at Gauss points on [0, L], and the weights:
    1, a linear function (the beam's rigid modes), then free-free beam functions."""
    xg, wg = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
    x = 0.5 * length * (xg + 1.0)
    w = 0.5 * length * wg
    roots = free_free_roots(terms - 2)
    values = np.zeros((3, terms, len(x)))
    values[0, 0] = 1.0
    values[0, 1] = 2.0 * x / length - 1.0
    values[1, 1] = 2.0 / length
    for i, root in enumerate(roots):
        for d in range(3):
            values[d, i + 2] = beam_function(x, length, root, d)
    return values, w


def _integrals(length: float, terms: int) -> dict:
    values, w = _trial_functions(length, terms)
    out = {}
    for a, b in ((0, 0), (1, 1), (2, 2), (0, 2), (2, 0)):
        out[a, b] = np.einsum("ik,jk,k->ij", values[a], values[b], w)
    return out


def plate_modes(a: float, b: float, h: float, young: float, poisson: float, density: float,
                count: int = DEFAULT_COUNT, axes: tuple = (0, 1)) -> Modes:
    """Free rectangular Kirchhoff plate a x b x h; `axes` are the body axes along a and b."""
    from scipy.linalg import eigh

    n = RITZ_TERMS
    X, Y = _integrals(a, n), _integrals(b, n)
    D = young * h**3 / (12.0 * (1.0 - poisson**2))
    nu = poisson
    # U = D/2 int [w_xx^2 + w_yy^2 + 2 nu w_xx w_yy + 2 (1 - nu) w_xy^2];  T = rho h / 2 int w_t^2
    K = D * (np.kron(X[2, 2], Y[0, 0]) + np.kron(X[0, 0], Y[2, 2])
             + nu * (np.kron(X[2, 0], Y[0, 2]) + np.kron(X[0, 2], Y[2, 0]))
             + 2.0 * (1.0 - nu) * np.kron(X[1, 1], Y[1, 1]))
    M = density * h * np.kron(X[0, 0], Y[0, 0])
    omega2, vectors = eigh(0.5 * (K + K.T), M)
    flexible = omega2 > 1e-6 * omega2.max()  # drop the three rigid-body modes (w = 1, x, y)
    omega2, vectors = omega2[flexible][:count], vectors[:, flexible][:, :count]
    freq = np.sqrt(omega2) / (2.0 * np.pi)
    peak = _plate_peaks(vectors, a, b, n)

    def shape(point, vectors=vectors, peak=peak):
        x = np.clip(point[axes[0]] + 0.5 * a, 0.0, a)
        y = np.clip(point[axes[1]] + 0.5 * b, 0.0, b)
        w = _plate_shape(vectors, x, y, a, b, n)
        return EXCITATION_UNIFORM + (1.0 - EXCITATION_UNIFORM) * np.abs(w) / peak

    return Modes(freq, np.zeros(len(freq)), np.ones(len(freq)), "free rectangular plate (Ritz)", shape)


def _basis(x: float, length: float, terms: int) -> np.ndarray:
    out = np.empty(terms)
    out[0], out[1] = 1.0, 2.0 * x / length - 1.0
    out[2:] = beam_function(x, length, np.array(free_free_roots(terms - 2)))
    return out


def _plate_shape(vectors, x, y, a, b, terms) -> np.ndarray:
    return np.kron(_basis(x, a, terms), _basis(y, b, terms)) @ vectors


def _plate_peaks(vectors, a, b, terms, grid: int = 21) -> np.ndarray:
    peak = np.zeros(vectors.shape[1])
    for x in np.linspace(0, a, grid):
        for y in np.linspace(0, b, grid):
            peak = np.maximum(peak, np.abs(_plate_shape(vectors, x, y, a, b, terms)))
    return np.where(peak > 0, peak, 1.0)


# ---- the free circular plate ----------------------------------------------------------------------------

def disc_modes(radius: float, h: float, young: float, poisson: float, density: float,
               count: int = DEFAULT_COUNT) -> Modes:
    """Free circular Kirchhoff plate: roots lambda of the free-edge frequency equation, n nodal diameters."""
    lambdas = _disc_roots(round(poisson, 4), count)
    D = young * h**3 / (12.0 * (1.0 - poisson**2))
    # omega = lambda^2 / a^2 * sqrt(D / (rho h))
    freq = np.array(lambdas) ** 2 / radius**2 * math.sqrt(D / (density * h)) / (2.0 * np.pi)
    return Modes(freq, np.zeros(len(freq)), np.ones(len(freq)), "free circular plate")


@functools.lru_cache(maxsize=16)
def _disc_roots(nu: float, count: int) -> tuple:
    from scipy.special import iv, ivp, jv, jvp

    def f(lam, n):
        # Leissa (1969) eq. 2.15, cross-multiplied so that it has no poles
        J, Jp, I, Ip = jv(n, lam), jvp(n, lam), iv(n, lam), ivp(n, lam)
        a = lam**2 * J + (1 - nu) * (lam * Jp - n * n * J)
        b = lam**2 * I - (1 - nu) * (lam * Ip - n * n * I)
        c = lam**3 * Jp + (1 - nu) * n * n * (lam * Jp - J)
        d = lam**3 * Ip - (1 - nu) * n * n * (lam * Ip - I)
        return (a * d - b * c) / (I * I)

    roots = []
    for n in range(0, 12):
        roots += _sign_changes(lambda x: f(x, n), 0.5, 14.0, 700)
    roots.sort()
    return tuple(roots[:count])


# ---- the free elastic sphere ----------------------------------------------------------------------------

def sphere_modes(radius: float, young: float, poisson: float, density: float,
                 count: int = DEFAULT_COUNT) -> Modes:
    """Spheroidal modes of a free elastic sphere (Lamb 1882): f = eta c_T / (2 pi a)."""
    shear = young / (2.0 * (1.0 + poisson))
    c_t = math.sqrt(shear / density)
    etas = _sphere_roots(round(poisson, 4), count)
    freq = np.array(etas) * c_t / (2.0 * np.pi * radius)
    return Modes(freq, np.zeros(len(freq)), np.ones(len(freq)), "free sphere (Lamb)")


@functools.lru_cache(maxsize=16)
def _sphere_roots(nu: float, count: int) -> tuple:
    """The lowest `count` roots eta of Lamb's equation for Poisson's ratio nu: from the table of
    sphere_roots.py when nu is one of its ratios (they are this function's own values, kept so that a run
    need not import scipy.special and scipy.optimize, a third of a second), else solved now."""
    from .sphere_roots import SPHERE_ROOTS

    if nu in SPHERE_ROOTS:
        return SPHERE_ROOTS[nu][:count]
    return solve_sphere_roots(nu)[:count]


def solve_sphere_roots(nu: float) -> tuple:
    """Every root eta of Lamb's equation the search finds: the fundamental and first overtone of the
    degrees l = 0..9, sorted."""
    from scipy.special import spherical_jn

    ratio = math.sqrt((1.0 - 2.0 * nu) / (2.0 * (1.0 - nu)))  # c_T / c_L

    def f(eta, l):
        xi = eta * ratio  # omega a / c_L
        if l == 0:
            # breathing mode: 4 (c_T/c_L)^2 j1(xi) = xi j0(xi)
            return 4.0 * ratio**2 * spherical_jn(1, xi) - xi * spherical_jn(0, xi)
        je, jx = spherical_jn(l, eta), spherical_jn(l, xi)
        qe, qx = eta * spherical_jn(l + 1, eta), xi * spherical_jn(l + 1, xi)
        # Lamb's equation multiplied by j_l(eta) j_l(xi):
        # 2 [eta^2 + (l-1)(l+2)(eta j_{l+1}/j_l - (l+1))] xi j_{l+1}/j_l - eta^4/2 + (l-1)(2l+1) eta^2
        #   + [eta^2 - 2 l (l-1)(l+2)] eta j_{l+1}/j_l = 0        (j_{l+1}/j_l at eta or xi as written)
        return (2.0 * (eta**2 * je + (l - 1) * (l + 2) * (qe - (l + 1) * je)) * qx
                - (0.5 * eta**4 - (l - 1) * (2 * l + 1) * eta**2) * je * jx
                + (eta**2 - 2 * l * (l - 1) * (l + 2)) * qe * jx)

    roots = []
    for l in range(0, 10):
        found = _sign_changes(lambda x: f(x, l), 0.3, 16.0, 800)
        roots += found[:2]  # the fundamental and first overtone of each degree
    roots.sort()
    return tuple(roots)


def _sign_changes(f, lo: float, hi: float, samples: int) -> list:
    from scipy.optimize import brentq

    xs = np.linspace(lo, hi, samples)
    values = f(xs)  # f takes arrays: one vectorised pass over the grid, brentq only where the sign changes
    # the functions searched here are written without poles, so every sign change brackets a root
    return [brentq(f, xs[i], xs[i + 1], xtol=1e-12)
            for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)]


# ---- choosing a model from a body ----------------------------------------------------------------------

class ModalError(ValueError):
    """A body whose modes cannot be derived (no material stiffness, a plane, a mesh): says what to add."""


def body_modes(body, material, model: str = "auto", count: int = DEFAULT_COUNT, inner: float | None = None,
               damping: dict | None = None) -> Modes:
    """The modes of a body: its `modes` table if the scene gives one, else a model from shape and material.

    damping: {"rt60": s} or {"loss": tan phi} or {"rayleigh": (alpha, beta)} overrides the material's.
    """
    if body.modes and model in ("auto", "table"):
        table = np.asarray(body.modes, float)
        modes = Modes(table[:, 0], table[:, 1], table[:, 2], "scene modes")
        return _damped(modes, material, damping, keep_table=True)
    modes = _shape_modes(body, material, model, count, inner)
    return _damped(modes, material, damping, keep_table=False)


def _shape_modes(body, material, model: str, count: int, inner: float | None) -> Modes:
    shape = body.shape
    if material is None or material.young is None or (material.density is None and body.mass is None):
        raise ModalError(f"body `{body.name}` has no modes: give it `modes ((f, decay, gain), ...)` or a "
                         f"material with `young` and `density`")
    E, nu = material.young, material.poisson
    rho = material.density if material.density is not None else _density(body)
    kind = model if model != "auto" else _auto_model(shape)
    if kind == "bar":
        return _bar_of(shape, E, rho, count, inner)
    if kind == "plate":
        if shape.type == "cylinder":
            return disc_modes(shape.radius, shape.length, E, nu, rho, count)
        order = np.argsort(shape.size)[::-1]
        a, b, h = (shape.size[i] for i in order)
        return plate_modes(a, b, h, E, nu, rho, count, axes=(int(order[0]), int(order[1])))
    if kind == "sphere":
        return sphere_modes(_equivalent_radius(shape), E, nu, rho, count)
    raise ModalError(f"body `{body.name}` ({shape.type}) has no modal model: give it `modes ((f, decay, gain), ...)`")


def _auto_model(shape) -> str:
    if shape.type == "sphere":
        return "sphere"
    if shape.type == "box":
        e = sorted(shape.size, reverse=True)
        if e[0] >= BAR_SLENDERNESS * e[1]:
            return "bar"
        if e[2] <= PLATE_THINNESS * e[1]:
            return "plate"
        return "sphere"
    if shape.type in ("cylinder", "capsule"):
        if shape.length >= BAR_SLENDERNESS * 2.0 * shape.radius:
            return "bar"
        if shape.type == "cylinder" and shape.length <= PLATE_THINNESS * 2.0 * shape.radius:
            return "plate"
        return "sphere"
    return "none"


def _bar_of(shape, E, rho, count, inner) -> Modes:
    if shape.type == "box":
        order = np.argsort(shape.size)[::-1]
        length, thin = shape.size[order[0]], shape.size[order[2]]
        return bar_modes(length, thin / math.sqrt(12.0), E, rho, count, axis=int(order[0]))
    if shape.type in ("cylinder", "capsule"):
        r = shape.radius
        # r_g = sqrt(I / A): R / 2 for a rod, sqrt(R^2 + R_i^2) / 2 for a tube
        gyration = math.sqrt(r * r + (inner or 0.0) ** 2) / 2.0
        return bar_modes(shape.length, gyration, E, rho, count, axis=2)
    raise ModalError(f"a {shape.type} is not a bar")


def _equivalent_radius(shape) -> float:
    from isaac_ir.mass import volume

    if shape.type == "sphere":
        return shape.radius
    # the sphere of equal volume: a rough stand-in for a compact solid
    return (3.0 * volume(shape) / (4.0 * math.pi)) ** (1.0 / 3.0)


def _density(body) -> float:
    from isaac_ir.mass import volume

    return body.mass / volume(body.shape)


def _damped(modes: Modes, material, damping: dict | None, keep_table: bool) -> Modes:
    damping = damping or {}
    if "rt60" in damping:
        decay = np.broadcast_to(rt60_decay(damping["rt60"]), modes.freq.shape).copy()
    elif "loss" in damping:
        decay = loss_decay(modes.freq, damping["loss"])
    elif "rayleigh" in damping:
        decay = rayleigh_decay(modes.freq, *damping["rayleigh"])
    elif keep_table:
        return modes
    else:
        decay, _ = material_decay(modes.freq, material)
    return Modes(modes.freq, decay, modes.gain, modes.model, modes.shape)
