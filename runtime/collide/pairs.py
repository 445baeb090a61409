"""Which pairs can touch (decided once, in the plan) and which of them might touch now (broad phase).

Exclusion, once: a pair never collides when
  * either body has `collide off` (it is not in the collidable list at all);
  * neither body is dynamic (static-static, static-kinematic, kinematic-kinematic: nothing could respond);
  * a constraint joins the two bodies for the whole run (a joint's parts overlap by design), unless a `collide`
    names them (`collide a, b, c`: every pair within the group collides anyway, a clapper and its bell);
  * the scene excludes them (`exclude a, b, c`: every pair within the group).
A pair joined by a constraint for part of the run only is excluded while the constraint is on (the collision
stage follows the epochs: collider.on_epoch), and collides before and after; a `collide` with a window gives a
joined pair back while its window lasts (CollisionPlan.excluded_now).
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

def exclusion_pairs(exclusion, index: dict) -> list:
    """The (i, j) pairs an `exclude` names."""
    members = sorted({index[b] for b in exclusion.bodies})
    return [(p, q) for k, p in enumerate(members) for q in members[k + 1:]]


def excluded_keys(scene, plan, collidable: np.ndarray) -> dict:
    """Sorted keys of the pairs excluded for the whole run that would otherwise count (both collidable, one
    dynamic), by reason: {"joined": keys (by a constraint on for the whole run, and no `collide` naming them at any
    time), "excluded": keys (by an `exclude` without a window)}; and the pairs a `collide` gives back:
    "restored": keys of pairs joined by a constraint (at any time) that a `collide` names, "suspended": keys of
    pairs joined for the whole run that only a `collide` with a window names (excluded outside that window: the
    collision stage's, CollisionPlan.excluded_now)."""
    n = len(scene.bodies)
    index = scene.body_index()
    ok = np.zeros(n, bool)
    ok[collidable] = True
    whole = (lambda start, end: start <= plan.start and end >= plan.end)
    joined, ever = [], []
    if plan.constraints is not None:
        c = plan.constraints
        rb = c.row_bodies
        pair = (rb[:, 0] >= 0) & (rb[:, 1] >= 0) & (rb[:, 0] != rb[:, 1])
        # rows on for the whole run
        always = (c.row_start <= plan.start) & (c.row_end >= plan.end)
        joined = [tuple(p) for p in rb[pair & always]]
        ever = [tuple(p) for p in rb[pair]]
        # a term may name two bodies without a row touching both (e.g. gear-to-weight of a static gear)
        for constraint in scene.constraints:
            for term in constraint.terms:
                named = [index[b] for b in term.bodies if b in index]
                both = [(p, q) for k, p in enumerate(named) for q in named[k + 1:] if p != q]
                ever += both
                if whole(constraint.start, constraint.end):
                    joined += both
    grouped = []
    for exclusion in scene.exclusions:
        if whole(exclusion.start, exclusion.end):  # (a windowed one: the collider's)
            grouped += exclusion_pairs(exclusion, index)
    collides = getattr(scene, "collides", ())
    named_always = [p for c in collides if whole(c.start, c.end) for p in exclusion_pairs(c, index)]
    named_ever = [p for c in collides for p in exclusion_pairs(c, index)]

    def counted(pairs):
        keys = pair_keys(np.array(pairs, np.int64).reshape(-1, 2), n)
        i, j = keys // n, keys % n
        return np.unique(keys[ok[i] & ok[j] & (plan.dynamic[i] | plan.dynamic[j])])

    joined, ever, grouped = counted(joined), counted(ever), counted(grouped)
    named_always, named_ever = counted(named_always), counted(named_ever)
    return {"joined": np.setdiff1d(joined, named_ever), "excluded": grouped,
            "restored": np.intersect1d(ever, named_ever),
            "suspended": np.setdiff1d(np.intersect1d(joined, named_ever), named_always)}


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


def _rows(index: np.ndarray):
    """index as a slice when it is consecutive (x[slice] is a view, x[index] a copy), else index itself."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


class BroadPhase:
    """Candidate pairs of a fixed set of bodies; `pairs` returns (k,2) body indices, a before b.

    still (n,) bool, optional: bodies that never move (static, not kinematic, at rest). With it, `anything_near` can
    tell cheaply that no pair can touch (most steps of most scenes), before the full broad phase: it bounds
    each dynamic body by a cube about its centre (no rotation needed) and keeps the boxes of the still bodies.
    And when nothing but dynamic bodies moves (no kinematic body, every plane still), each time it finds
    nothing near it also works out how far the dynamic bodies may move before that answer could change (the
    `room`): until one leaves it, a step costs a few array operations (`_within_room`)."""

    def __init__(self, table, collidable: np.ndarray, dynamic: np.ndarray, excluded: np.ndarray, margin: float,
                 still: np.ndarray | None = None):
        self.table, self.dynamic, self.excluded, self.margin = table, dynamic, excluded, margin
        self.n = len(dynamic)
        kinds = table.kind[collidable]
        self.boxed = collidable[kinds != PLANE]  # bodies with a finite box
        self.boxed_twice = np.concatenate([self.boxed, self.boxed])
        self.planes = collidable[kinds == PLANE]
        self.quick = still is not None
        if self.quick:
            # the early-out's split of the boxed bodies: dynamic ones (every pair has one), ones that never
            # move (boxes kept), the rest (kinematic: boxes every time)
            self.active = self.boxed[dynamic[self.boxed]]
            self.still = self.boxed[~dynamic[self.boxed] & still[self.boxed]]
            self.driven = self.boxed[~dynamic[self.boxed] & ~still[self.boxed]]
            self.reach = _reach(table, self.active) + margin  # (a,) half-edge of a cube about x that holds the box
            self.largest_reach = float(self.reach.max(initial=0.0))
            self.still_boxes = None  # (lo, hi) of `still`, from the first poses seen, grown by _SAFE
            self.still_scale = 1.0  # 1 + their largest coordinate
            # the room (state of the early-out): only when everything but the dynamic bodies stands still
            self.roomy = len(self.active) > 0 and not len(self.driven) and bool(np.all(still[self.planes]))
            self.rows = _rows(self.active)  # x[rows] is x[active] (a slice when they are consecutive)
            self.anchor = np.zeros((len(self.active), 3))  # (a,3) where the room was measured from
            self.room = -np.inf  # L-inf distance every dynamic body may move from its anchor, m
            self.was_near = False  # the last full test found something near
            moved = np.zeros((2, len(self.active), 3))  # scratch: |x - anchor| at the end and start of the step
            self.moved = (moved, moved[0], moved[1])

    def anything_near(self, x, R_of, x_before) -> bool:
        """False when `pairs` would find nothing: no cube bounding a dynamic body's box, swept from x_before
        to x, overlaps the box of another body or reaches a plane. The cubes hold the boxes, so this never
        says False where `pairs` would find a pair. R_of(index) -> (R now, R before) of those bodies (k,3,3)
        each, asked only for kinematic bodies and planes. Without `still`, always True.

        With a room (`roomy`): both ends of the step inside the room, nothing is near (`_within_room`). Else the
        room is measured again about the end of the step, and checked again; else the full test runs. The room
        stays true of its anchor whatever happens later, so it is only measured anew when the bodies leave it,
        and not while they stay near something (bodies lying on one another would measure no room every step)."""
        if not self.quick:
            return True
        if not len(self.active):
            return False
        if self.roomy:
            if self._within_room(x, x_before):
                return False
            if not self.was_near:
                self._measure_room(x, R_of)
                if self._within_room(x, x_before):
                    return False
        near = self._cubes_near(x, R_of, x_before)
        self.was_near = near
        return near

    def _within_room(self, x, x_before) -> bool:
        """Every dynamic body, at both ends of the step, within the room of its anchor (L-inf), strictly.

        Why that is enough (`_measure_room` gives the room): the cube about a body at p, |p - anchor| < room,
        has half-edge reach, so it lies inside the cube of half-edge reach + room about the anchor; the box
        swept between the two ends (what `_cubes_near` tests) is the box of two such cubes, inside it too. That
        bigger cube is apart from every still box, from every other dynamic body's bigger cube and from every
        plane (by construction of the room), so `_cubes_near` would find nothing: the same answer, and the
        same step, as before. Only end positions enter `_cubes_near` and `pairs` (the swept box is the union of
        the two ends' boxes), so the path between them does not matter here either."""
        moved, end, start = self.moved
        # |x - anchor| and |x_before - anchor|, per axis, against the smallest room
        np.subtract(x[self.rows], self.anchor, out=end)
        np.subtract(x_before[self.rows], self.anchor, out=start)
        return bool(np.abs(moved, out=moved).max() < self.room)

    def _measure_room(self, x, R_of) -> None:
        """Anchor at the dynamic bodies' centres now, p = x[active], and set the room: the smallest over the
        dynamic bodies of room_a, the L-inf distance body a may move from p_a with `_cubes_near` still finding
        nothing, less a rounding allowance:

          a still box S:        the cube of half-edge reach_a + room_a about p must miss S: on some axis k
                                the gap max(S.lo_k - p_k, p_k - S.hi_k) exceeds reach_a + room_a
          another dynamic b:    both bigger cubes apart on some axis: |p_a,k - p_b,k| - reach_a - reach_b
                                exceeds room_a + room_b; each body gets half
          a plane (n, point o): the bigger cube's lowest point along n, (p - o) . n - (reach_a + room_a) |n|_1,
                                above _near_a_plane's threshold margin + _SAFE (1 + |centre|_inf); with every
                                room at most 1 + P (P = max |p|_inf), |centre| <= 1 + 2 P, so
                                room_a = ((p - o) . n - reach_a |n|_1 - margin - 2 _SAFE (1 + P)) / |n|_1
        The rounding allowance, _SAFE (1 + the largest coordinate involved), is ~1e7 times the rounding error
        of these few operations, so rounding cannot turn the argument of `_within_room` around."""
        p = x[self.rows]
        reach = self.reach
        P = 1.0 + float(np.abs(p).max())
        room = np.full(len(p), P)
        scale = max(P, self.still_scale)
        if len(self.still):
            lo, hi = self._kept_boxes(x, R_of)
            gap = np.maximum(lo - p[:, None], p[:, None] - hi).max(axis=2)  # (a,s)
            room = np.minimum(room, gap.min(axis=1) - reach)
        if len(p) > 1:
            apart = np.abs(p[:, None] - p[None]).max(axis=2) - reach[:, None] - reach[None]  # (a,a)
            np.fill_diagonal(apart, np.inf)
            room = np.minimum(room, 0.5 * apart.min(axis=1))
        for plane, R in zip(self.planes, R_of(self.planes)[0] if len(self.planes) else ()):
            n = R @ self.table.normal[plane]
            spread = float(np.abs(n).sum())  # |n|_1
            height = (p - x[plane]) @ n - reach * spread - self.margin - 2.0 * _SAFE * P
            room = np.minimum(room, height / spread)
            scale = max(scale, 1.0 + float(np.abs(x[plane]).max()))
        self.anchor[...] = p
        self.room = float(room.min()) - _SAFE * (scale + self.largest_reach)

    def _cubes_near(self, x, R_of, x_before) -> bool:
        """anything_near's test itself, every time."""
        xa, xb = x[self.active], x_before[self.active]
        lo = np.minimum(xa, xb) - self.reach[:, None]
        hi = np.maximum(xa, xb) + self.reach[:, None]
        others_lo, others_hi = [lo], [hi]
        if len(self.still):
            lo_s, hi_s = self._kept_boxes(x, R_of)
            others_lo.append(lo_s)
            others_hi.append(hi_s)
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

    def _kept_boxes(self, x, R_of) -> tuple:
        """(lo, hi) of the still bodies, from the first poses seen (they never move), grown by _SAFE."""
        if self.still_boxes is None:
            lo, hi = boxes_of(self.table, self.still, x[self.still], R_of(self.still)[0], self.margin)
            self.still_boxes = (lo - _SAFE * (1.0 + np.abs(lo)), hi + _SAFE * (1.0 + np.abs(hi)))
            self.still_scale = 1.0 + max(float(np.abs(box).max()) for box in self.still_boxes)
        return self.still_boxes

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
        if poses_before is None:
            lo, hi = bounding_boxes(self.table, self.boxed, *poses_now, self.margin)
        else:
            lo, hi = self._swept_boxes(poses_now, poses_before)
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

    def _swept_boxes(self, poses_now, poses_before) -> tuple:
        """The union of each boxed body's boxes at both poses; both sets of boxes in one call of boxes_of."""
        (x, R), (x0, R0) = poses_now, poses_before
        k, b = len(self.boxed), self.boxed
        lo, hi = boxes_of(self.table, self.boxed_twice, np.concatenate([x[b], x0[b]]), np.concatenate([R[b], R0[b]]),
                          self.margin)
        return np.minimum(lo[:k], lo[k:]), np.maximum(hi[:k], hi[k:])

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
