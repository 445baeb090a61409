"""Compiled narrow phase: the contact points of one pair of bodies in closed form, written into the caller's arrays
with no allocation (numba, `_nrt=False`: 3-vectors are tuples of floats).

    count = pair_contacts(shapes, a, b, y, R, margin, point, normal, depth, feature, first, capacity, work)

shapes: the model's Shapes (core/model.py; kinds SHAPE_*, shapes in the body frame, capsule and cylinder axes along
body z); y (n+1,13) the state (position y[i, 0:3]); R (n+1,3,3) the bodies' rotations (body -> world). A plane
body is the half-space below the surface through its position with world normal R normal.
Contact k of the pair goes to slot first + k of

    point (C,3)    world, midway between the two surfaces
    normal (C,3)   unit, from b toward a: an impulse +j n on a and -j n on b pushes them apart
    depth (C,)     penetration, m (negative: a gap)
    feature (C,)   int64, which feature made the point: the same while the same features touch, unique in the pair
                   (a box's corner; a capsule's end 0, 1, its nearest axis point 2 or the ends of its axis over a box's face 3, 4; a clipped vertex: boxes.py;
                   a rim point, clipped line end or box corner of a cylinder on a box, a rim point or capsule
                   end of a cylinder on a cylinder or capsule: cylinders.py)

keeping the points with depth >= -margin (margin = inf: every test writes at least its closest feature, so
-max(depth) is the pair's signed distance). Nothing is written at or past capacity; the count returned is the
whole count, so first + count > capacity tells the caller to grow its buffers and call again.
work (16,4) float64 is scratch for the box-box clipping (boxes.py); its contents on return mean nothing.
Pairs without a closed form here (meshes, two planes) give 0: `closed_form` says which pairs are handled (every
pair of sphere, box, capsule, cylinder and plane but plane-plane; cylinder against box, cylinder or capsule too,
which the Python phase leaves to fcl).
"""
from __future__ import annotations

import math

from ..core.jit import kernel
from ..core.model import SHAPE_BOX, SHAPE_CAPSULE, SHAPE_CYLINDER, SHAPE_PLANE, SHAPE_SPHERE
from ..core.vec import add3, cross3, dot3, norm3, rotate, rotate_t, row3, scale3, sub3
from .boxes import box_box, box_plane, capsule_box, sphere_box
from .common import (clamp, closest_on_segment, col3, emit, flip, perpendicular, plane_of, segment, segment_segment,
                     spheres, unit3)
from .cylinders import cylinder_box, cylinder_capsule, cylinder_cylinder
from .kinds import closed_form  # noqa: F401 (the pairs pair_contacts handles, for its callers)

# cosines closer to 1 than this count as parallel segments (a capsule lying along another: two points)
PARALLEL_COS = 1.0 - 1e-6


# ---- spheres ---------------------------------------------------------------------------------------------------

@kernel
def sphere_sphere(shapes, a, b, y, R, sink):
    p, n, d = spheres(row3(y, a, 0), shapes.radius[a], row3(y, b, 0), shapes.radius[b])
    return emit(sink, 0, p, n, d, 0)


@kernel
def sphere_plane(shapes, a, b, y, R, sink):
    n, p0 = plane_of(shapes, b, y, R)
    r, x = shapes.radius[a], row3(y, a, 0)
    # centre height s = (x - p0) . n; deepest point x - n r, the surface under it x - n s: midway x - n (r + s) / 2
    s = dot3(sub3(x, p0), n)
    return emit(sink, 0, sub3(x, scale3(0.5 * (r + s), n)), n, r - s, 0)


@kernel
def sphere_capsule(shapes, a, b, y, R, sink):
    s0, s1 = segment(shapes, b, y, R)
    x = row3(y, a, 0)
    p, n, d = spheres(x, shapes.radius[a], closest_on_segment(x, s0, s1), shapes.radius[b])
    return emit(sink, 0, p, n, d, 0)


@kernel
def sphere_cylinder(shapes, a, b, y, R, sink):
    """The solid cylinder b's point nearest the sphere's centre, in b's frame (axis z); a centre inside leaves
    through the nearer of the side (room r - rho) and the cap (room hl - |z|)."""
    r, hl, rs = shapes.radius[b], shapes.half_length[b], shapes.radius[a]
    xa, xb = row3(y, a, 0), row3(y, b, 0)
    local = rotate_t(R, b, sub3(xa, xb))
    radial, rho = unit3((local[0], local[1], 0.0))
    if rho <= r and abs(local[2]) <= hl:
        if r - rho < hl - abs(local[2]):
            normal, surface, depth = radial, (r * radial[0], r * radial[1], local[2]), rs + r - rho
        else:
            s = 1.0 if local[2] >= 0.0 else -1.0
            normal, surface, depth = (0.0, 0.0, s), (local[0], local[1], s * hl), rs + hl - abs(local[2])
    else:
        rc = min(rho, r)
        surface = (rc * radial[0], rc * radial[1], clamp(local[2], -hl, hl))
        normal, dist = unit3(sub3(local, surface))
        depth = rs - dist
    n = rotate(R, b, normal)
    point = scale3(0.5, add3(sub3(xa, scale3(rs, n)), add3(xb, rotate(R, b, surface))))
    return emit(sink, 0, point, n, depth, 0)


# ---- capsules ----------------------------------------------------------------------------------------------

@kernel
def capsule_capsule(shapes, a, b, y, R, sink):
    """Closest points of the two axis segments; two capsules lying side by side (axes within PARALLEL_COS) touch
    along a line, given as its two ends (features 0, 1)."""
    a0, a1 = segment(shapes, a, y, R)
    b0, b1 = segment(shapes, b, y, R)
    ra, rb = shapes.radius[a], shapes.radius[b]
    ua, la = unit3(sub3(a1, a0))
    db = sub3(b1, b0)
    lb = norm3(db)
    if la > 1e-12 and lb > 1e-12 and abs(dot3(ua, db)) >= PARALLEL_COS * lb:
        # b's ends projected on a's axis, clamped to a: the ends of the overlap
        t0, t1 = dot3(sub3(b0, a0), ua), dot3(sub3(b1, a0), ua)
        s0, s1 = clamp(min(t0, t1), 0.0, la), clamp(max(t0, t1), 0.0, la)
        if s1 - s0 > 1e-9:
            k = 0
            for e in range(2):
                pa = add3(a0, scale3(s0 if e == 0 else s1, ua))
                p, n, d = spheres(pa, ra, closest_on_segment(pa, b0, b1), rb)
                k = emit(sink, k, p, n, d, e)
            return k
    pa, pb = segment_segment(a0, a1, b0, b1)
    p, n, d = spheres(pa, ra, pb, rb)
    return emit(sink, 0, p, n, d, 0)


@kernel
def capsule_plane(shapes, a, b, y, R, sink):
    """Each end sphere against the plane (features 0, 1): a capsule lying flat rests on two points."""
    n, p0 = plane_of(shapes, b, y, R)
    r = shapes.radius[a]
    s0, s1 = segment(shapes, a, y, R)
    k = 0
    for e in range(2):
        end = s0 if e == 0 else s1
        s = dot3(sub3(end, p0), n)
        k = emit(sink, k, sub3(end, scale3(0.5 * (r + s), n)), n, r - s, e)
    return k


# ---- cylinders ---------------------------------------------------------------------------------------------

@kernel
def cylinder_plane(shapes, a, b, y, R, sink):
    """Four points on each cap's rim (feature 4 cap + k), the first the rim's lowest point toward the plane
    (down: -n with its part along the axis removed), then a quarter turn apart: a cylinder on a cap rests on
    four, on its side on two (the lowest of each cap), tilted on its lowest rim point."""
    n, p0 = plane_of(shapes, b, y, R)
    axis, r = col3(R, a, 2), shapes.radius[a]
    down, length = unit3(sub3(scale3(dot3(n, axis), axis), n))
    if length < 1e-9:  # standing square on a cap: any direction across the axis
        down = perpendicular(axis)
    side = cross3(axis, down)
    s0, s1 = segment(shapes, a, y, R)
    k = 0
    for f in range(8):
        q = f % 4
        rim = scale3(r if q < 2 else -r, down if q % 2 == 0 else side)
        p = add3(s0 if f < 4 else s1, rim)
        d = -dot3(sub3(p, p0), n)
        k = emit(sink, k, add3(p, scale3(0.5 * d, n)), n, d, f)
    return k


# ---- dispatch ----------------------------------------------------------------------------------------------

@kernel
def ordered(shapes, ka, kb, a, b, y, R, sink, work):
    """The test of (kind a, kind b) in the order it is written for; -1: none in this order."""
    if ka == SHAPE_SPHERE:
        if kb == SHAPE_SPHERE:
            return sphere_sphere(shapes, a, b, y, R, sink)
        if kb == SHAPE_PLANE:
            return sphere_plane(shapes, a, b, y, R, sink)
        if kb == SHAPE_BOX:
            return sphere_box(shapes, a, b, y, R, sink)
        if kb == SHAPE_CAPSULE:
            return sphere_capsule(shapes, a, b, y, R, sink)
        if kb == SHAPE_CYLINDER:
            return sphere_cylinder(shapes, a, b, y, R, sink)
    elif ka == SHAPE_BOX:
        if kb == SHAPE_BOX:
            return box_box(shapes, a, b, y, R, sink, work)
        if kb == SHAPE_PLANE:
            return box_plane(shapes, a, b, y, R, sink)
    elif ka == SHAPE_CAPSULE:
        if kb == SHAPE_CAPSULE:
            return capsule_capsule(shapes, a, b, y, R, sink)
        if kb == SHAPE_PLANE:
            return capsule_plane(shapes, a, b, y, R, sink)
        if kb == SHAPE_BOX:
            return capsule_box(shapes, a, b, y, R, sink)
    elif ka == SHAPE_CYLINDER:
        if kb == SHAPE_PLANE:
            return cylinder_plane(shapes, a, b, y, R, sink)
        if kb == SHAPE_BOX:
            return cylinder_box(shapes, a, b, y, R, sink)
        if kb == SHAPE_CYLINDER:
            return cylinder_cylinder(shapes, a, b, y, R, sink)
        if kb == SHAPE_CAPSULE:
            return cylinder_capsule(shapes, a, b, y, R, sink)
    return -1


@kernel
def pair_contacts(shapes, a, b, y, R, margin, point, normal, depth, feature, first, capacity, work):
    """The contacts of pair (a, b) at slots first.. (module docstring); returns their count (0: none, or a pair
    without a closed form)."""
    sink = (point, normal, depth, feature, first, capacity, margin)
    ka, kb = shapes.kind[a], shapes.kind[b]
    count = ordered(shapes, ka, kb, a, b, y, R, sink, work)
    if count >= 0:
        return count
    # the test written for (b, a): its normals point from a toward b
    count = ordered(shapes, kb, ka, b, a, y, R, sink, work)
    if count > 0:
        flip(normal, first, count, capacity)
    return max(count, 0)


# ---- bounds ------------------------------------------------------------------------------------------------

@kernel
def bounds(shapes, i, y, R, box):
    """box[i] = (lo, hi), body i's world axis-aligned bounding box, no margin. A box of half-extents h turned by
    R: centre R c + x, half-extents |R| h; a sphere: r; a capsule or cylinder along world axis u: |u_k| hl + r
    (capsule), |u_k| hl + r sqrt(1 - u_k^2) (cylinder); a plane: -inf, +inf."""
    kind = shapes.kind[i]
    centre = add3(row3(y, i, 0), rotate(R, i, row3(shapes.centre, i, 0)))
    for k in range(3):
        if kind == SHAPE_PLANE:
            extent = math.inf
        elif kind == SHAPE_SPHERE:
            extent = shapes.radius[i]
        elif kind == SHAPE_CAPSULE or kind == SHAPE_CYLINDER:
            u, r = R[i, k, 2], shapes.radius[i]
            extent = abs(u) * shapes.half_length[i] + (r if kind == SHAPE_CAPSULE else
                                                      r * math.sqrt(max(1.0 - u * u, 0.0)))
        else:
            extent = 0.0
            for j in range(3):
                extent += abs(R[i, k, j]) * shapes.half[i, j]
        box[i, k] = centre[k] - extent
        box[i, 3 + k] = centre[k] + extent
