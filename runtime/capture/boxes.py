"""Compiled tests with a box on one side: box-plane, sphere-box, capsule-box and box-box (conventions: narrow.py).

Box-box: the gap of the boxes along each of the 15 candidate axes (3 face normals of each, 9 edge crosses),

    gap(L) = |d . L| - sum_i ha_i |a_i . L| - sum_j hb_j |b_j . L|,    d = x_a - x_b, L unit,

the largest gap is the separation (minus the penetration). A face axis wins unless an edge axis beats it by
EDGE_PREFERENCE of the smaller box (a resting stack picks a face). On a face axis, the incident face of the other
box (the one facing the reference face most) is clipped against the reference face's four side planes
(Sutherland-Hodgman) in the scratch `work` (16,4): rows 0-7 and 8-15 are two polygons of at most 8 vertices,
columns 0-2 a vertex, column 3 its tag. A vertex is where two lines of the face meet: the incident face's edges
(lines 0-3, edge e from corner e to corner e+1) and the reference face's side planes (lines 4-7), and its tag is
8 min + max of the two: the same vertex keeps its tag while the same features touch. The points below the
reference face are kept, at most four of them: the deepest, the farthest from it, then the two that add the most
area. On an edge axis: the closest points of the two edges, one contact.

Features: a face contact's is 64 (6 (6 side + ref face) + incident face) + tag (side 0: the reference face is
a's, faces numbered 2 axis + (0 outward along +axis, 1 along -axis)); an edge contact's EDGE + 3 i + j.
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from ..core.vec import add3, cross3, dot3, rotate, rotate_t, row3, scale3, sub3
from .common import clamp, clip_line, col3, emit, plane_of, point_box, segment, sign, unit3

EDGE_PREFERENCE = 1e-3
# ... and, where the edges touch or overlap, only if their common normal is farther than 8 degrees from the best
# face normal of either box: crossed edges nearer than that lie almost flat in that face, and their contact is the
# face's (clipped: up to four points, each no deeper than the boxes overlap).
# One point under a box resting on another, 2 degrees apart, let it rock onto corners that no contact held: a
# column of 15 turned boxes dropped onto one another sank 13.6 mm into itself in 1.2 s
FLAT_EDGES = math.cos(math.radians(8.0))
# edge-edge axes of nearly parallel edges (|a_i x b_j| below this) are skipped: a face axis covers them
PARALLEL_EDGES = 1e-6
EDGE = 72 * 64
# the deepest corner, when the incident face lies beside the reference face; the separation of boxes apart
SUPPORT, APART = EDGE + 9, EDGE + 10


@kernel
def corner(shapes, i, y, R, c):
    """World corner c of box i: x + R (h * s), s_k = +1 when bit k of c is set, else -1."""
    h = row3(shapes.half, i, 0)
    local = tuple_signs(c, h)
    return add3(row3(y, i, 0), rotate(R, i, local))


@kernel
def tuple_signs(c, h):
    return (h[0] if c & 1 else -h[0], h[1] if c & 2 else -h[1], h[2] if c & 4 else -h[2])


@kernel
def box_plane(shapes, a, b, y, R, sink):
    """Every corner of box a past (or within margin of) plane b; feature = corner index."""
    n, p0 = plane_of(shapes, b, y, R)
    k = 0
    for c in range(8):
        p = corner(shapes, a, y, R, c)
        # depth below the surface through p0: -(p - p0) . n; the point midway, on the surface plus half of it
        d = -dot3(sub3(p, p0), n)
        k = emit(sink, k, add3(p, scale3(0.5 * d, n)), n, d, c)
    return k


@kernel
def sphere_box(shapes, a, b, y, R, sink):
    r, x = shapes.radius[a], row3(y, a, 0)
    dist, surface, n = point_box(x, shapes, b, y, R)
    # midway between the sphere's deepest point x - n r and the box's surface point
    return emit(sink, 0, scale3(0.5, add3(sub3(x, scale3(r, n)), surface)), n, r - dist, 0)


@kernel
def capsule_box(shapes, a, b, y, R, sink):
    """The two end spheres (features 0, 1); then, where the axis point nearest the box lies over a face of it, the
    ends of the axis's part over that face (features 3, 4; the axis's distance to the face is linear along it, so
    its ends hold the least), else that nearest point when inside the segment (2). A capsule lying across a box's
    face rests on the face's two sides: held at its one nearest point, it rocked about it, and a 10 kg capsule on a
    0.1 kg cube sank 14 mm into it in 0.5 s (found 2026-12-07)."""
    r = shapes.radius[a]
    s0, s1 = segment(shapes, a, y, R)
    k = 0
    for e in range(2):
        end = s0 if e == 0 else s1
        dist, surface, n = point_box(end, shapes, b, y, R)
        k = emit(sink, k, scale3(0.5, add3(sub3(end, scale3(r, n)), surface)), n, r - dist, e)
    t = nearest_along(s0, s1, shapes, b, y, R)
    p = add3(s0, scale3(t, sub3(s1, s0)))
    dist, surface, n = point_box(p, shapes, b, y, R)
    face = _face_of(R, b, n)
    if dist > 0.0 and face >= 0:
        return _over_face(shapes, b, y, R, sink, k, s0, s1, r, n, face)
    if 0.01 < t < 0.99:
        k = emit(sink, k, scale3(0.5, add3(sub3(p, scale3(r, n)), surface)), n, r - dist, 2)
    return k


@kernel
def _face_of(R, b, n):
    """k where the unit n is box b's face normal +-b_k, else -1 (an edge's or a corner's direction)."""
    for k in range(3):
        if abs(dot3(col3(R, b, k), n)) > 1.0 - 1e-9:
            return k
    return -1


@kernel
def _over_face(shapes, b, y, R, sink, k, s0, s1, r, n, face):
    """The contacts of the capsule axis s0..s1 (radius r) over box b's face along the outward unit n (face: its
    axis): the ends of the axis's part over the face's rectangle that are not the axis's own ends (those are the end
    spheres'), each at depth r less its height over the face, its point halfway between the capsule's surface and
    the face. Returns the pair's count so far."""
    f = add3(row3(y, b, 0), scale3(shapes.half[b, face], n))
    t0, t1, c0, c1 = clip_line(shapes, b, R, face, f, s0, s1)
    if t0 > t1:
        return k
    for e in range(2):
        t = t0 if e == 0 else t1
        if t <= 1e-9 or t >= 1.0 - 1e-9:
            continue
        q = add3(s0, scale3(t, sub3(s1, s0)))
        height = dot3(sub3(q, f), n)
        # midway between the capsule's surface q - r n and the face's point q - height n
        point = sub3(q, scale3(0.5 * (r + height), n))
        k = emit(sink, k, point, n, r - height, 3 + e)
    return k


@kernel
def nearest_along(s0, s1, shapes, b, y, R):
    """argmin over t in [0, 1] of the signed distance of s0 + t (s1 - s0) to box b, convex along the segment
    (the box is convex): golden-section search, the interval shrinks 0.618x a step (40 steps: 4.5e-9 of the
    segment, 0.5 nm of a 10 cm capsule's, as the Python phase's). The search runs in the box's frame
    (`box_distance`): a heap's capsule-box pairs took 2.3 us each when every look turned the point into the box's
    frame and the nearest point back out (0.7 of its narrow phase; now 0.6 us)."""
    g = 0.6180339887498949
    x = row3(y, b, 0)
    start, d = rotate_t(R, b, sub3(s0, x)), rotate_t(R, b, sub3(s1, s0))
    half = row3(shapes.half, b, 0)
    lo, hi = 0.0, 1.0
    c, e = hi - g, g
    fc = box_distance(add3(start, scale3(c, d)), half)
    fe = box_distance(add3(start, scale3(e, d)), half)
    for _ in range(40):
        if fc < fe:
            hi, e, fe = e, c, fc
            c = hi - g * (hi - lo)
            fc = box_distance(add3(start, scale3(c, d)), half)
        else:
            lo, c, fc = c, e, fe
            e = lo + g * (hi - lo)
            fe = box_distance(add3(start, scale3(e, d)), half)
    return 0.5 * (lo + hi)


@kernel
def box_distance(p, half):
    """The signed distance of p (the box's frame) to the box of half-extents `half`: with q_k = |p_k| - half_k,
    |max(q, 0)| outside, max_k q_k inside (out through the face with the least room, as point_box)."""
    qx, qy, qz = abs(p[0]) - half[0], abs(p[1]) - half[1], abs(p[2]) - half[2]
    # |max(q, 0)| + min(max_k q_k, 0)
    outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
    return outside + min(max(qx, qy, qz), 0.0)


# ---- box-box ---------------------------------------------------------------------------------------------------

@kernel
def gap(shapes, a, b, R, d, L):
    """gap(L) = |d . L| - sum_i ha_i |a_i . L| - sum_j hb_j |b_j . L| (module docstring)."""
    s = abs(dot3(d, L))
    for i in range(3):
        s -= shapes.half[a, i] * abs(dot3(col3(R, a, i), L)) + shapes.half[b, i] * abs(dot3(col3(R, b, i), L))
    return s


@kernel
def box_box(shapes, a, b, y, R, sink, work):
    d = sub3(row3(y, a, 0), row3(y, b, 0))
    fa, ia, fb, ib = -1e300, 0, -1e300, 0
    for i in range(3):
        s = gap(shapes, a, b, R, d, col3(R, a, i))
        if s > fa:
            fa, ia = s, i
        s = gap(shapes, a, b, R, d, col3(R, b, i))
        if s > fb:
            fb, ib = s, i
    fe, ie, je = -1e300, 0, 0
    for i in range(3):
        for j in range(3):
            L, length = unit3(cross3(col3(R, a, i), col3(R, b, j)))
            if length > PARALLEL_EDGES:
                s = gap(shapes, a, b, R, d, L)
                if s > fe:
                    fe, ie, je = s, i, j
    small = min(min(shapes.half[a, 0], shapes.half[a, 1]), min(shapes.half[a, 2], shapes.half[b, 0]))
    tol = EDGE_PREFERENCE * min(small, min(shapes.half[b, 1], shapes.half[b, 2]))
    best = max(fa, fb)
    if max(best, fe) > sink[6]:  # apart by more than the margin (written only with margin = inf)
        n = toward(col3(R, a, ia), d)
        return emit(sink, 0, scale3(0.5, add3(row3(y, a, 0), row3(y, b, 0))), n, -max(best, fe), APART)
    edge = fe > best + tol
    if edge and (fe > 0.0 or not _flat(R, a, b, ia, ib, ie, je)):
        return edge_contact(shapes, a, b, y, R, sink, ie, je, fe)
    # (crossed edges that touch lying flat: the face's points, each no deeper than the boxes overlap, -fe; or the
    # edges' point when no point of the incident face is on the face)
    cap = -fe if edge else math.inf
    if fb > fa + tol:  # the reference face is b's, facing a (along n); a's face is clipped against it
        n = toward(col3(R, b, ib), d)
        count = face_contact(shapes, b, a, ib, n, n, y, R, sink, work, 1, best, cap)
    else:
        n = toward(col3(R, a, ia), d)
        count = face_contact(shapes, a, b, ia, scale3(-1.0, n), n, y, R, sink, work, 0, best, cap)
    return edge_contact(shapes, a, b, y, R, sink, ie, je, fe) if count < 0 else count


@kernel
def _flat(R, a, b, ia, ib, ie, je):
    """Whether edges a_ie and b_je lie nearly flat in face ia of a or face ib of b: their common normal within
    FLAT_EDGES of that face's normal."""
    L = unit3(cross3(col3(R, a, ie), col3(R, b, je)))[0]
    return max(abs(dot3(L, col3(R, a, ia))), abs(dot3(L, col3(R, b, ib)))) >= FLAT_EDGES


@kernel
def toward(axis, d):
    """The axis, signed to point from b toward a (d = x_a - x_b)."""
    return axis if dot3(axis, d) >= 0.0 else scale3(-1.0, axis)


@kernel
def face_contact(shapes, r, o, k, out, n, y, R, sink, work, side, best, cap):
    """Box o's incident face clipped against face k of box r, whose outward normal `out` faces o; n (from b
    toward a) is the contacts' normal, side 0 when r is a. A clipped point p is depth -(p - c) . out below the
    reference face (c its centre; written no deeper than cap), its contact point halfway back up,
    p + out depth / 2. When no point of the incident face lies on the reference face: -1 if cap is finite (crossed
    edges lying flat: the caller's edge contact), else o's deepest corner."""
    c = add3(row3(y, r, 0), scale3(shapes.half[r, k], out))
    face = 2 * k + (0 if dot3(out, col3(R, r, k)) > 0.0 else 1)
    base = 64 * (6 * (6 * side + face) + incident_face(shapes, o, scale3(-1.0, out), y, R, work))
    count, src = 4, 0
    for q in range(2):
        axis = col3(R, r, (k + 1 + q) % 3)
        extent, at = shapes.half[r, (k + 1 + q) % 3], dot3(c, axis)
        # the side planes u . p <= u . c + extent and -u . p <= -u . c + extent
        count = clip(work, src, 8 - src, count, axis, at + extent, 4 + 2 * q)
        count = clip(work, 8 - src, src, count, scale3(-1.0, axis), extent - at, 5 + 2 * q)
    m = 0
    for i in range(count):  # the points within margin below the face, to rows 8..
        if -dot3(sub3(row3(work, i, 0), c), out) >= -sink[6]:
            for col in range(4):
                work[8 + m, col] = work[i, col]
            m += 1
    if m == 0:
        if -best < -sink[6]:
            return 0
        if cap < math.inf:
            return -1
        # the incident face lies beside the reference face (a small box deep in a large one): o's deepest corner,
        # x_o + sum_j sign(o_j . -out) h_j o_j
        p = row3(y, o, 0)
        for j in range(3):
            axis = col3(R, o, j)
            p = add3(p, scale3(-sign(dot3(axis, out)) * shapes.half[o, j], axis))
        return emit(sink, 0, p, n, -best, SUPPORT)
    i0, i1, i2, i3 = reduce4(work, m, c, out)
    kept = 0
    for i in range(8, 8 + m):
        if m <= 4 or i == i0 or i == i1 or i == i2 or i == i3:
            p = row3(work, i, 0)
            depth = -dot3(sub3(p, c), out)
            kept = emit(sink, kept, add3(p, scale3(0.5 * depth, out)), n, min(depth, cap), base + int(work[i, 3]))
    return kept


@kernel
def incident_face(shapes, o, facing, y, R, work):
    """The corners of box o's face whose outward normal is nearest `facing`, in order around it, to rows 0-3 of
    work (corner e between edges e - 1 and e: tag 8 min + max); returns the face's number."""
    kk, best = 0, -1.0
    for j in range(3):
        if abs(dot3(col3(R, o, j), facing)) > best:
            kk, best = j, abs(dot3(col3(R, o, j), facing))
    s = 1.0 if dot3(col3(R, o, kk), facing) >= 0.0 else -1.0
    centre = add3(row3(y, o, 0), scale3(s * shapes.half[o, kk], col3(R, o, kk)))
    e1 = scale3(shapes.half[o, (kk + 1) % 3], col3(R, o, (kk + 1) % 3))
    e2 = scale3(shapes.half[o, (kk + 2) % 3], col3(R, o, (kk + 2) % 3))
    for e in range(4):
        # corners c + e1 + e2, c - e1 + e2, c - e1 - e2, c + e1 - e2
        s1 = 1.0 if e == 0 or e == 3 else -1.0
        s2 = 1.0 if e < 2 else -1.0
        p = add3(centre, add3(scale3(s1, e1), scale3(s2, e2)))
        for col in range(3):
            work[e, col] = p[col]
        work[e, 3] = 3.0 if e == 0 else 8.0 * (e - 1) + e
    return 2 * kk + (0 if s > 0.0 else 1)


@kernel
def clip(work, src, dst, count, u, offset, line):
    """Sutherland-Hodgman: rows dst.. <- the part of polygon rows src..src+count with u . p <= offset; a new
    vertex, where edge p-q crosses the plane, lies on the line p and q share and on this plane's `line`."""
    k = 0
    for i in range(count):
        j = src + (i + 1) % count
        p, q = row3(work, src + i, 0), row3(work, j, 0)
        dp, dq = dot3(u, p) - offset, dot3(u, q) - offset
        if dp <= 0.0:
            for col in range(4):
                work[dst + k, col] = work[src + i, col]
            k += 1
        if (dp < 0.0 < dq) or (dq < 0.0 < dp):
            # p + (q - p) dp / (dp - dq): on the plane
            v = add3(p, scale3(dp / (dp - dq), sub3(q, p)))
            for col in range(3):
                work[dst + k, col] = v[col]
            shared = shared_line(int(work[src + i, 3]), int(work[j, 3]))
            work[dst + k, 3] = 8.0 * min(shared, line) + max(shared, line)
            k += 1
    return k


@kernel
def shared_line(tp, tq):
    """The line two vertices (tags 8 l1 + l2) lie on together (the first of p's when they share none)."""
    p1, p2, q1, q2 = tp // 8, tp % 8, tq // 8, tq % 8
    if p1 == q1 or p1 == q2:
        return p1
    return p2


@kernel
def reduce4(work, m, c, out):
    """Rows of the (at most) four points kept of rows 8..8+m (all of them when m <= 4; -1: none): the deepest,
    the farthest from it, the one spanning the largest triangle with those, the one adding the most area."""
    if m <= 4:
        return -1, -1, -1, -1
    i0, i1, i2, i3, top = 8, -1, -1, -1, -1e300
    for i in range(8, 8 + m):
        if -dot3(sub3(row3(work, i, 0), c), out) > top:
            i0, top = i, -dot3(sub3(row3(work, i, 0), c), out)
    p0, top = row3(work, i0, 0), -1.0
    for i in range(8, 8 + m):
        if dot3(sub3(row3(work, i, 0), p0), sub3(row3(work, i, 0), p0)) > top:
            i1, top = i, dot3(sub3(row3(work, i, 0), p0), sub3(row3(work, i, 0), p0))
    p1, top = row3(work, i1, 0), 0.0
    for i in range(8, 8 + m):
        # twice the area of triangle p0 p1 p, signed about out
        area = dot3(cross3(sub3(p1, p0), sub3(row3(work, i, 0), p0)), out)
        if abs(area) > top:
            i2, top = i, abs(area)
    if i2 < 0:
        return i0, i1, -1, -1
    p2, top = row3(work, i2, 0), 0.0
    turn = sign(dot3(cross3(sub3(p1, p0), sub3(p2, p0)), out))
    for i in range(8, 8 + m):
        p = row3(work, i, 0)
        # the area p adds beyond the triangle's edges (positive outside an edge)
        grow = max(max(-turn * dot3(cross3(sub3(p1, p0), sub3(p, p0)), out),
                       -turn * dot3(cross3(sub3(p2, p1), sub3(p, p1)), out)),
                   -turn * dot3(cross3(sub3(p0, p2), sub3(p, p2)), out))
        if grow > top:
            i3, top = i, grow
    return i0, i1, i2, i3


@kernel
def edge_contact(shapes, a, b, y, R, sink, i, j, separation):
    """Crossed edges a_i and b_j: each box's edge along that axis on its side facing the other (its support
    point toward it), and the closest points pa + s a_i, pb + t b_j of the two lines, clamped to the edges."""
    xa, xb = row3(y, a, 0), row3(y, b, 0)
    da, db = col3(R, a, i), col3(R, b, j)
    n = toward(unit3(cross3(da, db))[0], sub3(xa, xb))
    pa, pb = xa, xb
    for k in range(3):
        if k != i:
            axis = col3(R, a, k)
            pa = sub3(pa, scale3(sign(dot3(axis, n)) * shapes.half[a, k], axis))
        if k != j:
            axis = col3(R, b, k)
            pb = add3(pb, scale3(sign(dot3(axis, n)) * shapes.half[b, k], axis))
    w = sub3(pa, pb)
    cab = dot3(da, db)
    denom = 1.0 - cab * cab
    # s = (c (b_j . w) - a_i . w) / (1 - c^2), c = a_i . b_j; t = b_j . w + c s
    s = clamp((cab * dot3(db, w) - dot3(da, w)) / denom, -shapes.half[a, i], shapes.half[a, i]) \
        if denom > 1e-12 else 0.0
    t = clamp(dot3(db, w) + cab * s, -shapes.half[b, j], shapes.half[b, j])
    point = scale3(0.5, add3(add3(pa, scale3(s, da)), add3(pb, scale3(t, db))))
    return emit(sink, 0, point, n, -separation, EDGE + 3 * i + j)
