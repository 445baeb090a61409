"""Narrow phase of pairs with a compound body: each part of one body against each part (or the shape) of the
other, with the tests of narrow.py / boxes.py / meshes.py, at the part's world pose x_body + R_body offset,
R_body turn (shapes.Elements).

A contact keeps the conventions of narrow.py (point midway, normal from b toward a, depth), and body a and b are
the bodies of the parts the test was given, in the order it wants them (a sphere part first against a box): one
pair of bodies may so have contacts in both orders, each consistent on its own. Its feature names both parts
(shapes.PART_SHIFT), so that a contact stays keyed to its part and its corner from one look to the next.

Only part pairs whose boxes come within the margin are tested; a distance (margin inf) tests the part pairs in
the order of their boxes' gap, a lower bound of their distance, and stops at the first gap beyond the nearest
distance found.

A pair of bodies whose part pairs all have a closed form is tested in compiled code (compound_compiled.py, the
same steps with capture/narrow.py's tests: the clock's escape wheel against its anchor, 95 x 9 parts, 25 s -> 10 s
of its run); the Python steps below take the pairs with a part python-fcl must test.
"""
from __future__ import annotations

import math

import numpy as np

from .narrow import closed_form
from .shapes import PART_BITS, PART_SHIFT, PLANE, Elements, boxes_of

EMPTY = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64),
         np.zeros(0, np.int64))


def encode(local, part_a, part_b):
    """The feature of a contact of part part_a of body a (-1: a itself) and part_b of body b."""
    return (np.asarray(local, np.int64) | ((part_a + 1) << PART_SHIFT) | ((part_b + 1) << (PART_SHIFT + PART_BITS)))


def contact_elements(elements: Elements | None, a, b, feature) -> tuple:
    """(ea, eb) (k,): the elements (parts, or the bodies themselves) of contacts of bodies a, b."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    if elements is None:
        return a, b
    from .shapes import part_of

    pa, pb = part_of(feature, 0), part_of(feature, 1)
    ea = np.where(pa >= 0, elements.first[a] + pa, a)
    eb = np.where(pb >= 0, elements.first[b] + pb, b)
    return ea, eb


class CompoundPairs:
    """The narrow phase of the pairs that involve a compound body; fcl: meshes.FclPairs over the elements (for
    part pairs without a closed form), or None."""

    def __init__(self, elements: Elements, fcl=None):
        self.el, self.fcl = elements, fcl
        count = len(elements.owner)
        self.X, self.RX = np.zeros((count, 3)), np.tile(np.eye(3), (count, 1, 1))  # element poses (scratch)
        self._posed = {}  # body -> (its pose as bytes, its elements, their boxes lo, hi): what X, RX hold of it
        # the pairs whose part pairs all have a closed form are tested in compiled code (compound_compiled.py)
        from .compound_compiled import CompiledCompound

        self.compiled = CompiledCompound(elements)

    def _pose(self, body: int, x, R) -> tuple:
        """The world poses of a body's elements into X, RX, and their boxes: (elements, lo, hi). Remembered for
        the pose they were computed at: a look asks for a body's at one pose for each pair it is in, for the
        contacts and again for the distance."""
        pose = x[body].tobytes() + R[body].tobytes()
        known = self._posed.get(body)
        if known is not None and known[0] == pose:
            return known[1:]
        mine = self.el.of(body)
        self.X[mine] = x[body] + self.el.offset[mine] @ R[body].T
        self.RX[mine] = R[body] @ self.el.turn[mine]
        lo, hi = boxes_of(self.el.table, mine, self.X[mine], self.RX[mine], 0.0)
        self._posed[body] = (pose, mine, lo, hi)
        return mine, lo, hi

    def _candidates(self, i, j, x, R, margin):
        """Element pairs (ea, eb) of bodies i, j with their boxes' gap (a lower bound of their distance)."""
        (ei, lo_i, hi_i), (ej, lo_j, hi_j) = self._pose(i, x, R), self._pose(j, x, R)
        table = self.el.table
        grow = 0.0 if not math.isfinite(margin) else margin
        # boxes grown by the margin on every side: their gap shrinks by twice the margin
        with np.errstate(invalid="ignore"):  # a plane's box is infinite (its gap is set below)
            gap = np.maximum(lo_j[None] - hi_i[:, None], lo_i[:, None] - hi_j[None]).max(axis=2) - 2.0 * grow
        gap[(table.kind[ei] == PLANE)[:, None] | (table.kind[ej] == PLANE)[None]] = -np.inf
        a, b = np.nonzero(gap <= 0.0) if math.isfinite(margin) else np.indices(gap.shape).reshape(2, -1)
        return ei[a], ej[b], gap[a, b]

    def _test(self, ea: int, eb: int, margin: float):
        """One element pair: (points, normals, depths, features, body a, body b), features naming the parts."""
        table = self.el.table
        test = closed_form(table.kind[ea], table.kind[eb])
        if test is None:
            found, (a, b) = self.fcl.contacts(ea, eb, self.X, self.RX, margin), (ea, eb)
        else:
            function, swapped = test
            a, b = (eb, ea) if swapped else (ea, eb)
            found = function(table, a, b, self.X, self.RX, margin)
        points, normals, depths, features = found
        k = len(depths)
        feature = encode(features, self.el.index[a], self.el.index[b])
        return (points, normals, depths, feature, np.full(k, self.el.owner[a], np.int64),
                np.full(k, self.el.owner[b], np.int64))

    def contacts(self, i: int, j: int, x, R, margin: float):
        """Contacts of bodies i and j: (points, normals, depths, features, a (k,), b (k,))."""
        if self.compiled.takes(i, j):
            return self.compiled.contacts(i, j, x, R, margin)
        # with margin inf, every part pair (each test then gives its closest feature: what a distance needs)
        found = [self._test(int(a), int(b), margin) for a, b, _ in zip(*self._candidates(i, j, x, R, margin))]
        found = [f for f in found if len(f[2])]
        if not found:
            return EMPTY
        return tuple(np.concatenate(column) for column in zip(*found))

    def distance(self, i: int, j: int, x, R, known=frozenset()) -> float:
        """Signed distance of bodies i and j (negative: interpenetrating); with `known`, of their other features."""
        return self.nearest(i, j, x, R, known)[0]

    def nearest(self, i: int, j: int, x, R, known=frozenset()) -> tuple:
        """(signed distance of bodies i and j, the world point of the feature that gives it, or None without
        one); with `known`, of their other features."""
        if self.compiled.takes(i, j):
            return self.compiled.nearest(i, j, x, R, known)
        ea, eb, gap = self._candidates(i, j, x, R, math.inf)
        best, where = math.inf, None
        for k in np.argsort(gap, kind="stable"):
            if gap[k] > best:
                break  # no part pair further on can come nearer than its boxes' gap
            points, _, depths, features, _, _ = self._test(int(ea[k]), int(eb[k]), math.inf)
            if known:
                other = [int(f) not in known for f in features]
                points, depths = points[other], depths[other]
            if len(depths) and -float(np.max(depths)) < best:
                deepest = int(np.argmax(depths))
                best, where = -float(depths[deepest]), points[deepest]
        return best, where


def fcl_elements(scene, table, elements: Elements, touchable) -> np.ndarray:
    """The elements that python-fcl must hold: those of a part pair without a closed form, in the pairs of bodies
    `touchable` ((k,2), which can touch) that involve a compound body."""
    from .narrow import needs_fcl

    kinds = elements.table.kind
    needed = set()
    for i, j in np.asarray(touchable, np.int64).reshape(-1, 2):
        if not (table.compound(int(i)) or table.compound(int(j))):
            continue
        ei, ej = elements.of(int(i)), elements.of(int(j))
        for a in ei:
            for b in ej:
                if needs_fcl(kinds[a], kinds[b]):
                    needed |= {int(a), int(b)}
    return np.array(sorted(needed), np.int64)

