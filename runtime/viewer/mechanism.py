"""What the viewer draws besides the bodies' surfaces: the parts of a mechanism, as data for the page.

    mechanism_data(scene, names, meshes, position)  ->  {"links", "joints", "springs", "ropes", "ground"}

- links: nails, a wire from the body's surface to the nailed point and a square at the world point;
- joints: ball joints (point constraints), a wire from each body's surface to its anchor (a mobile's rods and
  discs hang by them) and a dot where the two anchors meet; a joint whose body keeps one free axis (a hinge: two
  `orient` rows on the same body axis) also shows that axis;
- springs and dampers: a coil (a damper: a straight rod) between their two points;
- ropes (gear to weight): a line from the gear's rim to the weight;
- ground: the plane the scene stands on (a static plane whose normal is nearest to "up", else a floor under the
  bodies' paths), where the page draws a grid and the bodies' shadows.
Gear teeth are added to the surfaces of the bodies that a `gear` constraint turns (`gear_teeth`), so that they
turn with them. Every point is in its body's frame (a world point where the body slot is -1).
"""
from __future__ import annotations

import math

import numpy as np

from ..export import geometry

# teeth on the smaller gear of a pair (the other gets as many more as its radius is larger: equal pitch)
SMALL_GEAR_TEETH = 12
# teeth on the larger gear of a pair at most (a ratio of 3e8 would draw 3.6e9 teeth): past it the pitch grows, so
# the drawing stays a few thousand triangles whatever the ratio (the motion does not use the teeth)
MAX_GEAR_TEETH = 600
# below this distance (m) an anchor lies on its body's surface: no wire is drawn to it
ON_SURFACE = 1e-4


def mechanism_data(scene, names: list, position: np.ndarray) -> dict:
    row = {name: i for i, name in enumerate(names)}
    shapes = {b.name: b.shape for b in scene.bodies}
    links, joints, ropes = [], [], []
    for constraint in scene.constraints:
        window = {"start": constraint.start, "end": constraint.end if math.isfinite(constraint.end) else 1e300}
        axes = _free_axes(constraint)
        for term in constraint.terms:
            if any(b not in row for b in term.bodies):
                continue
            if term.family == "nail":
                link = _nail(term, row, shapes, window)
                if link is not None:
                    links.append(link)
            elif term.family == "point":
                joints.append(_ball(term, row, shapes, window, axes))
            elif term.family == "rope" and len(term.bodies) == 2:
                ropes.append({"gear": row[term.bodies[0]], "weight": row[term.bodies[1]],
                              "arm": _vector(term.param("arm")), "direction": _vector(term.param("direction")),
                              "reach": _reach(shapes[term.bodies[1]]), **window})
    return {"links": links, "joints": joints, "springs": _springs(scene, row), "ropes": ropes,
            "ground": ground(scene, position)}


# ---- constraints ----------------------------------------------------------------------------------------------

def _nail(term, row: dict, shapes: dict, window: dict) -> dict | None:
    """A nail to a fixed world point (a moving nail, a function of t, is not drawn)."""
    target = _value(term.param("target"))
    if target is None or len(term.bodies) != 1:
        return None
    body = term.bodies[0]
    point = _vector(term.param("point"))
    return {"body": row[body], "point": point, "attach": surface_point(shapes[body], point),
            "target": _vector(target), **window}


def _ball(term, row: dict, shapes: dict, window: dict, axes: dict) -> dict:
    """Both ends of a ball joint: each body's anchor (its frame) and the surface point its wire starts from."""
    ends = []
    for body, key in zip(term.bodies, ("point_a", "point_b")):
        anchor = _vector(term.param(key))
        ends.append({"body": row[body], "anchor": anchor, "attach": surface_point(shapes[body], anchor)})
    axis = axes.get(term.bodies[0])
    return {"ends": ends, "axis": axis, "size": 0.3 * _reach(shapes[term.bodies[0]]), **window}


def _free_axes(constraint) -> dict:
    """body -> the body axis two of its `orient` rows keep perpendicular to two directions (a hinge's axis)."""
    seen: dict = {}
    for term in constraint.terms:
        if term.family == "orient" and term.bodies:
            axis = tuple(np.round(_vector(term.param("axis_a")), 9))
            seen.setdefault((term.bodies[0], axis), 0)
            seen[(term.bodies[0], axis)] += 1
    return {body: list(axis) for (body, axis), count in seen.items() if count >= 2}


def _springs(scene, row: dict) -> list:
    out = []
    for force in scene.forces:
        if force.type not in ("spring", "damper") or any(b not in row for b in force.bodies):
            continue
        bodies = [row[b] for b in force.bodies] + [-1] * (2 - len(force.bodies))
        out.append({"bodies": bodies, "points": [_vector(p) for p in force.points[:2]], "type": force.type})
    return out


# ---- gear teeth -------------------------------------------------------------------------------------------------

def gear_teeth(scene) -> dict:
    """body name -> [(axis (3,), pitch radius, teeth)] of every gear a `gear` constraint turns: equal pitch on
    both gears of a pair, SMALL_GEAR_TEETH on the smaller one."""
    out: dict = {}
    for constraint in scene.constraints:
        for term in constraint.terms:
            if term.family != "gear" or len(term.bodies) != 2:
                continue
            radii = [_number(term.param("radius_a")), _number(term.param("radius_b"))]
            if None in radii or min(abs(r) for r in radii) <= 0:  # a radius that follows t: no teeth drawn
                continue
            pitch = 2.0 * math.pi * min(abs(r) for r in radii) / SMALL_GEAR_TEETH
            pitch = max(pitch, 2.0 * math.pi * max(abs(r) for r in radii) / MAX_GEAR_TEETH)
            for body, axis, radius in zip(term.bodies, ("axis_a", "axis_b"), radii):
                teeth = max(6, int(round(2.0 * math.pi * abs(radius) / pitch)))
                out.setdefault(body, []).append((_vector(term.param(axis)), abs(radius), teeth))
    return out


def with_teeth(mesh: geometry.TriMesh, shape, gears: list) -> geometry.TriMesh:
    """The body's surface with a ring of teeth for each of its gears: trapezoids about the pitch circle (module
    m = pitch / pi: addendum m, dedendum 1.25 m), as thick as the body along the gear's axis."""
    positions, triangles = [mesh.positions], [mesh.triangles]
    count = len(mesh.positions)
    for axis, radius, teeth in gears:
        w = _unit(np.asarray(axis, float))
        u = _unit(np.cross(w, (1.0, 0.0, 0.0) if abs(w[0]) < 0.9 else (0.0, 1.0, 0.0)))
        v = np.cross(w, u)
        module = 2.0 * math.pi * radius / teeth / math.pi
        half = _thickness(shape, w) / 2.0
        # one tooth's outline at angle 0: (radius, angular half-width) at its root and at its tip
        outline = [(radius - 1.25 * module, 0.62), (radius + module, 0.32)]
        for k in range(teeth):
            centre = 2.0 * math.pi * k / teeth
            ring = []
            for r, width in (outline[0], outline[1]):
                for side in (-1.0, 1.0):
                    a = centre + side * width * math.pi / teeth
                    ring.append(r * (math.cos(a) * u + math.sin(a) * v))
            # corners: root-, root+, tip-, tip+ at -half then +half along w
            corners = np.array([p + s * half * w for s in (-1.0, 1.0) for p in ring])
            positions.append(corners)
            triangles.append(count + _outward(corners, _PRISM))
            count += 8
    positions = np.vstack(positions)
    triangles = np.vstack(triangles)
    tone = None if mesh.tone is None else np.concatenate([mesh.tone, np.zeros(len(triangles) - len(mesh.tone),
                                                                              mesh.tone.dtype)])
    normals = np.zeros_like(positions)  # the page shades flat, by each triangle's own normal
    return geometry.TriMesh(positions, normals, triangles, tone, mesh.two_sided)


# the 12 triangles of a tooth (8 corners as above): two faces across the axis, root, tip and the flanks
_PRISM = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
                   (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)], np.int64)


def _outward(corners: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles of a convex solid, each turned counter-clockwise seen from outside (the page culls the
    backs of closed surfaces)."""
    centre = corners.mean(axis=0)
    a, b, c = (corners[triangles[:, i]] for i in range(3))
    outward = np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3.0 - centre) > 0
    return np.where(outward[:, None], triangles, triangles[:, [0, 2, 1]])


def _thickness(shape, axis: np.ndarray) -> float:
    if shape.type in ("cylinder", "capsule") and abs(axis[2]) > 0.99:
        return float(shape.length or 0.0) or 0.02
    if shape.type == "box":
        return float(np.abs(np.asarray(shape.size, float) @ np.abs(axis))) or 0.02
    return 0.2 * _reach(shape)


# ---- shapes -------------------------------------------------------------------------------------------------------

def surface_point(shape, point) -> list:
    """The point of the shape's surface (body frame) nearest to `point`; the point itself when it lies inside."""
    p = np.asarray(point, float)
    kind = shape.type
    if kind == "sphere":
        r, d = float(shape.radius), float(np.linalg.norm(p))
        q = p * (r / d) if d > r else p
    elif kind == "box":
        h = np.asarray(shape.size, float) / 2.0
        q = np.clip(p, -h, h)
    elif kind in ("cylinder", "capsule"):
        r, half = float(shape.radius), float(shape.length or 0.0) / 2.0
        z = float(np.clip(p[2], -half, half))
        if kind == "capsule":  # the nearest point of the axis segment, then the radius
            d = p - (0.0, 0.0, z)
            n = float(np.linalg.norm(d))
            q = p if n <= r else np.array([0.0, 0.0, z]) + d * (r / n)
        else:
            radial = float(np.hypot(p[0], p[1]))
            scale = r / radial if radial > r else 1.0
            q = np.array([p[0] * scale, p[1] * scale, z])
    else:  # a plane or a mesh: the anchor itself (no wire)
        q = p
    return [float(v) for v in (p if np.linalg.norm(q - p) < ON_SURFACE else q)]


def _reach(shape) -> float:
    """A body's size: the radius of a sphere about its centre that holds it (planes and meshes: 0.1 m)."""
    if shape.type == "sphere":
        return float(shape.radius)
    if shape.type == "box":
        return float(np.linalg.norm(shape.size)) / 2.0
    if shape.type in ("cylinder", "capsule"):
        return float(math.hypot(shape.radius, (shape.length or 0.0) / 2.0)) + (
            float(shape.radius) if shape.type == "capsule" else 0.0)
    return 0.1


# ---- the ground ----------------------------------------------------------------------------------------------------

def ground(scene, position: np.ndarray) -> dict:
    """{"point", "normal", "centre", "size", "spacing", "plane"}: where the grid and the shadows go. A static plane
    facing up is the ground; otherwise a floor at height 0, or under the lowest point the bodies reach."""
    up = _unit(-np.asarray(scene.gravity, float)) if np.linalg.norm(scene.gravity) > 0 else np.array([0.0, 1.0, 0.0])
    points = np.asarray(position, float).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if not len(points):
        points = np.zeros((1, 3))
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = max(float(np.linalg.norm(hi - lo)), 1.0)
    plane_index, best = -1, 0.7
    for i, body in enumerate(scene.bodies):
        if body.shape.type == "plane" and body.motion == "static":
            n = _unit(np.asarray(body.shape.normal or (0.0, 1.0, 0.0), float))
            if float(n @ up) > best:
                plane_index, best = i, float(n @ up)
    if plane_index >= 0:
        body = scene.bodies[plane_index]
        normal = _unit(np.asarray(body.shape.normal or (0.0, 1.0, 0.0), float))
        origin = np.asarray(_value(body.position), float)
    else:
        reach = max([_reach(b.shape) for b in scene.bodies if b.shape.type != "plane"] or [0.0])
        height = min(0.0, float((points @ up).min()) - reach - 0.02 * extent)
        normal, origin = up, up * height
    centre = (lo + hi) / 2.0
    centre = centre - normal * float((centre - origin) @ normal)
    size = 3.0 * extent
    return {"point": origin.tolist(), "normal": normal.tolist(), "centre": centre.tolist(), "size": size,
            "spacing": _nice(size / 24.0), "plane": plane_index}


def _nice(x: float) -> float:
    """1, 2 or 5 times a power of ten, near x."""
    exponent = math.floor(math.log10(x))
    for m in (1.0, 2.0, 5.0, 10.0):
        if x <= m * 10 ** exponent * 1.5:
            return m * 10 ** exponent
    return 10.0 ** (exponent + 1)


def _value(v):
    return getattr(v, "value", v)


def _number(v) -> float | None:
    v = _value(v)
    return float(v) if isinstance(v, (int, float)) else None


def _vector(v) -> list:
    """A vector parameter as drawn: its value, or where an expression of t puts it at t = 0 (a moving nail's
    target, a turning plane's normal: the page draws the joint where it starts)."""
    from isaac_ir import expr as E

    value = _value(v)
    if isinstance(value, E.Expr):
        value = E.evaluate(value, {"t": 0.0})
    return [float(c) for c in value]


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v
