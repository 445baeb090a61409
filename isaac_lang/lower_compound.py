"""Stage 2b, lower (bodies made of parts): a compound body's parts, and the mass properties of mesh solids.

    body hammer compound {
      material wood
      part handle box { size (3, 30, 3) cm  at (0, 15, 0) cm }
      part head cylinder { radius 2 cm  length 10 cm  at (0, 32, 0) cm  orient (0, 90, 0)  material steel }
    }

The parts are written about the body's origin (the frame the writer chose); `at` of the body places that origin
and `orient` turns it, and a body point `hammer @ p` is measured from it. The body frame of the IR (and of the
runtime) has its origin at the centre of mass and the axes of the written frame; `Shape.offset` is where the
written origin sits in it (minus the centre of mass), so that every consumer can go from one to the other.

A part's mass, first found wins: its `mass`; its `density` x volume; its own material's density x volume; a share
of the body's `mass` (what the parts' own masses leave, shared by volume); the body's `density`, or the body's
material's density, x volume. The body's mass, centre and inertia follow from the parts (mass.combine: the
parallel axis theorem, each part's inertia turned into the body's axes); `inertia` on the body overrides it.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_ir import mass as M
from isaac_ir import units as U
from isaac_ir.diagnostics import SceneError, did_you_mean
from isaac_lang.lower_expr import CONTEXTS, FIXED, Typed, interpolate_name
from isaac_lang.props import Props
from isaac_lang.vocabulary import MOTIONS, PART_PROPS

PART_SHAPES = ("sphere", "box", "cylinder", "capsule", "mesh")
NEEDS = {"sphere": ("radius",), "box": ("size",), "cylinder": ("radius", "length"), "capsule": ("radius", "length"),
         "mesh": ("file",)}
# properties of a single shape, which a compound body's parts carry instead
GEOMETRY = ("radius", "length", "size", "normal", "file", "scale")
# parts of one body after its loops are unrolled, at most (a body is one rigid thing, not a scene)
MAX_PARTS = 10_000
# a centre or a product of inertia this small against the body's size (its inertia) is rounding: zero
SNAP = 1e-13


def properties_of(block) -> list:
    """The property trees of a body's block (its parts, loops and lets are not properties)."""
    return [item for item in block.children if item.data == "prop"]


def pieces_of(block) -> list:
    """The parts, loops and lets of a body's block, in order."""
    return [item for item in block.children if item.data != "prop"]


def placed(position, orientation, offset):
    """The world centre of mass of a body whose origin `at` places: x = at - R(q) offset (a constant, or an
    expression when the pose follows t). R(q) v = v + 2 w (u x v) + 2 u x (u x v), q = (w, u)."""
    if not any(offset):
        return position
    c = -np.asarray(offset, float)
    if not isinstance(position, E.Expr) and not isinstance(orientation, E.Expr):
        w, x, y, z = np.asarray(orientation, float) / np.linalg.norm(orientation)
        u = np.array([x, y, z])
        turned = c + 2.0 * w * np.cross(u, c) + 2.0 * np.cross(u, np.cross(u, c))
        return tuple(float(v) for v in np.asarray(position, float) + turned)
    q = orientation if isinstance(orientation, E.Expr) else E.Const(tuple(orientation))
    w = E.Call("dot", (q, E.Const((1.0, 0.0, 0.0, 0.0))))
    u = E.Vec(tuple(E.Call("dot", (q, E.Const(axis))) for axis in
                    ((0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))))
    uc = E.Call("cross", (u, E.Const(tuple(c))))
    turned = E.add(E.add(E.Const(tuple(c)), E.mul(E.mul(E.Const(2.0), w), uc)),
                   E.mul(E.Const(2.0), E.Call("cross", (u, uc))))
    at = position if isinstance(position, E.Expr) else E.Const(tuple(position))
    return E.add(at, turned)


@dataclass
class _Part:
    """A part as it is lowered: what the IR keeps, and what its mass properties need."""

    name: str
    tree: object
    shape: ir.Shape
    position: np.ndarray  # (3,) about the body's origin
    orientation: tuple  # (w, x, y, z)
    mass: float | None  # its own (mass, density or its own material's density)
    material: ir.Material | None  # its own, or the body's
    modes: tuple | None
    volume: float
    mesh: tuple | None  # mass.mesh_integrals of a mesh part (scaled)
    source: str


class CompoundLowerer:
    """Lowers the parts of one compound body (`decl`, its body properties `props`)."""

    def __init__(self, scene, decl, props: Props):
        self.scene, self.decl, self.props = scene, decl, props
        self.lowerer = decl.lowerer
        self.body = decl.name

    def lower(self, motion: str, material) -> tuple:
        """(mass, inertia, shape) of the body: ir.Shape("compound") with its Parts and offset."""
        self._no_geometry()
        items = []
        self._expand(pieces_of(self.decl.tree.children[-1]), self.decl.scope.child(), items)
        parts, failed, seen = [], False, {}
        for tree, scope in items:
            try:
                part = self._part(tree, scope, material)
            except SceneError:
                failed = True
                continue
            if part.name in seen:
                self.lowerer.reporter.error(f"part `{part.name}` is declared twice in body `{self.body}`",
                                            self.lowerer.pos(tree.children[0]), f"the first is at {seen[part.name]}")
                failed = True
                continue
            seen[part.name] = part.source
            parts.append(part)
        if failed:
            raise SceneError(self.lowerer.reporter.diagnostics)
        masses = self._masses(parts, motion, material)
        mass, centre, inertia = None, np.zeros(3), None
        if masses is not None:
            mass, centre, inertia = self._combine(parts, masses)
        inertia = self._given_inertia(inertia)
        shape = ir.Shape("compound", offset=tuple(0.0 - float(v) for v in centre),
                         parts=tuple(ir.Part(p.name, p.shape, tuple(float(v) for v in p.position), p.orientation,
                                             None if masses is None else float(m), p.material.name if p.material
                                             else None, p.modes, p.source)
                                     for p, m in zip(parts, masses or [None] * len(parts))))
        return mass, inertia, shape

    # -- the parts ------------------------------------------------------------------------------------------

    def _no_geometry(self) -> None:
        for name in GEOMETRY:
            if self.props.has(name):
                raise self.lowerer.fail(f"a compound body's shape is its parts: `{name}` belongs in a part",
                                        self.props.key(name), f"e.g. `part {self.body}_core box {{ size ... }}`")

    def _expand(self, items, scope, out: list) -> None:
        """Parts in order, each with its scope, loops unrolled and lets bound."""
        for item in items:
            if item.data == "let_stmt":
                name, value = item.children
                scope.values[str(name)] = self.lowerer.lower(value, scope, CONTEXTS[False, False])
            elif item.data == "body_part":
                out.append((item, scope))
            else:  # part_loop
                var, low, high = item.children[:3]
                start, end = self._integer(low, scope), self._integer(high, scope)
                if len(out) + max(0, end - start) * max(1, len(item.children) - 3) > MAX_PARTS:
                    raise self.lowerer.fail(f"body `{self.body}` would have more than {MAX_PARTS} parts", item,
                                            "a compound body is one rigid thing: make the rest separate bodies")
                for i in range(start, end):
                    inner = scope.child()
                    inner.values[str(var)] = Typed(E.Const(float(i)), None)
                    self._expand(item.children[3:], inner, out)

    def _integer(self, tree, scope) -> int:
        value = self.lowerer.lower(tree, scope, FIXED)
        number = value.node.value if isinstance(value.node, E.Const) else None
        if not isinstance(number, float) or value.dim not in (None, U.DIMENSIONLESS) or number != int(number):
            raise self.lowerer.fail("a loop bound must be a whole number", tree)
        return int(number)

    def _part(self, tree, scope, body_material) -> _Part:

        name_tree, *words, block = tree.children
        token = name_tree.children[0]
        name = interpolate_name(str(token), token, scope, self.lowerer) if token.type == "TNAME" else str(token)
        kind = self._part_shape(name, token, words)
        props = Props(block, PART_PROPS, f"part `{name}` of body `{self.body}`", self.lowerer, scope)
        for need in NEEDS[kind]:
            if not props.has(need):
                raise self.lowerer.fail(f"part `{name}`: a {kind} needs `{need}`", token,
                                        {"box": "e.g. `size (2, 1, 1) cm`", "mesh": 'e.g. `file "tooth.obj"`'}
                                        .get(kind, "e.g. `radius 1 cm`" if need == "radius" else "e.g. `length 5 cm`"))
        shape = self.scene._shape(kind, props, self.decl)
        position = np.asarray(props.vector("at", U.LENGTH, (0.0, 0.0, 0.0)), float)
        orientation = tuple(float(v) for v in self.scene._orientation(props, False))
        mass, density = props.scalar("mass", U.MASS), props.scalar("density", U.DENSITY)
        if mass is not None and density is not None:
            raise self.lowerer.fail(f"part `{name}`: give `mass` or `density`, not both", props.key("density"),
                                    "a mass and a density together say the volume twice")
        self.scene._positive(mass, "mass", props)
        self.scene._positive(density, "density", props)
        own_material = self.scene._material_of(props)
        mesh = self._mesh(shape, props) if kind == "mesh" else None
        volume = mesh[0] if mesh is not None else M.volume(shape)
        if mass is None and density is None and own_material is not None:
            density = own_material.density
        if mass is None and density is not None:
            mass = density * volume
        return _Part(name, tree, shape, position, orientation, mass, own_material or body_material,
                     self.scene._modes(props), volume, mesh, str(self.lowerer.pos(tree)))

    def _part_shape(self, name: str, token, words) -> str:
        kinds = [str(w) for w in words]
        for word, text in zip(words, kinds):
            if text in MOTIONS:
                raise self.lowerer.fail(f"part `{name}` moves with its body: `{text}` belongs on the body", word,
                                        f"`body {self.body} {text} compound {{ ... }}`")
            if text == "plane":
                raise self.lowerer.fail(f"part `{name}`: a plane cannot be a part (it is infinite)", word,
                                        "a floor is a body of its own: `body floor plane { }`")
            if text == "compound":
                raise self.lowerer.fail(f"part `{name}`: a part is one shape, not a compound", word,
                                        "write the inner parts as parts of this body")
            if text not in PART_SHAPES:
                raise self.lowerer.fail(f"`{text}` is not a shape a part can have", word,
                                        did_you_mean(text, PART_SHAPES) or "shapes: " + ", ".join(PART_SHAPES))
        if not kinds:
            raise self.lowerer.fail(f"part `{name}` has no shape", token,
                                    "write e.g. `part " + name + " box { size (1, 1, 1) cm }`")
        if len(kinds) > 1:
            raise self.lowerer.fail(f"part `{name}` has two shapes, `{kinds[0]}` and `{kinds[1]}`", words[1],
                                    "a part is one shape; make another part for the other")
        return kinds[0]

    def _mesh(self, shape: ir.Shape, props: Props) -> tuple:
        return read_solid(self.scene, shape, props, "give this part a closed mesh (every edge shared by two "
                          "triangles, wound the same way)")

    # -- mass properties ----------------------------------------------------------------------------------

    def _masses(self, parts, motion: str, material) -> list | None:
        """Each part's mass (see the module docstring), or None when some part has none (then the body has no
        mass properties: allowed for a static or kinematic body)."""
        props = self.props
        total = props.scalar("mass", U.MASS)
        density = props.scalar("density", U.DENSITY, material.density if material else None)
        self.scene._positive(total, "mass", props)
        self.scene._positive(density if props.has("density") else None, "density", props)
        masses = [p.mass for p in parts]
        shared = [i for i, m in enumerate(masses) if m is None]
        if total is not None:
            known = sum(m for m in masses if m is not None)
            left = total - known
            volume = sum(parts[i].volume for i in shared)
            if left <= 0 if shared else not math.isclose(left, 0.0, abs_tol=1e-9 * total):
                raise self.lowerer.fail(f"body `{self.body}`: its parts' own masses add up to {known:.6g} kg, "
                                        f"{'not' if not shared else 'leaving nothing of'} its `mass`",
                                        props.node("mass"), "give the body no `mass` (its mass is then the "
                                        "parts'), or give fewer parts masses of their own")
            for i in shared:
                masses[i] = left * parts[i].volume / volume
        elif density is not None:
            for i in shared:
                masses[i] = density * parts[i].volume
        missing = [parts[i] for i, m in enumerate(masses) if m is None]
        if missing and motion == "dynamic":
            part = missing[0]
            raise self.lowerer.fail(f"part `{part.name}` of body `{self.body}` has no mass", part.tree.children[0],
                                    "give it `mass` or `density` (or a material with a density), or give the "
                                    "body a `mass` to share among its parts")
        return None if missing else masses

    def _combine(self, parts, masses) -> tuple:
        """(mass, centre (3,), inertia (3,3)) about the centre, in the written frame's axes."""
        pieces = []
        for part, m in zip(parts, masses):
            centre, own = M.solid(part.shape, m, part.mesh)
            R = _rotation(part.orientation)
            pieces.append((m, part.position + R @ centre, M.turned(own, R)))
        mass, centre, inertia = M.combine(pieces)
        if not np.all(np.isfinite(inertia)) or np.linalg.eigvalsh(inertia).min() <= 0:
            raise self.lowerer.fail(f"body `{self.body}`: its parts give no usable inertia",
                                    self.decl.tree.children[0], "give it `inertia (Ixx, Iyy, Izz) kg*m2`")
        # what is left of symmetry by rounding (a wheel's products of inertia of 1e-21) is zero: a canonical IR,
        # and a diagonal inertia takes the core's faster path
        reach = max(float(np.abs([p.position for p in parts]).max()), math.sqrt(np.trace(inertia) / mass))
        centre = np.where(np.abs(centre) < SNAP * reach, 0.0, centre) + 0.0
        inertia = np.where(np.abs(inertia) < SNAP * np.trace(inertia), 0.0, inertia) + 0.0
        return mass, centre, tuple(tuple(float(v) for v in row) for row in inertia)

    def _given_inertia(self, computed):
        given = self.props.vector("inertia", U.INERTIA)
        if given is None:
            return computed
        if min(given) <= 0:
            raise self.lowerer.fail("principal moments of inertia must be positive", self.props.node("inertia"))
        return M.diagonal(given)


# ---- mesh solids ------------------------------------------------------------------------------------------------

def mesh_body(scene, shape: ir.Shape, motion: str, props: Props, mass, density, decl) -> tuple:
    """(mass, inertia, shape) of a single mesh body: the file is read when its mass or inertia must come from it;
    then the centre of mass is the mesh's centroid and the shape's offset says where the file's origin is.
    A body that gives both `mass` and `inertia` keeps the file's origin as its centre of mass (the file is not
    read here)."""
    given = props.vector("inertia", U.INERTIA)
    if given is not None and min(given) <= 0:
        raise decl.lowerer.fail("principal moments of inertia must be positive", props.node("inertia"))
    if (mass is not None and given is not None) or (mass is None and density is None):
        if mass is None and motion == "dynamic":
            raise decl.lowerer.fail(f"body `{decl.name}` needs a mass", decl.tree.children[0],
                                    "give `mass 1 kg`, a `density`, or a material with a density")
        return mass, (M.diagonal(given) if given is not None else None), shape
    volume, centroid, unit = read_solid(scene, shape, props, "give the body `mass` and `inertia` instead")
    if mass is None:
        mass = density * volume
    inertia = M.diagonal(given) if given is not None else \
        tuple(tuple(float(v) * mass / volume for v in row) for row in unit)
    return mass, inertia, replace(shape, offset=tuple(0.0 - float(v) for v in centroid))


def read_solid(scene, shape: ir.Shape, props: Props, hint: str) -> tuple:
    """mass.mesh_integrals of a mesh shape's file (scaled), with a positioned error when it cannot be had."""
    from isaac_ir.meshfile import MeshFileError

    folder = getattr(scene.x, "folder", None)
    path = Path(shape.file) if Path(shape.file).is_absolute() or folder is None else Path(folder) / shape.file
    try:
        return _solid_of(str(path), _stamp(path), float(shape.scale))
    except FileNotFoundError:
        raise props.lowerer.fail(f"no such mesh file: `{shape.file}`", props.node("file"),
                                 f"looked for {path}; a mesh is named relative to the file that names it") from None
    except (OSError, MeshFileError) as error:
        raise props.lowerer.fail(f"cannot read the mesh file `{shape.file}`: {getattr(error, 'strerror', None) or error}",
                                 props.node("file")) from None
    except M.MeshMassError as error:
        raise props.lowerer.fail(f"the mesh `{shape.file}` bounds no solid: {error}", props.node("file"),
                                 hint) from None


def _stamp(path: Path) -> tuple:
    info = path.stat()
    return info.st_mtime_ns, info.st_size


@functools.lru_cache(maxsize=64)
def _solid_of(path: str, stamp: tuple, scale: float) -> tuple:
    """The volume integrals of a mesh file, read once per version of the file (a loop of 30 teeth reads one)."""
    from isaac_ir.meshfile import read_mesh

    vertices, faces = read_mesh(path)
    volume, centre, unit = M.mesh_integrals(vertices * scale, faces)
    return volume, tuple(centre), tuple(map(tuple, unit))


def _rotation(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
