"""The compiled narrow phase of the pairs with a compound body (runtime/capture/compound.py), driven from Python:
the buffers it writes into, and the pairs it takes. compound.py's CompoundPairs hands it every pair of bodies whose
part pairs all have a closed form in both phases (narrow.py here, capture/narrow.py compiled), and keeps the others
(a mesh part, a cylinder against a box: python-fcl) itself. The answers are the Python phase's: the same element
pairs, tested in the same order with the same order of bodies (checked at every call of the clock's first 8 s:
the same contacts within 6e-14 m), the same features but for a pair of boxes' (capture/boxes.py names a clipped
vertex by the lines it lies on, an edge contact EDGE + 3 i + j), which key a contact as consistently.
"""
from __future__ import annotations

import numpy as np

from ..core.jit import Bound
from ..core.model import Shapes
from .narrow import closed_form
from .shapes import CAPSULE, CORNER_SIGNS, CYLINDER, KINDS, NONE, SPHERE

# contacts the buffers hold at first (grown to what a call asks for)
FIRST_CAPACITY = 64


def compound_arrays(elements) -> tuple:
    """(Parts, Poses) of capture/compound.py for a scene's elements: the plan's arrays, read only, and the
    scratch of the element poses (the exact path's CompiledCompound and the capturing loop each hold their own)."""
    from ..capture import compound as kernels

    table = elements.table
    shapes = Shapes(*(np.ascontiguousarray(a) for a in (table.kind.astype(np.int64), table.radius, table.half,
                                                      table.half_length, table.normal, table.centre)))
    parts = kernels.Parts(shapes, *(np.ascontiguousarray(a) for a in (
        elements.owner.astype(np.int64), elements.index.astype(np.int64), elements.offset, elements.turn,
        elements.first.astype(np.int64), elements.count.astype(np.int64), _order(kernels),
        farthest(elements).astype(float))))
    count = len(elements.owner)
    # the most element pairs of one pair of bodies: the two largest bodies' counts of elements
    largest = np.sort(np.maximum(elements.count, 1))[-2:]
    poses = kernels.Poses(np.zeros((count, 3)), np.zeros((count, 3, 3)), np.zeros((count, 6)),
                          np.zeros(int(np.prod(largest))))
    return parts, poses


def _order(kernels) -> np.ndarray:
    """(7,7) the Python phase's order of each pair of kinds both phases test (KEEP, SWAP), else NO_TEST."""
    from ..capture.narrow import closed_form as compiled_closed_form

    kinds = range(max(KINDS.values()) + 1)
    order = np.full((len(kinds), len(kinds)), kernels.NO_TEST, np.int64)
    for ka in kinds:
        for kb in kinds:
            test = closed_form(ka, kb)
            if test is not None and compiled_closed_form(ka, kb):
                order[ka, kb] = kernels.SWAP if test[1] else kernels.KEEP
    return order


def farthest(elements) -> np.ndarray:
    """(n,) how far each compound body's farthest point lies from its centre of mass (0: a body that is its own
    shape): over its parts, a box's (or a mesh's local box's) farthest corner, a sphere's centre or a capsule's
    or cylinder's axis end plus the radius (for a cylinder a bound: its rim lies within it)."""
    table, n = elements.table, len(elements.first)
    reach = np.zeros(n)
    for e in range(n, len(elements.owner)):
        kind, offset, turn = table.kind[e], elements.offset[e], elements.turn[e]
        if kind in (SPHERE, CAPSULE, CYLINDER):
            # ends o -/+ hl z (a sphere: hl = 0), each with the radius about it: |o +- hl z| + r
            ends = offset + np.outer((-1.0, 1.0), table.half_length[e] * turn[:, 2])
            far = np.linalg.norm(ends, axis=1).max() + table.radius[e]
        elif np.isfinite(table.half[e]).all():
            # the local box's corners o + T (c + s h), s in {-1, 1}^3
            corners = offset + (table.centre[e] + CORNER_SIGNS * table.half[e]) @ turn.T
            far = np.linalg.norm(corners, axis=1).max()
        else:
            far = 0.0  # (a plane: none of its points comes nearer by turning)
        owner = int(elements.owner[e])
        reach[owner] = max(reach[owner], far)
    return reach


class CompiledCompound:
    """The compiled phase over a scene's elements (shapes.Elements)."""

    def __init__(self, elements):
        from ..capture import compound as kernels

        self.kernels = kernels
        self.parts, self.poses = compound_arrays(elements)
        self.order = self.parts.order
        self.out = self._buffers(FIRST_CAPACITY)
        self.work = np.zeros((16, 4))
        self.none_known = np.zeros(0, np.int64)
        self.call = Bound(kernels.compound_pair)
        self._kinds = [set(elements.table.kind[elements.of(b)].tolist()) for b in range(len(elements.first))]
        self._takes = {}

    def _buffers(self, capacity: int):
        return self.kernels.Found(np.zeros((capacity, 3)), np.zeros((capacity, 3)), np.zeros(capacity),
                                  np.zeros(capacity, np.int64), np.zeros(capacity, np.int64),
                                  np.zeros(capacity, np.int64))

    def takes(self, i: int, j: int) -> bool:
        """Whether every element pair of bodies i and j has a closed form in both phases."""
        key = (i, j)
        if key not in self._takes:
            self._takes[key] = all(self.order[ka, kb] != self.kernels.NO_TEST
                                   for ka in self._kinds[i] - {NONE} for kb in self._kinds[j] - {NONE})
        return self._takes[key]

    def contacts(self, i: int, j: int, x, R, margin: float) -> tuple:
        """(points, normals, depths, features, a (k,), b (k,)) of bodies i and j, as CompoundPairs.contacts."""
        x, R = np.ascontiguousarray(x, float), np.ascontiguousarray(R, float)
        count = self._call(i, j, x, R, margin, self.kernels.CONTACTS, self.none_known)[0]
        if count > len(self.out.depth):  # (it wrote what fitted: again, into buffers that hold them all)
            self.out = self._buffers(2 * count)
            count = self._call(i, j, x, R, margin, self.kernels.CONTACTS, self.none_known)[0]
        o = self.out
        return (o.point[:count].copy(), o.normal[:count].copy(), o.depth[:count].copy(), o.feature[:count].copy(),
                o.a[:count].copy(), o.b[:count].copy())

    def nearest(self, i: int, j: int, x, R, known=frozenset()) -> tuple:
        """(signed distance of bodies i and j, the world point of the feature that gives it, or None), as
        CompoundPairs.nearest."""
        x, R = np.ascontiguousarray(x, float), np.ascontiguousarray(R, float)
        known = np.array(sorted(known), np.int64) if known else self.none_known
        found, best = self._call(i, j, x, R, np.inf, self.kernels.NEAREST, known)
        return float(best), (self.out.point[0].copy() if found else None)

    def _call(self, i, j, x, R, margin, mode, known):
        return self.call(self.parts, self.poses, x, R, int(i), int(j), float(margin), mode, known, self.out, self.work)
