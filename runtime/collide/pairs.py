"""Which pairs can touch (decided once, in the plan) and which of them might touch now (broad phase).

Exclusion, once: a pair never collides when
  * either body has `collide off` (it is not in the collidable list at all);
  * neither body is dynamic (static-static, static-kinematic, kinematic-kinematic: nothing could respond);
  * a constraint joins the two bodies (at any time of the run: a joint's parts overlap by design);
  * the scene excludes them (`exclude a, b, c`: every pair within the group).
The explicit exclusions are kept as sorted pair keys i * n + j (i < j), so a lookup is a binary search and the
memory is O(excluded pairs), never O(n^2).

Broad phase, every step: a uniform grid (spatial hashing). Boxes (world AABBs, grown by the margin, and swept
over the step) are entered in the grid cells they cover, the cell twice the size of a typical box; pairs are
taken within each cell, checked on all three axes, made unique, then filtered by exclusion and by motion.
Boxes much larger than a cell are checked against every box; up to ALL_PAIRS_BELOW boxes, every pair is
checked directly. Cost O(n) at a given density (n log n for the sort). Measured, random spheres and boxes at
a fixed density: 100 / 1000 / 10000 bodies, 0.37 / 2.2 / 25 ms per step, where sort and sweep on one axis
(tried first) takes 0.18 / 4.0 / 168 ms: it pairs everything overlapping along its axis, n^(5/3) pairs in 3-D.
Planes are infinite: each plane is tested against every box by the box's signed distance to it.
"""
from __future__ import annotations

import numpy as np

from .shapes import PLANE, SPHERE, bounding_boxes, boxes_of

# up to this many boxes every pair is checked directly (k^2 / 2 comparisons beat any bookkeeping)
ALL_PAIRS_BELOW = 32
# grid cell = GRID_CELL x the GRID_QUANTILE-th quantile of the box sizes (larger boxes are checked against all)
GRID_CELL = 2.0
GRID_QUANTILE = 0.9


# ---- exclusion (once) ------------------------------------------------------------------------------------------

def excluded_keys(scene, plan, collidable: np.ndarray) -> dict:
    """Sorted keys of the explicitly excluded pairs that would otherwise count (both collidable, one dynamic),
    by reason: {"joined": keys, "excluded": keys}."""
    n = len(scene.bodies)
    index = scene.body_index()
    ok = np.zeros(n, bool)
    ok[collidable] = True
    joined = []
    if plan.constraints is not None:
        rb = plan.constraints.row_bodies
        both = (rb[:, 0] >= 0) & (rb[:, 1] >= 0) & (rb[:, 0] != rb[:, 1])
        joined = [tuple(p) for p in rb[both]]
        # a term may name two bodies without a row touching both (e.g. gear-to-weight of a static gear)
        for constraint in scene.constraints:
            for term in constraint.terms:
                named = [index[b] for b in term.bodies if b in index]
                joined += [(p, q) for k, p in enumerate(named) for q in named[k + 1:] if p != q]
    grouped = []
    for exclusion in scene.exclusions:
        members = sorted({index[b] for b in exclusion.bodies})
        grouped += [(p, q) for k, p in enumerate(members) for q in members[k + 1:]]
    out = {}
    for reason, pairs in (("joined", joined), ("excluded", grouped)):
        keys = pair_keys(np.array(pairs, np.int64).reshape(-1, 2), n)
        i, j = keys // n, keys % n
        counts = ok[i] & ok[j] & (plan.dynamic[i] | plan.dynamic[j])
        out[reason] = np.unique(keys[counts])
    return out


def pair_keys(pairs: np.ndarray, n: int) -> np.ndarray:
    """i * n + j with i < j, for (k,2) pairs."""
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    return lo.astype(np.int64) * n + hi


def count_pairs(collidable: np.ndarray, dynamic: np.ndarray, excluded: np.ndarray) -> int:
    """Pairs of collidable bodies with at least one dynamic body, minus the excluded ones (O(n))."""
    k = len(collidable)
    still = int(np.count_nonzero(~dynamic[collidable]))
    return k * (k - 1) // 2 - still * (still - 1) // 2 - len(excluded)


def is_excluded(keys: np.ndarray, excluded: np.ndarray) -> np.ndarray:
    if not len(excluded):
        return np.zeros(len(keys), bool)
    at = np.clip(np.searchsorted(excluded, keys), 0, len(excluded) - 1)
    return excluded[at] == keys


# ---- broad phase (every step) --------------------------------------------------------------------------------

# the early-out's boxes are grown by this fraction (plus as many metres) so that rounding never makes them
# smaller than the full broad phase's
_SAFE = 1e-9


def _reach(table, index: np.ndarray) -> np.ndarray:
    """(k,) a half-edge r such that the cube x +- r holds the body's box at any orientation: the radius of a
    sphere about the centre of mass holding the shape (a sphere's radius; else |centre| + |half|), grown by
    _SAFE."""
    radius = np.where(table.kind[index] == SPHERE, table.radius[index],
                      np.linalg.norm(table.centre[index], axis=1) + np.linalg.norm(table.half[index], axis=1))
    return radius * (1.0 + _SAFE) + _SAFE


class BroadPhase:
    """Candidate pairs of a fixed set of bodies; `pairs` returns (k,2) body indices, a before b.

    still (n,) bool, optional: bodies that never move (static, not kinematic). With it, `anything_near` can
    tell cheaply that no pair can touch (most steps of most scenes), before the full broad phase: it bounds
    each dynamic body by a cube about its centre (no rotation needed) and keeps the boxes of the still bodies."""

    def __init__(self, table, collidable: np.ndarray, dynamic: np.ndarray, excluded: np.ndarray, margin: float,
                 still: np.ndarray | None = None):
        self.table, self.dynamic, self.excluded, self.margin = table, dynamic, excluded, margin
        self.n = len(dynamic)
        kinds = table.kind[collidable]
        self.boxed = collidable[kinds != PLANE]  # bodies with a finite box
        self.planes = collidable[kinds == PLANE]
        self.quick = still is not None
        if self.quick:
            # the early-out's split of the boxed bodies: dynamic ones (every pair has one), ones that never
            # move (boxes kept), the rest (kinematic: boxes every time)
            self.active = self.boxed[dynamic[self.boxed]]
            self.still = self.boxed[~dynamic[self.boxed] & still[self.boxed]]
            self.driven = self.boxed[~dynamic[self.boxed] & ~still[self.boxed]]
            self.reach = _reach(table, self.active) + margin  # (a,) half-edge of a cube about x that holds the box
            self.still_boxes = None  # (lo, hi) of `still`, from the first poses seen, grown by _SAFE

    def anything_near(self, x, R_of, x_before) -> bool:
        """False when `pairs` would find nothing: no cube bounding a dynamic body's box, swept from x_before
        to x, overlaps the box of another body or reaches a plane. The cubes hold the boxes, so this never
        says False where `pairs` would find a pair. R_of(index) -> (R now, R before) of those bodies (k,3,3)
        each, asked only for kinematic bodies and planes. Without `still`, always True."""
        if not self.quick:
            return True
        if not len(self.active):
            return False
        xa, xb = x[self.active], x_before[self.active]
        lo = np.minimum(xa, xb) - self.reach[:, None]
        hi = np.maximum(xa, xb) + self.reach[:, None]
        others_lo, others_hi = [lo], [hi]
        if len(self.still):
            if self.still_boxes is None:
                lo_s, hi_s = boxes_of(self.table, self.still, x[self.still], R_of(self.still)[0], self.margin)
                self.still_boxes = (lo_s - _SAFE * (1.0 + np.abs(lo_s)), hi_s + _SAFE * (1.0 + np.abs(hi_s)))
            others_lo.append(self.still_boxes[0])
            others_hi.append(self.still_boxes[1])
        if len(self.driven):
            R_now, R_before = R_of(self.driven)
            lo_d, hi_d = boxes_of(self.table, self.driven, x[self.driven], R_now, self.margin)
            lo_b, hi_b = boxes_of(self.table, self.driven, x_before[self.driven], R_before, self.margin)
            others_lo.append(np.minimum(lo_d, lo_b) - _SAFE * (1.0 + np.abs(lo_d)))
            others_hi.append(np.maximum(hi_d, hi_b) + _SAFE * (1.0 + np.abs(hi_d)))
        other_lo = np.concatenate(others_lo) if len(others_lo) > 1 else lo
        other_hi = np.concatenate(others_hi) if len(others_hi) > 1 else hi
        # box a overlaps box b: lo_a <= hi_b and lo_b <= hi_a on every axis (a body with itself does not count)
        hit = np.all((lo[:, None] <= other_hi[None]) & (other_lo[None] <= hi[:, None]), axis=2)
        np.fill_diagonal(hit, False)  # (the dynamic bodies come first among the others)
        if hit.any():
            return True
        return bool(len(self.planes)) and self._near_a_plane(lo, hi, x, R_of(self.planes)[0])

    def _near_a_plane(self, lo, hi, x, R_planes) -> bool:
        centre, extent = 0.5 * (lo + hi), 0.5 * (hi - lo)
        for plane, R in zip(self.planes, R_planes):
            n = R @ self.table.normal[plane]
            # lowest point of a box along n: n . (c - p0) - sum |n_i| e_i (with room for rounding)
            low = (centre - x[plane]) @ n - extent @ np.abs(n)
            if np.any(low <= self.margin + _SAFE * (1.0 + np.abs(centre).max())):
                return True
        return False

    def pairs(self, poses_now, poses_before=None) -> np.ndarray:
        """Pairs whose boxes overlap at poses_now = (x, R), or, with poses_before, anywhere on the way (each
        box is the union of its boxes at both poses: a swept box)."""
        lo, hi = bounding_boxes(self.table, self.boxed, *poses_now, self.margin)
        if poses_before is not None:
            lo0, hi0 = bounding_boxes(self.table, self.boxed, *poses_before, self.margin)
            lo, hi = np.minimum(lo, lo0), np.maximum(hi, hi0)
        found = [self._grid(lo, hi), self._planes(lo, hi, *poses_now)]
        pairs = np.concatenate(found)
        if not len(pairs):
            return pairs
        a, b = pairs[:, 0], pairs[:, 1]
        moving = self.dynamic[a] | self.dynamic[b]
        keys = pair_keys(pairs, self.n)
        keep = moving & ~is_excluded(keys, self.excluded)
        pairs = pairs[keep]
        return pairs[np.argsort(keys[keep], kind="stable")]  # a deterministic order

    def _grid(self, lo, hi) -> np.ndarray:
        """Pairs of boxes that overlap, through a uniform grid: cell size GRID_CELL x the GRID_QUANTILE box
        size, so a typical box covers at most two cells per axis; each box is entered in every cell it
        covers, pairs are taken within each cell, then checked and made unique. Boxes too big for that (a
        large static table) are checked against every box instead."""
        k = len(lo)
        if k <= ALL_PAIRS_BELOW:  # a few bodies: every pair, at once
            pairs = self._against_all(np.arange(k), lo, hi)
            pairs = pairs[pairs[:, 0] < pairs[:, 1]]
            a, b = self.boxed[pairs[:, 0]], self.boxed[pairs[:, 1]]
            return np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
        size = (hi - lo).max(axis=1)
        cell = GRID_CELL * float(np.quantile(size, GRID_QUANTILE))
        big = size > cell
        found = [self._against_all(np.flatnonzero(big), lo, hi)]
        small = np.flatnonzero(~big)
        first = np.floor(lo[small] / cell).astype(np.int64)
        last = np.floor(hi[small] / cell).astype(np.int64)
        # every (box, cell) entry: the box's first cell plus each corner offset it reaches
        offsets = np.array([[i, j, l] for i in (0, 1) for j in (0, 1) for l in (0, 1)])
        reach = np.all(first[:, None, :] + offsets[None] <= last[:, None, :], axis=2)  # (s,8)
        box, corner = np.nonzero(reach)
        cells = first[box] + offsets[corner]
        key = (cells[:, 0] * 73856093) ^ (cells[:, 1] * 19349663) ^ (cells[:, 2] * 83492791)  # spatial hash
        order = np.argsort(key, kind="stable")
        key, box = key[order], box[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        count = np.diff(np.r_[starts, len(key)])
        # within each cell, every entry p pairs with the entries after it: (g - 1 - rank) partners
        rank = np.arange(len(key)) - np.repeat(starts, count)
        partners = np.repeat(count, count) - 1 - rank
        p = np.repeat(np.arange(len(key)), partners)
        q = p + 1 + (np.arange(partners.sum()) - np.repeat(np.cumsum(partners) - partners, partners))
        found.append(np.stack([small[box[p]], small[box[q]]], axis=1))
        pairs = np.concatenate(found)
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        overlap = np.all((lo[pairs[:, 0]] <= hi[pairs[:, 1]]) & (lo[pairs[:, 1]] <= hi[pairs[:, 0]]), axis=1)
        a, b = self.boxed[pairs[overlap, 0]], self.boxed[pairs[overlap, 1]]
        unique = np.unique(np.minimum(a, b) * self.n + np.maximum(a, b))
        return np.stack([unique // self.n, unique % self.n], axis=1)

    @staticmethod
    def _against_all(chosen, lo, hi) -> np.ndarray:
        """(k,2) indices into the boxes: each chosen box with every box it overlaps."""
        if not len(chosen):
            return np.zeros((0, 2), np.int64)
        hit = np.all((lo[chosen, None] <= hi[None]) & (lo[None] <= hi[chosen, None]), axis=2)
        c, other = np.nonzero(hit)
        return np.stack([chosen[c], other], axis=1)

    def _planes(self, lo, hi, x, R) -> np.ndarray:
        if not len(self.planes) or not len(lo):
            return np.zeros((0, 2), np.int64)
        out = []
        centre, extent = 0.5 * (lo + hi), 0.5 * (hi - lo)
        for plane in self.planes:
            n = R[plane] @ self.table.normal[plane]
            # lowest point of the box along n: n . (c - p0) - sum |n_i| e_i
            low = (centre - x[plane]) @ n - extent @ np.abs(n)
            near = self.boxed[low <= self.margin]
            out.append(np.stack([np.minimum(near, plane), np.maximum(near, plane)], axis=1))
        return np.concatenate(out)
