"""Stage 2b, lower: expanded declarations -> IR (SI units, names resolved, every default explicit)."""
from __future__ import annotations

import math
import sys
import weakref

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_lang import lower_compound as C
from isaac_ir import mass as M
from isaac_ir import units as U
from isaac_ir.diagnostics import Reporter, SceneError, SourcePos, did_you_mean
from isaac_lang.expand import Decl, Expansion
from isaac_lang.assets import refused_assets
from isaac_ir.meshfile import mesh_problem
from isaac_lang.lower_goals import GoalLowerer
from isaac_lang.lower_constraints import ConstraintLowerer, lengths_over_first_minute
from isaac_lang.origins import setting_origins
from isaac_lang.lower_expr import BodyRef, ExprContext, ExprLowerer, Scope, is_table, ref_name, written_with
from isaac_lang.props import Props
from isaac_lang.syntax import KEYWORDS
from isaac_lang.vocabulary import (AUDIO_PROPS, BODY_PROPS, CAMERA_PROPS, LIGHT_PROPS, LISTENER_PROPS,  # noqa: F401
                                   MATERIAL_PROPS, MOTIONS, SETTINGS, SHAPES, SOLVER_PROPS, SOUND_PROPS, WIND_PROPS)

AIR_DENSITY = 1.2  # kg/m3, air at sea level and 20 C
# the words that open a constraint's time window: a misspelled one after a constraint reads as a setting
WINDOW_WORDS = ("during", "from", "until")

DEFAULT_DRAG = {"sphere": 0.47, "box": 1.05, "cylinder": 0.82, "capsule": 0.82, "mesh": 1.0, "plane": 1.17,
                "compound": 1.05}


class SceneLowerer:
    def __init__(self, expansion: Expansion, reporter: Reporter, root_file: str):
        self.x = expansion
        self.reporter = reporter
        self.root_file = root_file
        self.materials: dict[str, ir.Material] = {}
        self.bodies: dict[str, ir.Body] = {}
        self.broken: set[str] = set()  # declared, but with errors: references to them are not errors again
        # it refers back to this lowerer weakly: a reference cycle would keep every parse tree alive until
        # Python's cyclic garbage collector ran (and made that collector walk them)
        self.constraints = ConstraintLowerer(weakref.proxy(self))

    # -- driver -------------------------------------------------------------------------------------------

    def run(self) -> ir.Scene:
        name = self._scene_name()
        settings = self._settings()
        solver = self._solver()
        by_kind = {kind: [] for kind in
                   ("material", "body", "camera", "light", "constraint", "force", "wind", "sound", "exclude",
                    "collide")}
        for decl in self.x.decls:
            by_kind[decl.kind].append(decl)
        self._each(by_kind["material"], self._material)
        self._each(by_kind["body"], self._body)
        cameras = self._each(by_kind["camera"], self._camera)
        lights = self._each(by_kind["light"], self._light)
        constraints = self._each(by_kind["constraint"], self.constraints.constraint)
        forces = self._each(by_kind["force"], self.constraints.force)
        winds = self._each(by_kind["wind"], self._wind)
        wind_names = {w.name for w in winds}
        sounds = self._each(by_kind["sound"], lambda d: self._sound(d, wind_names))
        exclusions = self._each(by_kind["exclude"], self._exclusion)
        collides = self._each(by_kind["collide"], lambda d: self._collide(d, settings["time"]))
        varies, goals = GoalLowerer(self, settings["time"]).run()  # (lower_goals.py)
        self.reporter.raise_if_any()
        scene = ir.Scene(
            name=name, file=self.root_file, time=settings["time"], gravity=settings["gravity"],
            seed=settings["seed"], solver=solver, cameras=tuple(cameras), lights=tuple(lights),
            materials=tuple(self.materials.values()), bodies=tuple(self.bodies.values()),
            constraints=tuple(constraints), forces=tuple(forces), winds=tuple(winds), sounds=tuple(sounds),
            exclusions=tuple(exclusions), listener=settings["listener"], audio=settings["audio"],
            parameters=tuple(sorted((k, _plain(v.node)) for k, v in self.x.parameters.items())),
            air_density=settings["air"], collides=tuple(collides), varies=varies, goals=goals,
            origins=setting_origins(self.x),
        )
        self._confined_files(scene)
        return scene

    def _confined_files(self, scene: ir.Scene) -> None:
        """The textures and recordings the scene names: refused at their declaration before anything opens them
        when they are not files it may read (files.refused_assets; meshes: _shape)."""
        for asset, refused in refused_assets(scene, self.x.folder, self.x.confinement):
            self.reporter.error(f"cannot read `{asset.name}`: {refused.message}", SourcePos.parse(asset.source),
                                refused.hint)
        self.reporter.raise_if_any()

    def _each(self, decls, build) -> list:
        out, seen = [], {}  # name -> its first declaration
        for decl in decls:
            if decl.name is not None and decl.name in seen:
                first = seen[decl.name]
                self.reporter.error(f"{decl.kind} `{decl.name}` is declared twice", decl.lowerer.pos(decl.tree),
                                    f"the first is at {first.lowerer.pos(first.tree)}")
                continue
            try:
                result = build(decl)
            except SceneError:
                if decl.name is not None:
                    self.broken.add(decl.name)
                continue
            if decl.name is not None:
                seen[decl.name] = decl
            if result is not None:
                out.append(result)
        return out

    def _scene_name(self) -> str:
        names = self.x.scene_names
        if not names:
            self.reporter.error("no `scene NAME { ... }` in this file", SourcePos(self.root_file, 1, 1),
                                "wrap the scene's declarations in `scene my_scene { ... }`")
            return "scene"
        for extra, pos in names[1:]:
            self.reporter.error(f"a second scene `{extra}` in one run", pos, "one scene per file")
        return names[0][0]

    # -- scene settings -----------------------------------------------------------------------------------

    def _settings(self) -> dict:
        lowerer = self.x.settings[0][2] if self.x.settings else None
        scope = self.x.settings[0][1] if self.x.settings else None
        # with no settings written, every getter returns its default
        props = Props(None, SETTINGS, "the scene", lowerer, scope, items=[t for t, _, _ in self.x.settings],
                      keywords=KEYWORDS + WINDOW_WORDS)
        start, end = props.range("time", U.TIME) or (0.0, 10.0)
        if end <= start:
            self.reporter.error("the scene ends before it starts", lowerer.pos(props.node("time")),
                                "write `time START .. END` with END after START")
        frame_rate = props.scalar("frames", U.FREQUENCY, 60.0, bare_ok=True)
        if frame_rate <= 0:
            self.reporter.error("the frame rate must be positive", lowerer.pos(props.node("frames")))
        gravity = props.vector("gravity", U.ACCELERATION, (0.0, -9.81, 0.0))
        # still air is air: 1.2 kg/m3 (sea level, 20 C) unless the scene says otherwise
        self.air_density = props.scalar("air", U.DENSITY, AIR_DENSITY)
        seed = props.integer("seed", 0)
        listener_props = props.block("listener", LISTENER_PROPS, "the listener")
        audio_props = props.block("audio", AUDIO_PROPS, "the audio settings")
        return {
            "time": ir.Timeline(start, end, frame_rate),
            "gravity": gravity,
            "air": self.air_density,
            "seed": seed,
            "listener": ir.Listener(listener_props.vector("at", U.LENGTH, (0.0, 0.0, 0.0)),
                                    listener_props.scalar("gain", U.DIMENSIONLESS, 1.0),
                                    listener_props.boolean("delay", False)),
            "audio": ir.Audio(self._audio_rate(audio_props), audio_props.integer("channels", 1, minimum=1)),
        }

    def _solver(self) -> ir.SolverOptions:
        plan, props = "auto", Props(None, SOLVER_PROPS, "the solver", None, None)  # unwritten: the defaults
        for tree, scope, lowerer in self.x.solvers[-1:]:
            plan = str(tree.children[0])
            if plan not in ("dynamics", "procedural", "auto"):
                raise lowerer.fail(f"unknown solver `{plan}`", tree.children[0],
                                   did_you_mean(plan, ("dynamics", "procedural", "auto")) or
                                   "choose dynamics, procedural or auto")
            block = tree.children[1] if len(tree.children) > 1 else None  # `solver auto` needs no block
            props = Props(block, SOLVER_PROPS, "the solver", lowerer, scope)
        step = props.scalar("step", U.TIME)
        if step is not None and step <= 0:
            raise props.lowerer.fail("the step must be positive", props.node("step"))
        return ir.SolverOptions(
            plan=plan,
            integrator=props.word("integrator", ("rk4", "euler", "midpoint"), "rk4"),
            step=step,
            stabilize_frequency=props.scalar("stabilize", U.FREQUENCY),
            damping_ratio=props.scalar("damping", U.DIMENSIONLESS, 1.0),
            linear_solver=props.word("linear", ("auto", "dense", "sparse", "tree"), "auto"),
            substeps=props.integer("substeps", 20, minimum=1),
            iterations=props.integer("iterations", 1, minimum=1),
            compliance=props.scalar("compliance", U.DIMENSIONLESS, 0.0),
            projection=props.word("projection", ("auto", "direct", "gauss_seidel"), "auto"),
            stabilization=props.word("stabilization", ("projection", "baumgarte"), "projection"),
            tolerance=props.scalar("tolerance", U.DIMENSIONLESS, ir.SolverOptions.tolerance,
                                   minimum=(0.0, "e.g. `tolerance 1e-9`; 0 takes every step as it is")),
        )

    # -- things -------------------------------------------------------------------------------------------

    def _camera(self, decl: Decl) -> ir.Camera:
        props = Props(decl.tree.children[1], CAMERA_PROPS, f"camera `{decl.name}`", decl.lowerer, decl.scope)
        return ir.Camera(decl.name, props.vector("at", U.LENGTH, (0.0, 1.0, 5.0)),
                         props.vector("look", U.LENGTH, (0.0, 0.0, 0.0)), props.vector("up", U.LENGTH, (0.0, 1.0, 0.0)),
                         props.scalar("fov", U.ANGLE, math.radians(45.0)), str(decl.lowerer.pos(decl.tree)))

    def _light(self, decl: Decl) -> ir.Light:
        kind = str(decl.tree.children[1])
        if kind not in ("distant", "point", "spot", "ambient"):
            raise decl.lowerer.fail(f"unknown light type `{kind}`", decl.tree.children[1],
                                    did_you_mean(kind, ("distant", "point", "spot", "ambient")))
        props = Props(decl.tree.children[2], LIGHT_PROPS, f"light `{decl.name}`", decl.lowerer, decl.scope)
        position = props.vector("from", U.LENGTH) or props.vector("at", U.LENGTH, (0.0, 10.0, 0.0))
        return ir.Light(decl.name, kind, position, props.vector("to", U.LENGTH, (0.0, 0.0, 0.0)),
                        props.scalar("intensity", U.DIMENSIONLESS, 1.0),
                        props.vector("color", U.DIMENSIONLESS, (1.0, 1.0, 1.0)), str(decl.lowerer.pos(decl.tree)))

    def _material(self, decl: Decl) -> ir.Material:
        props = Props(decl.tree.children[1], MATERIAL_PROPS, f"material `{decl.name}`", decl.lowerer, decl.scope)
        density = props.scalar("density", U.DENSITY)
        self._positive(density, "density", props)
        rayleigh = props.vector("rayleigh", U.DIMENSIONLESS, size=2)
        friction, restitution = (props.scalar(name, U.DIMENSIONLESS, 0.5) for name in ("friction", "restitution"))
        self._contact_coefficients(friction, restitution, props)
        material = ir.Material(
            decl.name, density, friction, restitution, props.scalar("young", U.PRESSURE),
            props.scalar("poisson", U.DIMENSIONLESS, 0.3), props.scalar("loss", U.DIMENSIONLESS), rayleigh,
            props.scalar("roughness", U.LENGTH, 1e-5), props.string("texture"), str(decl.lowerer.pos(decl.tree)),
        )
        self._sound_coefficients(material, props)
        self.materials[decl.name] = material
        return material

    def _sound_coefficients(self, material: ir.Material, props: Props) -> None:
        """The moduli an impact's sound divides by (the contact duration, the wave speeds): checked here, where
        they are written, not as a division by zero in the middle of a run."""
        self._positive(material.young, "young", props)
        if not -1.0 < material.poisson < 0.5:
            raise props.lowerer.fail(f"`poisson` must be above -1 and below 0.5, got {material.poisson:g}",
                                     props.node("poisson"), "about 0.3 for metals, 0.5 would be incompressible")
        for name in ("loss", "roughness"):
            value = getattr(material, name)
            if value is not None and not value >= 0.0:
                raise props.lowerer.fail(f"`{name}` must be 0 or more, got {value:g}", props.node(name))

    def _contact_coefficients(self, friction: float, restitution: float, props: Props) -> None:
        """Restitution above 1 makes energy at each bounce, below 0 lets it go through; friction below 0 pushes."""
        if not 0.0 <= restitution <= 1.0:
            raise props.lowerer.fail(f"`restitution` must be between 0 and 1, got {restitution:g}",
                                     props.node("restitution"), "0 is a plastic impact (no bounce), 1 an elastic "
                                     "one (the speed kept); above 1 each bounce would make energy")
        if not friction >= 0.0:
            raise props.lowerer.fail(f"`friction` must be 0 or more, got {friction:g}", props.node("friction"),
                                     "the Coulomb coefficient: 0 is frictionless ice, about 0.4 steel on steel")

    def _audio_rate(self, props: Props) -> float:
        rate = props.scalar("rate", U.FREQUENCY, 44100.0, bare_ok=True)
        if not rate >= 1.0:  # audio.wav holds a whole number of samples per second
            raise props.lowerer.fail(f"the audio rate must be at least 1 Hz, got {rate:g} Hz", props.node("rate"))
        return rate

    def _positive(self, value, name: str, props: Props) -> None:
        if value is not None and value <= 0:
            raise props.lowerer.fail(f"`{name}` must be positive", props.node(name))
        # below 2.2e-308 a float is subnormal: its digits are gone, and 1 / value overflows
        if value is not None and value < sys.float_info.min:
            raise props.lowerer.fail(f"`{name}` is {value:g}, too small to compute with", props.node(name),
                                     "in SI units it must be at least 2.2e-308; is the exponent's sign right?")

    def _body(self, decl: Decl) -> ir.Body:
        words = [t for t in decl.tree.children[1:-1]]
        block = decl.tree.children[-1]
        shape_word, motion = self._body_words(words, decl, C.pieces_of(block))
        what = f"body `{decl.name}`"
        props = Props(block, BODY_PROPS, what, decl.lowerer, decl.scope, items=C.properties_of(block))
        shape = None if shape_word == "compound" else self._shape(shape_word, props, decl)
        material = self._material_of(props)
        # a dynamic body may follow its path for a while: `kinematic START .. END` (docs/motion.md)
        window = props.range("kinematic", U.TIME)
        if window is not None and (motion != "dynamic" or window[1] <= window[0]):
            raise decl.lowerer.fail("`kinematic START .. END` is for a dynamic body, with END after START",
                                    props.node("kinematic"), "a body that follows its path throughout is "
                                    "`body NAME kinematic SHAPE { ... }`")
        kinematic = motion == "kinematic" or window is not None
        position = props.vector("at", U.LENGTH, E.Const((0.0, 0.0, 0.0)), time=kinematic)
        orientation = self._orientation(props, kinematic)
        try:  # a body made of parts (docs/compound.md), or of one shape
            mass, inertia, shape = C.CompoundLowerer(self, decl, props).lower(motion, material) if shape is None \
                else self._mass_properties(shape, motion, props, material, decl)
        except OverflowError:  # a volume or a moment beyond 1.8e308
            mass, inertia = math.inf, None
        self._computable(mass, inertia, props, decl)
        position = C.placed(position, orientation, shape.offset)  # `at` places the shape's origin
        body = ir.Body(
            name=decl.name, shape=shape, motion=motion, mass=mass, inertia=inertia,
            position=_as_expr(position), orientation=_as_expr(orientation),
            velocity=props.vector("velocity", U.VELOCITY, (0.0, 0.0, 0.0)),
            angular_velocity=props.vector("spin", U.ANGULAR_VELOCITY, (0.0, 0.0, 0.0)),
            material=material.name if material else None,
            collide=props.boolean("collide", True),
            wind=ir.WindResponse(props.boolean("wind", props.has("drag") or props.has("area")),
                                 props.scalar("drag", U.DIMENSIONLESS, DEFAULT_DRAG[shape.type]),
                                 props.scalar("area", U.AREA)),
            modes=self._modes(props),
            source=str(decl.lowerer.pos(decl.tree)),
            path_window=window,
        )
        self.bodies[decl.name] = body
        return body

    def _computable(self, mass, inertia, props: Props, decl: Decl) -> None:
        """A mass and principal moments the step can divide by (mass.py: finite, and not subnormal)."""
        moments, mass_ok = M.principal_moments(inertia), mass is None or M.computable([mass])
        if mass_ok and M.computable(moments):
            return
        culprits = ("radius", "size", "length", "file", "scale") if mass_ok else ("mass", "density", "radius", "size")
        where = next((props.node(n) for n in culprits if props.has(n)), decl.tree.children[0])
        told = f"mass {mass:g} kg" + (f" and principal moments {', '.join(f'{m:g}' for m in moments)} kg*m2"
                                      if moments else "")
        raise decl.lowerer.fail(f"body `{decl.name}` comes out with {told}: not numbers the step can divide by",
                                where, "each must be finite and above 2.2e-308 in SI units: is a size or a "
                                "density far too small or too large?")

    def _body_words(self, words, decl: Decl, pieces=()):
        shape_word, motion = None, "dynamic"
        for word in words:
            text = str(word)
            if text in SHAPES and shape_word is None:
                shape_word = text
            elif text in MOTIONS:
                motion = text
            else:
                raise decl.lowerer.fail(f"`{text}` is not a shape or a motion", word,
                                        did_you_mean(text, SHAPES + MOTIONS) or
                                        "shapes: " + ", ".join(SHAPES) + "; motions: " + ", ".join(MOTIONS))
        parts = [p for p in pieces if p.data != "let_stmt"]
        if shape_word is None and parts:
            shape_word = "compound"  # `body hammer { part ... }`
        if shape_word is None:
            raise decl.lowerer.fail(f"body `{decl.name}` has no shape", decl.tree.children[0],
                                    "write e.g. `body ball sphere { radius 5 cm }`")
        if shape_word == "compound" and not parts:
            raise decl.lowerer.fail(f"body `{decl.name}`: a compound body is made of parts", decl.tree.children[0],
                                    "write `body NAME compound { part NAME SHAPE { ... } ... }`")
        if shape_word != "compound" and pieces:
            raise decl.lowerer.fail(f"body `{decl.name}`: a {shape_word} has no parts or `let`s; a body made of "
                                    "parts is a compound", pieces[0],
                                    "write `body NAME compound { part NAME SHAPE { ... } ... }`")
        if shape_word == "plane" and motion == "dynamic":
            motion = "static"  # an infinite plane cannot move
        return shape_word, motion

    def _shape(self, kind: str, props: Props, decl: Decl) -> ir.Shape:
        need = {"sphere": ("radius",), "box": ("size",), "cylinder": ("radius", "length"),
                "capsule": ("radius", "length"), "plane": (), "mesh": ("file",)}[kind]
        for name in need:
            if not props.has(name):
                raise decl.lowerer.fail(f"a {kind} needs `{name}`", decl.tree.children[0])
        radius = props.scalar("radius", U.LENGTH)
        length = props.scalar("length", U.LENGTH)
        size = props.vector("size", U.LENGTH)
        for name, value in (("radius", radius), ("length", length)):
            self._positive(value, name, props)
        if size is not None and not min(size) >= sys.float_info.min:  # below it: subnormal, its digits gone
            raise decl.lowerer.fail("a box's edges must be positive", props.node("size"))
        normal = props.vector("normal", U.DIMENSIONLESS, (0.0, 1.0, 0.0) if kind == "plane" else None)
        if normal is not None:
            normal = _unit(normal, props, "normal")
        file = props.string("file")
        scale = props.scalar("scale", U.DIMENSIONLESS, 1.0)
        self._positive(scale, "scale", props)
        if file is not None:  # read and validated where it is named (meshfile.py); a missing one: assets.py
            file = self._asset(file, props, "file")
            problem = mesh_problem(file, self.x.folder, self.x.confinement)
            if problem is not None:
                raise props.lowerer.fail(f"cannot use the mesh file `{file}`: {problem[0]}", props.node("file"),
                                         problem[1])
        return ir.Shape(kind, radius=radius, length=length, size=size, normal=normal, file=file, scale=scale)

    def _asset(self, relative: str, props: Props, name: str) -> str:
        """A file the scene names, relative to the file that names it; it must exist."""
        from pathlib import Path

        here = Path(props.lowerer.file).parent
        return (here / relative).as_posix() if str(here) != "." else relative

    def _material_of(self, props: Props) -> ir.Material | None:
        name = props.word("material", None)
        if name is None:
            return None
        for candidate in [p + name for p in props.scope.prefixes()]:
            if candidate in self.materials:
                return self.materials[candidate]
            if candidate in self.broken:
                raise SceneError(self.reporter.diagnostics)
        raise props.lowerer.fail(f"unknown material `{name}`", props.node("material"),
                                 did_you_mean(name, self.materials) or "declare it with `material NAME { ... }`")

    def _orientation(self, props: Props, kinematic: bool):
        if not props.has("orient"):
            return (1.0, 0.0, 0.0, 0.0)
        value = props.typed("orient", ExprContext(time=kinematic))
        if is_table(value.node):
            raise props.lowerer.fail("`orient` takes euler(ax, ay, az), axis_angle(axis, angle), quat(w, x, y, z)",
                                     props.node("orient"))
        if value.size == 3:
            # a bare vector is Euler angles, degrees unless a unit says otherwise
            angles = value.node if value.dim == U.ANGLE else E.mul(value.node, E.Const(math.pi / 180.0))
            node = E.fold(E.Call("euler", tuple(_components(angles))))
        elif value.size == 4:
            node = value.node
        else:
            raise props.lowerer.fail("`orient` takes euler(ax, ay, az), axis_angle(axis, angle), quat(w, x, y, z)",
                                     props.node("orient"))
        return node if kinematic else props._constant(node, "orient")

    def _mass_properties(self, shape: ir.Shape, motion: str, props: Props, material, decl: Decl):
        mass = props.scalar("mass", U.MASS)
        density = props.scalar("density", U.DENSITY, material.density if material else None)
        self._positive(mass, "mass", props)
        self._positive(density if props.has("density") else None, "density", props)
        if shape.type == "mesh":  # its mass properties from the file (volume integrals), unless given
            return C.mesh_body(self, shape, motion, props, mass, density, decl)
        volume = M.volume(shape)
        if mass is None and density is not None and volume is not None:
            mass = density * volume
        if mass is None:
            if motion != "dynamic":
                return None, None, shape
            raise decl.lowerer.fail(f"body `{decl.name}` needs a mass", decl.tree.children[0],
                                    "give `mass 1 kg`, a `density`, or a material with a density")
        given = props.vector("inertia", U.INERTIA)
        if given is not None:
            if min(given) <= 0:
                raise decl.lowerer.fail("principal moments of inertia must be positive", props.node("inertia"))
            return mass, M.diagonal(given), shape
        moments = M.inertia(shape, mass)
        return mass, (M.diagonal(moments) if moments else None), shape

    def _modes(self, props: Props):
        if not props.has("modes"):
            return None
        value = props.typed("modes")
        data = value.node.value if isinstance(value.node, E.Const) else None
        if not isinstance(data, tuple) or not all(isinstance(m, tuple) and len(m) == 3 for m in data):
            raise props.lowerer.fail("`modes` takes ((frequency, decay, gain), ...)", props.node("modes"))
        return data

    def _wind(self, decl: Decl) -> ir.Wind:
        props = Props(decl.tree.children[1], WIND_PROPS, f"wind `{decl.name}`", decl.lowerer, decl.scope)
        # a source's point and a wind's direction may follow t (docs/wind.md): tuples when they do not
        origin = _constant_or_path(props.vector("from", U.LENGTH, time=True))
        aim = "toward" if origin is not None else "direction"
        direction = _constant_or_path(props.vector(aim, U.DIMENSIONLESS, time=True))
        if direction is None:
            raise decl.lowerer.fail(f"wind `{decl.name}` needs a `direction` (or `from` and `toward`)",
                                    decl.tree.children[0])
        direction = _unit(direction, props, aim) if isinstance(direction, tuple) else _never_zero(direction,
                                                                                                 props, aim)
        speed = props.scalar("speed", U.VELOCITY, E.Const(1.0), time=True, signals=True)
        return ir.Wind(
            decl.name, "source" if origin is not None else "uniform", origin, direction, _as_expr(speed),
            props.word("falloff", ("none", "inverse", "inverse_square"), "none" if origin is None else "inverse_square"),
            props.scalar("distance", U.LENGTH, 1.0), props.scalar("spread", U.ANGLE, math.radians(30.0)),
            props.scalar("turbulence", U.DIMENSIONLESS, 0.0), props.scalar("gust", U.TIME, 0.5),
            props.scalar("air", U.DENSITY, self.air_density), str(decl.lowerer.pos(decl.tree)),
        )

    def _sound(self, decl: Decl, winds: set) -> ir.Sound:
        trigger_tree = decl.tree.children[1]
        trigger, bodies, wind, time = self.constraints.trigger(trigger_tree, decl, winds)
        props = Props(decl.tree.children[2], SOUND_PROPS, f"sound `{decl.name}`", decl.lowerer, decl.scope)
        if not props.has("play"):
            raise decl.lowerer.fail(f"sound `{decl.name}` has nothing to `play`", decl.tree.children[0],
                                    "e.g. `{ play modal(bar) * impulse }`")
        graph = props.typed("play", ExprContext(time=True, signals=True, audio=True)).node
        gain_value = props.typed("gain") if props.has("gain") else None
        gain = 1.0
        if gain_value is not None:
            gain = self._gain(gain_value, props)
        return ir.Sound(decl.name, trigger, bodies, wind, time, graph, gain, str(decl.lowerer.pos(decl.tree)),
                        trigger_source=str(decl.lowerer.pos(trigger_tree) or decl.lowerer.pos(decl.tree)))

    def _gain(self, value, props: Props) -> float:
        node = props.lowerer.coerce(value, U.DIMENSIONLESS, "`gain`", props.node("gain"))
        number = props._constant(node, "gain")
        if not written_with(props.node("gain"), "dB"):  # a plain number is a linear factor
            return number
        # "-6 dB" reads as decibels: g = 10^(dB / 20)
        if number > 6000.0:  # 10^300: far past any loudness, and 10^(dB/20) overflows from 6165 dB
            raise props.lowerer.fail(f"a gain of {number:g} dB is too large to compute with (at most 6000 dB)",
                                     props.node("gain"), "0 dB keeps the level, -6 dB halves it, +6 dB doubles it")
        return 10.0 ** (number / 20.0)

    def _bodies_and_window(self, decl: Decl) -> tuple:
        """(the body names, their trees, the window's tree or None) of `exclude` or `collide`."""
        from lark import Tree

        children = list(decl.tree.children)
        window = None
        if children and isinstance(children[-1], Tree) and children[-1].data in ("during", "window_from",
                                                                               "window_until"):
            window = children.pop()
        return [self.resolve_body(t, decl) for t in children], children, window

    def _exclusion(self, decl: Decl) -> ir.Exclusion:
        names, _, window = self._bodies_and_window(decl)
        if len(names) < 2:
            raise decl.lowerer.fail("`exclude` names at least two bodies", decl.tree)
        start, end = self.constraints.window(window, decl, "exclusion") if window is not None else (-math.inf, math.inf)
        return ir.Exclusion(tuple(names), str(decl.lowerer.pos(decl.tree)), start, end)

    def _collide(self, decl: Decl, time: ir.Timeline) -> ir.Collide:
        """`collide a, b, ... [window]`: every pair among the bodies collides, even while a constraint joins it.
        Each pair must be able to touch: both bodies collide, one can move."""
        names, children, window = self._bodies_and_window(decl)
        if len(names) < 2:
            raise decl.lowerer.fail("`collide` names at least two bodies", decl.tree,
                                    "write `collide a, b`: the pairs among them collide even while a constraint "
                                    "joins them")
        seen = {}
        for name, tree in zip(names, children):
            if name in seen:
                raise decl.lowerer.fail(f"`{name}` is named twice in `collide`", tree)
            seen[name] = tree
            body = self.bodies[name]
            if not body.collide:
                raise decl.lowerer.fail(f"body `{name}` has `collide off`: it collides with nothing", tree,
                                        f"remove `collide off` from `{name}` (declared at {body.source})")
        for k, a in enumerate(names):
            for b in names[k + 1:]:
                if _never_moves(self.bodies[a]) and _never_moves(self.bodies[b]):
                    raise decl.lowerer.fail(
                        f"`{a}` and `{b}` can never touch: neither of them is dynamic ({self.bodies[a].motion} and "
                        f"{self.bodies[b].motion})", seen[b],
                        "a pair collides only when one of its bodies is dynamic; name only pairs that can move")
        start, end = self.constraints.window(window, decl, "collide window") if window is not None \
            else (-math.inf, math.inf)
        if window is not None and (start >= time.end or end <= time.start):
            raise decl.lowerer.fail(
                f"the window {start:g} s .. {end:g} s is outside the scene's time ({time.start:g} s .. "
                f"{time.end:g} s)", window, f"write a window within `time {time.start:g} s .. {time.end:g} s`, "
                                            "or none (the whole run)")
        return ir.Collide(tuple(names), str(decl.lowerer.pos(decl.tree)), start, end)

    # -- names --------------------------------------------------------------------------------------------

    def resolve_body(self, tree, decl: Decl, allow_world: bool = False) -> str | None:
        """A body named in a declaration: bound part parameter, then the instance's own, then outward."""
        from lark import Tree

        if not (isinstance(tree, Tree) and tree.data == "name_ref"):
            raise decl.lowerer.fail("expected a body name", tree)
        return self.resolve_body_name(ref_name(tree, decl.scope, decl.lowerer), tree, decl.scope, decl.lowerer,
                                      allow_world)

    def resolve_body_name(self, name: str, node, scope: Scope, lowerer: ExprLowerer, allow_world=False):
        if allow_world and name == "world":
            return None
        bound = scope.lookup("values", name)
        candidates = bound.candidates() if isinstance(bound, BodyRef) else [p + name for p in scope.prefixes()]
        for candidate in candidates:
            if candidate in self.bodies:
                return candidate
        if any(candidate in self.broken for candidate in candidates):
            raise SceneError(self.reporter.diagnostics)  # already reported where it was declared
        raise lowerer.fail(f"unknown body `{name}`", node,
                           did_you_mean(name, self.bodies) or "declare it with `body NAME SHAPE { ... }`")


def _never_moves(body: ir.Body) -> bool:
    """Static or kinematic for the whole run (a body with `kinematic A .. B` is dynamic before and after)."""
    return body.motion != "dynamic"


def _as_expr(value) -> E.Expr:
    return value if isinstance(value, E.Expr) else E.Const(value)


def _plain(node: E.Expr):
    return node.value if isinstance(node, E.Const) else node


def _components(node: E.Expr):
    if isinstance(node, E.Const):
        return [E.Const(v) for v in node.value]
    if isinstance(node, E.Vec):
        return list(node.items)
    return [E.Call("dot", (node, E.Const(axis))) for axis in ((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0))]


def _constant_or_path(node):
    """A vector property lowered with time allowed: its tuple when it is constant, else its expression of t."""
    if node is None or not isinstance(node, E.Const):
        return node
    return tuple(float(v) for v in node.value)


def _never_zero(node: E.Expr, props: Props, name: str) -> E.Expr:
    """A direction that follows t is made a unit vector at each instant; it must not pass through zero (checked
    over the first minute)."""
    for t, length in lengths_over_first_minute(node):
        if not length > 1e-12 or not math.isfinite(length):
            raise props.lowerer.fail(f"`{name}` must not be the zero vector (it is {length:.3g} long at t = {t:g} s)",
                                     props.node(name), "a direction of time, e.g. `(cos(t), 0, sin(t))`")
    return node


def _unit(vector, props: Props, name: str) -> tuple:
    norm = float(np.linalg.norm(vector))
    if norm == 0:
        raise props.lowerer.fail(f"`{name}` must not be the zero vector", props.node(name))
    return tuple(float(v) / norm for v in vector)
