"""Wind stage: air velocity fields and the aerodynamic drag they put on bodies (docs/design/physics.md section 7).

    fields.py      u(x, t): uniform and source winds, falloff, cone, their sum
    speed.py       a wind's speed expression s(t), compiled once into closures (no tree walk per call)
    turbulence.py  seeded fractal noise: gusts in time and space, the noise() and gust() signals
    drag.py        F = 1/2 rho Cd A |u - v| (u - v) at the centre of pressure, A from shape and orientation
    ../signals.py  envelope(...) of a recording and mic(): intensities from sound

Built by `compile_wind(scene, plan)` only when a dynamic body feels the air (`wind on`, or `drag` or `area`
given), with no winds too (still air: u = 0, the drag stays); the force
stage calls `WindPlan.apply` at every force evaluation. Two models of the same drag:
  force       (dynamics plan) the drag is one more force, integrated by RK4 with the rest;
  procedural  (procedural plan) drag linearized and solved exactly over the step: the forces on a body in the
              wind are scaled by phi(kappa h) = (1 - exp(-kappa h)) / (kappa h) (drag.relaxation_factors), so a
              light body in a strong wind never overshoots, at any step, and balances where the force model does.

For the audio graph: `wind_speed_at(plan.forces.wind, points, t)`, `WindPlan.air_velocity(points, t)`, and
`WindPlan.relative_speed` (n,), what each body felt at the last force evaluation.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos

from .. import signals as S
from . import turbulence
from .drag import DragBodies, drag_constants, relaxation_factors, shape_aero, stack_bodies
from .drag import drag as drag_on  # (the name `drag` stays the module's)
from .fields import WindFields, compile_fields, wind_seed

MODELS = ("force", "procedural")


class WindPlan:
    """What the wind stage decided (fields, the bodies that feel them, the model), plus the last relative
    speeds it saw (for the audio graph). `apply` adds drag into the force stage's arrays."""

    def __init__(self, fields: WindFields, bodies: DragBodies, air_density: float, model: str, step: float, n: int):
        if model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {model!r}")
        self.fields = fields
        self.bodies = bodies
        self.air_density = air_density
        self.constants = drag_constants(bodies, air_density)
        # where the results go in the force stage's arrays: a slice (in place, no gather) when the bodies are
        # consecutive; the inputs are still gathered by index (contiguous copies: the kernels see what they did)
        i = bodies.body
        consecutive = len(i) > 0 and np.array_equal(i, np.arange(i[0], i[0] + len(i)))
        self.rows = slice(int(i[0]), int(i[0]) + len(i)) if consecutive else i
        self.model = model
        self.step = step  # s: the procedural model's h (set_step keeps it exact)
        # one body in the wind, force model, no torque: its row, and its 1/2 rho Cd A (the float path of apply)
        plain = len(i) == 1 and model == "force" and not (self.constants.shaped or self.constants.turning)
        self.one_plain_body = int(i[0]) if plain else None
        self.one_plain_row = slice(int(i[0]), int(i[0]) + 1) if plain else None
        self.one_force_scale = float(self.constants.force_scale[0]) if plain else 0.0
        self.relative_speed = np.zeros(n)  # (n,) |u - v| at each body, last apply (0 for bodies out of the wind)
        self.last_air_velocity = np.zeros((n, 3))  # (n,3) u at each body, last apply (0 for bodies out of the wind)

    def set_step(self, h: float) -> None:
        """The procedural stepper's h for the coming step (hook; without it the plan's step is used)."""
        self.step = h

    def air_velocity(self, points, t: float, name: str | None = None) -> np.ndarray:
        """(k,3) air velocity u(x, t) at points (k,3): the sum of the winds, or wind `name` alone. This is the
        field that moves the bodies, so a sound that follows it hears what the bodies feel."""
        only = self.fields.names.index(name) if name is not None else None
        return self.fields.velocity(points, t, only)

    def apply(self, x, v, w, R, t, force_out, torque_out) -> None:
        """force_out, torque_out (n,3) += the drag on every body in the wind at time t (force model), or the
        forces on those bodies scaled by the step's relaxation factors (procedural model)."""
        if self.one_plain_body is not None:
            self._apply_to_one_plain_body(x, v, t, force_out)
            return
        b = self.bodies
        i = b.body
        # the body's frame and spin matter only when the wind can turn it, or to the procedural model
        Ri, wi = (R[i], w[i]) if self.constants.turning or self.model == "procedural" else (None, None)
        u = self.fields.velocity(x[i], t)
        result = drag_on(b, self.air_density, u, v[i], wi, Ri, self.constants)
        out = self.rows
        self.last_air_velocity[out] = u
        self.relative_speed[out] = result.speed
        if self.model == "force":
            force_out[out] += result.force
            if self.constants.turning:
                torque_out[out] += result.torque
            return
        w_body = np.einsum("kji,kj->ki", Ri, wi)
        phi, phi_w = relaxation_factors(b, self.air_density, result, w_body, self.step)
        force_out[out] = phi[:, None] * (force_out[out] + result.force)
        torque_out[out] = phi_w[:, None] * (torque_out[out] + result.torque)

    def _apply_to_one_plain_body(self, x, v, t, force_out) -> None:
        """The force model when one body feels the wind and the wind cannot turn it (a sphere, or a body given
        an `area`): drag()'s arithmetic on floats, term for term, so the same force to the bit."""
        j = self.one_plain_body
        u0, u1, u2 = u = self.fields.velocity_at_one_point(x[self.one_plain_row], t)
        v0, v1, v2 = v[j].tolist()
        # u_rel = u - v
        r0, r1, r2 = u0 - v0, u1 - v1, u2 - v2
        # |u_rel| (its terms added in np.einsum's order, as drag() adds them)
        speed = math.sqrt(r0 * r0 + r2 * r2 + r1 * r1)
        # F = 1/2 rho Cd A |u_rel| u_rel, A = area0
        scale = self.one_force_scale * speed
        f0, f1, f2 = force_out[j].tolist()
        force_out[j] = (f0 + scale * r0, f1 + scale * r1, f2 + scale * r2)
        self.last_air_velocity[j] = u
        self.relative_speed[j] = speed

    def describe(self) -> str:
        kinds = ", ".join(f"{name} ({'source' if s else 'uniform'})" for name, s in zip(self.fields.names,
                                                                                       self.fields.is_source))
        return (f"wind: {kinds}; {len(self.bodies.body)} bodies feel it; model {self.model}, "
                f"air {self.air_density:g} kg/m3")


def wind_speed_at(wind: WindPlan | None, points, t: float, velocity=None, name: str | None = None) -> np.ndarray:
    """Wind speed |u(x, t)| (m/s) at points (k,3) or one point (3,) -> (k,) or float; relative to `velocity`
    (k,3) when given (|u - v|, what a moving body hears); only wind `name` when given. 0 without a wind stage."""
    x = np.asarray(points, float)
    single = x.ndim == 1
    x = x.reshape(-1, 3)
    if wind is None:
        speed = np.zeros(len(x))
    else:
        u = wind.air_velocity(x, t, name)
        if velocity is not None:
            u = u - np.asarray(velocity, float).reshape(-1, 3)
        speed = np.linalg.norm(u, axis=1)
    return float(speed[0]) if single else speed


def wind_intensity(wind: WindPlan, name: str, t: float) -> float:
    """The speed expression s(t) of wind `name` (m/s), before falloff and gusts: "is the wind blowing"."""
    return wind.fields.speed_at(wind.fields.names.index(name), t)


# ---- compiling -------------------------------------------------------------------------------------------------

def compile_wind(scene: ir.Scene, plan, folder=None) -> WindPlan | None:
    """The wind stage of this scene, or None when no dynamic body feels the air (a body with `drag`, `area` or
    `wind on` feels it still where no wind blows: drag in still air at the scene's `air` density)."""
    chosen = [i for i, body in enumerate(scene.bodies) if body.wind.enabled and plan.dynamic[i]]
    if not chosen:
        return None
    folders = S.asset_folders(scene, folder if folder is not None else getattr(plan, "folder", None))
    functions = [wind_functions(scene, wind, folders, plan) for wind in scene.winds]
    fields = compile_fields(scene.winds, functions, scene.seed)
    for w, wind in enumerate(scene.winds):
        _try_speed(fields, w, wind, scene.time.start)
    aeros = [shape_aero(scene.bodies[i].shape, scene.bodies[i].mass, scene.bodies[i].inertia, scene.bodies[i].wind.area)
             for i in chosen]
    bodies = stack_bodies(chosen, aeros, [scene.bodies[i].wind.drag for i in chosen], plan.mass, plan.inertia_body)
    densities = sorted({wind.air_density for wind in scene.winds} or {getattr(scene, "air_density", 1.2)})
    if len(densities) > 1:
        plan.warnings.append(f"the winds give different air densities {densities}; drag uses {densities[-1]:g} kg/m3")
    model = "procedural" if plan.solver == "procedural" else "force"
    return WindPlan(fields, bodies, densities[-1], model, plan.step, plan.n)


def wind_functions(scene: ir.Scene, wind: ir.Wind, folders: list, plan) -> dict:
    """Signal functions of one wind: envelopes preloaded (a missing file is a scene error now), mic, noise."""
    envelopes = {}
    uses_mic = False
    for call in _calls(wind.speed):
        if call.fn == "envelope":
            key = _envelope_key(call, wind)
            if key not in envelopes:
                try:
                    envelopes[key] = S.load_envelope(S.resolve_asset(key[0], folders), *key[1:])
                except S.SignalError as error:
                    raise _scene_error(wind, str(error), error.hint) from None
        uses_mic |= call.fn == "mic"
    mic = S.microphone()
    if uses_mic and mic is None:
        plan.warnings.append(f"{wind.source}: wind `{wind.name}` listens to mic(), which stays 0 in this run; "
                             f"run with --mic to blow into the microphone")
    functions = S.signal_functions(envelopes, mic)
    functions.update(turbulence.signal_functions(wind_seed(scene, wind), wind.gust_scale))
    return functions


def _envelope_key(call: E.Call, wind: ir.Wind) -> tuple:
    if len(call.args) != 1 or not isinstance(call.args[0], E.Str):
        raise _scene_error(wind, "envelope(...) takes the sound file's name in quotes",
                           'e.g. envelope("assets/breath.wav", attack = 20 ms, release = 300 ms)')
    allowed = {"attack", "release", "start", "normalize"}
    options = {}
    for name, node in call.kwargs:
        if name not in allowed:
            raise _scene_error(wind, f"envelope(...) has no option `{name}`",
                               "its options: " + ", ".join(sorted(allowed)))
        if not E.is_constant(node):
            raise _scene_error(wind, f"envelope(...): `{name}` must be a constant")
        options[name] = float(E.evaluate(node, {"t": 0.0}))
    return S.envelope_key(call.args[0].value, options.get("attack", S.DEFAULT_ATTACK),
                          options.get("release", S.DEFAULT_RELEASE), options.get("normalize", 1.0))


def _try_speed(fields: WindFields, w: int, wind: ir.Wind, t: float) -> None:
    """Evaluate the speed once now, so that a bad signal call is a scene error with a position."""
    try:
        value = E.evaluate(fields.speed[w], {"t": t}, fields.functions[w])
        if np.ndim(value) != 0 or not np.isfinite(float(value)):
            raise ValueError("the speed must be one finite number")
    except (E.EvaluationError, ValueError, TypeError) as error:
        raise _scene_error(wind, f"wind `{wind.name}`: cannot evaluate its speed: {error}",
                           "signals: envelope(\"file\", attack =, release =, start =), mic(gain =), "
                           "noise(T, seed =), gust(T, depth =, seed =)") from None


def _calls(node: E.Expr):
    if isinstance(node, E.Call):
        yield node
        for arg in node.args:
            yield from _calls(arg)
        for _, arg in node.kwargs:
            yield from _calls(arg)
    elif isinstance(node, E.Op):
        for arg in node.args:
            yield from _calls(arg)
    elif isinstance(node, E.Vec):
        for item in node.items:
            yield from _calls(item)
    elif isinstance(node, E.Deriv):
        yield from _calls(node.arg)


def _scene_error(wind: ir.Wind, message: str, hint: str | None = None) -> SceneError:
    return SceneError([Diagnostic(message, SourcePos.parse(wind.source), hint)])
