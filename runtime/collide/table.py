"""The shape table of a scene's bodies, built from the IR when the collision plan is made: each primitive filled
from its shape, meshes loaded (meshes.py, and with it python-fcl, only when a scene has one), and the parts of
compound bodies laid out as elements (shapes.Elements) with a box about each compound that holds them."""
from __future__ import annotations

import numpy as np

from ..core.rotation import quat_to_matrix
from .shapes import (BOX, CAPSULE, CYLINDER, KINDS, MESH, NONE, PLANE, SPHERE, Elements, ShapeTable, boxes_of,
                     empty_table)


def build_table(scene, collidable: list, scene_folder=None) -> ShapeTable:
    """The table for the scene's bodies; only bodies in `collidable` get a kind. Meshes are loaded here (and
    `meshes`, with its python-fcl import, is imported only when one is present)."""
    table = empty_table(len(scene.bodies))
    compounds = [i for i in collidable if scene.bodies[i].shape.type == "compound"]
    for i in collidable:
        shape = scene.bodies[i].shape
        if shape.type != "compound":  # a compound's box is made from its parts (build_elements)
            fill(table, i, shape, scene_folder, shape.offset)
    if compounds:
        table.elements = build_elements(scene, table, compounds, scene_folder)
    return table


def fill(table: ShapeTable, i: int, shape, folders, offset=(0.0, 0.0, 0.0), loaded: dict | None = None) -> None:
    """Entry i of the table from an IR shape in its own frame (a mesh's vertices moved by offset); `loaded`
    (file, scale, offset) -> mesh index keeps one copy of a mesh many parts share."""
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

        key = (shape.file, shape.scale, tuple(offset))
        if loaded is None or key not in loaded:
            table.meshes.append(load_shape(shape.file, shape.scale, folders, offset))
            if loaded is not None:
                loaded[key] = len(table.meshes) - 1
        table.mesh[i] = loaded[key] if loaded is not None else len(table.meshes) - 1
        mesh = table.meshes[table.mesh[i]]
        table.half[i], table.centre[i] = mesh.half, mesh.centre
    table.thin[i] = float(np.min(table.half[i]))


def build_elements(scene, table, compounds: list, folders) -> Elements:
    """The elements of a scene whose bodies `compounds` are made of parts; each compound's entry in the body
    table becomes the box about its centre of mass that holds its parts."""
    n = len(scene.bodies)
    parts = [(i, k, part) for i in compounds for k, part in enumerate(scene.bodies[i].shape.parts)]
    count = n + len(parts)
    el = empty_table(count, table.meshes)  # the meshes list is shared: a mesh index means one mesh in both
    for name in ("kind", "radius", "half", "half_length", "normal", "centre", "thin", "mesh"):
        getattr(el, name)[:n] = getattr(table, name)
    owner = np.concatenate([np.arange(n), np.array([i for i, _, _ in parts], np.int64)])
    index = np.concatenate([np.full(n, -1, np.int64), np.array([k for _, k, _ in parts], np.int64)])
    offset, turn = np.zeros((count, 3)), np.tile(np.eye(3), (count, 1, 1))
    first, counts = np.zeros(n, np.int64), np.zeros(n, np.int64)
    loaded = {}
    for e, (i, k, part) in enumerate(parts, start=n):
        fill(el, e, part.shape, folders, loaded=loaded)
        offset[e] = np.asarray(scene.bodies[i].shape.offset, float) + np.asarray(part.position, float)
        q = np.asarray(part.orientation, float)
        turn[e] = quat_to_matrix(q / np.linalg.norm(q))
        if k == 0:
            first[i] = e
        counts[i] += 1
    elements = Elements(el, owner, index, offset, turn, first, counts, [p.name for _, _, p in parts])
    for i in compounds:
        mine = elements.of(i)
        # the parts' boxes in the body frame, then the box about the centre of mass that holds them all
        lo, hi = boxes_of(el, mine, offset[mine], turn[mine], 0.0)
        el.kind[i] = NONE
        table.kind[i], table.radius[i], table.half_length[i], table.centre[i] = BOX, 0.0, 0.0, 0.0
        table.half[i] = np.maximum(np.abs(lo), np.abs(hi)).max(axis=0)
        table.thin[i] = float(el.thin[mine].min())
    return elements
