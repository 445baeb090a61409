"""Volume and inertia of the primitive shapes, about the centre of mass, in body axes.

Cylinders and capsules have their axis along body z. Formulas: standard solid-body results (e.g. any
mechanics handbook); the capsule is a cylinder plus two hemispheres whose centres of mass sit 3r/8 from the
flat face (parallel-axis theorem).
"""
from __future__ import annotations

import math
import sys


def volume(shape) -> float | None:
    if shape.type == "sphere":
        return 4.0 / 3.0 * math.pi * shape.radius**3
    if shape.type == "box":
        a, b, c = shape.size
        return a * b * c
    if shape.type == "cylinder":
        return math.pi * shape.radius**2 * shape.length
    if shape.type == "capsule":
        return math.pi * shape.radius**2 * shape.length + 4.0 / 3.0 * math.pi * shape.radius**3
    return None  # plane: infinite; mesh: computed from the file by the runtime


def inertia(shape, mass: float) -> tuple | None:
    """Principal moments (Ixx, Iyy, Izz) of a solid of uniform density."""
    if shape.type == "sphere":
        # I = 2/5 m r^2
        i = 0.4 * mass * shape.radius**2
        return (i, i, i)
    if shape.type == "box":
        a, b, c = shape.size
        # I_xx = m (b^2 + c^2) / 12, and cyclically
        return (mass * (b * b + c * c) / 12.0, mass * (a * a + c * c) / 12.0, mass * (a * a + b * b) / 12.0)
    if shape.type == "cylinder":
        r, h = shape.radius, shape.length
        # I_zz = m r^2 / 2;  I_xx = I_yy = m (3 r^2 + h^2) / 12
        side = mass * (3 * r * r + h * h) / 12.0
        return (side, side, 0.5 * mass * r * r)
    if shape.type == "capsule":
        return _capsule_inertia(shape.radius, shape.length, mass)
    return None


def _capsule_inertia(r: float, h: float, mass: float) -> tuple:
    v_cyl = math.pi * r * r * h
    v_caps = 4.0 / 3.0 * math.pi * r**3
    m_cyl = mass * v_cyl / (v_cyl + v_caps)
    m_hemi = 0.5 * (mass - m_cyl)
    # axial: cylinder m r^2/2 + two hemispheres 2/5 m r^2 each
    axial = 0.5 * m_cyl * r * r + 2 * 0.4 * m_hemi * r * r
    # transverse: hemisphere about its own centre of mass (83/320 m r^2), moved by h/2 + 3r/8
    offset = 0.5 * h + 3.0 * r / 8.0
    hemi = (83.0 / 320.0) * m_hemi * r * r + m_hemi * offset**2
    side = m_cyl * (3 * r * r + h * h) / 12.0 + 2 * hemi
    return (side, side, axial)


def principal_moments(inertia) -> list:
    """The principal moments of an inertia tensor (3x3, symmetric); [] for none, [inf] when it is not finite."""
    import numpy as np

    if inertia is None:
        return []
    tensor = np.asarray(inertia, float)
    return [float(m) for m in np.linalg.eigvalsh(tensor)] if np.all(np.isfinite(tensor)) else [math.inf]


def computable(values) -> bool:
    """Masses or moments the step can divide by: finite, and at least the smallest normal double (2.2e-308;
    below it a number is subnormal, its digits gone, and one over it overflows)."""
    return all(math.isfinite(v) and v >= sys.float_info.min for v in values)


def diagonal(moments: tuple) -> tuple:
    a, b, c = moments
    return ((a, 0.0, 0.0), (0.0, b, 0.0), (0.0, 0.0, c))


# ---- closed triangle meshes: volume integrals by the divergence theorem ----------------------------------

class MeshMassError(ValueError):
    """A mesh whose solid has no volume to integrate (open, wound both ways, or flat): says what is wrong."""


def mesh_integrals(vertices, faces) -> tuple:
    """(volume, centroid (3,), inertia (3,3) about the centroid for unit density) of the solid bounded by a
    closed, consistently wound triangle mesh (vertices (V,3), faces (F,3) vertex indices).

    Each triangle (a, b, c) and the origin span a signed tetrahedron, det = a . (b x c) (positive for a
    triangle counter-clockwise seen from outside); summed, the signs leave exactly the enclosed solid
    (the divergence theorem, one tetrahedron per triangle: Tonon 2004, J. Math. Stat. 1(1); Blow & Binstock
    2004, "How to find the inertia tensor of a 3D solid body represented by a triangle mesh"):
        V          = sum det / 6
        int x dV   = sum det (a + b + c) / 24
        S = int x x^T dV = sum det A C A^T,  A = [a b c],  C_ij = (1 + delta_ij) / 120
    (C: the canonical tetrahedron's int u_i u_j), so A C A^T = (s s^T + a a^T + b b^T + c c^T) / 120, s = a + b + c.
    About the centroid c: S_c = S - V c c^T, and the inertia tensor is J = tr(S_c) I - S_c.
    The vertices are taken about their mean first, so that a mesh far from its origin loses no digits."""
    import numpy as np

    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    problem = _not_closed(f, len(v))
    if problem:
        raise MeshMassError(problem)
    shift = v.mean(axis=0) if len(v) else np.zeros(3)
    a, b, c = (v[f[:, k]] - shift for k in range(3))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    volume = det.sum() / 6.0
    if not volume > 0:
        if volume < 0:  # wound clockwise throughout: the same solid, every sign turned
            return mesh_integrals(v, f[:, ::-1])
        raise MeshMassError("the mesh encloses no volume")
    s = a + b + c
    first = (det[:, None] * s).sum(axis=0) / 24.0
    second = np.einsum("i,ij,ik->jk", det, s, s) + sum(np.einsum("i,ij,ik->jk", det, p, p) for p in (a, b, c))
    second /= 120.0
    centre = first / volume
    about = second - volume * np.outer(centre, centre)
    inertia = np.trace(about) * np.eye(3) - about
    return float(volume), centre + shift, 0.5 * (inertia + inertia.T)


def _not_closed(faces, count: int) -> str | None:
    """Why a triangle list does not bound a solid, or None: every edge must be used exactly once in each
    direction (closed, and wound the same way throughout)."""
    import numpy as np

    if len(faces) < 4:
        return "a closed mesh needs at least 4 triangles"
    if faces.min() < 0 or faces.max() >= count:
        return "a triangle names a vertex the file does not have"
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    if np.any(edges[:, 0] == edges[:, 1]):
        return "a triangle uses one vertex twice"
    key = edges[:, 0] * count + edges[:, 1]
    unique, uses = np.unique(key, return_counts=True)
    if np.any(uses > 1):
        return "an edge is used twice in the same direction: the triangles are not wound the same way"
    reverse = edges[:, 1] * count + edges[:, 0]
    if not np.all(np.isin(reverse, unique)):
        return "the mesh is not closed: an edge belongs to one triangle only"
    return None


# ---- bodies made of parts ------------------------------------------------------------------------------------

def solid(shape, mass: float, mesh=None) -> tuple:
    """(centre (3,), inertia (3,3) about that centre) of one solid of uniform density in its own frame: a
    primitive about its centre, a mesh (mesh = mesh_integrals(...) of its file, scaled) about its centroid."""
    import numpy as np

    if shape.type == "mesh":
        volume, centre, unit = mesh
        return np.asarray(centre, float), np.asarray(unit, float) * (mass / volume)
    return np.zeros(3), np.asarray(diagonal(inertia(shape, mass)), float)


def combine(pieces) -> tuple:
    """(mass, centre (3,), inertia (3,3) about the centre) of rigidly joined pieces, each (mass, centre (3,),
    inertia (3,3) about its own centre, all in one frame). Parallel axis theorem:
        m = sum m_k,   c = sum m_k c_k / m,   I = sum [ I_k + m_k (|d_k|^2 I3 - d_k d_k^T) ],  d_k = c_k - c."""
    import numpy as np

    masses = np.array([p[0] for p in pieces], float)
    centres = np.array([p[1] for p in pieces], float).reshape(-1, 3)
    total = float(masses.sum())
    centre = masses @ centres / total
    inertia = np.zeros((3, 3))
    for m, c, own in pieces:
        d = np.asarray(c, float) - centre
        inertia += np.asarray(own, float) + m * ((d @ d) * np.eye(3) - np.outer(d, d))
    return total, centre, 0.5 * (inertia + inertia.T)


def turned(inertia, rotation) -> "np.ndarray":  # noqa: F821
    """An inertia tensor in rotated axes: R I R^T (R takes the piece's axes to the frame's)."""
    import numpy as np

    R = np.asarray(rotation, float)
    return R @ np.asarray(inertia, float) @ R.T
