"""Lowering of expressions: parse tree -> expression tree with a dimension, constants folded, units in SI.

Names resolve through a `Scope` chain (lets, loop variables, part parameters). A value remembers its
dimension (`units.Dim`, or None for a bare number); a slot then `coerce`s it, which is where a missing or
wrong unit becomes a diagnostic.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from isaac_ir import expr as E
from isaac_lang import lower_chains as chains
from isaac_lang.dimension_hints import arguments_mismatch, components_mismatch
from isaac_lang.typed import Typed
from isaac_ir import units as U
from isaac_ir.diagnostics import Reporter, SourcePos, SceneError, did_you_mean
from isaac_lang.syntax import parse_expression

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
# the deepest nesting of brackets, calls and vectors lowered (each level a few Python frames; chains of one
# operator do not count, lower_chains.py)
MAX_NESTING = 64
# the deepest expression, and the most operations in one (its `let`s written out), the runtime is given: it
# evaluates and differentiates them by recursion, and a kinematic path once per step
MAX_EXPR_DEPTH = 100
MAX_EXPR_NODES = 100_000
# the largest length (m) a scene may write: a double keeps a place out there to 1e-4 m, and its square (a
# distance, a moment of inertia) stays far from overflow; 1e308 m is a typo, not a scene
MAX_LENGTH = 1e12

# functions of motion that only the runtime can evaluate (a recorded envelope, a live microphone, gusts)
SIGNAL_FUNCTIONS = {"envelope", "mic", "noise", "gust"}
# nodes of the audio graph (timbre trees), valid inside a sound's `play`
AUDIO_FUNCTIONS = {
    "modal", "noise", "sine", "pulse", "bandpass", "lowpass", "highpass", "decay", "adsr", "delay", "pan",
    "scrape", "roll", "wind_noise", "whistle", "impact", "mix", "gain", "envelope",
}
# motion signals a sound's graph may read (docs/design/sound.md#section-1: leaves mapped from the motion)
AUDIO_SIGNALS = {"impulse", "speed", "normal_force", "wind_speed", "distance", "t"}


@dataclass(frozen=True)
class BodyRef:
    """A part parameter bound to a body: the name as written and the instance prefixes to try, innermost first."""

    name: str
    pos: SourcePos | None = None
    prefixes: tuple = ("",)

    def candidates(self) -> list:
        return [prefix + self.name for prefix in self.prefixes]


@dataclass
class Scope:
    """Names visible at a point of the scene; `prefix` names the part instance being expanded ("left.")."""

    values: dict = field(default_factory=dict)
    kinds: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)
    parent: "Scope | None" = None
    prefix: str = ""

    def child(self, prefix: str | None = None) -> "Scope":
        return Scope(parent=self, prefix=self.prefix if prefix is None else prefix)

    def lookup(self, table: str, name: str):
        scope = self
        while scope is not None:
            found = getattr(scope, table).get(name)
            if found is not None:
                return found
            scope = scope.parent
        return None

    def visible(self, table: str) -> set:
        names, scope = set(), self
        while scope is not None:
            names |= set(getattr(scope, table))
            scope = scope.parent
        return names

    def prefixes(self) -> list:
        """Instance prefixes from the innermost out, ending with the scene's (empty) prefix."""
        out, scope = [], self
        while scope is not None:
            if scope.prefix not in out:
                out.append(scope.prefix)
            scope = scope.parent
        if "" not in out:
            out.append("")
        return out


@dataclass(frozen=True)
class ExprContext:
    """What an expression may use where it stands."""

    time: bool = True  # may depend on t
    signals: bool = False  # envelope(), mic(), noise(): wind speeds
    audio: bool = False  # audio-graph nodes and motion signals: a sound's `play`


# the contexts, made once and shared: (may depend on t, may use signals) -> context
CONTEXTS = {(time, signals): ExprContext(time=time, signals=signals) for time in (False, True)
            for signals in (False, True)}
FIXED = CONTEXTS[False, False]  # a value known before the run: a time window, a body point, a loop bound


class ExprLowerer:
    """Turns expression parse trees into `Typed` values."""

    def __init__(self, file: str, reporter: Reporter):
        self.file = file
        self.reporter = reporter
        self.nesting = 0  # how many `lower` calls are open: brackets, calls and vectors inside one another

    # -- positions ----------------------------------------------------------------------------------------

    def pos(self, node) -> SourcePos | None:
        if isinstance(node, Token):
            return SourcePos(self.file, node.line, node.column, max(1, len(node)))
        meta = getattr(node, "meta", None)
        if meta is None or getattr(meta, "empty", True):
            return None
        length = meta.end_column - meta.column if meta.end_line == meta.line else 1
        return SourcePos(self.file, meta.line, meta.column, max(1, length))

    def fail(self, message: str, node, hint: str | None = None) -> SceneError:
        return self.reporter.fatal(message, self.pos(node), hint)

    # -- the walk -----------------------------------------------------------------------------------------

    def lower(self, tree, scope: Scope, ctx: ExprContext) -> Typed:
        """The value of an expression's parse tree. Chains of one operator are lowered by loops
        (lower_chains.py); other nesting (brackets, calls, vectors) by recursion, at most MAX_NESTING deep; the
        finished expression is at most MAX_EXPR_DEPTH deep and MAX_EXPR_NODES large."""
        if self.nesting >= MAX_NESTING:
            raise self.fail(f"this expression nests more than {MAX_NESTING} levels deep (brackets, calls or "
                            "vectors inside one another)", tree, "give its inner parts names with `let`")
        self.nesting += 1
        try:
            value = self._lower_tree(tree, scope, ctx)
        finally:
            self.nesting -= 1
        if type(value.node) is not E.Const and self.nesting == 0:
            self._check_extent(value.node, tree)
        return value

    def _check_extent(self, node: E.Expr, tree) -> None:
        """An expression the runtime can evaluate, differentiate and print without deep recursion or a tree of
        millions of nodes (a `let` used twice in the next, and so on, doubles the tree each time)."""
        depth, count = E.extent(node, MAX_EXPR_NODES)
        if depth > MAX_EXPR_DEPTH:
            raise self.fail(f"this expression is {depth} operations deep, more than the {MAX_EXPR_DEPTH} the "
                            "runtime evaluates", tree, "write it with fewer nested operations (a tower of "
                            "powers of t, functions of functions)")
        if count > MAX_EXPR_NODES:
            raise self.fail(f"this expression has more than {MAX_EXPR_NODES} operations once its `let`s are "
                            "written out", tree, "a `let` used twice in the next one doubles the expression: "
                            "use fewer of them")

    def _lower_tree(self, tree, scope: Scope, ctx: ExprContext) -> Typed:
        if isinstance(tree, Token):
            raise self.fail(f"unexpected `{tree}`", tree)
        method = _RULES.get(tree.data)
        if method is None:
            raise self.fail(self._misplaced(tree.data), tree)
        try:
            value = method(self, tree, scope, ctx)
        except U.UnitError as error:  # e.g. sqrt(1 m)
            raise self.fail(str(error), tree) from None
        except (ArithmeticError, ValueError) as error:  # folding constants: 1/0, 10^1000...
            raise self.fail(f"this value cannot be computed ({error})", tree) from None
        if type(value.node) is E.Const and not _finite(value.node.value):
            raise self.fail("this value is not a finite number", tree, "check for a division by zero, log(0) "
                            "or a number too large")
        return value

    def _misplaced(self, data: str) -> str:
        if data in ("anchor", "world_anchor"):
            return "a body point `body @ (x, y, z)` is only valid as a constraint or force argument"
        if data == "kwarg":
            return "a named argument `name = value` is only valid in a call"
        return f"`{data}` is not valid here"

    def _number(self, tree, scope, ctx) -> Typed:
        return _read_number(tree.children[0].value)

    def _string(self, tree, scope, ctx) -> Typed:
        return Typed(E.Str(str(tree.children[0])[1:-1]), U.DIMENSIONLESS)

    def _quantity(self, tree, scope, ctx) -> Typed:
        value_tree, unit = tree.children
        if isinstance(value_tree, Token):  # `5 cm`, the common case
            try:
                return _read_quantity(value_tree.value, unit.value)
            except U.UnitError as error:
                raise self.fail(str(error), unit, UNITS_HINT)
        value = self.lower(value_tree, scope, ctx)
        try:
            factor, dim = U.parse_unit(str(unit))
        except U.UnitError as error:
            raise self.fail(str(error), unit, UNITS_HINT)
        if value.dim is not None and value.dim != U.DIMENSIONLESS:
            raise self.fail(f"this value already has a unit ({U.describe(value.dim)})", unit)
        return Typed(E.mul(value.node, E.Const(factor)), dim)

    def _vector(self, tree, scope, ctx) -> Typed:
        items = [self.lower(child, scope, ctx) for child in tree.children]
        values = [item.node.value for item in items if type(item.node) is E.Const]
        numbers = len(values) == len(items) and set(map(type, values)) == {float}  # the common case
        sizes = [0] * len(items) if numbers else [item.size for item in items]
        dim = None
        # a table of constant rows of one size, as `modes ((440, 3, 1), (880, 5, 0.5))` is; else numbers
        table = sizes[0] and all(s == sizes[0] and type(i.node) is E.Const for s, i in zip(sizes, items))
        for child, item, size in zip(tree.children, items, sizes):
            if size and not table:
                raise self.fail("a vector's components must be numbers", tree)
            if item.dim is not None and item.dim != dim:  # (else U.unify leaves `dim` as it is)
                try:
                    dim = U.unify(dim, item.dim)
                except U.UnitError:
                    first = next(c for c, i in zip(tree.children, items) if i.dim is not None)
                    raise self.fail(f"vector components disagree: {U.describe(dim)} and {U.describe(item.dim)}", tree,
                                    components_mismatch(dim, item.dim, first, child))
        if table or numbers:  # rows as written (E.Vec stacks its items along the last axis: it would transpose
            return Typed(E.Const(tuple(values)), dim)  # them); numbers as folding E.Vec of them gives them
        return Typed(E.fold(E.Vec(tuple(i.node for i in items))), dim)

    def _neg(self, tree, scope, ctx) -> Typed:
        return chains.lower_negation(self, tree, scope, ctx)

    def _add(self, tree, scope, ctx) -> Typed:
        return chains.lower_sum(self, tree, scope, ctx)

    _sub = _add

    def _mul(self, tree, scope, ctx) -> Typed:
        return chains.lower_product(self, tree, scope, ctx)

    _div = _mul

    def _pow(self, tree, scope, ctx) -> Typed:
        return chains.lower_power(self, tree, scope, ctx)

    def _name_ref(self, tree, scope, ctx) -> Typed:
        if len(tree.children) > 1:
            raise self.fail(f"`{'.'.join(map(str, tree.children))}` names a body direction, which is only valid "
                            "in a constraint", tree)
        return self.name(str(tree.children[0]), tree, scope, ctx)

    def name(self, name: str, node, scope: Scope, ctx: ExprContext) -> Typed:
        value = scope.lookup("values", name)
        if isinstance(value, Typed):
            return value
        if isinstance(value, BodyRef):
            raise self.fail(f"`{name}` is a body here, not a value", node)
        if name == "t":
            if not ctx.time:
                raise self.fail("this value cannot change over time (`t` is not allowed here)", node)
            return Typed(E.Var("t"), U.TIME)
        if name in E.CONSTANTS:
            return Typed(E.Const(E.CONSTANTS[name]), None)
        if ctx.audio and name in AUDIO_SIGNALS:
            return Typed(E.Var(name), None)
        known = scope.visible("values") | set(E.CONSTANTS) | ({"t"} if ctx.time else set())
        if ctx.audio:
            known |= AUDIO_SIGNALS
        raise self.fail(f"unknown name `{name}`", node, did_you_mean(name, known) or
                        "declare it with `let NAME = value`")

    def _call(self, tree, scope, ctx) -> Typed:
        fn = str(tree.children[0])
        arg_trees = [c for c in tree.children[1:] if c is not None]
        if scope.lookup("kinds", fn) is not None or fn in CONSTRAINT_CALLS:
            raise self.fail(f"`{fn}(...)` is a constraint; it is only valid after `constraint NAME`", tree)
        if fn in E.ARITY:
            return self._math_call(fn, tree, arg_trees, scope, ctx)
        if (ctx.signals or ctx.audio) and fn in SIGNAL_FUNCTIONS or ctx.audio and fn in AUDIO_FUNCTIONS:
            return self._opaque_call(fn, tree, arg_trees, scope, ctx)
        known = set(E.ARITY) | (SIGNAL_FUNCTIONS if ctx.signals or ctx.audio else set())
        known |= AUDIO_FUNCTIONS if ctx.audio else set()
        hint = did_you_mean(fn, known)
        if fn in SIGNAL_FUNCTIONS and not ctx.signals:
            hint = f"`{fn}(...)` is a signal: valid in a wind's speed or a sound"
        raise self.fail(f"unknown function `{fn}`", tree.children[0], hint)

    def _math_call(self, fn, tree, arg_trees, scope, ctx) -> Typed:
        if len(arg_trees) != E.ARITY[fn]:
            raise self.fail(f"`{fn}` takes {E.ARITY[fn]} argument(s), got {len(arg_trees)}", tree)
        args = [self.lower(a, scope, ctx) for a in arg_trees]
        self._check_sizes(fn, args, tree)
        nodes = tuple(self._angle_arg(fn, i, a) for i, a in enumerate(args))
        dim = self._call_dim(fn, args, tree)
        return Typed(E.fold(E.Call(fn, nodes)), dim)

    def _check_sizes(self, fn: str, args: list, tree) -> None:
        """Vector functions want vectors of the right size; element-wise ones, arguments of one size."""
        sizes = [a.size for a in args]
        wanted = VECTOR_ARGUMENTS.get(fn)
        if wanted is not None:
            wrong = any((s == 0) if w is None else (s != w) for s, w in zip(sizes, wanted))
            if wrong or (fn == "dot" and sizes[0] != sizes[1]):
                usage = ", ".join("a number" if w == 0 else f"a {w}-vector" if w else "a vector" for w in wanted)
                raise self.fail(f"`{fn}` takes ({usage})", tree)
        elif len({s for s in sizes if s}) > 1:
            raise self.fail(f"`{fn}`: the vector arguments differ in size", tree)

    def _angle_arg(self, fn: str, index: int, arg: Typed) -> E.Expr:
        # euler(...) and axis_angle(axis, angle) take degrees when no unit is written (docs/language.md)
        if (fn == "euler" or (fn == "axis_angle" and index == 1)) and arg.dim is None:
            return E.mul(arg.node, E.Const(math.pi / 180.0))
        return arg.node

    def _call_dim(self, fn: str, args: list, tree):
        if fn in ("sin", "cos", "tan"):
            if args[0].dim not in (None, U.DIMENSIONLESS, U.ANGLE, U.TIME):
                raise self.fail(f"`{fn}` of {U.describe(args[0].dim)}", tree)
            return None
        if fn in ("exp", "log", "asin", "acos", "atan", "atan2", "smoothstep", "step", "sign", "floor",
                  "euler", "axis_angle", "quat", "normalize"):
            return None
        if fn == "sqrt":
            return U.scale_dim(args[0].dim, 0.5) if args[0].dim else None
        if fn in ("dot", "cross"):
            return U.combine(args[0].dim, args[1].dim, +1)
        return self._common_dim(fn, args[:2] if fn == "lerp" else args, tree)

    def _common_dim(self, fn: str, args: list, tree):
        """The one dimension of arguments that must agree (a bare number adapts); an error names the two."""
        arg_trees = [c for c in tree.children[1:] if c is not None]
        dim, first = None, None
        for arg, arg_tree in zip(args, arg_trees):
            try:
                dim = U.unify(dim, arg.dim)
            except U.UnitError:
                message, hint = arguments_mismatch(fn, dim, arg.dim, first, arg_tree)
                raise self.fail(message, tree, hint) from None
            if first is None and arg.dim is not None:
                first = arg_tree
        return dim

    def _opaque_call(self, fn, tree, arg_trees, scope, ctx) -> Typed:
        """A runtime signal or an audio node: arguments lowered, kept as a call the runtime evaluates."""
        args, kwargs = [], []
        for a in arg_trees:
            if isinstance(a, Tree) and a.data == "kwarg":
                kwargs.append((str(a.children[0]), self.lower(a.children[1], scope, ctx).node))
            elif isinstance(a, Tree) and a.data == "name_ref" and ctx.audio and (len(a.children) > 1 or (
                    scope.lookup("values", str(a.children[0])) is None
                    and str(a.children[0]) not in AUDIO_SIGNALS | {"t"} | set(E.CONSTANTS))):
                # a body, material or wind named as an audio-node argument: modal(bar), modal(left.bob)
                args.append(E.Str(ref_name(a, scope, self)))
            else:
                args.append(self.lower(a, scope, ctx).node)
        return Typed(E.Call(fn, tuple(args), tuple(sorted(kwargs))), None)

    def _keys(self, tree, scope, ctx) -> Typed:
        interp = "linear"
        frames = []
        for child in tree.children:
            if isinstance(child, Token):
                interp = str(child)
            elif child is not None:
                frames.append(child)
        if interp not in ("linear", "cubic", "step"):
            raise self.fail(f"unknown interpolation `{interp}`", tree, "use linear, cubic or step")
        if not frames:
            raise self.fail("a keyframe table needs at least one key", tree)
        times, values, dim = [], [], None
        for frame in frames:
            time = self.constant(self.lower(frame.children[0], scope, ctx), U.TIME, "a key's time", frame)
            value = self.lower(frame.children[1], scope, ctx)
            if not isinstance(value.node, E.Const):
                raise self.fail("a key's value must be constant", frame.children[1])
            try:
                dim = U.unify(dim, value.dim)
            except U.UnitError as error:
                raise self.fail(str(error), frame.children[1])
            times.append(time)
            values.append(value.node.value)
        if any(b <= a for a, b in zip(times, times[1:])):
            raise self.fail("key times must increase", tree)
        if len({len(v) if isinstance(v, tuple) else 0 for v in values}) != 1:
            raise self.fail("all keys must have values of the same size", tree)
        if not _interpolable(times, values):
            raise self.fail("these keys change too fast to interpolate: a slope between two keys overflows", tree,
                            "keep the values and their changes per second well below 1e300")
        return Typed(E.Keys(interp, tuple(times), tuple(values)), dim)

    # -- slots --------------------------------------------------------------------------------------------

    def coerce(self, value: Typed, dim: tuple, what: str, node, size: int = 0,
               bare_ok: bool = False) -> E.Expr:
        """Check value against a slot (its dimension and vector size) and return its SI expression.

        A bare number is SI in a vector slot, degrees in an angle slot, and an error in any other slot with a
        unit unless `bare_ok` (e.g. a frame rate). A constant length is at most MAX_LENGTH.
        """
        si = self._coerce(value, dim, what, node, size, bare_ok)
        largest = _largest(si.value) if dim == U.LENGTH and type(si) is E.Const else 0.0
        if largest > MAX_LENGTH:
            raise self.fail(f"{what} reaches {largest:g} m, beyond the {MAX_LENGTH:g} m a scene may place or size "
                            "anything", node, "is the exponent right? (a double holds 16 digits: out there a 5 cm "
                            "ball could not keep its place)")
        return si

    def _coerce(self, value: Typed, dim: tuple, what: str, node, size: int, bare_ok: bool) -> E.Expr:
        if value.size != size or (size and is_table(value.node)):
            shape = f"a {size}-vector" if size else "a single number"
            raise self.fail(f"{what} wants {shape}", node)
        if value.dim is None:
            if dim == U.DIMENSIONLESS or bare_ok or is_zero(value.node):
                return value.node
            if size:
                message, hint = bare_vector_reading(value, dim, what)
                self.reporter.warn(message, self.pos(node), hint)
                return value.node
            message, hint = bare_number_refusal(value, dim, what, size)
            raise self.fail(message, node, hint)
        if value.dim == dim or (dim == U.DIMENSIONLESS and value.dim == U.ANGLE):
            return value.node
        if U.without_angle(value.dim) == U.without_angle(dim) and dim[3] != 0:
            # rad is dimensionless, as in SI: sqrt(g / L) is an angular velocity; but Hz counts cycles
            if _written_in_hertz(node):
                raise self.fail(f"{what} wants {U.describe(dim)}: Hz counts cycles, not radians", node,
                                "1 Hz is 2 pi rad/s: write e.g. `2 * pi * 3 rad/s`, or the value in rad/s")
            return value.node
        raise self.fail(f"{what} wants {U.describe(dim)}, not {U.describe(value.dim)}", node,
                        wrong_unit_hint(dim, value.dim))

    def constant(self, value: Typed, dim: tuple, what: str, node, size: int = 0, bare_ok=False):
        node_si = self.coerce(value, dim, what, node, size, bare_ok)
        if not isinstance(node_si, E.Const):
            raise self.fail(f"{what} must be constant", node)
        return node_si.value


# the method lowering each kind of tree: `number` -> `ExprLowerer._number` (one look-up per node)
_RULES = {name: getattr(ExprLowerer, "_" + name) for name in (
    "number", "string", "quantity", "vector", "neg", "add", "sub", "mul", "div", "pow", "name_ref", "call", "keys")}


def _written_in_hertz(tree) -> bool:
    """Whether a unit in the source of this expression is Hz or kHz."""
    return written_with(tree, "Hz")


def written_with(tree, unit: str) -> bool:
    """Whether a token of this expression's source (not a string) holds `unit` (`Hz`, `dB`): a walk with a stack,
    for trees may be deep."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, Tree):
            stack.extend(node.children)
        elif isinstance(node, Token) and node.type != "STRING" and unit in node:
            return True
    return False


UNITS_HINT = "units: m cm mm kg g s ms deg rad Hz N Pa GPa, combined as kg/m3"


@functools.lru_cache(maxsize=4096)
def _read_number(text: str) -> Typed:
    """A number as written (`0.5`): scenes repeat the same few, each read once (values are immutable)."""
    return Typed(E.Const(float(text)), None)


@functools.lru_cache(maxsize=4096)
def _read_quantity(number: str, unit: str) -> Typed:
    """A number with a unit as written (`5 cm`), in SI, each spelling read once; raises UnitError."""
    factor, dim = U.parse_unit(unit)
    return Typed(E.mul(_read_number(number).node, E.Const(factor)), dim)


# argument sizes of the vector functions: 0 a number, k a k-vector, None any vector (size >= 1)
VECTOR_ARGUMENTS = {"length": (None,), "normalize": (None,), "dot": (None, None), "cross": (3, 3),
                    "euler": (0, 0, 0), "axis_angle": (3, 0), "quat": (0, 0, 0, 0)}


def is_table(node: E.Expr) -> bool:
    """A constant whose rows are vectors (`modes`), which no vector slot takes."""
    return type(node) is E.Const and type(node.value) is tuple and bool(node.value) \
        and type(node.value[0]) is tuple


def _interpolable(times: list, values: list) -> bool:
    """The slopes between keys and their changes (what a cubic spline's coefficients are made of) are finite,
    with room to spare (a factor 1000): keys of 1e308 and -1e308 a second apart are not."""
    import numpy as np

    with np.errstate(all="ignore"):
        gaps = np.diff(np.asarray(times, float))
        points = np.asarray(values, float).reshape(len(times), -1)
        slopes = np.diff(points, axis=0) / gaps[:, None]
        bends = np.diff(slopes, axis=0) / gaps[1:, None] if len(gaps) > 1 else slopes[:0]
        return bool(np.all(np.isfinite(slopes * 1e3)) and np.all(np.isfinite(bends * 1e3)))


def _finite(value) -> bool:
    if type(value) is float:
        return math.isfinite(value)
    if type(value) is tuple and set(map(type, value)) == {float}:
        return all(map(math.isfinite, value))  # a vector: the common case, without a call per component
    return all(_finite(v) for v in value) if isinstance(value, tuple) else True


def _largest(value) -> float:
    """The largest magnitude of the numbers of a constant (a number, a vector, a table)."""
    if isinstance(value, tuple):
        return max((_largest(v) for v in value), default=0.0)
    return abs(value) if isinstance(value, (int, float)) else 0.0


def _example_number(value: Typed) -> str:
    if isinstance(value.node, E.Const) and not isinstance(value.node.value, tuple):
        return f"{value.node.value:g}"
    if isinstance(value.node, E.Const) and all(isinstance(v, float) for v in value.node.value):
        return "(" + ", ".join(f"{v:g}" for v in value.node.value) + ")"
    return "(x, y, z)" if value.size == 3 else "1"


# ---- the rule for bare numbers (docs/language.md, "Bare numbers") -------------------------------------------

def is_zero(node: E.Expr) -> bool:
    """A constant zero, or a vector of zeros: zero in every unit, so it needs none."""
    if type(node) is not E.Const:
        return False
    value = node.value
    if type(value) is tuple:
        return all(type(v) is float and v == 0.0 for v in value)
    return type(value) is float and value == 0.0


def bare_number_refusal(value: Typed, dim: tuple, what: str, size: int) -> tuple:
    """(message, hint) for a number without a unit in a slot that has one: it is never read in a unit it does
    not name, for a scalar, a vector or a range alike."""
    example = U.EXAMPLE_UNIT.get(dim, U.format_dim(dim))
    message = f"{what} needs a unit: it is {U.describe(dim)}"
    return message, f"write the unit after the {'vector' if size else 'number'}, e.g. " \
                    f"`{_example_number(value)} {example}`"


def written_unit(tree) -> str | None:
    """The unit a value is written in: `30 deg` -> deg, `-2 cm` -> cm, `(1, 2, 3) m` -> m; None for an expression
    of other values (`2 * length`)."""
    while isinstance(tree, Tree) and tree.data == "neg":
        tree = tree.children[0]
    if isinstance(tree, Tree) and tree.data == "quantity" and isinstance(tree.children[1], Token):
        return str(tree.children[1])
    return None


def range_ends(lowerer: "ExprLowerer", trees, scope: Scope, ctx: ExprContext) -> list:
    """The two ends of `START .. END` lowered, a start without a unit taking the unit its end is written in
    (`0 .. 2 s`, `5 .. 20 ms`): a range has one unit, written once at its end."""
    start, end = (lowerer.lower(tree, scope, ctx) for tree in trees)
    unit = written_unit(trees[1])
    if start.dim is None and end.dim is not None and unit is not None:
        factor, dim = U.parse_unit(unit)
        start = Typed(E.fold(E.mul(start.node, E.Const(factor))), dim)
    return [start, end]


def bare_vector_reading(value: Typed, dim: tuple, what: str) -> tuple:
    """(message, hint) of a vector written without a unit in a slot with one: read in SI, and said so."""
    unit = U.SI_UNIT.get(dim, U.format_dim(dim))
    written = _example_number(value)
    other = U.OTHER_UNIT.get(dim)
    meant = f" (or `{written} {other}` if that is what was meant)" if other else ""
    return (f"{what} has no unit: read as {written} {unit}, {U.describe(dim)} in SI",
            f"write the unit after the vector: `{written} {unit}`{meant}")


def wrong_unit_hint(wanted: tuple, given: tuple) -> str:
    """What to write instead of a value of the wrong dimension."""
    if wanted == U.DIMENSIONLESS:
        return f"this takes a plain number (a ratio, a count or a direction): drop the unit ({U.describe(given)})"
    expected = U.EXAMPLE_UNIT.get(wanted, U.format_dim(wanted))
    return f"use a unit of {U.describe(wanted)}, e.g. `{expected}`"


# constraint library calls (kept here so expressions can say "this is a constraint")
CONSTRAINT_CALLS = {"nail", "point", "orient", "plane", "gear", "rope", "weld",
                    "tx", "ty", "tz", "rx", "ry", "rz"}


def ref_text(token, scope: Scope, lowerer: ExprLowerer) -> str:
    """The name a reference token stands for: `link{i+1}` is interpolated in the current scope."""
    if getattr(token, "type", None) == "TNAME":

        return interpolate_name(str(token), token, scope, lowerer)
    return str(token)


def ref_name(tree: Tree, scope: Scope, lowerer: ExprLowerer) -> str:
    """The full name a `name_ref` stands for: `bob`, `link{i}` interpolated, or a part instance's `left.bob`."""
    return ".".join([ref_text(tree.children[0], scope, lowerer)] + [str(t) for t in tree.children[1:]])


# ---- names with {expr} pieces -------------------------------------------------------------------------------

def interpolate_name(text: str, token, scope: Scope, lowerer: ExprLowerer) -> str:
    """link{i+1} -> link3 with i = 2: each {expr} must be a whole number."""
    out, rest = [], text
    while "{" in rest:
        head, _, tail = rest.partition("{")
        inner, _, rest = tail.partition("}")
        out.append(head + str(_name_piece(inner, token, scope, lowerer)))
    out.append(rest)
    return "".join(out)


def _name_piece(inner: str, token, scope: Scope, lowerer: ExprLowerer) -> int:
    """The whole number `{inner}` stands for; a problem inside the braces is reported at the name."""
    scratch = ExprLowerer(lowerer.file, Reporter())  # positions inside `inner` are not the file's
    try:
        value = scratch.lower(_piece_tree(inner), scope, FIXED)
    except UnexpectedInput:
        raise lowerer.fail(f"cannot read `{{{inner}}}` in a name", token, "write e.g. `link{i+1}`") from None
    except SceneError as error:
        first = error.diagnostics[0]
        raise lowerer.fail(f"in `{{{inner}}}`: {first.message}", token, first.hint) from None
    number = value.node.value if isinstance(value.node, E.Const) else None
    if not isinstance(number, float) or number != int(number):
        raise lowerer.fail(f"`{{{inner}}}` in a name must be a whole number", token)
    return int(number)


@functools.lru_cache(maxsize=4096)
def _piece_tree(inner: str) -> Tree:
    """Parse trees of the `{...}` pieces of names, parsed once each (a loop repeats the same few)."""
    return parse_expression(inner)
