"""Volume and inertia of the primitive shapes, about the centre of mass, in body axes.

Cylinders and capsules have their axis along body z. Formulas: standard solid-body results (e.g. any
mechanics handbook); the capsule is a cylinder plus two hemispheres whose centres of mass sit 3r/8 from the
flat face (parallel-axis theorem).
"""
from __future__ import annotations

import math


def volume(shape) -> float | None:
    if shape.type == "sphere":
        return 4.0 / 3.0 * math.pi * shape.radius**3
    if shape.type == "box":
        a, b, c = shape.size
        return a * b * c
    if shape.type == "cylinder":
        return math.pi * shape.radius**2 * shape.length
    if shape.type == "capsule":
        return math.pi * shape.radius**2 * shape.length + 4.0 / 3.0 * math.pi * shape.radius**3
    return None  # plane: infinite; mesh: computed from the file by the runtime


def inertia(shape, mass: float) -> tuple | None:
    """Principal moments (Ixx, Iyy, Izz) of a solid of uniform density."""
    if shape.type == "sphere":
        # I = 2/5 m r^2
        i = 0.4 * mass * shape.radius**2
        return (i, i, i)
    if shape.type == "box":
        a, b, c = shape.size
        # I_xx = m (b^2 + c^2) / 12, and cyclically
        return (mass * (b * b + c * c) / 12.0, mass * (a * a + c * c) / 12.0, mass * (a * a + b * b) / 12.0)
    if shape.type == "cylinder":
        r, h = shape.radius, shape.length
        # I_zz = m r^2 / 2;  I_xx = I_yy = m (3 r^2 + h^2) / 12
        side = mass * (3 * r * r + h * h) / 12.0
        return (side, side, 0.5 * mass * r * r)
    if shape.type == "capsule":
        return _capsule_inertia(shape.radius, shape.length, mass)
    return None


def _capsule_inertia(r: float, h: float, mass: float) -> tuple:
    v_cyl = math.pi * r * r * h
    v_caps = 4.0 / 3.0 * math.pi * r**3
    m_cyl = mass * v_cyl / (v_cyl + v_caps)
    m_hemi = 0.5 * (mass - m_cyl)
    # axial: cylinder m r^2/2 + two hemispheres 2/5 m r^2 each
    axial = 0.5 * m_cyl * r * r + 2 * 0.4 * m_hemi * r * r
    # transverse: hemisphere about its own centre of mass (83/320 m r^2), moved by h/2 + 3r/8
    offset = 0.5 * h + 3.0 * r / 8.0
    hemi = (83.0 / 320.0) * m_hemi * r * r + m_hemi * offset**2
    side = m_cyl * (3 * r * r + h * h) / 12.0 + 2 * hemi
    return (side, side, axial)


def diagonal(moments: tuple) -> tuple:
    a, b, c = moments
    return ((a, 0.0, 0.0), (0.0, b, 0.0), (0.0, 0.0, c))
