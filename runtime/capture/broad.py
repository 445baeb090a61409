"""Broad phase of the capturing step, compiled: each body's world box grown by how far it can move in the step,
then a uniform grid: a cell as wide as the widest box, each body in the cell of its box's low corner, so two boxes
that overlap are in the same cell or in neighbouring ones, and each body looks at its own cell and the 13
neighbours on one side (every neighbouring pair of cells once). The cells are buckets of their own when the bodies
span no more cells than there are buckets (a dense grid: a heap in its bin), else they are hashed into buckets
(spatial hashing), where a look-up also meets other cells' bodies. Either way a bucket's bodies and their boxes lie
in one run of memory: 1000 spheres looked at 22 bodies each, 11 of them in other cells, spread over the whole
table, and their grid took 3 times 125 spheres' time a body. A body whose box
is more than BIG times the mean box wide would make the cells as large: it is tested against every box instead.
Planes are tested against every box by the box's lowest corner. A compound
body's box is the union of its parts' (compound.place, in poses.box), its reach its farthest part point
(parts.reach): the model's shape of a compound body is a box about its centre that holds every part, larger.

Cost: n for the boxes, the hashing and the look-ups, plus the pairs in neighbouring cells (n at a given density).
A sort along x and a sweep cost n times the bodies in a slab as wide as a box: 1000 spheres piled ten high met
150 boxes each, and 8 times the bodies cost 20 times the time.
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from ..core.model import SHAPE_CAPSULE, SHAPE_CYLINDER, SHAPE_NONE, SHAPE_PLANE, SHAPE_SPHERE


@kernel
def _extent(shapes, i, R, k):
    """Half the extent along world axis k of body i's shape about its centre (R current)."""
    kind = shapes.kind[i]
    r = shapes.radius[i]
    if kind == SHAPE_SPHERE:
        return r
    if kind == SHAPE_CAPSULE:
        # the axis (body z) from -L to +L, and a sphere of r about every point of it
        return abs(R[i, k, 2]) * shapes.half_length[i] + r
    if kind == SHAPE_CYLINDER:
        # a disc of radius r across the axis a reaches r sqrt(1 - a_k^2) along axis k
        a = R[i, k, 2]
        return abs(a) * shapes.half_length[i] + r * math.sqrt(max(0.0, 1.0 - a * a))
    # a box (or any shape's local bounding box): sum over the body axes of |R_kj| half_j
    return abs(R[i, k, 0]) * shapes.half[i, 0] + abs(R[i, k, 1]) * shapes.half[i, 1] + abs(R[i, k, 2]) * shapes.half[i, 2]


@kernel
def reach(shapes, i):
    """The farthest point of body i's shape from its centre of mass, m (planes: 0)."""
    kind = shapes.kind[i]
    if kind == SHAPE_SPHERE:
        return shapes.radius[i]
    if kind == SHAPE_CAPSULE:
        return shapes.half_length[i] + shapes.radius[i]
    if kind == SHAPE_CYLINDER:
        return math.sqrt(shapes.half_length[i] ** 2 + shapes.radius[i] ** 2)
    if kind == SHAPE_PLANE or kind == SHAPE_NONE:
        return 0.0
    c = shapes.centre[i]
    return math.sqrt((abs(c[0]) + shapes.half[i, 0]) ** 2 + (abs(c[1]) + shapes.half[i, 1]) ** 2
                     + (abs(c[2]) + shapes.half[i, 2]) ** 2)


# contacts are found as far apart as this many times what a body's velocities before the step carry it in the step:
# an impulse of the step can turn a body faster (a box struck on an edge, 8 cm, 49 rad/s: its z spin 5.6 -> 23.9
# rad/s) and bring a part of it down that was beyond the plain travel (1.5 mm deep at the next step)
SPECULATION = 2.0


@kernel
def body_reach(shapes, parts, i):
    """The farthest point of body i from its centre of mass, m: its farthest part's for a compound body."""
    if parts.count[i] > 0:
        return parts.reach[i]
    return reach(shapes, i)


@kernel
def travel(shapes, i, y, h, parts, floor):
    """How far any point of body i may move in a step of h: SPECULATION (|v| + |w| reach) h at its present
    velocities (the step's impulses may send it off faster than it came), the speed of its farthest point at least
    floor[i] (m/s: set when this step's impacts sent it faster, loop.py `_outran`)."""
    return SPECULATION * max(point_speed(shapes, i, y, parts), floor[i]) * h


@kernel
def point_speed(shapes, i, y, parts):
    """|v| + |w| reach of body i: the speed of its farthest point at most (m/s)."""
    v = math.sqrt(y[i, 7] ** 2 + y[i, 8] ** 2 + y[i, 9] ** 2)
    w = math.sqrt(y[i, 10] ** 2 + y[i, 11] ** 2 + y[i, 12] ** 2)
    return v + w * body_reach(shapes, parts, i)


@kernel
def _boxes(shapes, sw, y, R, h, margin, parts, poses):
    """sw.box[i] <- body i's world box, grown by the margin and its travel over the step (a compound body's: the
    union of its parts' boxes, poses.box[i])."""
    for idx in range(len(sw.order)):
        i = sw.order[idx]
        grow = margin + travel(shapes, i, y, h, parts, sw.reach)
        if parts.count[i] > 0:
            for k in range(3):
                sw.box[i, k], sw.box[i, 3 + k] = poses.box[i, k] - grow, poses.box[i, 3 + k] + grow
            continue
        for k in range(3):
            # a mesh's box is about its local centre, turned with the body
            centre = y[i, k] + R[i, k, 0] * shapes.centre[i, 0] + R[i, k, 1] * shapes.centre[i, 1] + R[i, k, 2] * shapes.centre[i, 2]
            e = _extent(shapes, i, R, k) + grow
            sw.box[i, k], sw.box[i, 3 + k] = centre - e, centre + e


@kernel
def find_key(keys, count, key):
    """Index of key in the sorted keys[:count] (binary search), or -1."""
    lo = first_at_least(keys, count, key)
    return lo if lo < count and keys[lo] == key else -1


@kernel
def first_at_least(keys, count, key):
    """The first index of the sorted keys[:count] whose key is >= key (count: none)."""
    lo, hi = 0, count
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def _add_pair(sw, dynamic, n, i, j):
    """Candidate pair (min, max) unless neither moves or it is excluded now."""
    if not dynamic[i] and not dynamic[j]:
        return
    a, b = min(i, j), max(i, j)
    if find_key(sw.excluded, len(sw.excluded), a * n + b) >= 0:
        return
    c = sw.count[0]
    if c < len(sw.pairs):
        sw.pairs[c, 0], sw.pairs[c, 1] = a, b
    sw.count[0] = c + 1


@kernel
def _plane_pairs(shapes, sw, dynamic, n, y, R):
    """Every body whose box reaches below a plane's surface (the box's lowest corner along the plane's normal)."""
    for p_idx in range(len(sw.planes)):
        p = sw.planes[p_idx]
        for idx in range(len(sw.order)):
            i = sw.order[idx]
            if _lowest(shapes, y, R, p, sw.box[i], 0.0) <= 0.0:
                _add_pair(sw, dynamic, n, i, p)


@kernel
def _lowest(shapes, y, R, p, box, extra):
    """How far the corner of box ([lo, hi]) grown by `extra` on every side that is lowest along plane p's normal N
    lies above its surface: centre . N - sum |N_k| (half_k + extra), from the plane's point (m)."""
    nx = R[p, 0, 0] * shapes.normal[p, 0] + R[p, 0, 1] * shapes.normal[p, 1] + R[p, 0, 2] * shapes.normal[p, 2]
    ny = R[p, 1, 0] * shapes.normal[p, 0] + R[p, 1, 1] * shapes.normal[p, 1] + R[p, 1, 2] * shapes.normal[p, 2]
    nz = R[p, 2, 0] * shapes.normal[p, 0] + R[p, 2, 1] * shapes.normal[p, 1] + R[p, 2, 2] * shapes.normal[p, 2]
    cx, cy, cz = 0.5 * (box[0] + box[3]), 0.5 * (box[1] + box[4]), 0.5 * (box[2] + box[5])
    low = (nx * (cx - y[p, 0]) + ny * (cy - y[p, 1]) + nz * (cz - y[p, 2])
           - 0.5 * (abs(nx) * (box[3] - box[0]) + abs(ny) * (box[4] - box[1]) + abs(nz) * (box[5] - box[2])))
    return low - extra * (abs(nx) + abs(ny) + abs(nz))


@kernel
def meets_more(shapes, sw, y, R, b, extra):
    """Whether body b's box (this step's, sw.box) grown by `extra` more (m) on every side meets a body's box or a
    plane's half-space that it did not meet: a candidate pair that the broad phase would find now."""
    box = sw.box[b]
    for idx in range(len(sw.order)):
        c = sw.order[idx]
        if c != b and not _meet(box, sw.box[c]) and _meet_grown(box, sw.box[c], extra):
            return True
    for p_idx in range(len(sw.planes)):
        p = sw.planes[p_idx]
        if _lowest(shapes, y, R, p, box, 0.0) > 0.0 and _lowest(shapes, y, R, p, box, extra) <= 0.0:
            return True
    return False


# a body whose box is wider than this many times the mean box is not in the grid (module docstring)
BIG = 4.0


@kernel
def _side(box, i):
    """The widest side of body i's box."""
    return max(box[i, 3] - box[i, 0], box[i, 4] - box[i, 1], box[i, 5] - box[i, 2])


@kernel
def _grid_cell(sw):
    """(the grid's cell: the widest side of the boxes that are not big, and the side over which a box is big)."""
    total = 0.0
    for idx in range(len(sw.order)):
        total += _side(sw.box, sw.order[idx])
    big = BIG * total / max(len(sw.order), 1)
    cell = 0.0
    for idx in range(len(sw.order)):
        side = _side(sw.box, sw.order[idx])
        if side <= big:
            cell = max(cell, side)
    return max(cell, 1e-9), big


@kernel
def _bucket(cx, cy, cz, mask):
    """The bucket of the cell (cx, cy, cz): its coordinates times three large primes, xor-ed (spatial hashing)."""
    return ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) & mask


@kernel
def _cell_of(box, i, cell):
    """(cx, cy, cz): the cell of body i's box's low corner."""
    return (int(math.floor(box[i, 0] / cell)), int(math.floor(box[i, 1] / cell)),
            int(math.floor(box[i, 2] / cell)))


@kernel
def _frame(sw, cell, big):
    """sw.frame <- [dense, x0, y0, z0, nx, ny, nz]: the cells from (x0, y0, z0) that the grid's bodies' low
    corners span, nx ny nz of them; dense 1 when they are no more than the buckets (each cell its own bucket,
    `_slot_of`: no two cells share one, and cells next to each other along z are next to each other), else 0."""
    lo = (1 << 40, 1 << 40, 1 << 40)
    hi = (-(1 << 40), -(1 << 40), -(1 << 40))
    for idx in range(len(sw.order)):
        i = sw.order[idx]
        if _side(sw.box, i) <= big:
            c = _cell_of(sw.box, i, cell)
            lo = (min(lo[0], c[0]), min(lo[1], c[1]), min(lo[2], c[2]))
            hi = (max(hi[0], c[0]), max(hi[1], c[1]), max(hi[2], c[2]))
    nx, ny, nz = max(hi[0] - lo[0] + 1, 1), max(hi[1] - lo[1] + 1, 1), max(hi[2] - lo[2] + 1, 1)
    sw.frame[0] = 1 if nx * ny * nz <= len(sw.start) - 1 else 0
    sw.frame[1], sw.frame[2], sw.frame[3] = lo
    sw.frame[4], sw.frame[5], sw.frame[6] = nx, ny, nz


@kernel
def _slot_of(frame, cx, cy, cz, mask):
    """The bucket of cell (cx, cy, cz): in a dense frame its index in the frame (-1: outside it), else its hash."""
    if frame[0] == 0:
        return _bucket(cx, cy, cz, mask)
    x, y, z = cx - frame[1], cy - frame[2], cz - frame[3]
    if x < 0 or y < 0 or z < 0 or x >= frame[4] or y >= frame[5] or z >= frame[6]:
        return -1
    return (x * frame[5] + y) * frame[6] + z


@kernel
def _hash_bodies(sw, cell, big):
    """sw.cell[i] <- (cx, cy, cz, bucket) of the cell of each body's low corner (bucket -1: a big body), and the
    bodies sorted by bucket (counting sort, stable): sw.slots[sw.start[k]:sw.start[k + 1]] are bucket k's, with
    their boxes in sw.sorted_box in the same order (a bucket's look-up reads one run of memory)."""
    _frame(sw, cell, big)
    buckets = len(sw.start) - 1
    mask = buckets - 1
    used = sw.frame[4] * sw.frame[5] * sw.frame[6] if sw.frame[0] else buckets
    for k in range(used + 1):
        sw.start[k] = 0
    for idx in range(len(sw.order)):
        i = sw.order[idx]
        if _side(sw.box, i) > big:
            sw.cell[i, 3] = -1
            continue
        cx, cy, cz = _cell_of(sw.box, i, cell)
        k = _slot_of(sw.frame, cx, cy, cz, mask)
        sw.cell[i, 0], sw.cell[i, 1], sw.cell[i, 2], sw.cell[i, 3] = cx, cy, cz, k
        sw.start[k + 1] += 1
    for k in range(used):
        sw.start[k + 1] += sw.start[k]
        sw.fill[k] = sw.start[k]
    for idx in range(len(sw.order)):
        i = sw.order[idx]
        k = sw.cell[i, 3]
        if k >= 0:
            slot = sw.fill[k]
            sw.slots[slot] = i
            for e in range(6):
                sw.sorted_box[slot, e] = sw.box[i, e]
            sw.fill[k] = slot + 1


@kernel
def _meet(p, q):
    """Whether the boxes p and q ([lo, hi], (6,)) overlap."""
    return _meet_grown(p, q, 0.0)


@kernel
def _meet_grown(p, q, extra):
    """Whether box p grown by `extra` on every side overlaps box q."""
    return not (q[0] > p[3] + extra or p[0] - extra > q[3] or q[1] > p[4] + extra or p[1] - extra > q[4]
                or q[2] > p[5] + extra or p[2] - extra > q[5])


@kernel
def _grid_pairs(sw, dynamic, n, i):
    """The pairs of body i (in the grid) with the bodies of its own cell after it and of the 13 neighbouring cells
    on the side (dx, dy, dz) > 0 in that order of axes."""
    mask = len(sw.start) - 2
    dense = sw.frame[0] == 1
    cx, cy, cz = sw.cell[i, 0], sw.cell[i, 1], sw.cell[i, 2]
    mine = sw.box[i]
    for dx in range(0, 2):
        for dy in range(-1 if dx > 0 else 0, 2):
            for dz in range(-1 if (dx > 0 or dy > 0) else 0, 2):
                k = _slot_of(sw.frame, cx + dx, cy + dy, cz + dz, mask)
                if k < 0:
                    continue
                for slot in range(sw.start[k], sw.start[k + 1]):
                    j = sw.slots[slot]
                    # (a hashed bucket holds other cells too; the own cell's pairs once, from the lower index)
                    if not dense and (sw.cell[j, 0] != cx + dx or sw.cell[j, 1] != cy + dy
                                      or sw.cell[j, 2] != cz + dz):
                        continue
                    if dx == 0 and dy == 0 and dz == 0 and j <= i:
                        continue
                    if _meet(mine, sw.sorted_box[slot]):
                        _add_pair(sw, dynamic, n, i, j)


@kernel
def find_pairs(shapes, sw, dynamic, y, R, h, margin, parts, poses):
    """sw.pairs[:sw.count[0]] <- the pairs whose grown boxes overlap (count beyond len(sw.pairs): grow, retake).
    The compound bodies' boxes are poses.box's (compound.place, before)."""
    n = len(y) - 1
    sw.count[0] = 0
    _boxes(shapes, sw, y, R, h, margin, parts, poses)
    cell, big = _grid_cell(sw)
    _hash_bodies(sw, cell, big)
    for idx in range(len(sw.order)):
        i = sw.order[idx]
        if sw.cell[i, 3] >= 0:
            _grid_pairs(sw, dynamic, n, i)
            continue
        # a big body: against every other box (a pair of big ones once, from the lower index)
        for jdx in range(len(sw.order)):
            j = sw.order[jdx]
            if j != i and (sw.cell[j, 3] >= 0 or j > i) and _meet(sw.box[i], sw.box[j]):
                _add_pair(sw, dynamic, n, i, j)
    _plane_pairs(shapes, sw, dynamic, n, y, R)
