"""What the viewer and the exporters draw: shapes as triangle meshes, colours, poses and framing.

One source of truth for every picture of a scene: the HTML viewer, glTF and RIB all take their triangles (RIB
only for boxes, planes and meshes; it has true quadrics for the rest), their colours and their poses from here.
Body frame conventions follow the IR: cylinders and capsules have their axis along body z; a plane passes through
its body's origin with the shape's `normal`; mesh files (OBJ/STL) are in the body frame, times `scale`.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# tessellation of curved shapes: segments around an axis, and rings from pole to pole
SEGMENTS = 32
RINGS = 16
# a plane is drawn as a square of this many tiles per side (a checker, so that motion over it reads)
PLANE_TILES = 16
# distinct, colour-blind-friendly hues for dynamic bodies (Okabe-Ito), and grey for static ones
PALETTE = ((0.90, 0.62, 0.00), (0.34, 0.71, 0.91), (0.00, 0.62, 0.45), (0.94, 0.89, 0.26),
           (0.00, 0.45, 0.70), (0.84, 0.37, 0.00), (0.80, 0.47, 0.65))
STATIC_COLOR = (0.62, 0.62, 0.60)
PLANE_COLOR = (0.80, 0.80, 0.78)


@dataclass
class TriMesh:
    """A body's surface in its own frame: positions (V,3), per-vertex normals (V,3), triangles (F,3) counter-
    clockwise seen from outside, and a tone (F,) per triangle (0 or 1: the checker of a plane)."""

    positions: np.ndarray
    normals: np.ndarray
    triangles: np.ndarray
    tone: np.ndarray | None = None
    two_sided: bool = False


class MeshFileError(ValueError):
    """A mesh file that cannot be read; the message names the file and the line or byte."""


# ---- shapes -----------------------------------------------------------------------------------------------

def tessellate(shape, plane_size: float = 10.0, folder: Path | None = None) -> TriMesh:
    """The triangles of an IR shape (`isaac_ir.ir.Shape`) in the body frame."""
    kind = shape.type
    if kind == "sphere":
        return sphere(shape.radius)
    if kind == "box":
        return box(shape.size)
    if kind == "cylinder":
        return cylinder(shape.radius, shape.length)
    if kind == "capsule":
        return capsule(shape.radius, shape.length)
    if kind == "plane":
        return plane(shape.normal or (0.0, 1.0, 0.0), plane_size)
    if kind == "mesh":
        path = Path(shape.file) if folder is None else Path(folder) / shape.file
        positions, triangles = read_mesh(path)
        # the file's origin sits at the shape's offset in the body frame (the centroid is the centre of mass)
        return _flat(positions * shape.scale + np.asarray(shape.offset, float), triangles)
    if kind == "compound":
        return compound(shape, plane_size, folder)
    raise ValueError(f"shape: unknown type {kind!r}")


def compound(shape, plane_size: float = 10.0, folder: Path | None = None) -> TriMesh:
    """The parts of a compound body, each tessellated and placed in the body frame: p = offset + at + R p_part."""
    from isaac_runtime.core.rotation import quat_to_matrix

    positions, normals, triangles, count = [], [], [], 0
    for part in shape.parts:
        mesh = tessellate(part.shape, plane_size, folder)
        R = quat_to_matrix(np.asarray(part.orientation, float))
        positions.append(np.asarray(shape.offset, float) + np.asarray(part.position, float) + mesh.positions @ R.T)
        normals.append(mesh.normals @ R.T)
        triangles.append(mesh.triangles + count)
        count += len(mesh.positions)
    return TriMesh(np.vstack(positions), np.vstack(normals), np.vstack(triangles))


def box(size) -> TriMesh:
    h = np.asarray(size, float) / 2.0
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * h
    # the six faces as quads of corner indices (bit 2: x, bit 1: y, bit 0: z), counter-clockwise from outside
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return _flat(corners, np.array(triangles))


def sphere(radius: float) -> TriMesh:
    return _revolve(_arc(radius, 0.0, -math.pi / 2, math.pi / 2, RINGS), SEGMENTS)


def capsule(radius: float, length: float) -> TriMesh:
    """A cylinder of `length` along z with hemispherical ends of `radius`."""
    half = length / 2.0
    bottom = _arc(radius, -half, -math.pi / 2, 0.0, RINGS // 2)
    top = _arc(radius, half, 0.0, math.pi / 2, RINGS // 2)
    return _revolve(np.vstack([bottom, top]), SEGMENTS)


def cylinder(radius: float, length: float) -> TriMesh:
    half = length / 2.0
    a = np.linspace(0.0, 2.0 * math.pi, SEGMENTS, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    side = np.vstack([ring * radius + (0, 0, -half), ring * radius + (0, 0, half)])
    side_n = np.vstack([ring, ring])
    n = SEGMENTS
    tris = []
    for i in range(n):
        j = (i + 1) % n
        tris += [(i, j, n + j), (i, n + j, n + i)]
    positions, normals = [side], [side_n]
    offset = 2 * n
    for z, sign in ((-half, -1.0), (half, 1.0)):
        positions.append(np.vstack([[0.0, 0.0, z], ring * radius + (0, 0, z)]))
        normals.append(np.tile([0.0, 0.0, sign], (n + 1, 1)))
        for i in range(n):
            j = (i + 1) % n
            a_, b_ = (offset + 1 + i, offset + 1 + j)
            tris.append((offset, a_, b_) if sign > 0 else (offset, b_, a_))
        offset += n + 1
    return TriMesh(np.vstack(positions), np.vstack(normals), np.array(tris, dtype=np.int64))


def plane(normal, size: float) -> TriMesh:
    """A square of side `size` centred on the body origin, perpendicular to `normal`, as a checker of tiles."""
    n = _unit(np.asarray(normal, float))
    u = _unit(np.cross(n, (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 0.0, 1.0)))
    v = np.cross(n, u)
    k = PLANE_TILES
    s = (np.arange(k + 1) / k - 0.5) * size
    grid = s[:, None, None] * u + s[None, :, None] * v  # (k+1, k+1, 3)
    positions = grid.reshape(-1, 3)
    tris, tone = [], []
    for i in range(k):
        for j in range(k):
            a, b, c, d = i * (k + 1) + j, (i + 1) * (k + 1) + j, (i + 1) * (k + 1) + j + 1, i * (k + 1) + j + 1
            tris += [(a, b, c), (a, c, d)]
            tone += [(i + j) % 2] * 2
    normals = np.tile(n, (len(positions), 1))
    return TriMesh(positions, normals, np.array(tris, dtype=np.int64), np.array(tone, dtype=np.uint8), True)


def _arc(radius: float, z0: float, lat0: float, lat1: float, rings: int) -> np.ndarray:
    """A profile (rings+1, 4) of (distance from the z axis, z, normal's rho, normal's z) along a circle of
    latitude lat0..lat1 about (0, 0, z0)."""
    lat = np.linspace(lat0, lat1, rings + 1)
    c, s = np.cos(lat), np.sin(lat)
    return np.stack([radius * c, z0 + radius * s, c, s], axis=1)


def _revolve(profile: np.ndarray, segments: int) -> TriMesh:
    """Turn a profile of (rho, z, n_rho, n_z) rows about the z axis; a ring of rho = 0 is a pole."""
    a = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    cos, sin = np.cos(a)[None, :], np.sin(a)[None, :]
    rho, z, n_rho, n_z = (profile[:, k:k + 1] for k in range(4))
    positions = np.stack(np.broadcast_arrays(rho * cos, rho * sin, z), axis=2).reshape(-1, 3)
    normals = np.stack(np.broadcast_arrays(n_rho * cos, n_rho * sin, n_z), axis=2).reshape(-1, 3)
    tris = []
    for r in range(len(profile) - 1):
        for i in range(segments):
            j = (i + 1) % segments
            a_, b_, c_, d_ = r * segments + i, r * segments + j, (r + 1) * segments + j, (r + 1) * segments + i
            if profile[r, 0] > 1e-12:  # not the south pole: the lower triangle has area
                tris.append((a_, b_, c_))
            if profile[r + 1, 0] > 1e-12:
                tris.append((a_, c_, d_))
    return TriMesh(positions, normals, np.array(tris, dtype=np.int64))


def _flat(positions: np.ndarray, triangles: np.ndarray) -> TriMesh:
    """Faceted: each triangle gets its own three vertices and its face normal."""
    corners = positions[triangles]  # (F,3,3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    flat_positions = corners.reshape(-1, 3)
    flat_normals = np.repeat(normals, 3, axis=0)
    return TriMesh(flat_positions, flat_normals, np.arange(len(flat_positions)).reshape(-1, 3))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-300)


# ---- mesh files -------------------------------------------------------------------------------------------

def read_mesh(path: Path) -> tuple:
    """Vertices (V,3) and triangles (F,3) of an OBJ or STL (ASCII or binary) file."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as error:
        raise MeshFileError(f"{path}: cannot read mesh: {error.strerror or error}") from None
    if path.suffix.lower() == ".stl":
        return _read_stl(data, path)
    return _read_obj(data.decode("utf-8", errors="replace"), path)


def _read_obj(text: str, path: Path) -> tuple:
    vertices, triangles = [], []
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        try:
            if fields[0] == "v":
                vertices.append([float(x) for x in fields[1:4]])
            elif fields[0] == "f":
                # v, v/vt, v//vn or v/vt/vn; negative indices count back from the last vertex
                idx = [int(f.split("/")[0]) for f in fields[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                triangles += [(idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1)]
        except (ValueError, IndexError):
            raise MeshFileError(f"{path}:{number}: cannot read `{line.strip()}`") from None
    return _checked(np.array(vertices, float).reshape(-1, 3), np.array(triangles, np.int64).reshape(-1, 3), path)


def _read_stl(data: bytes, path: Path) -> tuple:
    if len(data) >= 84:
        count = struct.unpack_from("<I", data, 80)[0]
        if 84 + 50 * count == len(data):
            record = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
            corners = np.frombuffer(data, record, count, 84)["corners"].astype(float)
            return _merge(corners, path)
    text = data.decode("ascii", errors="replace")
    points = [line.split()[1:4] for line in text.splitlines() if line.strip().startswith("vertex")]
    try:
        corners = np.array(points, float).reshape(-1, 3, 3)
    except ValueError:
        raise MeshFileError(f"{path}: not a binary STL and not an ASCII STL with whole triangles") from None
    return _merge(corners, path)


def _merge(corners: np.ndarray, path: Path) -> tuple:
    vertices, inverse = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    return _checked(vertices, inverse.reshape(-1, 3), path)


def _checked(vertices: np.ndarray, triangles: np.ndarray, path: Path) -> tuple:
    if len(triangles) == 0:
        raise MeshFileError(f"{path}: no triangles")
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise MeshFileError(f"{path}: a face names a vertex that does not exist")
    return vertices, triangles


# ---- colours, poses, framing ------------------------------------------------------------------------------

def scene_colors(scene) -> list:
    """An (r, g, b) per body: planes light, other static bodies grey, the moving ones the palette in order."""
    colors, rank = [], 0
    for body in scene.bodies:
        if body.shape.type == "plane":
            colors.append(PLANE_COLOR)
        elif body.motion == "static":
            colors.append(STATIC_COLOR)
        else:
            colors.append(PALETTE[rank % len(PALETTE)])
            rank += 1
    return colors


def plane_size(position: np.ndarray) -> float:
    """Side of the square drawn for a plane: twice the widest excursion of any body, at least 4 m."""
    finite = position[np.isfinite(position).all(axis=-1)] if position.size else np.zeros((1, 3))
    extent = float(np.abs(finite).max()) if finite.size else 1.0
    return max(4.0, 4.0 * extent)


def matrices(position: np.ndarray, orientation: np.ndarray) -> np.ndarray:
    """Body-to-world 4x4 matrices (..., 4, 4) from positions (..., 3) and quaternions (..., 4) (w, x, y, z)."""
    from isaac_runtime.core.rotation import quat_to_matrix

    q = orientation / np.linalg.norm(orientation, axis=-1, keepdims=True)
    out = np.zeros(position.shape[:-1] + (4, 4))
    out[..., :3, :3] = quat_to_matrix(q)
    out[..., :3, 3] = position
    out[..., 3, 3] = 1.0
    return out


def camera_of(scene, position: np.ndarray | None = None, name: str | None = None) -> dict:
    """The camera to draw with: the named one, else the scene's first, else one framing every body's path."""
    for camera in scene.cameras:
        if name is None or camera.name == name:
            return {"name": camera.name, "position": list(camera.position), "look_at": list(camera.look_at),
                    "up": list(camera.up), "fov": camera.fov}
    if name is not None:
        raise ValueError(f"the scene has no camera `{name}` (it has: "
                         f"{', '.join(c.name for c in scene.cameras) or 'none'})")
    return framing_camera(position)


def framing_camera(position: np.ndarray | None, fov: float = math.radians(45.0)) -> dict:
    """A camera on +z looking at the centre of the bodies' paths, far enough back to see all of them."""
    points = position.reshape(-1, 3) if position is not None and position.size else np.zeros((1, 3))
    points = points[np.isfinite(points).all(axis=1)]
    if not len(points):
        points = np.zeros((1, 3))
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 0.5)
    distance = 1.3 * radius / math.tan(fov / 2.0)
    eye = centre + np.array([0.0, 0.35, 1.0]) / math.hypot(0.35, 1.0) * distance
    return {"name": "auto", "position": eye.tolist(), "look_at": centre.tolist(), "up": [0.0, 1.0, 0.0], "fov": fov}


def look_at_matrix(eye, target, up) -> np.ndarray:
    """World-to-camera 4x4 (right-handed camera looking down -z, y up), as OpenGL's gluLookAt."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    f = _unit(target - eye)
    s = np.cross(f, up)
    if np.linalg.norm(s) < 1e-9:  # looking along up: pick any side
        s = np.cross(f, (1.0, 0.0, 0.0) if abs(f[0]) < 0.9 else (0.0, 0.0, 1.0))
    s = _unit(s)
    u = np.cross(s, f)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = s, u, -f
    view[:3, 3] = -view[:3, :3] @ eye
    return view
