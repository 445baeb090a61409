"""The intermediate representation: what a scene says, in SI units, every default explicit.

Frozen dataclasses, so a lowered scene can be shared, hashed and compared. `to_json` gives the canonical form
that `isaac parse` prints and golden tests compare: sorted keys, parts/loops/includes expanded, a schema
version, and every declaration's source position as "file:line:col".

Fields that may change over time (a moving nail, a wind speed, a kinematic path) hold expression trees
(`isaac_ir.expr`); a constant is a `Const` and prints as its plain value.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from typing import Any

from isaac_ir import expr as E
from isaac_ir import expr_forms

SCHEMA = "isaac-ir/1"

Vec3 = tuple  # (x, y, z) floats


@dataclass(frozen=True)
class Timeline:
    start: float
    end: float
    frame_rate: float  # Hz: output samples of the trajectory


@dataclass(frozen=True)
class SolverOptions:
    plan: str  # dynamics | procedural | auto
    integrator: str  # rk4 | euler (semi-implicit) | midpoint
    step: float | None  # s; None: the runtime picks one and reports it
    stabilize_frequency: float | None  # Hz; None: the default (10 Hz; 1 / (20 h) under `stabilization baumgarte`)
    damping_ratio: float  # 1 = critically damped
    linear_solver: str  # auto | dense | sparse | tree
    substeps: int  # procedural plan
    iterations: int  # procedural plan
    compliance: float  # procedural plan, m/N (0 = rigid)
    projection: str = "auto"  # procedural plan: all rows at once (direct), sweeps (gauss_seidel), or auto
    # dynamics plan: held rows projected back after each step (projection), or Baumgarte on every row for the
    # whole run (baumgarte: the dissertation's formulation)
    stabilization: str = "projection"
    # dynamics plan, rk4: the largest local error of a step (its velocities in the kinetic-energy norm, relative to
    # the scene's energy scale) before the step is taken again in substeps; 0: every step as it is
    tolerance: float = 3e-6


@dataclass(frozen=True)
class Camera:
    name: str
    position: Vec3
    look_at: Vec3
    up: Vec3
    fov: float  # rad, vertical
    source: str


@dataclass(frozen=True)
class Light:
    name: str
    type: str  # distant | point | spot | ambient
    position: Vec3  # "from" of a distant light, position of a point light
    target: Vec3
    intensity: float
    color: Vec3
    source: str


@dataclass(frozen=True)
class Material:
    name: str
    density: float | None  # kg/m3
    friction: float
    restitution: float
    young: float | None  # Pa
    poisson: float
    loss: float | None  # internal friction tan(phi), modal decay d = pi f loss
    rayleigh: tuple | None  # (alpha 1/s, beta s)
    roughness: float  # surface texture amplitude, m
    texture: str | None  # a height-profile file, or None for fractal noise
    source: str


@dataclass(frozen=True)
class Shape:
    type: str  # sphere | box | cylinder | capsule | plane | mesh | compound
    radius: float | None = None
    length: float | None = None  # cylinder/capsule length along body z (capsule: of the straight part)
    size: Vec3 | None = None  # box edge lengths
    normal: Vec3 | None = None  # plane
    file: str | None = None  # mesh (OBJ/STL), relative to the scene folder
    scale: float = 1.0
    # where, in the body frame (origin at the centre of mass), the shape's own origin sits: the point `at` places
    # and body points `a @ p` are measured from (a mesh file's origin; the origin a compound's parts are written
    # about); (0, 0, 0) for the primitives, whose origin is their centre
    offset: Vec3 = (0.0, 0.0, 0.0)
    parts: tuple = ()  # a compound's Parts (type "compound")


@dataclass(frozen=True)
class Part:
    """One shape of a compound body (docs/compound.md), posed about the compound's origin (Shape.offset): a
    body-frame point of the part's own frame p is offset + position + R(orientation) p."""

    name: str
    shape: Shape  # a primitive or a mesh (never a plane or a compound); its own offset is (0, 0, 0)
    position: Vec3  # its origin (a primitive's centre, a mesh file's origin) about the compound's origin
    orientation: tuple  # (w, x, y, z)
    mass: float | None  # kg; None only in a static or kinematic body without densities
    material: str | None  # its own, or the body's
    modes: tuple | None  # ((frequency Hz, decay 1/s, gain), ...) for modal sound
    source: str


@dataclass(frozen=True)
class WindResponse:
    enabled: bool
    drag: float  # drag coefficient Cd
    area: float | None  # m2 facing the wind; None: from the shape and orientation


@dataclass(frozen=True)
class Body:
    name: str
    shape: Shape
    motion: str  # dynamic | static | kinematic
    mass: float | None  # kg; None for a static or kinematic body without one
    inertia: tuple | None  # 3x3 body-frame inertia about the centre of mass, kg m2
    position: E.Expr  # (3,) world centre of mass; a function of t for a kinematic body
    orientation: E.Expr  # (4,) quaternion (w, x, y, z); a function of t for a kinematic body
    velocity: Vec3
    angular_velocity: Vec3  # world frame, rad/s
    material: str | None
    collide: bool
    wind: WindResponse
    modes: tuple | None  # ((frequency Hz, decay 1/s, gain), ...) for modal sound
    source: str
    path_window: tuple | None = None  # (start, end) s: a dynamic body on its path (kinematic) in this window


@dataclass(frozen=True)
class ConstraintTerm:
    """One instance of a library family; `rows` are the element rows kept after subtraction."""

    family: str  # point | nail | orient | plane | gear | rope | element
    bodies: tuple  # body names (a world slot is omitted)
    params: tuple  # ((name, value), ...) sorted; values are floats, vectors or expressions
    rows: tuple  # row tags kept, e.g. ("tx", "ty", "tz")

    def param(self, name: str, default: Any = None) -> Any:
        for key, value in self.params:
            if key == name:
                return value
        return default


@dataclass(frozen=True)
class Constraint:
    name: str
    terms: tuple  # ConstraintTerm, ...
    start: float
    end: float  # math.inf: until the end
    stabilize_frequency: float | None  # None: the scene's
    damping_ratio: float | None
    compliance: float | None
    source: str


@dataclass(frozen=True)
class Force:
    name: str
    type: str  # spring | damper | load
    bodies: tuple
    points: tuple  # body-frame points, one per body
    stiffness: float
    rest_length: float | None
    damping: float
    force: E.Expr  # load: world force (3,), N
    torque: E.Expr  # load: world torque (3,), N m
    source: str


@dataclass(frozen=True)
class Wind:
    name: str
    type: str  # uniform | source
    origin: Vec3 | E.Expr | None  # source point; an expression of t when the source moves
    direction: Vec3 | E.Expr  # unit, toward where the air goes; an expression of t (made unit at each instant)
    speed: E.Expr  # m/s, may use t, envelope("file"), mic()
    falloff: str  # none | inverse | inverse_square
    reference_distance: float  # m: the distance at which speed is as given
    spread: float  # rad, half-angle of the cone a source blows into
    turbulence: float  # relative gust amplitude (0 = steady)
    gust_scale: float  # s, time scale of the gusts
    air_density: float  # kg/m3
    source: str


@dataclass(frozen=True)
class Sound:
    name: str
    trigger: str  # collide | contact | wind | time | always
    bodies: tuple  # bodies of a collide/contact trigger (empty: any)
    wind: str | None
    time: float | None
    graph: E.Expr  # audio-graph expression (timbre tree)
    gain: float
    source: str
    # where its trigger (`collide(a, b)`, ...) is written, for a warning about it; not part of the canonical IR
    trigger_source: str = field(default="", compare=False, repr=False, metadata={"ir": False})


@dataclass(frozen=True)
class Exclusion:
    bodies: tuple
    source: str
    start: float = -math.inf  # s: the window in which the pairs do not collide (the whole run by default)
    end: float = math.inf


@dataclass(frozen=True)
class Collide:
    """`collide a, b, ...`: every pair among the bodies collides, even while a constraint joins it."""

    bodies: tuple
    source: str
    start: float = -math.inf  # s: the window in which the pairs collide (the whole run by default)
    end: float = math.inf


@dataclass(frozen=True)
class Vary:
    """`vary NAME in LOW .. HIGH`: the `let` NAME is free between LOW and HIGH for `isaac fit` (docs/goals.md)."""

    name: str
    low: float  # SI
    high: float  # SI
    start: float  # SI: the let's own value (after --set), where a fit starts
    dimension: tuple  # (m, kg, s, rad) exponents of the let's value
    unit: str  # the unit the bounds were written in ("deg", "m/s"; "" for a plain number), to print values in
    source: str


@dataclass(frozen=True)
class Goal:
    """`goal NAME: BODY.QUANTITY at TIME = VALUE within TOLERANCE` (kind "state") or `goal NAME: first
    EVENT(A, B) at TIME within TOLERANCE` (kind "event"); values SI (docs/goals.md)."""

    name: str
    kind: str  # state | event
    bodies: tuple  # (body,) for a state goal; (a, b) for an event goal
    quantity: str  # position | velocity | angle; an event goal: collide | contact
    component: str | None  # x | y | z, or None for the whole quantity
    time: float  # s: when the state must hold, or when the first event must come
    target: Any  # float, or a 3-tuple for a whole position or velocity; None for an event goal (its time)
    tolerance: float  # in the quantity's unit (s for an event goal)
    source: str


@dataclass(frozen=True)
class Listener:
    position: Vec3
    gain: float
    delay: bool  # delay sounds by distance / speed of sound


@dataclass(frozen=True)
class Audio:
    rate: float  # samples per second
    channels: int


@dataclass(frozen=True)
class Scene:
    name: str
    file: str
    time: Timeline
    gravity: Vec3
    seed: int
    solver: SolverOptions
    cameras: tuple
    lights: tuple
    materials: tuple
    bodies: tuple
    constraints: tuple
    forces: tuple
    winds: tuple
    sounds: tuple
    exclusions: tuple
    listener: Listener
    audio: Audio
    parameters: tuple  # ((name, value), ...) the scene's `let`s after --set overrides
    air_density: float = 1.2  # kg/m3: the drag of bodies that feel air, in still air and in the winds
    # `collide` statements (Collide, ...); in the canonical JSON only when there are some, so that the IR of a
    # scene without one is what it was before the statement existed
    collides: tuple = field(default=(), metadata={"omit_empty": True})
    # `vary` and `goal` statements (Vary, ..., Goal, ...; docs/goals.md); omitted when empty, likewise
    varies: tuple = field(default=(), metadata={"omit_empty": True})
    goals: tuple = field(default=(), metadata={"omit_empty": True})
    schema: str = SCHEMA
    # where each scene-wide setting was written: (("time", "file:line:col"), ("solver.step", ...), ...), so that
    # the plan can point at the setting a budget is about; not part of the canonical IR (no JSON, no comparison)
    origins: tuple = field(default=(), compare=False, repr=False, metadata={"ir": False})

    def body(self, name: str) -> Body:
        for body in self.bodies:
            if body.name == name:
                return body
        raise KeyError(name)

    def body_index(self) -> dict:
        return {body.name: i for i, body in enumerate(self.bodies)}

    def origin(self, setting: str) -> str | None:
        """Where a scene-wide setting (`time`, `frames`, `solver.step`, `audio.rate`, ...) was written, if it was."""
        return dict(self.origins).get(setting)


# ---- canonical JSON --------------------------------------------------------------------------------------

def to_data(value):
    """Plain JSON-able data of an IR value (dataclasses become dicts, expressions their JSON form)."""
    if isinstance(value, E.Expr):
        return expr_forms.to_json(value)
    if dataclasses.is_dataclass(value):
        return {f.name: to_data(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.metadata.get("ir", True) and not (f.metadata.get("omit_empty") and not getattr(value, f.name))}
    if isinstance(value, tuple) and value and all(isinstance(v, tuple) and len(v) == 2 and isinstance(v[0], str)
                                                  for v in value) and _is_pairs(value):
        return {k: to_data(v) for k, v in value}
    if isinstance(value, (tuple, list)):
        return [to_data(v) for v in value]
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return value


def _is_pairs(value) -> bool:
    # a tuple of (name, value) pairs is a mapping (params, parameters); a tuple of 2-vectors of strings is not
    return len({k for k, _ in value}) == len(value)


def to_json(scene: Scene, indent: int | None = 1) -> str:
    return json.dumps(to_data(scene), sort_keys=True, indent=indent, allow_nan=False)
