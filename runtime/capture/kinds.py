"""The pairs of shape kinds that the compiled narrow phase (narrow.py) has a closed form for, as plain Python: a
scene's plan asks whether it may take the capturing path (`eligible`) without importing the compiled kernels,
which only a run that takes it needs (14 ms of every other run's start).
"""
from __future__ import annotations

from ..core.model import SHAPE_BOX, SHAPE_CAPSULE, SHAPE_CYLINDER, SHAPE_PLANE, SHAPE_SPHERE

HANDLED = {(SHAPE_SPHERE, k) for k in (SHAPE_SPHERE, SHAPE_PLANE, SHAPE_BOX, SHAPE_CAPSULE, SHAPE_CYLINDER)} | {
    (SHAPE_BOX, SHAPE_BOX), (SHAPE_BOX, SHAPE_PLANE), (SHAPE_CAPSULE, SHAPE_CAPSULE), (SHAPE_CAPSULE, SHAPE_PLANE),
    (SHAPE_CAPSULE, SHAPE_BOX), (SHAPE_CYLINDER, SHAPE_PLANE), (SHAPE_CYLINDER, SHAPE_BOX),
    (SHAPE_CYLINDER, SHAPE_CYLINDER), (SHAPE_CYLINDER, SHAPE_CAPSULE)}


# a compound pair's contacts are keyed, in the capturing loop, by their shape's local feature plus this many times
# the number of their pair of parts (compound.fold): every local feature is below it (boxes.py's largest is
# EDGE + 10 = 4618), and a pair of bodies may have at most data.FEATURES / LOCAL_FEATURES = 2048 pairs of parts
LOCAL_FEATURES = 1 << 13


def closed_form(kind_a: int, kind_b: int) -> bool:
    """Whether narrow.pair_contacts handles a pair of shape kinds (in either order)."""
    return (int(kind_a), int(kind_b)) in HANDLED or (int(kind_b), int(kind_a)) in HANDLED
