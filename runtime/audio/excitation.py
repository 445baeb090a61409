"""Audio stage, excitation: how long a contact lasts, and the force pulse it puts into the modes.

A real contact lasts a time tau, which low-passes the excitation (docs/design/sound.md#section-5). The pulse is a
half-sine of length tau: its spectrum falls by 3 dB near 0.59 / tau and has its first null at 1.5 / tau.

Contact duration, in order of preference:
- Hertz, when at least one of the two surfaces is curved (sphere, cylinder, capsule) and the materials give
  Young's moduli:  tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5), with
  m* = m1 m2 / (m1 + m2) (a static body: m* = m1), R* = R1 R2 / (R1 + R2) (flat: R = infinity),
  1 / E* = (1 - nu1^2) / E1 + (1 - nu2^2) / E2 (no material, or a static floor: rigid, term 0),
  v the normal approach speed. Valid for elastic impacts well below the yield speed.
- the cheap rule tau = min(0.001 s/kg * m_min, 2 ms) otherwise (flat on flat, missing moduli).
Either is clamped to [1 sample, 5 ms].
"""
from __future__ import annotations

import math

import numpy as np

# tau = min(RULE_SECONDS_PER_KG * m_min, RULE_MAX)
RULE_SECONDS_PER_KG = 1e-3
RULE_MAX = 2e-3
# a contact never lasts longer than this (a soft, slow contact is a push, not a hit)
LONGEST_CONTACT = 5e-3
CURVED = ("sphere", "cylinder", "capsule")


def hertz_duration(m_eff: float, r_eff: float, e_eff: float, speed: float) -> float:
    # tau = 2.87 (m*^2 / (R* E*^2 v))^(1/5)
    return 2.87 * (m_eff**2 / (r_eff * e_eff**2 * speed)) ** 0.2


def rule_duration(m_min: float) -> float:
    # tau = min(0.001 m_min, 2 ms)
    return min(RULE_SECONDS_PER_KG * m_min, RULE_MAX)


def contact_duration(a: dict, b: dict | None, speed: float, fs: float) -> float:
    """tau of a contact between bodies described by {mass (inf if static), radius (inf if flat),
    young, poisson (None if unknown)}; b is None for the world."""
    b = b or {"mass": math.inf, "radius": math.inf, "young": None, "poisson": 0.3}
    tau = None
    curved = min(a["radius"], b["radius"]) < math.inf
    moduli = [x for x in (a, b) if x["young"] is not None]
    if curved and moduli and speed > 1e-6 and (a["mass"] < math.inf or b["mass"] < math.inf):
        m_eff = _series(a["mass"], b["mass"])
        r_eff = _series(a["radius"], b["radius"])
        compliance = sum((1.0 - x["poisson"] ** 2) / x["young"] for x in moduli)
        tau = hertz_duration(m_eff, r_eff, 1.0 / compliance, speed)
    if tau is None:
        tau = rule_duration(min(a["mass"], b["mass"]))
    return float(np.clip(tau, 1.0 / fs, LONGEST_CONTACT))


def _series(x: float, y: float) -> float:
    """x y / (x + y), with infinity as the neutral element."""
    if x == math.inf:
        return y
    if y == math.inf:
        return x
    return x * y / (x + y)


def body_contact_properties(body, material) -> dict:
    """What contact_duration needs of one body."""
    shape = body.shape
    radius = shape.radius if shape.type in CURVED and shape.radius else math.inf
    mass = body.mass if body.motion == "dynamic" and body.mass else math.inf
    young = material.young if material is not None else None
    poisson = material.poisson if material is not None else 0.3
    return {"mass": mass, "radius": radius, "young": young, "poisson": poisson}


def half_sine(tau: float, fs: float, area: bool = True) -> np.ndarray:
    """The contact pulse: L = round(tau fs) samples (at least 1) of a half-sine sampled at mid-points,
    x[j] = sin(pi (j + 1/2) / L), so that its first sample is already non-zero (the onset is exact).
    area=True: scaled to unit sum (a unit impulse); else to unit peak."""
    length = max(1, int(round(tau * fs)))
    x = np.sin(np.pi * (np.arange(length) + 0.5) / length)
    return x / (x.sum() if area else x.max())
