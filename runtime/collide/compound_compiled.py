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
from .shapes import KINDS, NONE

# contacts the buffers hold at first (grown to what a call asks for)
FIRST_CAPACITY = 64


class CompiledCompound:
    """The compiled phase over a scene's elements (shapes.Elements)."""

    def __init__(self, elements):
        from ..capture import compound as kernels
        from ..capture.narrow import closed_form as compiled_closed_form

        self.kernels, table = kernels, elements.table
        kinds = range(max(KINDS.values()) + 1)
        order = np.full((len(kinds), len(kinds)), kernels.NO_TEST, np.int64)
        for ka in kinds:
            for kb in kinds:
                test = closed_form(ka, kb)
                if test is not None and compiled_closed_form(ka, kb):
                    order[ka, kb] = kernels.SWAP if test[1] else kernels.KEEP
        self.order = order
        shapes = Shapes(*(np.ascontiguousarray(a) for a in (table.kind.astype(np.int64), table.radius, table.half,
                                                          table.half_length, table.normal, table.centre)))
        self.parts = kernels.Parts(shapes, *(np.ascontiguousarray(a) for a in (
            elements.owner.astype(np.int64), elements.index.astype(np.int64), elements.offset, elements.turn,
            elements.first.astype(np.int64), elements.count.astype(np.int64), order)))
        count = len(elements.owner)
        # the most element pairs of one pair of bodies: the two largest bodies' counts of elements
        largest = np.sort(np.maximum(elements.count, 1))[-2:]
        self.poses = kernels.Poses(np.zeros((count, 3)), np.zeros((count, 3, 3)), np.zeros((count, 6)),
                                   np.zeros(int(np.prod(largest))))
        self.out = self._buffers(FIRST_CAPACITY)
        self.work = np.zeros((16, 4))
        self.none_known = np.zeros(0, np.int64)
        self.call = Bound(kernels.compound_pair)
        self._kinds = [set(table.kind[elements.of(b)].tolist()) for b in range(len(elements.first))]
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
