"""Meshes and python-fcl: OBJ/STL loading, and the narrow phase of every pair without a closed form.

This module is the only one that imports fcl, and only when a pair needs it (`FclPairs`): a mesh against
anything but a plane, or a cylinder against a box, a capsule or a cylinder (narrow.needs_fcl). Loading a mesh
does not import it (a mesh on a floor is a closed form: its vertices against the plane).

A convex mesh (its volume equals its hull's) becomes an `fcl.Convex`, whose contact comes from GJK/EPA with a
true penetration depth; any other mesh becomes a `fcl.BVHModel` (triangles: contact points, but normals and
depths only where fcl computes them). fcl gives one deepest point for convex pairs, too few for a body resting
on a face, so `FclPairs.contacts` adds the vertices (box corners, mesh vertices) of either body that lie inside
the other, with depth and normal from the other's signed distance function (`signed_distance`, exact for
spheres, boxes, capsules, cylinders and planes, the hull planes for a convex mesh).

fcl's normal points from its first object to its second; ours points from body b to body a (a is pushed along
+n), so the pair is passed as (a, b) and the normal negated.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .shapes import BOX, CAPSULE, CYLINDER, FCL_POINT, MESH, PLANE, SPHERE, VERTEX_OF_B

# most contact points fcl returns for a pair of triangle meshes
MAX_MESH_CONTACTS = 8
# a mesh is convex when its volume is within this fraction of its convex hull's
CONVEX_VOLUME_RTOL = 1e-6


class MeshError(Exception):
    """A mesh file that cannot be found or read: says which file and what to do."""


@dataclass
class MeshShape:
    vertices: np.ndarray  # (V,3) body frame, m
    faces: np.ndarray  # (F,3) int, counter-clockwise seen from outside
    convex: bool
    half: np.ndarray  # (3,) local bounding-box half extents
    centre: np.ndarray  # (3,) local bounding-box centre
    volume: float
    hull_faces: np.ndarray  # (H,3) int, outward
    planes: np.ndarray  # (H,4) outward unit normal and offset of each hull triangle: n . p <= d inside the hull

    def geometry(self):
        """The fcl geometry (imports fcl): Convex for a convex mesh, else a BVHModel of its triangles."""
        import fcl

        if self.convex:
            flat = np.hstack([np.full((len(self.hull_faces), 1), 3), self.hull_faces]).ravel()
            return fcl.Convex(self.vertices, len(self.hull_faces), flat)
        model = fcl.BVHModel()
        model.beginModel(len(self.vertices), len(self.faces))
        model.addSubModel(self.vertices, self.faces)
        model.endModel()
        return model


# ---- loading ---------------------------------------------------------------------------------------------------

def read_mesh(path) -> tuple:
    """(vertices (V,3), faces (F,3)) of an OBJ or STL file (isaac_ir.meshfile: the reader lowering uses too)."""
    from isaac_ir.meshfile import MeshFileError, read_mesh as read

    try:
        return read(path)
    except MeshFileError as error:
        raise MeshError(str(error)) from None


def resolve(name: str, folders) -> Path:
    from ..signals import find_asset

    found, tried = find_asset(name, folders)
    if found is None:
        raise MeshError(f"no such mesh file: `{name}` (a mesh is named relative to the scene's folder; looked in "
                        + ", ".join(tried) + ")")
    return found


def load_shape(name: str, scale: float, folders, offset=(0.0, 0.0, 0.0)) -> MeshShape:
    """The mesh of a file, its vertices times scale, plus offset (where the file's origin sits in its frame)."""
    vertices, faces = read_mesh(resolve(name, folders))
    if len(faces) == 0:
        raise MeshError(f"`{name}` has no faces")
    vertices = vertices * scale + np.asarray(offset, float)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    volume = _volume(vertices, faces)
    convex, hull_faces = _hull(vertices, volume)
    a, b, c = (vertices[hull_faces[:, k]] for k in range(3))
    normals = np.cross(b - a, c - a)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    planes = np.column_stack([normals, np.einsum("ij,ij->i", normals, a)])
    return MeshShape(vertices, faces, convex, 0.5 * (hi - lo), 0.5 * (hi + lo), volume, hull_faces, planes)


def _volume(vertices, faces) -> float:
    # divergence theorem: V = sum over triangles of a . (b x c) / 6
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)


def _hull(vertices, volume):
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    faces = hull.simplices.copy()
    # orient each hull triangle outward (its normal away from the hull's centroid)
    centroid = vertices[hull.vertices].mean(axis=0)
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - centroid) < 0
    faces[inward] = faces[inward][:, ::-1]
    return abs(hull.volume - volume) <= CONVEX_VOLUME_RTOL * hull.volume, faces


# ---- signed distance of the convex shapes ----------------------------------------------------------------------

def signed_distance(table, i: int, points, x, R):
    """(distance (k,), outward unit normal (k,3)) of world points to body i's surface, negative inside; None for
    a shape without one here (a non-convex mesh)."""
    kind = table.kind[i]
    local = (points - x[i]) @ R[i]
    if kind == SPHERE:
        d, n = _round(local, table.radius[i])
    elif kind == BOX:
        d, n = _box(local, table.half[i])
    elif kind == CAPSULE:
        hl = table.half_length[i]
        axis_point = np.zeros_like(local)
        axis_point[:, 2] = np.clip(local[:, 2], -hl, hl)
        d, n = _round(local - axis_point, table.radius[i])
    elif kind == CYLINDER:
        d, n = _cylinder(local, table.radius[i], table.half_length[i])
    elif kind == PLANE:
        normal = table.normal[i]
        d, n = local @ normal, np.tile(normal, (len(local), 1))
    elif kind == MESH and table.meshes[table.mesh[i]].convex:
        d, n = _convex_distance(local, table.meshes[table.mesh[i]].planes)
    else:
        return None
    return d, n @ R[i].T


# the most point-plane distances held at once (160 MB): the points of a large mesh are taken a block at a time
MAX_DISTANCES_AT_ONCE = 20_000_000


def _convex_distance(local, planes) -> tuple:
    """(distance, outward normal) of local points to a convex mesh given by its face planes: the largest of the
    points' heights over the planes, a block of points at a time."""
    block = max(1, MAX_DISTANCES_AT_ONCE // max(1, len(planes)))
    d, n = np.empty(len(local)), np.empty((len(local), 3))
    for start in range(0, len(local), block):
        s = local[start:start + block] @ planes[:, :3].T - planes[:, 3]
        face = np.argmax(s, axis=1)
        d[start:start + block], n[start:start + block] = s[np.arange(len(s)), face], planes[face, :3]
    return d, n


def _round(v, r):
    length = np.linalg.norm(v, axis=1)
    safe = np.where(length > 1e-12, length, 1.0)
    n = np.where((length > 1e-12)[:, None], v / safe[:, None], [[0.0, 1.0, 0.0]])
    return length - r, n


def _box(local, half):
    q = np.abs(local) - half
    outside = np.maximum(q, 0.0)
    out_len = np.linalg.norm(outside, axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    sign = np.where(local >= 0, 1.0, -1.0)
    face = np.zeros_like(local)
    face[np.arange(len(local)), np.argmax(q, axis=1)] = 1.0
    n = np.where((out_len > 1e-12)[:, None], outside / np.where(out_len > 1e-12, out_len, 1.0)[:, None], face)
    return out_len + inside, n * sign


def _cylinder(local, r, hl):
    rho = np.hypot(local[:, 0], local[:, 1])
    radial = np.where((rho > 1e-12)[:, None], local[:, :2] / np.where(rho > 1e-12, rho, 1.0)[:, None], [[1.0, 0.0]])
    d2, n2 = _box(np.column_stack([rho, local[:, 2]]), np.array([r, hl]))
    n = np.column_stack([n2[:, :1] * radial, n2[:, 1]])
    return d2, n


def _vertices(table, i, x, R, toward):
    """World corners of a box, vertices of a mesh, or for a cylinder four points on each cap's rim, the first
    of them the one furthest along `toward`; None for spheres and capsules."""
    kind = table.kind[i]
    if kind == BOX:
        from .shapes import CORNER_SIGNS

        local = CORNER_SIGNS * table.half[i]
    elif kind == MESH:
        local = table.meshes[table.mesh[i]].vertices
    elif kind == CYLINDER:
        axis = R[i][:, 2]
        down = toward - (toward @ axis) * axis
        length = np.linalg.norm(down)
        down = down / length if length > 1e-9 else _unit(np.cross(axis, [0.3, 0.5, 0.8]))
        side = np.cross(axis, down)
        rim = table.radius[i] * np.array([down, side, -down, -side])
        caps = np.array([x[i] - axis * table.half_length[i], x[i] + axis * table.half_length[i]])
        return (caps[:, None, :] + rim[None, :, :]).reshape(-1, 3)
    else:
        return None
    return x[i] + local @ R[i].T


# ---- the fcl narrow phase ------------------------------------------------------------------------------------

def primitive_geometry(table, i: int):
    """The fcl geometry of body i's shape."""
    import fcl

    kind = table.kind[i]
    if kind == SPHERE:
        return fcl.Sphere(table.radius[i])
    if kind == BOX:
        return fcl.Box(*(2.0 * table.half[i]))
    if kind == CAPSULE:
        return fcl.Capsule(table.radius[i], 2.0 * table.half_length[i])
    if kind == CYLINDER:
        return fcl.Cylinder(table.radius[i], 2.0 * table.half_length[i])
    if kind == MESH:
        return table.meshes[table.mesh[i]].geometry()
    raise ValueError(f"no fcl geometry for shape kind {kind}")


class FclPairs:
    """fcl collision objects of the bodies that need them, built once; `contacts` moves them to the poses."""

    def __init__(self, table, bodies):
        import fcl

        self.fcl, self.table = fcl, table
        self.objects = {int(i): fcl.CollisionObject(primitive_geometry(table, int(i)), fcl.Transform())
                        for i in bodies}
        self.request = fcl.CollisionRequest(num_max_contacts=MAX_MESH_CONTACTS, enable_contact=True)
        self.distance_request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)

    def contacts(self, a: int, b: int, x, R, margin: float):
        """Contacts of bodies a and b: (points (k,3), normals (k,3) from b to a, depths (k,), features (k,))."""
        fcl = self.fcl
        oa, ob = self._place(a, x, R), self._place(b, x, R)
        result = fcl.CollisionResult()
        found = []
        if fcl.collide(oa, ob, self.request, result):
            for c in result.contacts:
                n = -np.asarray(c.normal, float)
                length = np.linalg.norm(n)
                if length > 1e-12:  # triangle-triangle contacts of BVH meshes may come without a normal
                    found.append((np.asarray(c.pos, float), n / length, float(c.penetration_depth)))
        # a vertex inside (or within the margin) is a touch with a place on each body; fcl's points (somewhere
        # in the overlap) only where none is (an edge across an edge), and its nearest points where nothing is
        normal = _unit(x[a] - x[b])
        if found:
            fcl_points = self._fcl_points(a, b, x, found)
            normal = fcl_points[1][0]
        else:
            d = fcl.distance(oa, ob, self.distance_request, fcl.DistanceResult())
            if d > margin:  # apart: no vertex of one is within the margin of the other (none is looked at)
                return np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), np.array([-d]), np.array([FCL_POINT])
        parts = self._vertices_inside(a, b, x, R, margin, normal)
        if not parts and found:
            parts = [fcl_points]
        if parts:
            if self._triangles(a) or self._triangles(b):
                parts = _consistent(parts)
            points, normals, depths, features = (np.concatenate(p) for p in zip(*parts))
            return points, normals, depths, features
        distance_result = fcl.DistanceResult()
        d = fcl.distance(oa, ob, self.distance_request, distance_result)
        if d > margin:
            return np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), np.array([-d]), np.array([FCL_POINT])
        pa, pb = (np.asarray(p, float) for p in distance_result.nearest_points)
        n = pa - pb
        length = np.linalg.norm(n)
        n = n / length if length > 1e-12 else _unit(x[a] - x[b])
        return (0.5 * (pa + pb))[None], n[None], np.array([-d]), np.array([FCL_POINT])

    def _triangles(self, i) -> bool:
        """Body i is a non-convex mesh (fcl treats it as loose triangles)."""
        t = self.table
        return t.kind[i] == MESH and not t.meshes[t.mesh[i]].convex

    def _fcl_points(self, a, b, x, found) -> list:
        """fcl's contacts; a triangle's normal may point either way, so with a non-convex mesh each normal is
        turned to point from b's centre toward a's side."""
        points = np.array([f[0] for f in found])
        normals = np.array([f[1] for f in found])
        depths = np.array([f[2] for f in found])
        if self._triangles(a) or self._triangles(b):
            flip = normals @ (x[a] - x[b]) < 0
            normals[flip] *= -1.0
        return points, normals, depths, FCL_POINT + np.arange(len(depths))

    def _place(self, i: int, x, R):
        obj = self.objects[i]
        obj.setTransform(self.fcl.Transform(R[i], x[i]))
        return obj

    def _vertices_inside(self, a, b, x, R, margin, normal) -> list:
        """Vertices of one body within margin of the inside of the other, as contacts (a cylinder's vertices
        are four points on each cap's rim, the first toward the other body along fcl's normal)."""
        parts = []
        for mine, other, sign, base in ((a, b, 1.0, 0), (b, a, -1.0, VERTEX_OF_B)):
            vertices = _vertices(self.table, mine, x, R, -sign * normal)
            if vertices is None:
                continue
            found = signed_distance(self.table, other, vertices, x, R)
            if found is None:
                continue
            d, outward = found
            keep = d <= margin
            if keep.any():
                # the normal from b to a is the other's outward normal when the vertex is a's, else its opposite
                n = sign * outward[keep]
                depth = -d[keep]
                # the contact point midway between the vertex and the surface it is under
                parts.append((vertices[keep] + sign * 0.5 * depth[:, None] * n, n, depth, base + np.flatnonzero(keep)))
        return parts


def _consistent(parts) -> list:
    """Drop contacts whose normal opposes the pair's mean normal (loose triangles can give both sides of a
    thin part): two opposite normals on one pair ask the solver for the impossible."""
    normals = np.concatenate([p[1] for p in parts])
    mean = normals.sum(axis=0)
    if np.linalg.norm(mean) < 1e-12:
        return parts
    return [tuple(column[keep] for column in p) for p in parts for keep in [p[1] @ mean > 0] if keep.any()]



def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else np.array([0.0, 1.0, 0.0])
