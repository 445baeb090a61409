"""Collision geometry of every body, as a struct of arrays, and the bounding boxes the broad phase sorts.

Shapes live in the body frame (origin at the centre of mass). Cylinders and capsules have their axis along body
z; `length` is the straight part (a capsule adds a hemisphere of `radius` at each end). A plane is the
half-space below its surface: the surface passes through the body's position with the body-frame `normal`,
and everything on the other side of the normal is solid (so nothing can tunnel through a floor).
A mesh is its file's vertices times `scale`, moved by the shape's `offset` (where the file's origin sits in the
body frame: the centroid is the centre of mass when lowering computed it from the file).

A compound body (docs/compound.md) has one entry here too, a box about its centre of mass that holds all of its
parts (the broad phase's and the compiled step's "is anything near"; centred, so that the step's plane test, which
measures from the body's position, holds it), and its parts in `elements` (compound.py tests them).
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
# a feature of a compound pair says which part of each body made it: local | (part_a + 1) << PART_SHIFT |
# (part_b + 1) << (PART_SHIFT + PART_BITS), part -1 for a body that is its own shape (compound.py)
PART_SHIFT = 22
PART_BITS = 16
LOCAL_MASK = (1 << PART_SHIFT) - 1

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
    elements: "Elements | None" = None  # the parts of the compound bodies (None: there are none)

    def compound(self, i: int) -> bool:
        return self.elements is not None and self.elements.count[i] > 0


@dataclass
class Elements:
    """What the narrow phase of a scene with compound bodies tests: entry e < n is body e's own shape (the body
    table's; NONE for a compound body), the entries from n on are the compound bodies' parts.

    table: ShapeTable (n+P,) of the shapes, each in its own frame; owner (n+P,) body; index (n+P,) the part's
    number in its body (-1: a body's own shape); offset (n+P,3) where the element's origin sits in its body's frame
    (a primitive's centre, a mesh file's origin); turn (n+P,3,3) its axes in the body frame; first, count (n,):
    body b's parts are the elements first[b] .. first[b] + count[b] - 1 (count 0: b is its own element); names (P,)
    the parts' names."""

    table: ShapeTable
    owner: np.ndarray
    index: np.ndarray
    offset: np.ndarray
    turn: np.ndarray
    first: np.ndarray
    count: np.ndarray
    names: list

    def of(self, body: int) -> np.ndarray:
        """The elements of a body: its parts, or itself."""
        c = self.count[body]
        return np.arange(self.first[body], self.first[body] + c) if c else np.array([body])

    def element(self, body: int, part: int) -> int:
        """Part number `part` of body (-1: the body's own shape)."""
        return int(self.first[body] + part) if part >= 0 else int(body)

    def part_name(self, body: int, part: int) -> str | None:
        return self.names[int(self.first[body] + part) - len(self.first)] if part >= 0 else None


def part_of(feature, side: int):
    """The part number (-1: none) of a contact's body a (side 0) or b (side 1) that its feature names."""
    return ((np.asarray(feature, np.int64) >> (PART_SHIFT + side * PART_BITS)) & ((1 << PART_BITS) - 1)) - 1


def local_feature(feature):
    """The feature within one shape (a corner, an end, a mesh vertex: narrow.py) of a possibly compound one."""
    return np.asarray(feature, np.int64) & LOCAL_MASK


def empty_table(n: int, meshes: list | None = None) -> ShapeTable:
    return ShapeTable(np.zeros(n, np.int64), np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)),
                      np.zeros((n, 3)), np.full(n, np.inf), np.full(n, -1, np.int64), [] if meshes is None else meshes)


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


def segment(table, i, x, R):
    """End points of the axis segment of a capsule or cylinder."""
    half = R[i][:, 2] * table.half_length[i]
    return x[i] - half, x[i] + half


def kinds_of(table, i: int) -> set:
    """The shape kinds of body i of a collision table: its parts' for a compound body, else its own."""
    elements = table.elements
    if elements is not None and elements.count[i] > 0:
        return {int(k) for k in elements.table.kind[elements.of(i)]}
    return {int(table.kind[i])}
