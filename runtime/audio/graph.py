"""Audio stage, compile: a sound's `play` expression (IR) -> a tree of nodes, and what it needs recorded.

The expression tree of the IR is walked once. Audio calls become nodes (nodes.py, impact.py, scrape.py,
wind_sound.py); parts without audio calls become `Control` nodes (functions of t and of motion signals,
evaluated per block); motion signals are variables (impulse, speed, normal_force, wind_speed, distance, t).

Event factors move onto the exciters. In `modal(bar) * impulse` the factor `impulse` is a value of each
hit: multiplying the bank's output by the latest hit's impulse would make the ringing of earlier hits jump
in level at every new hit. So a product (or quotient) of an exciter (modal, impact, pulse) by an expression
of event signals only becomes the exciter's per-hit strength, through every node that is linear in its
input (+, -, mix, gain, filters, decay, adsr, delay, pan). Where a factor cannot move further (a sine times
the impulse) it is held: the value of the latest hit, from its sample on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isaac_ir import expr as E
from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos, did_you_mean

from ..core.rotation import quat_to_matrix
from . import modal as M
from .excitation import body_contact_properties
from .impact import BodyBank, Impact, Modal, Pulse, ringing_of
from .nodes import (ADSR, Binary, Constant, Control, DelayLine, Decay, Filter, Follower, Function, Gain, Held,
                    FileEnvelope, Mix, Negate, Node, Noise, Pan, Sine)
from .noise import COLORS, seed_for
from .scrape import (DEFAULT_MAX_SPEED, ROLL_BETA, SCRAPE_BETA, TEXTURE_STEP, Scrape, SurfaceProfile)
from .wind_sound import STROUHAL, WHISTLE_Q, Whistle, WindNoise, cross_dimension, merge_whistles

EVENT_SIGNALS = {"impulse", "speed", "normal_force", "distance", "wind_speed"}
EXCITERS = {"modal", "impact", "pulse"}
# nodes linear in their first argument (all arguments for mix): an event factor passes through them
LINEAR = {"mix", "gain", "lowpass", "highpass", "bandpass", "decay", "adsr", "delay", "pan"}
HIT_TRIGGERS = ("collide", "contact", "time")
DEFAULT_DELAY_LIMIT = 2.0  # s, longest delay of a varying delay(...)
FREQUENCY_NAMES = ("freq", "frequency", "cutoff", "centre", "center")  # a filter's frequency by name


@dataclass
class Needs:
    """What the recorder must keep for the sounds (record.py)."""

    bodies: set = field(default_factory=set)  # positions
    pairs: set = field(default_factory=set)  # contact signals
    wind_bodies: set = field(default_factory=set)  # relative wind speed
    listener_winds: set = field(default_factory=set)  # wind speed at the listener


@dataclass
class SoundPlan:
    """One sound, compiled: `root` is a template (the renderer copies it, so a plan renders many times)."""

    sound: object  # ir.Sound
    root: Node
    hit_bodies: tuple | None  # the hits it hears: events between exactly these bodies; () none; None all
    anchor: str | None  # the body it sounds from (None: its latest hit's point, or the listener)
    winds: tuple  # winds whose speed at the listener `wind_speed` / wind_noise() read
    modes: dict  # body -> Modes of its banks (for the plan and the report)


class SoundCompiler:
    """Compiles one sound. Errors are SceneErrors at the sound's position."""

    def __init__(self, scene, sound, fs: float, needs: Needs, warnings: list, folder=None):
        self.folder = folder  # the scene's folder, where textures and recordings are found
        self.scene, self.sound, self.fs = scene, sound, fs
        self.needs, self.warnings = needs, warnings
        self.bodies = {b.name: b for b in scene.bodies}
        self.materials = {m.name: m for m in scene.materials}
        self.counter = 0
        self.modes: dict = {}
        self.hits = sound.trigger in HIT_TRIGGERS

    # -- driver -------------------------------------------------------------------------------------------

    def compile(self) -> SoundPlan:
        sound = self.sound
        root = self.node(sound.graph, None)
        if sound.gain != 1.0:
            root = Binary("mul", root, Constant(sound.gain))
        anchor = sound.bodies[0] if sound.bodies else self._first_named_body(sound.graph)
        if anchor is not None:
            self.needs.bodies.add(anchor)
        if sound.trigger == "contact":
            self.needs.pairs.add(tuple(sound.bodies))
        winds = (sound.wind,) if sound.wind else tuple(w.name for w in self.scene.winds)
        if "wind_speed" in E.free_vars(sound.graph):
            if anchor is not None and sound.trigger != "wind":
                self.needs.wind_bodies.add(anchor)
            else:
                self.needs.listener_winds.update(winds)
        # the hits it hears: events between exactly its bodies (None: any event; (): none but its own time)
        hit_bodies = (tuple(sound.bodies) or None) if sound.trigger in ("collide", "contact") else ()
        silent = [n for n in root.walk() if isinstance(n, (Modal, Impact, Pulse)) and getattr(n, "drive", None) is None]
        if not self.hits and silent:
            self.warnings.append(f"{sound.source}: sound `{sound.name}` ({sound.trigger}) has no hits: its modal, "
                                 f"impact and pulse nodes stay silent unless driven, e.g. modal(bar, noise())")
        return SoundPlan(sound, root, hit_bodies, anchor, winds, self.modes)

    def fail(self, message: str, hint: str | None = None) -> SceneError:
        return SceneError([Diagnostic(f"sound `{self.sound.name}`: {message}", _position(self.sound.source), hint)])

    # -- expressions --------------------------------------------------------------------------------------

    def node(self, e: E.Expr, strength) -> Node:
        """The node of e, its hits scaled by `strength` (an expression of event signals, or None for 1)."""
        if isinstance(e, E.Str):
            raise self.fail(f"`{e.value}` is a name, not a sound", "a body or material name is an argument of "
                            "an audio node, e.g. modal(bar)")
        if not _has_audio(e):
            if isinstance(e, E.Const) and isinstance(e.value, tuple):
                raise self.fail("a vector is not a sound", "audio values are single numbers")
            return self._scaled(Constant(e.value) if isinstance(e, E.Const) else Control(e), strength)
        if isinstance(e, E.Op):
            return self._op(e, strength)
        if isinstance(e, E.Call) and e.fn in E.SCALAR_FUNCTIONS:
            return self._scaled(Function(e.fn, [self.node(a, None) for a in e.args]), strength)
        if isinstance(e, E.Call):
            return self._call(e, strength)
        raise self.fail(f"cannot play {type(e).__name__}")

    def _scaled(self, node: Node, strength) -> Node:
        return node if strength is None else Binary("mul", node, Held(strength))

    def _op(self, e: E.Op, strength) -> Node:
        if e.op == "neg":
            return Negate(self.node(e.args[0], strength))
        a, b = e.args
        if e.op in ("add", "sub"):
            return Binary(e.op, self.node(a, strength), self.node(b, strength))
        if e.op == "mul" and (_excites(a) != _excites(b)):
            source, factor = (a, b) if _excites(a) else (b, a)
            if self.hits and _event_rate(factor):
                return self.node(source, _times(strength, factor))
            return Binary("mul", self.node(source, strength), self.node(factor, None))
        if e.op == "div" and _excites(a) and not _excites(b):
            if self.hits and _event_rate(b):
                return self.node(a, _times(strength, E.Op("div", (E.Const(1.0), b))))
            return Binary("div", self.node(a, strength), self.node(b, None))
        return self._scaled(Binary(e.op, self.node(a, None), self.node(b, None)), strength)

    def _call(self, e: E.Call, strength) -> Node:
        build = getattr(self, "_fn_" + e.fn, None)
        if build is None:
            raise self.fail(f"`{e.fn}(...)` is not an audio node here",
                            "audio nodes: " + ", ".join(sorted(n[4:] for n in dir(self) if n.startswith("_fn_"))))
        self.counter += 1
        args = Args(self, e)
        if e.fn in EXCITERS:
            return build(args, strength)
        if e.fn in LINEAR:
            return build(args, strength)
        return self._scaled(build(args, None), strength)

    # -- exciters -----------------------------------------------------------------------------------------

    def _fn_modal(self, args, strength):
        names = args.bodies(0, lambda: self._hit_body_names(modal=True))
        options = args.mode_options()
        banks = [b for name in names for b in self._banks(name, options, required=bool(args.positional))]
        if not banks:
            raise self.fail("modal(): none of the bodies has modes", "give a body `modes ((f, decay, gain), ...)` "
                            "or a material with `young` and `density`")
        drive = self.node(args.positional[1], None) if len(args.positional) > 1 else None
        return Modal(banks, strength, self.fs, drive, args.number("tau", None))

    def _fn_impact(self, args, strength):
        names = args.bodies(0, lambda: self._hit_body_names(modal=False), many=True)
        options = args.mode_options()
        banks = [b for name in names for b in self._banks(name, options, required=False)]
        ringing = {(name, None): 0.0 for name in names}
        for b in banks:  # the ringing of each body with modes, or of each part of a compound body
            ringing[(b.body, b.part)] = ringing_of(self._material(b.body, b.part))
        seed = (self.scene.seed, self.sound.name, self.counter)
        return Impact(banks, ringing, strength, seed, self.fs, args.number("tau", None))

    def _fn_pulse(self, args, strength):
        duration = args.number(0, None) if args.positional else args.number("duration", None)
        return Pulse(strength, duration)

    def _banks(self, name: str, options: dict, required: bool) -> list:
        """The banks of a body: its own modes; a compound body without a `modes` table of its own rings part
        by part, each part with the modes of its shape and material (those that have some)."""
        body = self.bodies[name]
        if body.shape.type != "compound" or body.modes:
            bank = self._bank(name, body, self._material(name), options, required)
            return [bank] if bank is not None else []
        banks = []
        for part in body.shape.parts:
            stand_in = _PartBody(f"{name}.{part.name}", part.shape, part.modes, part.mass, body.motion)
            pose = (np.asarray(body.shape.offset, float) + np.asarray(part.position, float),
                    quat_to_matrix(np.asarray(part.orientation, float)))
            bank = self._bank(stand_in.name, stand_in, self._material(name, part.name), options, False)
            if bank is not None:
                banks.append(BodyBank(name, bank.modes, part.name, pose))
        if not banks and required:
            raise self.fail(f"body `{name}`: none of its parts has modes", "give a part `modes ((f, decay, gain), "
                            "...)` or a material with `young` and `density`")
        return banks

    def _bank(self, name: str, body, material, options: dict, required: bool) -> BodyBank | None:
        try:
            modes = M.body_modes(body, material, **options["model"]).audible(self.fs, options["count"])
        except M.ModalError as error:
            if required:
                raise self.fail(str(error)) from None
            return None
        if len(modes) == 0:
            if required:
                self.warnings.append(f"{self.sound.source}: body `{name}`: every mode is above "
                                     f"{M.NYQUIST_MARGIN:g} x Nyquist at {self.fs:g} Hz: it is silent")
            return None
        self.modes[name] = modes
        return BodyBank(name, modes)

    def _material(self, body_name: str, part: str | None = None):
        body = self.bodies[body_name]
        name = body.material
        if part is not None:
            name = next((p.material for p in body.shape.parts if p.name == part), name)
        return self.materials.get(name) if name else None

    def _hit_body_names(self, modal: bool) -> list:
        """The bodies a modal() or impact() without names rings: the two of its trigger, or (a trigger naming
        one body or none) every body that can take part in a collision."""
        if len(self.sound.bodies) == 2:
            return list(self.sound.bodies)
        if self.sound.trigger not in ("collide", "contact"):
            raise self.fail(f"{'modal' if modal else 'impact'}() needs a body here",
                            "name it, e.g. modal(bell); without a name it rings the bodies of each collision")
        return [b.name for b in self.scene.bodies if b.collide]

    # -- sources ------------------------------------------------------------------------------------------

    def _fn_sine(self, args, strength):
        return Sine(args.node(0), args.number("phase", 0.0))

    def _fn_noise(self, args, strength):
        color = args.positional[0] if args.positional else E.Str("white")
        if isinstance(color, E.Str):
            if color.value not in COLORS:
                raise self.fail(f"unknown noise colour `{color.value}`", did_you_mean(color.value, COLORS))
            beta = COLORS[color.value]
        else:
            beta = args.number(0)
        if beta not in (0.0, 1.0, 2.0):
            raise self.fail("noise(beta): beta is 0 (white), 1 (pink) or 2 (brown)")
        return Noise(beta, self.fs, self._seed())

    def _fn_scrape(self, args, strength, rolling: bool = False):
        pair = tuple(args.bodies(0, list(self.sound.bodies), many=True))
        if len(pair) < 2 and len(self.sound.bodies) == 2 and set(pair) <= set(self.sound.bodies):
            pair = tuple(self.sound.bodies)  # scrape(bar) in a contact(bar, floor) sound
        if len(pair) != 2:
            raise self.fail(f"{'roll' if rolling else 'scrape'}() needs the two bodies in contact",
                            "name them, scrape(block, slope), or use it in a `contact(a, b)` sound")
        self.needs.pairs.add(pair)
        max_speed = args.number("max_speed", DEFAULT_MAX_SPEED)
        dx = max_speed / self.fs
        texture = args.text("texture", None) or next(
            (m.texture for m in (self._material(n) for n in pair) if m is not None and m.texture), None)
        if texture is not None:
            path = _asset(self.scene, texture, self.folder)
            try:
                profile = SurfaceProfile.from_file(path, dx, args.number("step", TEXTURE_STEP))
            except (OSError, ValueError) as error:
                raise self.fail(f"cannot read texture `{texture}`: {error}") from None
        else:
            beta = args.number("beta", ROLL_BETA if rolling else SCRAPE_BETA)
            profile = SurfaceProfile.fractal(beta, dx, self._seed())
        roughness = max((m.roughness for m in (self._material(n) for n in pair) if m is not None), default=1e-5)
        options = args.mode_options()
        banks = [b for n in pair for b in self._banks(n, options, required=False)]
        return Scrape(pair, banks, profile, max_speed, rolling, roughness, self.fs)

    def _fn_roll(self, args, strength):
        return self._fn_scrape(args, strength, rolling=True)

    def _fn_wind_noise(self, args, strength):
        body = args.bodies(0, [None])[0]
        names = (self.sound.wind,) if self.sound.wind else tuple(w.name for w in self.scene.winds)
        winds = [w for w in self.scene.winds if w.name in names]
        if body is not None:
            self.needs.wind_bodies.add(body)
        else:
            self.needs.listener_winds.update(names)
        # gusts: the wind's own turbulence when it has some, else a gentle default
        gusty = any(w.turbulence > 0 for w in winds)
        scale = min((w.gust_scale for w in winds), default=0.5)
        return WindNoise(body, args.number("gust", 0.0 if gusty else 0.3), args.number("scale", scale), self.fs,
                         self._seed())

    def _fn_whistle(self, args, strength):
        (body,) = args.bodies(0, [], count=1)
        self.needs.wind_bodies.add(body)
        diameter = args.number("diameter", None) or cross_dimension(self.bodies[body].shape)
        if not diameter:
            raise self.fail(f"whistle({body}): its shape has no cross dimension", "give `diameter = 5 mm`")
        return Whistle(body, diameter, args.number("st", STROUHAL), args.number("q", WHISTLE_Q), self.fs,
                       self._seed())

    # -- filters, envelopes, mixing -----------------------------------------------------------------------

    def _filter(self, kind, args, strength, q_default):
        """x, the frequency (2nd argument, or freq = / cutoff = / centre =), Q (3rd argument, or q =)."""
        freq = 1 if len(args.positional) > 1 else next((k for k in FREQUENCY_NAMES if k in args.kwargs), "freq")
        q = 2 if len(args.positional) > 2 else "q"
        return Filter(kind, args.node(0, strength), args.node(freq), args.node(q, default=q_default))

    def _fn_lowpass(self, args, strength):
        return self._filter("lowpass", args, strength, 0.7071)

    def _fn_highpass(self, args, strength):
        return self._filter("highpass", args, strength, 0.7071)

    def _fn_bandpass(self, args, strength):
        return self._filter("bandpass", args, strength, 1.0)

    def _fn_decay(self, args, strength):
        """decay(x, t60), or decay(t60) alone: the envelope itself (x = 1)."""
        first = args.positional[0] if args.positional else None
        if len(args.positional) == 1 and isinstance(first, E.Const):
            return Decay(self._scaled(Constant(1.0), strength), args.node(0))
        return Decay(args.node(0, strength), args.node(1 if len(args.positional) > 1 else "t60", default=1.0))

    def _fn_adsr(self, args, strength):
        values = [args.number(i if i < len(args.positional) else name, default)
                  for i, (name, default) in enumerate((("attack", 0.005), ("decay", 0.1), ("sustain", 0.7),
                                                       ("release", 0.3)), start=1)]
        return ADSR(args.node(0, strength), *values)

    def _fn_envelope(self, args, strength):
        attack, release = args.number("attack", 0.02), args.number("release", 0.25)
        first = args.positional[0] if args.positional else None
        if isinstance(first, E.Str):
            from .. import signals

            try:
                path = signals.resolve_asset(first.value, signals.asset_folders(self.scene, self.folder))
                return FileEnvelope(signals.load_envelope(path, attack, release))
            except signals.SignalError as error:
                raise self.fail(str(error), error.hint) from None
        return Follower(args.node(0), attack, release)

    def _fn_delay(self, args, strength):
        time = args.positional[1] if len(args.positional) > 1 else E.Const(0.0)
        longest = time.value if isinstance(time, E.Const) else args.number("max", DEFAULT_DELAY_LIMIT)
        self._check_delay(float(longest))
        return DelayLine(args.node(0, strength), args.node(1), float(longest), self.fs)

    def _check_delay(self, longest: float) -> None:
        """A delay line holds `longest` seconds of samples: no longer than the scene (what comes out after it is
        never heard), so that a delay of 1e9 s is refused here instead of asking for 321 TiB."""
        span = self.scene.time.end - self.scene.time.start
        if not 0.0 <= longest <= span + 1.0:
            raise self.fail(f"a delay of {longest:g} s: a delay is between 0 s and the scene's length "
                            f"({span:g} s)", "a delay longer than the scene is never heard")

    def _fn_pan(self, args, strength):
        return Pan(args.node(0, strength), args.node(1 if len(args.positional) > 1 else "position", default=0.0))

    def _fn_mix(self, args, strength):
        return Mix(merge_whistles([self.node(a, strength) for a in args.positional]))

    def _fn_gain(self, args, strength):
        if "db" in args.kwargs:
            return Gain(args.node(0, strength), args.node("db"), decibels=True)
        return Gain(args.node(0, strength), args.node(1, default=1.0))

    # -- helpers ------------------------------------------------------------------------------------------

    def _seed(self) -> int:
        return seed_for(self.scene.seed, self.sound.name, self.counter)

    def _first_named_body(self, e: E.Expr) -> str | None:
        if isinstance(e, E.Str) and e.value in self.bodies:
            return e.value
        for child in E._children(e):
            found = self._first_named_body(child)
            if found is not None:
                return found
        return None


class Args:
    """The arguments of one audio call, read by position or keyword, with helpful errors."""

    def __init__(self, compiler: SoundCompiler, call: E.Call):
        self.c, self.call = compiler, call
        self.positional = list(call.args)
        self.kwargs = dict(call.kwargs)

    def _get(self, key):
        if isinstance(key, int):
            return self.positional[key] if key < len(self.positional) else None
        return self.kwargs.get(key)

    def node(self, key, strength=None, default=None) -> Node:
        e = self._get(key)
        if e is None:
            if default is None:
                raise self.c.fail(f"`{self.call.fn}(...)` is missing its argument {_describe(key)}")
            return Constant(default)
        return self.c.node(e, strength)

    def number(self, key, default=math.nan):
        e = self._get(key)
        if e is None:
            if isinstance(default, float) and math.isnan(default):
                raise self.c.fail(f"`{self.call.fn}(...)` is missing its argument {_describe(key)}")
            return default
        if not isinstance(e, E.Const) or isinstance(e.value, tuple):
            raise self.c.fail(f"`{self.call.fn}(...)`: {_describe(key)} must be a constant number")
        return float(e.value)

    def text(self, key, default=None):
        e = self._get(key)
        if e is None:
            return default
        if not isinstance(e, E.Str):
            raise self.c.fail(f"`{self.call.fn}(...)`: {_describe(key)} must be a name or a quoted file name")
        return e.value

    def bodies(self, start: int, default, many: bool = False, count: int | None = None) -> list:
        """Body names among the positional arguments from `start` (else the default: a list, or a function
        giving one)."""
        names = []
        for e in self.positional[start:]:
            if not isinstance(e, E.Str):
                break
            if e.value not in self.c.bodies:
                hint = ("that is a material; an audio node takes a body" if e.value in self.c.materials
                        else did_you_mean(e.value, self.c.bodies))
                raise self.c.fail(f"unknown body `{e.value}` in {self.call.fn}(...)", hint)
            names.append(e.value)
            if not many:
                break
        names = names or list(default() if callable(default) else default)
        if count is not None and len(names) != count:
            raise self.c.fail(f"`{self.call.fn}(...)` takes {count} body name(s)")
        return names

    def mode_options(self) -> dict:
        damping = {}
        for key in ("rt60", "loss"):
            if key in self.kwargs:
                damping[key] = self.number(key)
        if "rayleigh" in self.kwargs:
            value = self.kwargs["rayleigh"]
            if not (isinstance(value, E.Const) and isinstance(value.value, tuple) and len(value.value) == 2):
                raise self.c.fail("rayleigh = (alpha, beta)")
            damping["rayleigh"] = value.value
        model = self.text("model", "auto")
        if model not in ("auto", "table", "bar", "plate", "sphere"):
            raise self.c.fail(f"unknown modal model `{model}`", "auto, table, bar, plate or sphere")
        count = int(self.number("count", M.DEFAULT_COUNT))
        return {"model": {"model": model, "count": max(count * 2, count), "inner": self.number("inner", None),
                          "damping": damping}, "count": count}


def _describe(key) -> str:
    return f"#{key + 1}" if isinstance(key, int) else f"`{key}`"


def _has_audio(e: E.Expr) -> bool:
    if isinstance(e, E.Call) and e.fn not in E.SCALAR_FUNCTIONS and e.fn not in E.VECTOR_FUNCTIONS:
        return True
    return any(_has_audio(c) for c in E._children(e))


def _excites(e: E.Expr) -> bool:
    if isinstance(e, E.Call) and e.fn in EXCITERS:
        return True
    if isinstance(e, E.Call) and e.fn not in LINEAR:
        return False  # an exciter inside a non-linear node cannot take a per-hit factor
    return any(_excites(c) for c in E._children(e))


def _event_rate(e: E.Expr) -> bool:
    """An expression of event signals only (and constants): one value per hit."""
    names = E.free_vars(e)
    return bool(names) and names <= EVENT_SIGNALS and not _has_audio(e)


def _times(strength, factor: E.Expr) -> E.Expr:
    return factor if strength is None else E.Op("mul", (strength, factor))


def _position(source: str) -> SourcePos | None:
    try:
        file, line, col = source.rsplit(":", 2)
        return SourcePos(file, int(line), int(col))
    except (ValueError, AttributeError):
        return None


def _asset(scene, name: str, folder=None) -> str:
    from pathlib import Path

    path = Path(name)
    if path.is_absolute():
        return str(path)
    from ..signals import asset_folders

    for place in asset_folders(scene, folder):
        if (place / path).is_file():
            return str(place / path)
    return name


def contact_properties(scene) -> dict:
    """body -> what excitation.contact_duration needs; and (body, part) -> the same of each part of a compound
    body (its curvature and material; the whole body's mass)."""
    materials = {m.name: m for m in scene.materials}
    props = {b.name: body_contact_properties(b, materials.get(b.material)) for b in scene.bodies}
    for b in scene.bodies:
        for part in b.shape.parts:
            stand_in = _PartBody(b.name, part.shape, part.modes, b.mass, b.motion)
            props[(b.name, part.name)] = body_contact_properties(stand_in, materials.get(part.material))
    return props


@dataclass(frozen=True)
class _PartBody:
    """A part of a compound body as the modal models and the contact duration read a body."""

    name: str
    shape: object
    modes: tuple | None
    mass: float | None
    motion: str
