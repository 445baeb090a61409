"""The viewer's geometry, bounded: viewer.html embeds at most MAX_VIEWER_TRIANGLES triangles, shared among the
bodies (at least MIN_SHARE each). A body's surface beyond its share is simplified by clustering its vertices on a
grid (each cell's vertices merged into their mean, the triangles that collapse dropped), the grid coarsened until
the surface fits; the page's note says which bodies were drawn so, and with how many of their triangles. The
motion, the trajectory and every other output use the mesh itself: only the drawing is simplified.
"""
from __future__ import annotations

import numpy as np

from ..export.geometry import TriMesh

# triangles viewer.html embeds over all bodies: about 24 MB of page (positions and indices in base64)
MAX_VIEWER_TRIANGLES = 1_000_000
# the fewest triangles a body's share may fall to (a few thousand draw any solid recognisably)
MIN_SHARE = 2_000
# the finest grid tried, in cells along the surface's largest extent
FINEST_GRID = 1024


def triangle_share(bodies: int) -> int:
    return max(MIN_SHARE, MAX_VIEWER_TRIANGLES // max(1, bodies))


def within_share(mesh: TriMesh, share: int) -> tuple:
    """(the mesh, or a simplified one of at most `share` triangles; "" or what was done, for the page's note)."""
    count = len(mesh.triangles)
    if count <= share:
        return mesh, ""
    cells = FINEST_GRID
    while cells >= 1:
        simplified = clustered(mesh, cells)
        if len(simplified.triangles) <= share:
            return simplified, f"{len(simplified.triangles)} of its {count} triangles (the viewer draws {share} " \
                               f"a body)"
        cells //= 2
    return clustered(mesh, 1), f"no triangles of its {count} (the viewer draws {share} a body)"


def clustered(mesh: TriMesh, cells: int) -> TriMesh:
    """The mesh with its vertices merged cell by cell on a grid of `cells` along its largest extent."""
    positions = np.asarray(mesh.positions, float)
    low = positions.min(axis=0)
    extent = float(np.max(positions.max(axis=0) - low)) or 1.0
    key = np.clip(np.floor((positions - low) / extent * cells), 0, cells - 1).astype(np.int64)
    cell = (key[:, 0] * cells + key[:, 1]) * cells + key[:, 2]
    _, inverse = np.unique(cell, return_inverse=True)
    inverse = inverse.reshape(-1)
    merged = np.zeros((inverse.max() + 1, 3))
    np.add.at(merged, inverse, positions)
    merged /= np.bincount(inverse)[:, None]
    triangles = inverse[np.asarray(mesh.triangles)]
    keep = (triangles[:, 0] != triangles[:, 1]) & (triangles[:, 1] != triangles[:, 2]) & \
        (triangles[:, 0] != triangles[:, 2])
    triangles = triangles[keep]
    tone = None if mesh.tone is None else np.asarray(mesh.tone)[keep]
    return TriMesh(merged, _vertex_normals(merged, triangles), triangles, tone, mesh.two_sided)


def _vertex_normals(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    a, b, c = (positions[triangles[:, i]] for i in range(3))
    faces = np.cross(b - a, c - a)
    normals = np.zeros_like(positions)
    for i in range(3):
        np.add.at(normals, triangles[:, i], faces)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
