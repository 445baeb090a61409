"""Narrow phase: closed-form contact tests for spheres, capsules, cylinders, boxes and planes.

Every test takes the shape table, the two bodies (a, b), the poses x (n,3) and R (n,3,3), and a margin, and
returns the contact points of the pair as arrays

    points (k,3)   world, midway between the two surfaces
    normals (k,3)  unit, from b toward a: an impulse +j n on a and -j n on b pushes them apart
    depths (k,)    penetration, m (negative: a gap)
    features (k,)  which corner / end / edge made the point (stable from step to step)

keeping the points with depth >= -margin. With margin = inf a test returns at least its closest feature, so
`-max(depths)` is the pair's signed distance (what the time-of-impact search needs).
Pairs with no closed form here go to python-fcl (meshes.py): see `closed_form`.
"""
from __future__ import annotations

import numpy as np

from .boxes import box_box, box_plane, capsule_box, sphere_box
from .shapes import BOX, CAPSULE, CYLINDER, MESH, PLANE, SPHERE, segment

UP = np.array([0.0, 1.0, 0.0])
# cosines closer to 1 than this count as parallel segments (a capsule lying along another)
PARALLEL_COS = 1.0 - 1e-6


def _keep(points, normals, depths, features, margin):
    keep = depths >= -margin
    if keep.all():
        return points, normals, depths, features
    return points[keep], normals[keep], depths[keep], features[keep]


def unit(v):
    n = np.linalg.norm(v)
    return (v / n, n) if n > 1e-12 else (UP.copy(), 0.0)


def _spheres(ca, ra, cb, rb, feature=0):
    """One sphere-sphere contact as 1-row arrays (the building block of capsules)."""
    n, dist = unit(ca - cb)
    depth = ra + rb - dist
    # midway between a's deepest point ca - n ra and b's cb + n rb
    point = 0.5 * (ca - n * ra + cb + n * rb)
    return point[None], n[None], np.array([depth]), np.array([feature])


def plane_of(table, b, x, R):
    """World normal and a point of plane body b."""
    return R[b] @ table.normal[b], x[b]


def closest_on_segment(p, s0, s1):
    d = s1 - s0
    dd = d @ d
    t = 0.0 if dd < 1e-24 else float(np.clip((p - s0) @ d / dd, 0.0, 1.0))
    return s0 + t * d


# ---- spheres ---------------------------------------------------------------------------------------------------

def sphere_sphere(table, a, b, x, R, margin):
    return _keep(*_spheres(x[a], table.radius[a], x[b], table.radius[b]), margin)


def sphere_plane(table, a, b, x, R, margin):
    n, p0 = plane_of(table, b, x, R)
    r = table.radius[a]
    s = (x[a] - p0) @ n
    # a's deepest point x - n r, the plane under the centre x - n s: the point is midway
    point = x[a] - n * 0.5 * (r + s)
    return _keep(point[None], n[None], np.array([r - s]), np.zeros(1, np.int64), margin)


def sphere_capsule(table, a, b, x, R, margin):
    q = closest_on_segment(x[a], *segment(table, b, x, R))
    return _keep(*_spheres(x[a], table.radius[a], q, table.radius[b]), margin)


def sphere_cylinder(table, a, b, x, R, margin):
    """Closest point of the solid cylinder b to the sphere's centre, in b's frame (axis z)."""
    r, hl, rs = table.radius[b], table.half_length[b], table.radius[a]
    local = R[b].T @ (x[a] - x[b])
    radial, rho = unit(np.array([local[0], local[1], 0.0]))
    if rho <= r and abs(local[2]) <= hl:  # centre inside: leave through the nearer of side and cap
        side, cap = r - rho, hl - abs(local[2])
        if side < cap:
            normal, surface, inside = radial, np.array([r * radial[0], r * radial[1], local[2]]), side
        else:
            sign = 1.0 if local[2] >= 0 else -1.0
            normal, surface, inside = np.array([0.0, 0.0, sign]), np.array([local[0], local[1], sign * hl]), cap
        depth = rs + inside
    else:
        surface = np.array([min(rho, r) * radial[0], min(rho, r) * radial[1], np.clip(local[2], -hl, hl)])
        normal, dist = unit(local - surface)
        depth = rs - dist
    n = R[b] @ normal
    world_surface = x[b] + R[b] @ surface
    point = 0.5 * (x[a] - n * rs + world_surface)
    return _keep(point[None], n[None], np.array([depth]), np.zeros(1, np.int64), margin)


# ---- capsules ----------------------------------------------------------------------------------------------

def capsule_capsule(table, a, b, x, R, margin):
    """Closest points of the two axis segments (Ericson, Real-Time Collision Detection 5.1.9); two capsules
    lying side by side touch along a line, given as the two ends of the overlap."""
    a0, a1 = segment(table, a, x, R)
    b0, b1 = segment(table, b, x, R)
    ra, rb = table.radius[a], table.radius[b]
    da, db = a1 - a0, b1 - b0
    la, lb = np.linalg.norm(da), np.linalg.norm(db)
    if la > 1e-12 and lb > 1e-12 and abs(da @ db) >= PARALLEL_COS * la * lb:
        ua = da / la
        # b's ends projected on a's axis, clipped to a: the overlap's ends, each with its closest point on b
        s = np.clip(sorted([(b0 - a0) @ ua, (b1 - a0) @ ua]), 0.0, la)
        if s[1] - s[0] > 1e-9:
            parts = [_spheres(a0 + si * ua, ra, closest_on_segment(a0 + si * ua, b0, b1), rb, k)
                     for k, si in enumerate(s)]
            return _keep(*(np.concatenate(p) for p in zip(*parts)), margin)
    pa, pb = _segment_segment(a0, a1, b0, b1)
    return _keep(*_spheres(pa, ra, pb, rb), margin)


def _segment_segment(p1, q1, p2, q2):
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    if a <= 1e-24 and e <= 1e-24:
        return p1, p2
    if a <= 1e-24:
        s, t = 0.0, np.clip(f / e, 0.0, 1.0)
    else:
        c = d1 @ r
        if e <= 1e-24:
            s, t = np.clip(-c / a, 0.0, 1.0), 0.0
        else:
            b = d1 @ d2
            denom = a * e - b * b
            s = np.clip((b * f - c * e) / denom, 0.0, 1.0) if denom > 1e-24 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = np.clip(-c / a, 0.0, 1.0), 0.0
            elif t > 1.0:
                s, t = np.clip((b - c) / a, 0.0, 1.0), 1.0
    return p1 + s * d1, p2 + t * d2


def capsule_plane(table, a, b, x, R, margin):
    """Each end sphere against the plane: a capsule lying flat rests on two points."""
    n, p0 = plane_of(table, b, x, R)
    r = table.radius[a]
    ends = np.array(segment(table, a, x, R))
    s = (ends - p0) @ n
    points = ends - n * (0.5 * (r + s))[:, None]
    return _keep(points, np.tile(n, (2, 1)), r - s, np.arange(2), margin)


# ---- cylinders ---------------------------------------------------------------------------------------------

def cylinder_plane(table, a, b, x, R, margin):
    """Four points on each cap's rim, the first of them the rim's lowest point toward the plane: a cylinder on
    its side rests on two points, on a cap on four, on a rim on one."""
    n, p0 = plane_of(table, b, x, R)
    axis = R[a][:, 2]
    r = table.radius[a]
    down, length = unit(-(n - (n @ axis) * axis))  # the rim's direction toward the plane
    if length < 1e-9:
        down = unit(np.cross(axis, UP if abs(axis @ UP) < 0.9 else np.array([1.0, 0.0, 0.0])))[0]
    side = np.cross(axis, down)
    rim = r * np.array([down, side, -down, -side])
    caps = np.array(segment(table, a, x, R))
    corners = (caps[:, None, :] + rim[None, :, :]).reshape(-1, 3)
    depth = -((corners - p0) @ n)
    points = corners + 0.5 * depth[:, None] * n
    return _keep(points, np.tile(n, (8, 1)), depth, np.arange(8), margin)


def mesh_plane(table, a, b, x, R, margin):
    """Every vertex of the mesh past the plane (the deepest eight when more are)."""
    n, p0 = plane_of(table, b, x, R)
    vertices = x[a] + table.meshes[table.mesh[a]].vertices @ R[a].T
    depth = -((vertices - p0) @ n)
    order = np.argsort(-depth)[:8]
    points = vertices[order] + 0.5 * depth[order, None] * n
    return _keep(points, np.tile(n, (len(order), 1)), depth[order], order, margin)


# ---- dispatch ----------------------------------------------------------------------------------------------

# (kind of a, kind of b) -> test; the table is symmetric through `closed_form`, which swaps the pair
TESTS = {
    (SPHERE, SPHERE): sphere_sphere,
    (SPHERE, PLANE): sphere_plane,
    (SPHERE, BOX): sphere_box,
    (SPHERE, CAPSULE): sphere_capsule,
    (SPHERE, CYLINDER): sphere_cylinder,
    (BOX, BOX): box_box,
    (BOX, PLANE): box_plane,
    (CAPSULE, CAPSULE): capsule_capsule,
    (CAPSULE, PLANE): capsule_plane,
    (CAPSULE, BOX): capsule_box,
    (CYLINDER, PLANE): cylinder_plane,
    (MESH, PLANE): mesh_plane,
}


def closed_form(kind_a: int, kind_b: int):
    """(test, swapped) for a pair of shape kinds, or None when the pair needs python-fcl."""
    if (kind_a, kind_b) in TESTS:
        return TESTS[(kind_a, kind_b)], False
    if (kind_b, kind_a) in TESTS:
        return TESTS[(kind_b, kind_a)], True
    return None


def needs_fcl(kind_a: int, kind_b: int) -> bool:
    """Pairs without a closed form: a mesh against anything but a plane; a cylinder against a box, a capsule or
    another cylinder."""
    return closed_form(kind_a, kind_b) is None
