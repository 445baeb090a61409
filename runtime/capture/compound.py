"""Compiled narrow phase of a pair of bodies of which one at least is compound (made of parts): each part of one
against each part (or the shape) of the other, with the closed-form tests of narrow.py (boxes.py, cylinders.py),
at the part's world pose. runtime/collide/compound.py calls it for the exact path's looks; it is the Python
phase's CompoundPairs, compiled, for the pairs of parts that have a closed form there.

    count, best = compound_pair(parts, poses, x, R, i, j, margin, mode, known, out, work)

parts (`Parts`): the elements of the scene (collide/shapes.py Elements: entries 0..n-1 the bodies' own shapes, then
the parts), as plain arrays: shapes (model.Shapes), owner, index (the part's number in its body, -1: a body's own
shape), offset (E,3) and turn (E,3,3) in the body's frame, first and count (n,) each body's parts, order (7,7)
the Python phase's order of a pair of kinds (KEEP: the test is written for (a, b), SWAP: for (b, a)), reach (n,)
each compound body's farthest point from its centre of mass (the capturing loop's travel; 0 for the others).
poses (`Poses`): scratch, each element's world position (E,3), rotation (E,3,3) and box (E,6), and the gaps of one
pair's element pairs (G,). x (n,3), R (n,3,3): the bodies' poses (or the state (n+1,13): its first three columns).
The capturing loop keeps in box[b] of a compound body b (an element that is never tested: its kind is NONE) the
union of its parts' boxes (`place`).

The capturing loop (loop.py) poses the compound bodies once a step (`place`, for its broad phase too) and calls
the CONTACTS mode as kernels (`pose` of a body that is its own shape, `posed_contacts`), then turns what it finds to
its own conventions (`fold`): one order (a, b) for the whole pair, and features that fit its keys (data.py
FEATURES per pair: the local feature, below kinds.LOCAL_FEATURES, plus that many times the element pair's number).

mode CONTACTS: the contacts of every element pair whose boxes, grown by the margin, overlap, in the order of
the Python phase (i's elements, then j's), into out (`Found`): point, normal, depth, feature (encoded with both
parts' numbers, collide/shapes.py PART_SHIFT), a and b (the bodies, in the order of their test); returns their
count (beyond capacity: the caller grows `out` and calls again) and 0.
mode NEAREST: the signed distance of the two bodies (margin inf: every test gives its closest feature), the
element pairs taken in the order of their boxes' gap, a lower bound of their distance, up to the first gap beyond
the nearest distance found; contacts whose feature is in `known` (sorted) are left out. Returns (1 with the
feature's point in out.point[0], or 0 with none, and the distance, inf with none).
"""
from __future__ import annotations

import math
from collections import namedtuple

from ..core.jit import entry, kernel
from ..core.model import SHAPE_PLANE
from .broad import find_key
from .common import flip
from .kinds import LOCAL_FEATURES
from .narrow import bounds, pair_contacts

CONTACTS, NEAREST = 0, 1
# the order of a pair of kinds in the Python phase's table (collide/narrow.py closed_form)
KEEP, SWAP, NO_TEST = 0, 1, 2
# a feature names its parts: local | (part_a + 1) << PART_SHIFT | (part_b + 1) << (PART_SHIFT + PART_BITS)
PART_SHIFT, PART_BITS = 22, 16

Parts = namedtuple("Parts", "shapes owner index offset turn first count order reach")
Poses = namedtuple("Poses", "x R box gap")
Found = namedtuple("Found", "point normal depth feature a b")


@kernel
def pose(parts, poses, x, R, body):
    """The world poses of a body's elements, X = x + R offset, RX = R turn, and their boxes."""
    first, count = _elements(parts, body)
    for e in range(first, first + count):
        for r in range(3):
            # (R offset)_r = sum_k R_rk offset_k
            poses.x[e, r] = x[body, r] + (R[body, r, 0] * parts.offset[e, 0] + R[body, r, 1] * parts.offset[e, 1]
                                          + R[body, r, 2] * parts.offset[e, 2])
            for c in range(3):
                poses.R[e, r, c] = (R[body, r, 0] * parts.turn[e, 0, c] + R[body, r, 1] * parts.turn[e, 1, c]
                                    + R[body, r, 2] * parts.turn[e, 2, c])
        bounds(parts.shapes, e, poses.x, poses.R, poses.box)


@kernel
def _elements(parts, body):
    """(first, count) of a body's elements: its parts, or itself."""
    if parts.count[body] > 0:
        return parts.first[body], parts.count[body]
    return body, 1


@kernel
def _gap(parts, poses, a, b, grow):
    """A lower bound of the distance of elements a and b: the largest gap of their boxes along a world axis, less
    twice the margin they grow by; -inf with a plane (its box is infinite)."""
    if parts.shapes.kind[a] == SHAPE_PLANE or parts.shapes.kind[b] == SHAPE_PLANE:
        return -math.inf
    gap = -math.inf
    for k in range(3):
        gap = max(gap, max(poses.box[b, k] - poses.box[a, 3 + k], poses.box[a, k] - poses.box[b, 3 + k]))
    return gap - 2.0 * grow


@kernel
def _test(parts, poses, a, b, margin, out, first, work):
    """The contacts of elements a and b at slots first.. of out, in the order of the Python phase's test, their
    features encoded with the parts and their bodies set; returns their count."""
    if parts.order[parts.shapes.kind[a], parts.shapes.kind[b]] == SWAP:
        a, b = b, a
    capacity = len(out.depth)
    count = pair_contacts(parts.shapes, a, b, poses.x, poses.R, margin, out.point, out.normal, out.depth,
                          out.feature, first, capacity, work)
    parts_ab = ((parts.index[a] + 1) << PART_SHIFT) | ((parts.index[b] + 1) << (PART_SHIFT + PART_BITS))
    for k in range(first, min(first + count, capacity)):
        out.feature[k] = out.feature[k] | parts_ab
        out.a[k], out.b[k] = parts.owner[a], parts.owner[b]
    return count


@kernel
def _apart(box, lo, hi, room):
    """Whether box (6,) lies farther than room from the box (lo, hi) along some world axis."""
    for k in range(3):
        if box[k] - hi[k] > room or lo[k] - box[3 + k] > room:
            return True
    return False


@kernel
def _union(parts, poses, body, lo, hi, room):
    """The union (lo, hi) of the boxes of body's elements within room of the box (lo, hi) ((inf, -inf): none)."""
    inf = math.inf
    ulo, uhi = (inf, inf, inf), (-inf, -inf, -inf)
    first, count = _elements(parts, body)
    for e in range(first, first + count):
        box = poses.box[e]
        if _apart(box, lo, hi, room):
            continue
        ulo = (min(ulo[0], box[0]), min(ulo[1], box[1]), min(ulo[2], box[2]))
        uhi = (max(uhi[0], box[3]), max(uhi[1], box[4]), max(uhi[2], box[5]))
    return ulo, uhi


@kernel
def posed_contacts(parts, poses, i, j, margin, out, work):
    """Mode CONTACTS (module docstring) of bodies whose elements are posed (`pose`): the element pairs whose grown
    boxes overlap, i's elements first. An element of i is looked at only if its box comes within the margins of
    the union of j's elements that come within them of i's box (no pair is lost: both boxes of a pair that meets
    lie in those unions): the clock's wheel of 95 parts against the pendulum's 9 tests some 40 pairs, not 855."""
    fi, ci = _elements(parts, i)
    fj, cj = _elements(parts, j)
    grow = margin if math.isfinite(margin) else 0.0
    # (margin inf: every element pair, each test then gives its closest feature)
    room = 2.0 * grow if math.isfinite(margin) else math.inf
    inf = math.inf
    lo_i, hi_i = _union(parts, poses, i, (-inf, -inf, -inf), (inf, inf, inf), room)
    lo_j, hi_j = _union(parts, poses, j, lo_i, hi_i, room)
    found = 0
    for a in range(fi, fi + ci):
        if _apart(poses.box[a], lo_j, hi_j, room):
            continue
        for b in range(fj, fj + cj):
            if not math.isfinite(margin) or _gap(parts, poses, a, b, grow) <= 0.0:
                found += _test(parts, poses, a, b, margin, out, found, work)
    return found


@kernel
def _next_nearest(gaps, count):
    """The untested element pair of least gap (the first of equal ones, as a stable sort takes them), or -1."""
    chosen, least = -1, math.inf
    for k in range(count):
        if gaps[k] < least:
            chosen, least = k, gaps[k]
    return chosen


@kernel
def _nearest(parts, poses, i, j, known, out, work):
    """Mode NEAREST (module docstring): (1 or 0, the signed distance); the nearest feature's point in out.point[0]."""
    fi, ci = _elements(parts, i)
    fj, cj = _elements(parts, j)
    for a in range(ci):
        for b in range(cj):
            poses.gap[a * cj + b] = _gap(parts, poses, fi + a, fj + b, 0.0)
    best, where = math.inf, (0.0, 0.0, 0.0)
    found = 0
    for _ in range(ci * cj):
        k = _next_nearest(poses.gap, ci * cj)
        # no element pair further on can come nearer than its boxes' gap (a tested pair's gap is set to inf)
        if k < 0 or poses.gap[k] > best:
            break
        poses.gap[k] = math.inf
        count = min(_test(parts, poses, fi + k // cj, fj + k % cj, math.inf, out, 0, work), len(out.depth))
        deepest, depth = -1, -math.inf
        for c in range(count):
            if find_key(known, len(known), out.feature[c]) < 0 and out.depth[c] > depth:
                deepest, depth = c, out.depth[c]
        if deepest >= 0 and -depth < best:
            best, found = -depth, 1
            where = (out.point[deepest, 0], out.point[deepest, 1], out.point[deepest, 2])
    for c in range(3):
        out.point[0, c] = where[c]
    return found, best


@entry
def compound_pair(parts, poses, x, R, i, j, margin, mode, known, out, work):
    """The contacts (mode CONTACTS) or the nearest feature (NEAREST) of bodies i and j (module docstring)."""
    pose(parts, poses, x, R, i)
    pose(parts, poses, x, R, j)
    if mode == NEAREST:
        return _nearest(parts, poses, i, j, known, out, work)
    return posed_contacts(parts, poses, i, j, margin, out, work), 0.0


# ---- the capturing loop's side ---------------------------------------------------------------------------------

@kernel
def place(parts, poses, x, R, bodies):
    """Each compound body among `bodies` posed, and its box, the union of its parts' boxes, in poses.box[body]."""
    for idx in range(len(bodies)):
        b = bodies[idx]
        if parts.count[b] == 0:
            continue
        pose(parts, poses, x, R, b)
        first = parts.first[b]
        for k in range(6):
            poses.box[b, k] = poses.box[first, k]
        for e in range(first + 1, first + parts.count[b]):
            for k in range(3):
                poses.box[b, k] = min(poses.box[b, k], poses.box[e, k])
                poses.box[b, 3 + k] = max(poses.box[b, 3 + k], poses.box[e, 3 + k])


@kernel
def _named_parts(feature):
    """(local feature, part of the test's body a, part of its body b) that a compound feature names (-1: a body's
    own shape)."""
    mask = (1 << PART_BITS) - 1
    return (feature & ((1 << PART_SHIFT) - 1), ((feature >> PART_SHIFT) & mask) - 1,
            ((feature >> (PART_SHIFT + PART_BITS)) & mask) - 1)


@kernel
def fold(parts, out, c, a, b):
    """Contact c of out (found for the pair of bodies a, b by `compound_contacts`) turned to the order (a, b): the
    normal reversed if its test took them as (b, a), the bodies set; its feature folded to
    local + LOCAL_FEATURES (part_a max(count_b, 1) + part_b), unique in the pair (a part number -1 counts as 0:
    that body has one element). Returns (part of a, part of b)."""
    local, first, second = _named_parts(out.feature[c])
    if out.a[c] != a:
        first, second = second, first
        flip(out.normal, c, 1, len(out.normal))
    out.a[c], out.b[c] = a, b
    # feature' = local + LOCAL_FEATURES (part_a max(count_b, 1) + part_b)
    out.feature[c] = local + LOCAL_FEATURES * (max(first, 0) * max(parts.count[b], 1) + max(second, 0))
    return first, second


@kernel
def material_of(parts, body, part):
    """The row of the capturing loop's materials (capture CaptureStage) for part `part` of body (-1: the body's
    own): the bodies' rows 0..n-1, the world's n, then the parts' (element e at e + 1)."""
    return body if part < 0 else parts.first[body] + part + 1
