"""Reading the mesh files a scene names (OBJ, STL): what `isaac check` validates, what lowering integrates
(mass.mesh_integrals) and what the collision stage collides (isaac_runtime.collide.meshes) come from this one
reader.

    vertices (V,3), faces (F,3) = read_mesh(path)

OBJ: `v` and `f` lines (polygons fanned into triangles; `v/vt/vn` and negative indices allowed). STL: ASCII or
binary, coincident corners merged (to 1e-12) so that the triangles share vertices. The file is read through
isaac_ir.files (a regular file of bounded size: never a FIFO or a device) and what it holds is validated: at
least one triangle, finite coordinates, every index naming a vertex, and a solid that is not flat.
"""
from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from isaac_ir.files import MAX_ASSET_BYTES, FileRefused, read_bounded

# the most vertices a mesh may have (a 64 MiB OBJ holds about 2.5 million vertex lines); a face index beyond it
# names no vertex
MAX_MESH_ITEMS = 2_000_000
# the most triangles a mesh may have: checking a mesh of 2 million took 24 s and running it 43 s; 200,000 is a
# finely detailed solid that checks in about 2 s (docs/budgets.md, "Limits on files")
MAX_MESH_TRIANGLES = 200_000
# the largest coordinate a mesh may hold, in the file's units: the bound on a scene's lengths (1e12 m); beyond
# it a double places a point to worse than 1e-4 and the squares and cubes of the volume integrals overflow
MAX_MESH_COORDINATE = 1e12
# a mesh is flat when its thinnest extent (the smallest singular value of its centred vertices) is below this
# fraction of its widest: 1e-9 of a metre-sized rock is a nanometre
FLAT_RATIO = 1e-9
MESH_HINT = "a mesh is an OBJ or STL file of triangles around a solid"


class MeshFileError(ValueError):
    """A mesh file of an unknown format, one that cannot be read as one, or one that holds no usable solid."""


def read_mesh(path) -> tuple:
    """(vertices (V,3), faces (F,3) int) of an OBJ or STL file, validated (MeshFileError when not usable)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".obj", ".stl"):
        raise MeshFileError(f"`{path.name}`: unknown mesh format `{suffix}` (use .obj or .stl)")
    try:
        data = read_bounded(path, MAX_ASSET_BYTES["mesh"])
    except FileRefused as error:
        raise MeshFileError(error.message) from None
    vertices, faces = read_obj(data.decode("utf-8", errors="replace")) if suffix == ".obj" else read_stl(data)
    validate(vertices, faces)
    return vertices, faces


def mesh_problem(name: str, folder, confinement) -> tuple | None:
    """(message, hint) saying why a scene may not use the mesh file it names (relative to its folder, or
    absolute), or None. A missing file is None too: the assets stage (isaac_lang/assets.py) reports it with the
    other files the scene names, and a load that does not read assets does not miss it. A file outside the
    folders the scene may read from is refused before anything opens it."""
    path = Path(name) if Path(name).is_absolute() else Path(folder or ".") / name
    try:
        real = confinement.allowed(path) if confinement is not None else path
        if not os.path.lexists(real):
            return None
        info = os.stat(real)
    except FileRefused as error:
        return error.message, error.hint
    except OSError as error:
        return (error.strerror or str(error)), MESH_HINT
    problem = _checked(str(real), (info.st_mtime_ns, info.st_size, info.st_ino))
    return None if problem is None else (problem, MESH_HINT)


@functools.lru_cache(maxsize=64)
def _checked(path: str, stamp: tuple) -> str | None:
    """What read_mesh finds wrong with the file, or None; once per version of the file, a refusal as well as an
    acceptance (thirty bodies of one mesh, or a loop of 30 teeth, read it once)."""
    try:
        read_mesh(path)
    except FileRefused as error:
        return error.message
    except (OSError, MeshFileError) as error:
        return getattr(error, "strerror", None) or str(error)
    return None


def validate(vertices: np.ndarray, faces: np.ndarray) -> None:
    """MeshFileError saying what makes the mesh unusable: none of it, non-finite, bad indices, too large, flat."""
    if len(vertices) == 0 or len(faces) == 0:
        raise MeshFileError(f"it holds {len(vertices)} vertices and {len(faces)} triangles: no solid "
                            "(an OBJ file needs `v x y z` and `f i j k` lines)")
    _check_counts(len(vertices), len(faces))
    if not np.all(np.isfinite(vertices)):
        row = int(np.flatnonzero(~np.all(np.isfinite(vertices), axis=1))[0])
        raise MeshFileError(f"vertex {row + 1} is not a finite point: ({_point(vertices[row])})")
    far = np.any(np.abs(vertices) > MAX_MESH_COORDINATE, axis=1)
    if np.any(far):
        row = int(np.flatnonzero(far)[0])
        raise MeshFileError(f"vertex {row + 1} is at ({_point(vertices[row])}): a coordinate beyond "
                            f"±{MAX_MESH_COORDINATE:g}, the largest a mesh may hold (a scene's lengths are at most "
                            f"{MAX_MESH_COORDINATE:g} m)")
    if faces.min() < 0 or faces.max() >= len(vertices):
        bad = faces[(faces < 0) | (faces >= len(vertices))][0]
        raise MeshFileError(f"a triangle names vertex {_written(int(bad), len(vertices))}, and the file has "
                            f"{len(vertices)} (OBJ indices count from 1)")
    used = vertices[np.unique(faces)]
    # thickness along each principal direction: the singular values of the centred vertices
    spread = np.linalg.svd(used - used.mean(axis=0), compute_uv=False)
    if not spread[0] > 0:
        raise MeshFileError("its triangles all sit on one point")
    if len(spread) < 3 or spread[2] <= FLAT_RATIO * spread[0]:
        raise MeshFileError("it is flat: its triangles all lie in one plane (or on one line), so it bounds no solid")


def _check_counts(vertices: int, triangles: int) -> None:
    if vertices > MAX_MESH_ITEMS:
        raise MeshFileError(f"it holds more than {MAX_MESH_ITEMS} vertices, the most a mesh may have (simplify it)")
    if triangles > MAX_MESH_TRIANGLES:
        raise MeshFileError(f"it holds more than {MAX_MESH_TRIANGLES} triangles, the most a mesh may have "
                            "(simplify it, e.g. with a decimate modifier)")


def _point(xyz) -> str:
    return ", ".join(f"{c:g}" for c in xyz)


def _written(index: int, count: int) -> str:
    """An index as the file wrote it (1-based; 0 in an OBJ comes out as `count`)."""
    return "0" if index == count else str(index + 1)


def read_obj(text: str) -> tuple:
    vertices, faces = [], []
    for number, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts or parts[0] not in ("v", "f"):
            continue
        try:
            if parts[0] == "v":
                if len(parts) < 4:
                    raise ValueError("a vertex needs three coordinates")
                vertices.append([float(p) for p in parts[1:4]])
            else:
                ids = [int(p.split("/")[0]) for p in parts[1:]]
                if len(ids) < 3:
                    raise ValueError("a face needs three vertices")
                _check_face_indices(ids)
                ids = [i - 1 if i > 0 else len(vertices) + i for i in ids]
                faces.extend([ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1))
        except ValueError as error:
            raise MeshFileError(f"not an OBJ file: line {number}: {error}") from None
        if len(vertices) > MAX_MESH_ITEMS or len(faces) > MAX_MESH_TRIANGLES:
            _check_counts(len(vertices), len(faces))  # refused as soon as it is over: the rest is not read
    return np.asarray(vertices, float).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3)


def _check_face_indices(ids: list) -> None:
    """An index no mesh can have is refused as it is read: beyond MAX_MESH_ITEMS (either sign) it names no
    vertex, and beyond 2**63 it would not fit the index array at all."""
    for index in ids:
        if abs(index) > MAX_MESH_ITEMS:
            raise ValueError(f"face index {index:.6g} is beyond the {MAX_MESH_ITEMS} vertices a mesh may have"
                             if abs(index) > 1e15 else
                             f"face index {index} is beyond the {MAX_MESH_ITEMS} vertices a mesh may have")


def read_stl(data: bytes) -> tuple:
    count = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    if len(data) == 84 + 50 * count:  # binary: 80-byte header, count, then 50 bytes per triangle
        _check_counts(0, count)
        record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
        corners = np.frombuffer(data, record, count, 84)["corners"].astype(float).reshape(-1, 3)
    elif data[:5].lower() != b"solid" and count >= 0:
        raise MeshFileError(f"not an STL file: a binary STL of {count} triangles has {84 + 50 * count} bytes, "
                            f"this one {len(data)}; an ASCII one starts with `solid`")
    else:
        words = data.decode("ascii", errors="replace").split()
        try:
            corners = np.array([[float(w) for w in words[k + 1:k + 4]] for k, w in enumerate(words)
                                if w == "vertex"], float)
            corners = corners.reshape(-1, 3)
        except ValueError as error:
            raise MeshFileError(f"not an STL file: {error}") from None
        if len(corners) % 3:
            raise MeshFileError("not an STL file: its corners do not make whole triangles")
        _check_counts(0, len(corners) // 3)
    if not np.all(np.isfinite(corners)):
        raise MeshFileError("a corner is not a finite point")
    vertices, inverse = np.unique(np.round(corners, 12), axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3)
