"""Closed-form tests with a box on one side: box-box (separating axes, then face clipping), box-plane,
sphere-box and capsule-box. Conventions as in narrow.py: normals from b toward a, points midway.

Box-box follows Gottschalk's OBB test for the 15 candidate axes (3 face normals of each box, 9 edge-edge
cross products) and the reference-face / incident-face clipping of ODE's dBoxBox and Box2D: the axis of least
penetration wins (a face axis unless an edge axis is clearly better and its edges do not lie nearly flat in
the best face), and the incident face of the other box
is clipped against the side planes of the reference face, which gives up to four points for boxes resting on
each other, or one point for crossed edges.
"""
from __future__ import annotations

import numpy as np

from .shapes import CORNER_SIGNS, segment

# an edge-edge axis wins over the best face axis only if it separates more by this fraction of the smaller box
EDGE_PREFERENCE = 1e-3
# ... and, where the edges touch or overlap, only if their common normal is farther than 8 degrees from the best
# face normal of either box (crossed edges nearer than that lie almost flat in that face: the face's points, each
# no deeper than the boxes overlap, as runtime/capture/boxes.py FLAT_EDGES)
FLAT_EDGES = np.cos(np.radians(8.0))
# edge-edge axes of nearly parallel edges (|a_i x b_j| below this) are skipped: a face axis covers them
PARALLEL_EDGES = 1e-6
# most points of one face contact (ODE and Box2D keep four)
MAX_FACE_POINTS = 4

_NEXT, _PREV = np.array([1, 2, 0]), np.array([2, 0, 1])


def _keep(points, normals, depths, features, margin):
    keep = depths >= -margin
    return points[keep], normals[keep], depths[keep], features[keep]


def _one(point, normal, depth, feature=0):
    return point[None], normal[None], np.array([depth]), np.array([feature])


# ---- box-plane and sphere-box --------------------------------------------------------------------------------

def box_plane(table, a, b, x, R, margin):
    """The corners past the plane (all eight are returned with margin = inf)."""
    n, p0 = R[b] @ table.normal[b], x[b]
    corners = x[a] + (CORNER_SIGNS * table.half[a]) @ R[a].T
    depth = -((corners - p0) @ n)
    points = corners + 0.5 * depth[:, None] * n
    return _keep(points, np.tile(n, (8, 1)), depth, np.arange(8), margin)


def point_box(p, xb, Rb, half):
    """Signed distance from world point p to box (xb, Rb, half), the box's surface point nearest p, and the
    outward normal there (world)."""
    local = Rb.T @ (p - xb)
    clamped = np.clip(local, -half, half)
    if np.array_equal(clamped, local):  # inside: leave through the nearest face
        room = half - np.abs(local)
        k = int(np.argmin(room))
        normal = np.zeros(3)
        normal[k] = 1.0 if local[k] >= 0 else -1.0
        surface = local.copy()
        surface[k] = normal[k] * half[k]
        return -room[k], xb + Rb @ surface, Rb @ normal
    diff = local - clamped
    dist = float(np.linalg.norm(diff))
    return dist, xb + Rb @ clamped, Rb @ (diff / dist)


def sphere_box(table, a, b, x, R, margin):
    r = table.radius[a]
    dist, surface, n = point_box(x[a], x[b], R[b], table.half[b])
    point = 0.5 * (x[a] - n * r + surface)
    return _keep(*_one(point, n, r - dist), margin)


def capsule_box(table, a, b, x, R, margin):
    """The two end spheres; then, where the point of the axis segment nearest the box lies over a face of it, the
    ends of the segment's part over that face (features 3, 4; the segment's height over the face is linear along
    it, so those ends and the end spheres hold its least), else that nearest point when it lies inside the segment
    (2: a capsule across a box's edge). A capsule lying across a face rests on the face's two sides, not on one
    point it rocks about. The distance from the segment to the box is convex along the segment, so a golden-section
    search finds the nearest point."""

    r, xb, Rb, hb = table.radius[a], x[b], R[b], table.half[b]
    s0, s1 = segment(table, a, x, R)
    parts = []
    for k, end in enumerate((s0, s1)):
        dist, surface, n = point_box(end, xb, Rb, hb)
        parts.append(_one(0.5 * (end - n * r + surface), n, r - dist, k))
    t = _golden(lambda u: point_box(s0 + u * (s1 - s0), xb, Rb, hb)[0])
    p = s0 + t * (s1 - s0)
    dist, surface, n = point_box(p, xb, Rb, hb)
    faces = np.flatnonzero(np.abs(Rb.T @ n) > 1.0 - 1e-9)
    if dist > 0.0 and faces.size:
        parts += _over_face(s0, s1, r, xb, Rb, hb, int(faces[0]), n)
    elif 0.01 < t < 0.99:
        parts.append(_one(0.5 * (p - n * r + surface), n, r - dist, 2))
    return _keep(*(np.concatenate(q) for q in zip(*parts)), margin)


def _over_face(s0, s1, r, xb, Rb, hb, k, n):
    """Contacts at the ends of the part of the segment s0..s1 (radius r) that lies over the rectangle of the box's
    face k (outward unit normal n) and are not the segment's own ends: depth r less the end's height over the face,
    the point halfway between the capsule's surface and the face."""
    f = xb + hb[k] * n
    lo, hi = 0.0, 1.0
    for j in ((k + 1) % 3, (k + 2) % 3):
        # |(s0 + t (s1 - s0) - f) . b_j| <= h_j
        a0, a1 = (s0 - f) @ Rb[:, j], (s1 - f) @ Rb[:, j]
        if a1 == a0:
            if abs(a0) > hb[j]:
                return []
            continue
        ta, tb = sorted(((hb[j] - a0) / (a1 - a0), (-hb[j] - a0) / (a1 - a0)))
        lo, hi = max(lo, ta), min(hi, tb)
    if lo > hi:
        return []
    out = []
    for feature, t in ((3, lo), (4, hi)):
        if 1e-9 < t < 1.0 - 1e-9:
            q = s0 + t * (s1 - s0)
            height = float((q - f) @ n)
            out.append(_one(q - 0.5 * (r + height) * n, n, r - height, feature))
    return out


def _golden(f, iterations: int = 40) -> float:
    """argmin of a convex f on [0, 1] (golden-section search, interval shrinks 0.618x per step)."""
    g = 0.5 * (np.sqrt(5.0) - 1.0)
    lo, hi = 0.0, 1.0
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if fc < fd:
            hi, d, fd = d, c, fc
            c = hi - g * (hi - lo)
            fc = f(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + g * (hi - lo)
            fd = f(d)
    return 0.5 * (lo + hi)


# ---- box-box ---------------------------------------------------------------------------------------------------

def separating_axes(A, ha, B, hb, d):
    """Separation of boxes (axes A, half ha) and (B, hb), d = x_a - x_b, along the 15 candidate axes:
    (face separations of a (3,), of b (3,), edge separations (3,3), C = A^T B). Positive: apart by that much.

        face i of a:    |d . a_i| - ha_i - sum_j hb_j |a_i . b_j|
        edge a_i x b_j: (|d . (a_i x b_j)| - r_a - r_b) / |a_i x b_j|
    """
    C = A.T @ B
    absC = np.abs(C) + 1e-12
    dA, dB = A.T @ d, B.T @ d
    face_a = np.abs(dA) - ha - absC @ hb
    face_b = np.abs(dB) - hb - absC.T @ ha
    i1, i2 = _NEXT[:, None], _PREV[:, None]
    j1, j2 = _NEXT[None, :], _PREV[None, :]
    j = np.arange(3)[None, :]
    i = np.arange(3)[:, None]
    ra = ha[i1] * absC[i2, j] + ha[i2] * absC[i1, j]
    rb = hb[j1] * absC[i, j2] + hb[j2] * absC[i, j1]
    dist = np.abs(dA[i2] * C[i1, j] - dA[i1] * C[i2, j])
    length = np.sqrt(np.clip(1.0 - C**2, 0.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        edges = np.where(length > PARALLEL_EDGES, (dist - ra - rb) / length, -np.inf)
    return face_a, face_b, edges, C


def box_box(table, a, b, x, R, margin):
    A, B, ha, hb = R[a], R[b], table.half[a], table.half[b]
    d = x[a] - x[b]
    face_a, face_b, edges, _ = separating_axes(A, ha, B, hb, d)
    ia, ib = int(np.argmax(face_a)), int(np.argmax(face_b))
    tol = EDGE_PREFERENCE * min(ha.min(), hb.min())
    best = max(face_a[ia], face_b[ib])
    ie = np.unravel_index(int(np.argmax(edges)), (3, 3))
    separation = max(best, edges[ie])
    if separation > margin or separation == np.inf:
        return _keep(*_one(0.5 * (x[a] + x[b]), _toward(A[:, ia], d), -separation), margin)
    edge = edges[ie] > best + tol
    if edge and (edges[ie] > 0.0 or not _flat(A[:, ie[0]], B[:, ie[1]], A[:, ia], B[:, ib])):
        return _keep(*_edge_contact(A, ha, B, hb, x[a], x[b], ie, edges[ie]), margin)
    if face_b[ib] > face_a[ia] + tol:  # reference face on b, a's face clipped against it
        n = _toward(B[:, ib], d)
        ref_centre = x[b] + n * hb[ib]
        incident = _incident_face(A, ha, x[a], -n)
        # a's points penetrate b when below b's face (on -n side)
        found = _clip_contact(incident, ref_centre, n, B, hb, ib, -1.0, margin)
        support = x[a] - A @ (np.sign(A.T @ n) * ha)  # a's deepest corner along -n
    else:
        n = _toward(A[:, ia], d)
        ref_centre = x[a] - n * ha[ia]
        incident = _incident_face(B, hb, x[b], n)
        found = _clip_contact(incident, ref_centre, n, A, ha, ia, 1.0, margin)
        support = x[b] + B @ (np.sign(B.T @ n) * hb)
    if edge and len(found[2]):  # (crossed edges lying flat: the face's points, no deeper than the boxes overlap)
        return found[0], found[1], np.minimum(found[2], -edges[ie]), found[3]
    if len(found[2]) or -best < -margin:
        return found
    if edge:  # (crossed edges lying flat, beside the reference face: theirs is the contact)
        return _keep(*_edge_contact(A, ha, B, hb, x[a], x[b], ie, edges[ie]), margin)
    # the incident face lies beside the reference face (a small box deep in a large one): its deepest corner
    return _one(support, n, -best)


def _flat(edge_a, edge_b, face_a, face_b) -> bool:
    """Whether the crossed edges lie nearly flat in either face: their common normal within FLAT_EDGES of it."""
    L = np.cross(edge_a, edge_b)
    L = L / np.linalg.norm(L)
    return max(abs(L @ face_a), abs(L @ face_b)) >= FLAT_EDGES


def _toward(axis, d):
    """The axis, signed to point from b toward a (d = x_a - x_b)."""
    return axis if axis @ d >= 0 else -axis


def _incident_face(axes, half, centre, facing):
    """The four corners, in order around the face, of the face of a box whose outward normal is most nearly
    `facing`."""
    dots = axes.T @ facing
    k = int(np.argmax(np.abs(dots)))
    sign = 1.0 if dots[k] >= 0 else -1.0
    c = centre + sign * half[k] * axes[:, k]
    e1 = half[_NEXT[k]] * axes[:, _NEXT[k]]
    e2 = half[_PREV[k]] * axes[:, _PREV[k]]
    return np.array([c + e1 + e2, c - e1 + e2, c - e1 - e2, c + e1 - e2])


def _clip_contact(polygon, ref_centre, n, axes, half, k, sign, margin):
    """Clip the incident polygon against the reference face's four side planes; the points within margin of
    the face are contacts. sign = +1: the reference face belongs to a (the polygon is b's, inside a when on the
    +n side of the face); -1: to b."""
    for side in (_NEXT[k], _PREV[k]):
        u, extent = axes[:, side], half[side]
        polygon = _clip(polygon, u, ref_centre @ u + extent)
        polygon = _clip(polygon, -u, -(ref_centre @ u) + extent)
        if len(polygon) == 0:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
    points = np.array(polygon)
    depth = sign * ((points - ref_centre) @ n)
    points = points - sign * 0.5 * depth[:, None] * n
    keep = depth >= -margin
    points, depth = points[keep], depth[keep]
    if len(points) > MAX_FACE_POINTS:
        chosen = reduce_manifold(points, depth)
        points, depth = points[chosen], depth[chosen]
    return points, np.tile(n, (len(points), 1)), depth, np.arange(len(points))


def _clip(polygon, normal, offset):
    """Sutherland-Hodgman: the part of the polygon with normal . p <= offset."""
    out = []
    count = len(polygon)
    for i in range(count):
        p, q = polygon[i], polygon[(i + 1) % count]
        dp, dq = normal @ p - offset, normal @ q - offset
        if dp <= 0:
            out.append(p)
        if (dp < 0 < dq) or (dq < 0 < dp):
            out.append(p + (q - p) * (dp / (dp - dq)))
    return out


def reduce_manifold(points, depth) -> list:
    """Four of many contact points: the deepest, the farthest from it, then the two that widen the
    patch most (each the farthest from those already chosen)."""
    chosen = [int(np.argmax(depth))]
    for _ in range(MAX_FACE_POINTS - 1):
        gap = np.min(np.linalg.norm(points[:, None, :] - points[chosen][None, :, :], axis=2), axis=1)
        chosen.append(int(np.argmax(gap)))
    return sorted(set(chosen))


def _edge_contact(A, ha, B, hb, xa, xb, index, separation):
    """Crossed edges: the closest points of the edge of a nearest b and the edge of b nearest a."""
    i, j = index
    axis = np.cross(A[:, i], B[:, j])
    axis /= np.linalg.norm(axis)
    n = _toward(axis, xa - xb)
    # each box's edge along its axis i (j), on the box's side facing the other: its support point toward it
    pa = xa - A @ (np.sign(A.T @ n) * ha * (np.arange(3) != i))
    pb = xb + B @ (np.sign(B.T @ n) * hb * (np.arange(3) != j))
    da, db = A[:, i], B[:, j]
    r = pa - pb
    b_ = da @ db
    denom = 1.0 - b_ * b_
    s = np.clip((b_ * (db @ r) - (da @ r)) / denom, -ha[i], ha[i]) if denom > 1e-12 else 0.0
    t = np.clip(db @ r + b_ * s, -hb[j], hb[j])
    point = 0.5 * (pa + s * da + pb + t * db)
    return _one(point, n, -separation, 8 + 3 * i + j)
