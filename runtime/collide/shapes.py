"""Collision geometry of every body, as a struct of arrays, and the bounding boxes the broad phase sorts.

Shapes live in the body frame (origin at the centre of mass). Cylinders and capsules have their axis along body
z; `length` is the straight part (a capsule adds a hemisphere of `radius` at each end). A plane is the
half-space below its surface: the surface passes through the body's position with the body-frame `normal`,
and everything on the other side of the normal is solid (so nothing can tunnel through a floor).
A mesh is its file's vertices times `scale`, in body coordinates (the file's origin is the centre of mass).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NONE, SPHERE, BOX, CAPSULE, CYLINDER, PLANE, MESH = range(7)
KINDS = {"sphere": SPHERE, "box": BOX, "capsule": CAPSULE, "cylinder": CYLINDER, "plane": PLANE, "mesh": MESH}
KIND_NAMES = {v: k for k, v in KINDS.items()}
# the features of the contacts fcl finds (stable from look to look but for fcl's own points): a vertex of a (its
# index), a vertex of b (VERTEX_OF_B + its index: the contact's point is b's), a point of fcl's (FCL_POINT + k)
VERTEX_OF_B = 1 << 20
FCL_POINT = 1 << 21

# box corner signs, corner c = half * CORNER_SIGNS[c]; bit k of c set -> +half along axis k
CORNER_SIGNS = np.array([[1.0 if c & (1 << k) else -1.0 for k in range(3)] for c in range(8)])


@dataclass
class ShapeTable:
    """Per body (n = all bodies of the scene; bodies that do not collide have kind NONE).

    kind (n,) int; radius (n,) m (sphere, capsule, cylinder); half (n,3) m: box half edges, or the local
    bounding half-extents of any shape; half_length (n,) m: half the straight part of a capsule or cylinder;
    normal (n,3) body-frame plane normal (unit); centre (n,3) body-frame centre of the local bounding box
    (non-zero only for meshes); thin (n,) m: the smallest half-extent (how far a body can move before it can
    pass through something: the sweep test's yardstick); mesh (n,) int index into `meshes` or -1.
    """

    kind: np.ndarray
    radius: np.ndarray
    half: np.ndarray
    half_length: np.ndarray
    normal: np.ndarray
    centre: np.ndarray
    thin: np.ndarray
    mesh: np.ndarray
    meshes: list = field(default_factory=list)  # meshes.MeshShape


def build_table(scene, collidable: list, scene_folder=None) -> ShapeTable:
    """The table for the scene's bodies; only bodies in `collidable` get a kind. Meshes are loaded here (and
    `meshes`, with its python-fcl import, is imported only when one is present)."""
    n = len(scene.bodies)
    table = ShapeTable(np.zeros(n, np.int64), np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)),
                       np.zeros((n, 3)), np.full(n, np.inf), np.full(n, -1, np.int64))
    for i in collidable:
        shape = scene.bodies[i].shape
        kind = KINDS[shape.type]
        table.kind[i] = kind
        r = shape.radius or 0.0
        table.radius[i] = r
        if kind == SPHERE:
            table.half[i] = r
        elif kind == BOX:
            table.half[i] = 0.5 * np.asarray(shape.size, float)
        elif kind in (CAPSULE, CYLINDER):
            table.half_length[i] = 0.5 * shape.length
            table.half[i] = (r, r, 0.5 * shape.length + (r if kind == CAPSULE else 0.0))
        elif kind == PLANE:
            normal = np.asarray(shape.normal or (0.0, 1.0, 0.0), float)
            table.normal[i] = normal / np.linalg.norm(normal)
            table.half[i] = np.inf
        elif kind == MESH:
            from .meshes import load_shape

            mesh = load_shape(shape.file, shape.scale, scene_folder)
            table.mesh[i] = len(table.meshes)
            table.meshes.append(mesh)
            table.half[i], table.centre[i] = mesh.half, mesh.centre
        table.thin[i] = float(np.min(table.half[i]))
    return table


def bounding_boxes(table: ShapeTable, index: np.ndarray, x: np.ndarray, R: np.ndarray, margin: float):
    """World axis-aligned boxes (lo, hi), each (k,3), of the bodies `index` (not planes) at poses x (n,3),
    R (n,3,3), grown by margin. A box of half-extents h turned by R has world half-extents |R| h; a cylinder
    along axis a is tighter: |a_i| L/2 + r sqrt(1 - a_i^2)."""
    return boxes_of(table, index, x[index], R[index], margin)


def boxes_of(table: ShapeTable, index: np.ndarray, xi: np.ndarray, Ri: np.ndarray, margin: float):
    """`bounding_boxes` from the poses of those bodies alone: xi (k,3), Ri (k,3,3)."""
    kind = table.kind[index]
    centre = xi + np.einsum("kij,kj->ki", Ri, table.centre[index])
    extent = np.einsum("kij,kj->ki", np.abs(Ri), table.half[index])
    sphere = kind == SPHERE
    extent[sphere] = table.radius[index][sphere, None]
    round_ = (kind == CAPSULE) | (kind == CYLINDER)
    if round_.any():
        axis = Ri[round_][:, :, 2]
        r = table.radius[index][round_, None]
        hl = table.half_length[index][round_, None]
        side = np.where((kind[round_] == CAPSULE)[:, None], r, r * np.sqrt(np.clip(1.0 - axis**2, 0.0, 1.0)))
        extent[round_] = np.abs(axis) * hl + side
    extent += margin
    return centre - extent, centre + extent


def reach(table: ShapeTable) -> np.ndarray:
    """(n,) how far a point of each shape can be from its centre (m): what turning by an angle a can bring a point
    nearer by at most reach * a (a plane: none of its points comes nearer by turning)."""
    finite = np.isfinite(table.half).all(axis=1)
    box = np.where(finite, np.linalg.norm(np.nan_to_num(table.half, posinf=0.0), axis=1), 0.0)
    return box + np.linalg.norm(table.centre, axis=1) + table.radius + table.half_length
