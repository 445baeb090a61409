"""Units and dimensions. Every quantity is converted to SI when the scene is lowered.

A dimension is a tuple of exponents (metre, kilogram, second, radian). Radians are tracked so that an angular
velocity in Hz (cycles per second) is not silently taken for rad/s. A bare number has no dimension yet
(`None`): it adapts to whatever it is added to, and a slot decides what a bare number means there.
"""
from __future__ import annotations

import functools
import math
import re

Dim = tuple  # (m, kg, s, rad)

DIMENSIONLESS: Dim = (0, 0, 0, 0)
LENGTH: Dim = (1, 0, 0, 0)
MASS: Dim = (0, 1, 0, 0)
TIME: Dim = (0, 0, 1, 0)
ANGLE: Dim = (0, 0, 0, 1)
FREQUENCY: Dim = (0, 0, -1, 0)
VELOCITY: Dim = (1, 0, -1, 0)
ACCELERATION: Dim = (1, 0, -2, 0)
ANGULAR_VELOCITY: Dim = (0, 0, -1, 1)
DENSITY: Dim = (-3, 1, 0, 0)
FORCE: Dim = (1, 1, -2, 0)
TORQUE: Dim = (2, 1, -2, 0)
STIFFNESS: Dim = (0, 1, -2, 0)
DAMPING: Dim = (0, 1, -1, 0)
PRESSURE: Dim = (-1, 1, -2, 0)
AREA: Dim = (2, 0, 0, 0)
INERTIA: Dim = (2, 1, 0, 0)

# unit -> (factor to SI, dimension)
UNITS: dict[str, tuple[float, Dim]] = {
    "m": (1.0, LENGTH),
    "km": (1e3, LENGTH),
    "cm": (1e-2, LENGTH),
    "mm": (1e-3, LENGTH),
    "um": (1e-6, LENGTH),
    "kg": (1.0, MASS),
    "g": (1e-3, MASS),
    "s": (1.0, TIME),
    "ms": (1e-3, TIME),
    "us": (1e-6, TIME),
    "min": (60.0, TIME),
    "rad": (1.0, ANGLE),
    "deg": (math.pi / 180.0, ANGLE),
    "Hz": (1.0, FREQUENCY),
    "kHz": (1e3, FREQUENCY),
    "N": (1.0, FORCE),
    "J": (1.0, (2, 1, -2, 0)),
    "W": (1.0, (2, 1, -3, 0)),
    "Pa": (1.0, PRESSURE),
    "kPa": (1e3, PRESSURE),
    "MPa": (1e6, PRESSURE),
    "GPa": (1e9, PRESSURE),
    # decibels are a gain, converted to a linear amplitude factor where a gain is due
    "dB": (1.0, DIMENSIONLESS),
}

DIM_NAMES = {
    DIMENSIONLESS: "a plain number",
    LENGTH: "a length",
    MASS: "a mass",
    TIME: "a time",
    ANGLE: "an angle",
    FREQUENCY: "a frequency",
    VELOCITY: "a velocity",
    ACCELERATION: "an acceleration",
    ANGULAR_VELOCITY: "an angular velocity",
    DENSITY: "a density",
    FORCE: "a force",
    TORQUE: "a torque",
    STIFFNESS: "a stiffness",
    DAMPING: "a damping coefficient",
    PRESSURE: "a pressure",
    AREA: "an area",
    INERTIA: "a moment of inertia",
}

# what a writer would type for each kind of quantity, for hints
EXAMPLE_UNIT = {
    LENGTH: "m",
    MASS: "kg",
    TIME: "s",
    ANGLE: "deg",
    FREQUENCY: "Hz",
    VELOCITY: "m/s",
    ACCELERATION: "m/s2",
    ANGULAR_VELOCITY: "rad/s",
    DENSITY: "kg/m3",
    FORCE: "N",
    TORQUE: "N*m",
    STIFFNESS: "N/m",
    DAMPING: "N*s/m",
    PRESSURE: "GPa",
    AREA: "m2",
    INERTIA: "kg*m2",
}

# the SI unit a number without a unit is read in, as a writer would type it
SI_UNIT = {**EXAMPLE_UNIT, ANGLE: "rad", PRESSURE: "Pa"}
# another unit of the same quantity a writer often means, for hints
OTHER_UNIT = {LENGTH: "cm", TIME: "ms", VELOCITY: "cm/s", ACCELERATION: "cm/s2", ANGLE: "deg",
              ANGULAR_VELOCITY: "deg/s", MASS: "g"}

_FACTOR = re.compile(r"([*/]?)([A-Za-z]+)\^?(-?[0-9])?")


class UnitError(ValueError):
    pass


@functools.lru_cache(maxsize=1024)
def parse_unit(text: str) -> tuple[float, Dim]:
    """'kg/m3' -> (1.0, DENSITY); 'N*s/m' -> (1.0, DAMPING). Raises UnitError for an unknown unit."""
    factor, dim = 1.0, [0, 0, 0, 0]
    pos = 0
    for match in _FACTOR.finditer(text):
        if match.start() != pos:
            raise UnitError(f"cannot read unit `{text}`")
        pos = match.end()
        op, name, power = match.group(1), match.group(2), match.group(3)
        if name not in UNITS:
            raise UnitError(f"unknown unit `{name}`")
        scale, base = UNITS[name]
        exponent = int(power) if power else 1
        if op == "/":
            exponent = -exponent
        factor *= scale**exponent
        for axis in range(4):
            dim[axis] += base[axis] * exponent
    if pos != len(text):
        raise UnitError(f"cannot read unit `{text}`")
    return factor, tuple(dim)


def without_angle(dim: Dim | None):
    """The dimension with radians dropped (they are dimensionless in SI; the language keeps them apart only so
    that a bare angle means degrees and Hz is not read as rad/s)."""
    return None if dim is None else (dim[0], dim[1], dim[2], 0)


def describe(dim: Dim | None) -> str:
    if dim is None:
        return "a number without unit"
    if dim in DIM_NAMES:
        return DIM_NAMES[dim]
    return "a quantity in " + format_dim(dim)


def format_dim(dim: Dim) -> str:
    names = ("m", "kg", "s", "rad")
    up = [f"{n}{e if e != 1 else ''}" for n, e in zip(names, dim) if e > 0]
    down = [f"{n}{-e if e != -1 else ''}" for n, e in zip(names, dim) if e < 0]
    text = "*".join(up) or "1"
    return text + ("/" + "/".join(down) if down else "")


def combine(a: Dim | None, b: Dim | None, sign: int) -> Dim | None:
    """Dimension of a product (sign +1) or quotient (sign -1)."""
    if a is None and b is None:
        return None
    a = a or DIMENSIONLESS
    b = b or DIMENSIONLESS
    return tuple(x + sign * y for x, y in zip(a, b))


def scale_dim(a: Dim | None, k: float) -> Dim | None:
    if a is None:
        return None
    scaled = tuple(x * k for x in a)
    if any(abs(x - round(x)) > 1e-12 for x in scaled):
        raise UnitError(f"{describe(a)} cannot be raised to the power {k:g}")
    return tuple(int(round(x)) for x in scaled)


def unify(a: Dim | None, b: Dim | None) -> Dim | None:
    """Dimension of a sum: both must agree, a bare number adapts. Raises UnitError on a mismatch."""
    if a is None:
        return b
    if b is None or a == b:
        return a
    raise UnitError(f"cannot add {describe(a)} and {describe(b)}")
