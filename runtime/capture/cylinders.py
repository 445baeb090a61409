"""Compiled cylinder-box test (conventions: narrow.py; a cylinder's axis along its body z, radius r, half length hl).

The separation along a unit axis L, as for two boxes (boxes.py), with the cylinder's half extent along L

    gap(L) = |d . L| - (|u . L| hl + r sqrt(1 - (u . L)^2)) - sum_j h_j |b_j . L|,    d = x_cyl - x_box,

over the candidate axes: the box's face normals (0-2), the cylinder's axis u (3), the crosses b_j x u (4-6: an
edge against the side), for each box corner the direction from the cylinder's nearest point to it (8-15: a corner
against a rim), and the best across each edge direction b_i in each of two quarter turns (16-21: an edge against
a rim, or lying along the side: `across_edge`; 7 is none). Every gap is at most the signed distance (which is the
largest gap over all directions), so the largest is the closest to it (the pair's -depth). A face normal wins
unless another axis beats it by PREFERENCE of the smallest size (a resting cylinder picks the face), the axis
unless another beats it so.

On a face normal or the axis: the box face facing the cylinder most is the reference face, and the contacts are

    the cylinder's lowest line (the rim points of each cap nearest the face, down: -n with its part along u
    removed) clipped to the face's rectangle: its two ends (features 0 and 4, or 8 + 4 end + the side that
    clipped it);
    the other rim points a quarter turn apart (4 cap + q, q = 1..3) inside the rectangle;
    the face's corners inside the cylinder (16 + corner), their depth the cylinder's closed-form penetration;

a rim point's depth is how far it lies below the face, its contact point halfway back up. A cylinder standing on
a face rests on the rim points of its cap (four), lying on it on its lowest line (two), tilted on its lowest rim
point; a box on a cap rests on its corners within the disc. Each feature is 32 face + the one above. On any other
axis, one point (192 + the axis) midway between the closest points of the two supports along it (a box's edge or
corner; the cylinder's side line or rim point).
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from ..core.vec import add3, cross3, dot3, norm3, row3, scale3, sub3
from .boxes import corner, toward
from .common import (UP, clamp, clip_line, closest_on_segment, col3, emit, perpendicular, segment, segment_segment,
                     sign, unit3)

PREFERENCE = 1e-3
# crosses of nearly parallel directions (|b_j x u| below this) are skipped: `across_edge` covers them
PARALLEL = 1e-6
# directions this close to across the axis (|u . n|), or to along a box face (|b_j . n|), make a support a line
FLAT = 1e-6
SINGLE, APART = 192, 224  # SINGLE + axis (0-21)


@kernel
def extent(u, r, hl, n):
    """The cylinder's half extent along unit n: |u . n| hl + r sqrt(1 - (u . n)^2)."""
    c = abs(dot3(u, n))
    return c * hl + r * math.sqrt(max(1.0 - c * c, 0.0))


@kernel
def gap(shapes, b, R, d, u, r, hl, n):
    s = abs(dot3(d, n)) - extent(u, r, hl, n)
    for j in range(3):
        s -= shapes.half[b, j] * abs(dot3(col3(R, b, j), n))
    return s


@kernel
def point_cylinder(p, c, u, r, hl):
    """(signed distance, nearest surface point) of p to the solid cylinder (centre c, axis u); a point inside
    leaves through the nearer of the side (room r - rho) and the cap (room hl - |z|)."""
    v = sub3(p, c)
    z = dot3(v, u)
    radial, rho = unit3(sub3(v, scale3(z, u)))
    if rho <= r and abs(z) <= hl:
        if r - rho < hl - abs(z):
            return rho - r, add3(c, add3(scale3(z, u), scale3(r, radial)))
        return abs(z) - hl, add3(c, add3(scale3(hl if z >= 0.0 else -hl, u), scale3(rho, radial)))
    s = add3(c, add3(scale3(clamp(z, -hl, hl), u), scale3(min(rho, r), radial)))
    return norm3(sub3(p, s)), s


@kernel
def candidate(shapes, b, y, R, c, u, r, hl, d, k):
    """(candidate axis k, whether it is one; module docstring)."""
    if k < 3:
        return col3(R, b, k), True
    if k == 3:
        return u, True
    if k < 8:  # (7: unused)
        n, length = unit3(cross3(col3(R, b, k - 4), u))
        return n, length > PARALLEL and k < 7
    if k < 16:
        q = corner(shapes, b, y, R, k - 8)
        n, length = unit3(sub3(q, point_cylinder(q, c, u, r, hl)[1]))
        return n, length > 1e-12
    return across_edge(shapes, b, R, d, u, r, hl, (k - 16) // 2, k % 2), True


@kernel
def cylinder_box(shapes, a, b, y, R, sink):
    c, u, r, hl = row3(y, a, 0), col3(R, a, 2), shapes.radius[a], shapes.half_length[a]
    x = row3(y, b, 0)
    d = sub3(c, x)
    ff, kf, fu, fo, io, no = -1e300, 0, -1e300, -1e300, 0, UP
    for k in range(22):
        n, valid = candidate(shapes, b, y, R, c, u, r, hl, d, k)
        g = gap(shapes, b, R, d, u, r, hl, n) if valid else -1e300
        if k < 3 and g > ff:
            ff, kf = g, k
        elif k == 3:
            fu = g
        elif k > 3 and g > fo:
            fo, io, no = g, k, n
    best = max(max(ff, fu), fo)
    if best > sink[6]:  # apart by more than the margin (written only with margin = inf)
        n = toward(col3(R, b, kf) if ff >= best else (u if fu >= best else no), d)
        return emit(sink, 0, scale3(0.5, add3(c, x)), n, -best, APART)
    small = min(min(r, hl), min(shapes.half[b, 0], min(shapes.half[b, 1], shapes.half[b, 2])))
    tol = PREFERENCE * small
    if fo > max(ff, fu) + tol:
        return single(shapes, a, b, y, R, sink, toward(no, d), -fo, SINGLE + io, 0)
    if fu > ff + tol:
        n = toward(u, d)
        k, top = 0, -1.0
        for j in range(3):
            if abs(dot3(col3(R, b, j), n)) > top:
                k, top = j, abs(dot3(col3(R, b, j), n))
        return cap_face(shapes, a, b, y, R, sink, k, n, -fu, 3, tol)
    return cap_face(shapes, a, b, y, R, sink, kf, toward(col3(R, b, kf), d), -ff, kf, tol)


@kernel
def across_edge(shapes, b, R, d, u, r, hl, i, quarter):
    """The axis of largest gap across box b's edges along b_i, n = cos t b_j + sin t b_k, t in the quarter turn
    [0, pi/2] or [pi/2, pi] (j, k = i + 1, i + 2; with -n, that quarter and the opposite one): a rim against an
    edge. Golden-section search (the gap is the 2-D signed distance of the shapes projected across b_i, one peak
    when they are apart): 41 steps, 2e-9 rad."""
    g = 0.6180339887498949
    bj, bk = col3(R, b, (i + 1) % 3), col3(R, b, (i + 2) % 3)
    lo, hi = 0.5 * math.pi * quarter, 0.5 * math.pi * (quarter + 1)
    c, e, fc, fe, which = hi - g * (hi - lo), lo + g * (hi - lo), 0.0, 0.0, 0
    for step in range(42):  # one gap a step, at c (which = 0) or e, the point the last step moved
        t = c if which == 0 else e
        f = gap(shapes, b, R, d, u, r, hl, add3(scale3(math.cos(t), bj), scale3(math.sin(t), bk)))
        if which == 0:
            fc = f
        else:
            fe = f
        if step == 0:
            which = 1
        elif fc > fe:
            hi, e, fe, which = e, c, fc, 0
            c = hi - g * (hi - lo)
        else:
            lo, c, fc, which = c, e, fe, 1
            e = lo + g * (hi - lo)
    t = 0.5 * (lo + hi)
    return add3(scale3(math.cos(t), bj), scale3(math.sin(t), bk))


@kernel
def cap_face(shapes, a, b, y, R, sink, k, n, depth, axis_index, tol):
    """The contacts on box b's face k facing the cylinder a (module docstring), normal n from b toward a; when
    none of them is within tol of the pair's depth (the deepest point lies beside the face): one more on the
    winning axis (its index axis_index) at that depth."""
    u, r = col3(R, a, 2), shapes.radius[a]
    m = toward(col3(R, b, k), n)  # the face's outward normal
    f = add3(row3(y, b, 0), scale3(shapes.half[b, k], m))
    base = 32 * (2 * k + (0 if dot3(m, col3(R, b, k)) > 0.0 else 1))
    down, length = unit3(sub3(scale3(dot3(n, u), u), n))
    if length < 1e-9:  # the axis along n: any direction across it
        down = perpendicular(u)
    side = cross3(u, down)
    s0, s1 = segment(shapes, a, y, R)
    p0, p1 = add3(s0, scale3(r, down)), add3(s1, scale3(r, down))
    t0, t1, c0, c1 = clip_line(shapes, b, R, k, f, p0, p1)
    kept, top = 0, -1e300
    if t0 <= t1:
        for e in range(2):
            p = add3(p0, scale3(t0 if e == 0 else t1, sub3(p1, p0)))
            clipped = c0 if e == 0 else c1
            h = -dot3(sub3(p, f), m)
            top = max(top, h)
            kept = emit(sink, kept, add3(p, scale3(0.5 * h, m)), n, h,
                        base + (4 * e if clipped < 0 else 8 + 4 * e + clipped))
    for i in range(8):
        q = i % 4
        if q > 0:
            p = add3(s0 if i < 4 else s1, scale3(r if q < 2 else -r, down if q % 2 == 0 else side))
            if inside_face(shapes, b, R, k, f, p):
                h = -dot3(sub3(p, f), m)
                top = max(top, h)
                kept = emit(sink, kept, add3(p, scale3(0.5 * h, m)), n, h, base + i)
    e1, e2 = (k + 1) % 3, (k + 2) % 3
    for i in range(4):
        q = add3(f, add3(scale3((1.0 if i & 1 else -1.0) * shapes.half[b, e1], col3(R, b, e1)),
                         scale3((1.0 if i & 2 else -1.0) * shapes.half[b, e2], col3(R, b, e2))))
        h = -point_cylinder(q, row3(y, a, 0), u, r, shapes.half_length[a])[0]
        top = max(top, h)
        kept = emit(sink, kept, sub3(q, scale3(0.5 * h, n)), n, h, base + 16 + i)
    if top < depth - tol:
        return single(shapes, a, b, y, R, sink, n, depth, SINGLE + axis_index, kept)
    return kept


@kernel
def inside_face(shapes, b, R, k, f, p):
    """Whether p lies over the rectangle of box b's face k (centre f)."""
    v = sub3(p, f)
    return (abs(dot3(v, col3(R, b, (k + 1) % 3))) <= shapes.half[b, (k + 1) % 3]
            and abs(dot3(v, col3(R, b, (k + 2) % 3))) <= shapes.half[b, (k + 2) % 3])


@kernel
def single(shapes, a, b, y, R, sink, n, depth, feature, k):
    """One contact at the given depth, midway between the closest points of the box's support toward the
    cylinder (+n: a corner, or an edge when n lies across it) and the cylinder's toward the box (-n: a rim
    point or its cap's centre, or a side line when n lies across the axis)."""
    p, edge = row3(y, b, 0), -1
    for j in range(3):
        axis, w = col3(R, b, j), dot3(col3(R, b, j), n)
        if abs(w) < FLAT and edge < 0:
            edge = j
        else:
            p = add3(p, scale3(sign(w) * shapes.half[b, j], axis))
    b0, b1 = p, p
    if edge >= 0:
        half = scale3(shapes.half[b, edge], col3(R, b, edge))
        b0, b1 = sub3(p, half), add3(p, half)
    u, r = col3(R, a, 2), shapes.radius[a]
    w = dot3(u, n)
    across = unit3(sub3(scale3(w, u), n))[0]
    s0, s1 = segment(shapes, a, y, R)
    a0, a1 = add3(s0, scale3(r, across)), add3(s1, scale3(r, across))
    if abs(w) >= FLAT:  # the cap facing -n
        cap = s0 if w > 0.0 else s1
        rim = cap if abs(w) > 1.0 - 1e-12 else add3(cap, scale3(r, across))
        a0, a1 = rim, rim
    pa, pb = segment_segment(a0, a1, b0, b1)
    return emit(sink, k, scale3(0.5, add3(pa, pb)), n, depth, feature)


# ---- cylinder against cylinder or capsule ------------------------------------------------------------------------
#
# The depth is minus the largest separation over directions n (as above),
#
#     gap(n) = |d . n| - extent_a(n) - extent_b(n),    extent of a capsule |u . n| hl + r,
#
# found by a pattern search on the sphere from the best of a few candidate directions (the axes, their cross, the
# line between the axes' closest points, the directions between each cap's centre and the other body). The
# contacts, all with the normal n from b toward a:
#
#     two cylinders or a cylinder and a capsule lying side by side (n across both axes, the axes parallel within
#     SIDE): the two ends of the overlap of the axes (features 0, 1), depth r_a + r_b - the axes' distance there;
#     else each cylinder's rim points (feature 8 body + 4 cap + q): on each cap its deepest toward the other body
#     (q = 0), and on the cap facing it (within 60 degrees of -n for a, of n for b) three more a quarter turn
#     apart; a capsule's end spheres (8 + 4 + end); each at its closed-form depth in the other body (-its signed distance to the solid cylinder, or to the
#     capsule's segment minus its radius);
#     when none of them is within TOL of the pair's depth (a side across a side, a rim across a rim): one more
#     (ACROSS) at that depth, midway between the closest points of the two supports along n.

SIDE = 1e-3  # |u_a x u_b| and |u . n| below this: lying side by side
TOL = 1e-3  # of the smallest size
FACING = 0.5  # |u . n| above this: a cap faces the other body (its quarter-turn rim points)
ACROSS = 32


@kernel
def round_extent(u, r, hl, n, capsule):
    return abs(dot3(u, n)) * hl + r if capsule else extent(u, r, hl, n)


@kernel
def round_gap(d, ua, ra, ha, ub, rb, hb, capsule, n):
    return abs(dot3(d, n)) - extent(ua, ra, ha, n) - round_extent(ub, rb, hb, n, capsule)


@kernel
def refine(d, ua, ra, ha, ub, rb, hb, capsule, n, f):
    """Pattern search from n: steps along two tangents, their diagonals and the two ridges (the great circles
    across each axis), halved when none gains, from 0.1 rad to 1e-9."""
    step = 0.1
    for _ in range(400):
        if step < 1e-9:
            break
        t1 = perpendicular(n)
        t2 = cross3(n, t1)
        moved = False
        bn, bf = n, f
        for j in range(12):
            m = j // 2
            if m == 0:
                t = t1
            elif m == 1:
                t = t2
            elif m == 2:
                t = unit3(add3(t1, t2))[0]
            elif m == 3:
                t = unit3(sub3(t1, t2))[0]
            else:
                t = unit3(cross3(ua if m == 4 else ub, n))[0]
            trial = unit3(add3(n, scale3(step if j % 2 == 0 else -step, t)))[0]
            g = round_gap(d, ua, ra, ha, ub, rb, hb, capsule, trial)
            if g > bf:
                bn, bf, moved = trial, g, True
        if moved:
            n, f = bn, bf
        else:
            step *= 0.5
    return n, f


@kernel
def round_support(c, u, r, hl, n, capsule):
    """The ends of the support of a cylinder or capsule along n: a line (its side) when n lies across the axis
    within FLAT, else a point (a rim point, a cap's centre, a capsule's end)."""
    w = dot3(u, n)
    across = unit3(sub3(n, scale3(w, u)))[0]
    half = scale3(hl, u)
    if capsule:
        if abs(w) < FLAT:
            return add3(sub3(c, half), scale3(r, n)), add3(add3(c, half), scale3(r, n))
        p = add3(add3(c, scale3(sign(w), half)), scale3(r, n))
        return p, p
    if abs(w) < FLAT:
        return add3(sub3(c, half), scale3(r, across)), add3(add3(c, half), scale3(r, across))
    p = add3(c, scale3(sign(w), half))
    if abs(w) < 1.0 - 1e-12:
        p = add3(p, scale3(r, across))
    return p, p


@kernel
def point_round(p, c, u, r, hl, capsule):
    """Signed distance of p to a solid cylinder or capsule."""
    if capsule:
        half = scale3(hl, u)
        return norm3(sub3(p, closest_on_segment(p, sub3(c, half), add3(c, half)))) - r
    return point_cylinder(p, c, u, r, hl)[0]


@kernel
def round_pair(shapes, a, b, y, R, sink, capsule):
    """Cylinder a against cylinder b, or capsule b when `capsule` (the docstring above)."""
    ca, ua, ra, ha = row3(y, a, 0), col3(R, a, 2), shapes.radius[a], shapes.half_length[a]
    cb, ub, rb, hb = row3(y, b, 0), col3(R, b, 2), shapes.radius[b], shapes.half_length[b]
    d = sub3(ca, cb)
    a0, a1 = sub3(ca, scale3(ha, ua)), add3(ca, scale3(ha, ua))
    b0, b1 = sub3(cb, scale3(hb, ub)), add3(cb, scale3(hb, ub))
    # candidates: keep the best three, refine each
    n1, n2, n3 = UP, UP, UP
    f1, f2, f3 = -1e300, -1e300, -1e300
    for k in range(9):
        if k == 0:
            n, ok = ua, True
        elif k == 1:
            n, ok = ub, True
        elif k == 2:
            n, length = unit3(cross3(ua, ub))
            ok = length > 1e-9
        elif k == 3:
            pa, pb = segment_segment(a0, a1, b0, b1)
            n, length = unit3(sub3(pa, pb))
            ok = length > 1e-12
        elif k == 4:
            n, length = unit3(d)
            ok = length > 1e-12
        else:  # 5-8: each cap centre of a (of b) to the other body's axis
            e = k - 5
            if e < 2:
                q = a0 if e == 0 else a1
                n, length = unit3(sub3(q, closest_on_segment(q, b0, b1)))
            else:
                q = b0 if e == 2 else b1
                n, length = unit3(sub3(closest_on_segment(q, a0, a1), q))
            ok = length > 1e-12
        if not ok:
            continue
        g = round_gap(d, ua, ra, ha, ub, rb, hb, capsule, n)
        if g > f1:
            n1, f1, n2, f2, n3, f3 = n, g, n1, f1, n2, f2
        elif g > f2:
            n2, f2, n3, f3 = n, g, n2, f2
        elif g > f3:
            n3, f3 = n, g
    best, nb = -1e300, UP
    for s in range(3):
        n0, g0 = (n1, f1) if s == 0 else ((n2, f2) if s == 1 else (n3, f3))
        if g0 > -1e299:
            n, g = refine(d, ua, ra, ha, ub, rb, hb, capsule, n0, g0)
            if g > best:
                best, nb = g, n
    n = nb if dot3(nb, d) >= 0.0 else scale3(-1.0, nb)
    depth = -best
    if best > sink[6]:  # apart by more than the margin (written only with margin = inf)
        return across_point(ca, ua, ra, ha, cb, ub, rb, hb, capsule, sink, n, depth, APART, 0)
    # side by side
    if (norm3(cross3(ua, ub)) < SIDE and abs(dot3(ua, n)) < SIDE and abs(dot3(ub, n)) < SIDE):
        t0, t1 = dot3(sub3(b0, a0), ua), dot3(sub3(b1, a0), ua)
        s0, s1 = clamp(min(t0, t1), 0.0, 2.0 * ha), clamp(max(t0, t1), 0.0, 2.0 * ha)
        if s1 - s0 > 1e-9:
            k = 0
            for e in range(2):
                pa = add3(a0, scale3(s0 if e == 0 else s1, ua))
                pb = closest_on_segment(pa, b0, b1)
                dist = norm3(sub3(pa, pb))
                h = ra + rb - dist
                # midway between a's surface (pa - n ra) and b's (pb + n rb)
                p = scale3(0.5, add3(sub3(pa, scale3(ra, n)), add3(pb, scale3(rb, n))))
                k = emit(sink, k, p, n, h, e)
            return k
    kept, top = 0, -1e300
    for body in range(2):
        if body == 1 and capsule:
            for e in range(2):
                end = b0 if e == 0 else b1
                sd, surface = point_cylinder(end, ca, ua, ra, ha)
                # midway between the surface point nearest the end's centre and the sphere's deepest point, along
                # the cylinder's outward normal there (n when the centre is on the surface)
                out, length = unit3(sub3(end, surface) if sd >= 0.0 else sub3(surface, end))
                if length < 1e-12:
                    out = n
                h = rb - sd
                top = max(top, h)
                kept = emit(sink, kept, scale3(0.5, add3(surface, sub3(end, scale3(rb, out)))), n, h, 8 + 4 + e)
            continue
        c, u, r, hl = (ca, ua, ra, ha) if body == 0 else (cb, ub, rb, hb)
        toward_other = scale3(-1.0, n) if body == 0 else n
        w = dot3(u, toward_other)
        down, length = unit3(sub3(toward_other, scale3(w, u)))
        if length < 1e-9:
            down = perpendicular(u)
        side = cross3(u, down)
        for i in range(8):
            q, cap = i % 4, i // 4  # cap 0: -hl, 1: +hl
            facing = abs(w) > FACING and (cap == 1) == (w > 0.0)
            if q > 0 and not facing:
                continue
            p = add3(add3(c, scale3(hl if cap == 1 else -hl, u)),
                     scale3(r if q < 2 else -r, down if q % 2 == 0 else side))
            if body == 0:
                h = -point_round(p, cb, ub, rb, hb, capsule)
                point = add3(p, scale3(0.5 * h, n))
            else:
                h = -point_cylinder(p, ca, ua, ra, ha)[0]
                point = sub3(p, scale3(0.5 * h, n))
            top = max(top, h)
            kept = emit(sink, kept, point, n, h, 8 * body + i)
    small = min(min(ra, ha), min(rb, hb) if not capsule else rb)
    if top < depth - TOL * small:
        return across_point(ca, ua, ra, ha, cb, ub, rb, hb, capsule, sink, n, depth, ACROSS, kept)
    return kept


@kernel
def across_point(ca, ua, ra, ha, cb, ub, rb, hb, capsule, sink, n, depth, feature, k):
    """One contact at the given depth midway between the closest points of a's support along -n and b's along n."""
    a0, a1 = round_support(ca, ua, ra, ha, scale3(-1.0, n), False)
    b0, b1 = round_support(cb, ub, rb, hb, n, capsule)
    pa, pb = segment_segment(a0, a1, b0, b1)
    return emit(sink, k, scale3(0.5, add3(pa, pb)), n, depth, feature)


@kernel
def cylinder_cylinder(shapes, a, b, y, R, sink):
    return round_pair(shapes, a, b, y, R, sink, False)


@kernel
def cylinder_capsule(shapes, a, b, y, R, sink):
    return round_pair(shapes, a, b, y, R, sink, True)
