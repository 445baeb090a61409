"""Reading the mesh files a scene names (OBJ, STL): what lowering integrates (mass.mesh_integrals) and what the
collision stage collides (isaac_runtime.collide.meshes) come from this one reader.

    vertices (V,3), faces (F,3) = read_mesh(path)

OBJ: `v` and `f` lines (polygons fanned into triangles; `v/vt/vn` and negative indices allowed). STL: ASCII or
binary, coincident corners merged (to 1e-12) so that the triangles share vertices.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


class MeshFileError(ValueError):
    """A mesh file of an unknown format, or one that cannot be read as one."""


def read_mesh(path) -> tuple:
    """(vertices (V,3), faces (F,3) int) of an OBJ or STL file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        return read_obj(path.read_text(errors="replace"))
    if suffix == ".stl":
        return read_stl(path.read_bytes())
    raise MeshFileError(f"`{path}`: unknown mesh format `{suffix}` (use .obj or .stl)")


def read_obj(text: str) -> tuple:
    vertices, faces = [], []
    try:
        for line in text.splitlines():
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(p) for p in parts[1:4]])
            elif parts[0] == "f":
                ids = [int(p.split("/")[0]) for p in parts[1:]]
                ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
                faces.extend([ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1))
        return np.asarray(vertices, float).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3)
    except ValueError as error:
        raise MeshFileError(f"not an OBJ file: {error}") from None


def read_stl(data: bytes) -> tuple:
    count = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    if len(data) == 84 + 50 * count:  # binary: 80-byte header, count, then 50 bytes per triangle
        record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
        corners = np.frombuffer(data, record, count, 84)["corners"].astype(float).reshape(-1, 3)
    else:
        words = data.decode("ascii", errors="replace").split()
        try:
            corners = np.array([[float(w) for w in words[k + 1:k + 4]] for k, w in enumerate(words)
                                if w == "vertex"]).reshape(-1, 3)
        except ValueError as error:
            raise MeshFileError(f"not an STL file: {error}") from None
    vertices, inverse = np.unique(np.round(corners, 12), axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3)
