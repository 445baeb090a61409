"""What the compiled contact tests share: the writer of one contact (`emit`), and small geometry on 3-vectors held
as tuples of floats (an axis segment, the closest point of a segment, of a box, two spheres).

A test writes through a `sink`, the tuple (point, normal, depth, feature, first, capacity, margin) that
`narrow.pair_contacts` packs from its arguments: contact k of the pair goes to slot first + k, when it fits.
"""
from __future__ import annotations

from ..core.jit import kernel
from ..core.vec import add3, cross3, dot3, norm3, rotate, rotate_t, row3, scale3, sub3

UP = (0.0, 1.0, 0.0)


@kernel
def emit(sink, k, p, n, d, f):
    """Contact number k of the pair (point p, normal n, depth d, feature f) at slot first + k when d >= -margin;
    never written at or past capacity (the count still grows: the caller sees it and grows its buffers).
    Returns the pair's count so far."""
    point, normal, depth, feature, first, capacity, margin = sink
    if not d >= -margin:
        return k
    i = first + k
    if i < capacity:
        for c in range(3):
            point[i, c] = p[c]
            normal[i, c] = n[c]
        depth[i] = d
        feature[i] = f
    return k + 1


@kernel
def flip(normal, first, count, capacity):
    """Reverse the normals a swapped test wrote (it ran with b as a)."""
    for i in range(first, min(first + count, capacity)):
        for c in range(3):
            normal[i, c] = -normal[i, c]


@kernel
def unit3(v):
    """(v / |v|, |v|); a zero vector gives (UP, 0)."""
    length = norm3(v)
    if length > 1e-12:
        return scale3(1.0 / length, v), length
    return UP, 0.0


@kernel
def col3(R, b, k):
    """Column k of R[b]: body b's axis k in the world."""
    return (R[b, 0, k], R[b, 1, k], R[b, 2, k])


@kernel
def sign(v):
    return 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)


@kernel
def clamp(v, lo, hi):
    return lo if v < lo else (min(v, hi))


@kernel
def plane_of(shapes, b, y, R):
    """World normal and a point of plane body b."""
    return rotate(R, b, row3(shapes.normal, b, 0)), row3(y, b, 0)


@kernel
def segment(shapes, i, y, R):
    """End points x -/+ z hl of the axis segment of a capsule or cylinder."""
    half = scale3(shapes.half_length[i], col3(R, i, 2))
    x = row3(y, i, 0)
    return sub3(x, half), add3(x, half)


@kernel
def closest_on_segment(p, s0, s1):
    """s0 + t d, t = clamp((p - s0) . d / d . d, 0, 1), d = s1 - s0."""
    d = sub3(s1, s0)
    dd = dot3(d, d)
    t = 0.0 if dd < 1e-24 else clamp(dot3(sub3(p, s0), d) / dd, 0.0, 1.0)
    return add3(s0, scale3(t, d))


@kernel
def spheres(ca, ra, cb, rb):
    """(point, normal, depth) of sphere (ca, ra) against (cb, rb): depth = ra + rb - |ca - cb|, the point midway
    between a's deepest point ca - n ra and b's cb + n rb."""
    n, dist = unit3(sub3(ca, cb))
    point = scale3(0.5, add3(sub3(ca, scale3(ra, n)), add3(cb, scale3(rb, n))))
    return point, n, ra + rb - dist


@kernel
def point_box(p, shapes, b, y, R):
    """(signed distance, nearest surface point, outward normal), world, of point p to box b. Inside: out through
    the face with the least room h_k - |l_k|."""
    local = rotate_t(R, b, sub3(p, row3(y, b, 0)))
    h = row3(shapes.half, b, 0)
    clamped = (clamp(local[0], -h[0], h[0]), clamp(local[1], -h[1], h[1]), clamp(local[2], -h[2], h[2]))
    x = row3(y, b, 0)
    if clamped[0] == local[0] and clamped[1] == local[1] and clamped[2] == local[2]:
        k, room = 0, h[0] - abs(local[0])
        for c in range(1, 3):
            if h[c] - abs(local[c]) < room:
                k, room = c, h[c] - abs(local[c])
        s = 1.0 if local[k] >= 0.0 else -1.0
        e = (s if k == 0 else 0.0, s if k == 1 else 0.0, s if k == 2 else 0.0)
        surface = (e[0] * h[0] if k == 0 else local[0], e[1] * h[1] if k == 1 else local[1],
                   e[2] * h[2] if k == 2 else local[2])
        return -room, add3(x, rotate(R, b, surface)), rotate(R, b, e)
    diff = sub3(local, clamped)
    dist = norm3(diff)
    return dist, add3(x, rotate(R, b, clamped)), rotate(R, b, scale3(1.0 / dist, diff))


@kernel
def perpendicular(axis):
    """A unit vector across axis: axis x UP, or axis x X when axis is near UP."""
    other = UP if abs(dot3(axis, UP)) < 0.9 else (1.0, 0.0, 0.0)
    return unit3(cross3(axis, other))[0]


@kernel
def segment_segment(p1, q1, p2, q2):
    """Closest points p1 + s d1, p2 + t d2 of two segments (Ericson, Real-Time Collision Detection 5.1.9):
    s = (b f - c e) / (a e - b^2), t = (b s + f) / e, each clamped and the other recomputed."""
    d1, d2, r = sub3(q1, p1), sub3(q2, p2), sub3(p1, p2)
    a, e, f = dot3(d1, d1), dot3(d2, d2), dot3(d2, r)
    s, t = 0.0, 0.0
    if a <= 1e-24 and e <= 1e-24:
        return p1, p2
    if a <= 1e-24:
        t = clamp(f / e, 0.0, 1.0)
    else:
        c = dot3(d1, r)
        if e <= 1e-24:
            s = clamp(-c / a, 0.0, 1.0)
        else:
            b = dot3(d1, d2)
            denom = a * e - b * b
            s = clamp((b * f - c * e) / denom, 0.0, 1.0) if denom > 1e-24 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = clamp(-c / a, 0.0, 1.0), 0.0
            elif t > 1.0:
                s, t = clamp((b - c) / a, 0.0, 1.0), 1.0
    return add3(p1, scale3(s, d1)), add3(p2, scale3(t, d2))


@kernel
def clip_line(shapes, b, R, k, f, p0, p1):
    """The part t0..t1 of p0 + t (p1 - p0), t in [0, 1], over the rectangle of box b's face k (centre f), and the
    side (2 q + 0 for +b_j, 1 for -b_j, j = k + 1 + q) that cut each end (-1: not cut); t0 > t1: none of it.
    Liang-Barsky: side s (sign g) keeps g (a0 + t (a1 - a0)) <= h."""
    t0, t1, c0, c1 = 0.0, 1.0, -1, -1
    for q in range(2):
        j = (k + 1 + q) % 3
        axis, h = col3(R, b, j), shapes.half[b, j]
        a0, a1 = dot3(sub3(p0, f), axis), dot3(sub3(p1, f), axis)
        for s in range(2):
            g = 1.0 - 2.0 * s
            v, dv = g * a0 - h, g * (a1 - a0)
            if dv == 0.0:
                if v > 0.0:
                    return 1.0, 0.0, -1, -1
            elif dv > 0.0:
                if -v / dv < t1:
                    t1, c1 = -v / dv, 2 * q + s
            elif -v / dv > t0:
                t0, c0 = -v / dv, 2 * q + s
    return t0, t1, c0, c1
