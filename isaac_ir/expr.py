"""Expression trees of the IR, their evaluator and their smart constructors (their time derivative:
derivative.py). Never `eval`.

A value that changes over time stays a small tree (`Op`, `Call`, `Vec`, `Keys`, `Var("t")`); everything
else is folded into a `Const` when the scene is lowered. Values are in SI units.

Evaluation is vectorized: `evaluate(node, {"t": times})` with `times` of shape (T,) gives (T,) for a scalar,
(T, k) for a k-vector; with a float `t` it gives a float or a (k,) array.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos


class Expr:
    """Base of the expression nodes (frozen dataclasses: hashable, comparable, safe to share)."""

    __slots__ = ()


@dataclass(frozen=True)
class Const(Expr):
    value: Any  # float, or nested tuples of floats for vectors


@dataclass(frozen=True)
class Var(Expr):
    name: str


@dataclass(frozen=True)
class Str(Expr):
    value: str


@dataclass(frozen=True)
class Op(Expr):
    op: str  # add sub mul div neg pow
    args: tuple


@dataclass(frozen=True)
class Call(Expr):
    fn: str
    args: tuple
    kwargs: tuple = ()  # ((name, Expr), ...) sorted by name


@dataclass(frozen=True)
class Vec(Expr):
    items: tuple


@dataclass(frozen=True)
class Keys(Expr):
    """A keyframe table: value at each time, interpolated `linear`, `cubic` (natural spline) or `step`."""

    interp: str
    times: tuple
    values: tuple
    order: int = 0  # derivative order: the runtime asks for dP/dt and d2P/dt2 of a keyframed path


@dataclass(frozen=True)
class Deriv(Expr):
    """d^order/dt^order of a node with no closed-form derivative (a recorded envelope): central differences."""

    arg: Expr
    order: int = 1


@dataclass(frozen=True)
class Guard(Expr):
    """A value that must be finite wherever it is evaluated (a kinematic body's path, which the runtime
    evaluates at every step): where it is not, evaluating it raises NotFinite, naming what it is, the
    expression, the declaration it belongs to and the first time it fails. Not part of the IR: the plan wraps
    the paths it evaluates (runtime/plan/kinematics.py)."""

    arg: Expr
    what: str  # e.g. "the position of body `cart` on its path"
    source: str  # "file:line:col" of the declaration


class NotFinite(SceneError):
    """A guarded value that is not a finite number at some time (exit 2, at the declaration)."""


# ---- functions the evaluator knows -----------------------------------------------------------------------

def _smoothstep(e0, e1, x):
    u = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    # 3u^2 - 2u^3
    return u * u * (3.0 - 2.0 * u)


def _quat_from_euler(ax, ay, az):
    """Extrinsic x, then y, then z rotation (radians): q = qz * qy * qx."""
    cx, sx = np.cos(0.5 * ax), np.sin(0.5 * ax)
    cy, sy = np.cos(0.5 * ay), np.sin(0.5 * ay)
    cz, sz = np.cos(0.5 * az), np.sin(0.5 * az)
    return np.stack(np.broadcast_arrays(
        cz * cy * cx + sz * sy * sx,
        cz * cy * sx - sz * sy * cx,
        cz * sy * cx + sz * cy * sx,
        sz * cy * cx - cz * sy * sx,
    ), axis=-1)


def _quat_from_axis_angle(axis, angle):
    axis = np.asarray(axis, dtype=float)
    unit = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    vector = np.sin(half) * unit  # (..., 3)
    # q = (cos(angle/2), sin(angle/2) axis); the scalar part broadcast to (..., 1), not to (..., 3)
    return np.concatenate([np.broadcast_to(np.cos(half), vector.shape[:-1] + (1,)), vector], axis=-1)


def _quat(w, x, y, z):
    q = np.stack(np.broadcast_arrays(w, x, y, z), axis=-1).astype(float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


SCALAR_FUNCTIONS: dict[str, Callable] = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log, "sqrt": np.sqrt,
    "abs": np.abs, "min": np.minimum, "max": np.maximum, "floor": np.floor, "sign": np.sign,
    "atan2": np.arctan2, "asin": np.arcsin, "acos": np.arccos, "atan": np.arctan,
    "clamp": lambda x, lo, hi: np.clip(x, lo, hi),
    "lerp": lambda a, b, u: a + (b - a) * u,
    "smoothstep": _smoothstep,
    "step": lambda edge, x: np.where(x >= edge, 1.0, 0.0),
}
VECTOR_FUNCTIONS: dict[str, Callable] = {
    "length": lambda v: np.linalg.norm(v, axis=-1),
    "normalize": lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True),
    "dot": lambda a, b: np.sum(a * b, axis=-1),
    "cross": lambda a, b: np.cross(a, b),
    "euler": _quat_from_euler,
    "axis_angle": _quat_from_axis_angle,
    "quat": _quat,
}
# result size of vector-valued functions (0 = scalar); None = same as the first argument
RESULT_SIZE = {"length": 0, "dot": 0, "normalize": None, "cross": 3, "euler": 4, "axis_angle": 4, "quat": 4}
ARITY = {
    "sin": 1, "cos": 1, "tan": 1, "exp": 1, "log": 1, "sqrt": 1, "abs": 1, "floor": 1, "sign": 1,
    "asin": 1, "acos": 1, "atan": 1, "atan2": 2, "min": 2, "max": 2, "clamp": 3, "lerp": 3,
    "smoothstep": 3, "step": 2, "length": 1, "normalize": 1, "dot": 2, "cross": 2, "euler": 3,
    "axis_angle": 2, "quat": 4,
}
CONSTANTS = {"pi": math.pi, "e": math.e, "tau": 2.0 * math.pi}


class EvaluationError(ValueError):
    pass


# ---- shape -----------------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=4096)
def size_of(node: Expr) -> int:
    """0 for a scalar, k for a k-vector (static: known without evaluating)."""
    if isinstance(node, Const):
        return len(node.value) if isinstance(node.value, tuple) else 0
    if isinstance(node, Vec):
        return len(node.items)
    if isinstance(node, (Op,)):
        return max(size_of(a) for a in node.args)
    if isinstance(node, Call):
        if node.fn in RESULT_SIZE:
            size = RESULT_SIZE[node.fn]
            return size_of(node.args[0]) if size is None else size
        return max((size_of(a) for a in node.args), default=0)
    if isinstance(node, Keys):
        first = node.values[0]
        return len(first) if isinstance(first, tuple) else 0
    if isinstance(node, (Deriv, Guard)):
        return size_of(node.arg)
    return 0


def is_constant(node: Expr) -> bool:
    return isinstance(node, Const)


def free_vars(node: Expr) -> frozenset:
    """The names of the variables in an expression (a walk with a stack: expressions may be deep)."""
    if isinstance(node, Var):
        return frozenset([node.name])
    if isinstance(node, (Const, Str, Keys)):
        return frozenset()
    return frozenset(n.name for n in _walk(node) if isinstance(n, Var))


def _walk(node: Expr):
    """Every node of an expression, each shared node once."""
    seen, stack = set(), [node]
    while stack:
        current = stack.pop()
        if id(current) in seen:
            continue
        seen.add(id(current))
        yield current
        stack.extend(_children(current))


def extent(node: Expr, most: int | None = None) -> tuple:
    """(depth, count) of an expression as a tree: the longest path from it to a leaf, in nodes, and how many
    nodes it has with every shared subtree counted each time it is used. Iterative, each shared node visited
    once, so that a tree too deep or too large to evaluate can be measured; stops counting once past `most`."""
    measured = {}  # id(node) -> (depth, count)
    stack = [(node, False)]
    while stack:
        current, expanded = stack.pop()
        key = id(current)
        if key in measured:
            continue
        children = _children(current)
        if expanded or not children:
            sizes = [measured[id(c)] for c in children]
            depth = 1 + max((d for d, _ in sizes), default=0)
            count = 1 + sum(c for _, c in sizes)
            measured[key] = (depth, count)
            if most is not None and count > most:
                return depth, count
            continue
        stack.append((current, True))
        stack.extend((c, False) for c in children if id(c) not in measured)
    return measured[id(node)]


def _children(node: Expr) -> tuple:
    if isinstance(node, Op):
        return node.args
    if isinstance(node, Call):
        return node.args + tuple(v for _, v in node.kwargs)
    if isinstance(node, Vec):
        return node.items
    if isinstance(node, (Deriv, Guard)):
        return (node.arg,)
    return ()


# ---- evaluation ------------------------------------------------------------------------------------------

def evaluate(node: Expr, env: dict, functions: dict | None = None):
    """Value of node with the variables of env (e.g. {"t": 0.5} or {"t": times}).

    `functions` adds signal functions the runtime provides (a recorded envelope, a live microphone):
    name -> callable(env, *evaluated_args, **kwargs).
    """
    if isinstance(node, Const):
        return np.asarray(node.value, dtype=float) if isinstance(node.value, tuple) else node.value
    if isinstance(node, Var):
        try:
            return env[node.name]
        except KeyError:
            raise EvaluationError(f"`{node.name}` has no value here") from None
    if isinstance(node, Op):
        return _evaluate_op(node, env, functions)
    if isinstance(node, Vec):
        parts = [evaluate(item, env, functions) for item in node.items]
        return np.stack(np.broadcast_arrays(*parts), axis=-1).astype(float)
    if isinstance(node, Call):
        return _evaluate_call(node, env, functions)
    if isinstance(node, Keys):
        return _evaluate_keys(node, env["t"])
    if isinstance(node, Deriv):
        return _evaluate_numeric_derivative(node, env, functions)
    if isinstance(node, Str):
        return node.value
    if isinstance(node, Guard):
        return _evaluate_guarded(node, env, functions)
    raise EvaluationError(f"cannot evaluate {type(node).__name__}")


def _evaluate_guarded(node: Guard, env, functions):
    """A Guard's value, or NotFinite at the first time it is not finite (numpy's warnings silenced: the error
    says it instead)."""
    with np.errstate(all="ignore"):
        value = evaluate(node.arg, env, functions)
    finite = np.isfinite(np.asarray(value, dtype=float))
    if finite.all():
        return value
    times = np.asarray(env.get("t", np.nan), dtype=float).reshape(-1)
    if finite.ndim and len(times) == finite.shape[0]:  # values at many times: the first that fails
        times = times[~finite.reshape(len(times), -1).all(axis=1)]
    when = float(times[0]) if len(times) else math.nan
    message = f"{node.what} is not a finite number at t = {when:.6g} s: {render(node.arg)}"
    hint = "look for a division by zero, a log or square root of a negative number, or an overflow near that time"
    raise NotFinite([Diagnostic(message, SourcePos.parse(node.source), hint)])


def _lift(value, size: int, other_size: int):
    """Give a scalar of shape (T,) a trailing axis when it meets a vector, so that it broadcasts."""
    if size == 0 and other_size > 0 and np.ndim(value) > 0:
        return np.asarray(value)[..., None]
    return value


def _evaluate_op(node: Op, env, functions):
    values = [evaluate(a, env, functions) for a in node.args]
    if node.op == "neg":
        return -values[0]
    a, b = values
    if np.ndim(a) and np.ndim(b):
        # two arrays: a scalar series (T,) may meet a vector, which only the static sizes tell apart (a plain
        # number, as at a single time t, broadcasts by itself and skips this)
        sizes = [size_of(x) for x in node.args]
        a, b = _lift(a, sizes[0], sizes[1]), _lift(b, sizes[1], sizes[0])
    if node.op == "add":
        return a + b
    if node.op == "sub":
        return a - b
    if node.op == "mul":
        return a * b
    if node.op == "div":
        return a / b
    if node.op == "pow":
        return np.power(a, b)
    raise EvaluationError(f"unknown operator {node.op}")


def _evaluate_call(node: Call, env, functions):
    if functions and node.fn in functions:
        args = [evaluate(a, env, functions) for a in node.args]
        kwargs = {k: evaluate(v, env, functions) for k, v in node.kwargs}
        return functions[node.fn](env, *args, **kwargs)
    args = [evaluate(a, env, functions) for a in node.args]
    if node.fn in VECTOR_FUNCTIONS:
        return VECTOR_FUNCTIONS[node.fn](*args)
    if node.fn in SCALAR_FUNCTIONS:
        if sum(1 for v in args if np.ndim(v)) > 1:
            sizes = [size_of(a) for a in node.args]
            widest = max(sizes)
            args = [_lift(v, s, widest) for v, s in zip(args, sizes)]
        return SCALAR_FUNCTIONS[node.fn](*args)
    raise EvaluationError(f"unknown function `{node.fn}`")


@functools.lru_cache(maxsize=256)
def _interpolator(node: Keys):
    from scipy.interpolate import CubicSpline

    times = np.asarray(node.times, dtype=float)
    values = np.asarray(node.values, dtype=float)
    if node.interp == "cubic" and len(times) > 2:
        return CubicSpline(times, values, axis=0, bc_type="natural", extrapolate=False)
    return None


def _evaluate_keys(node: Keys, t):
    value = _keys_inside(node, t)
    if node.order == 0:
        return value
    # before the first key and after the last the value holds still: its derivatives are zero there
    t = np.asarray(t, dtype=float)
    still = (t < node.times[0]) | (t > node.times[-1]) | (len(node.times) == 1)
    if not np.any(still):
        return value
    return np.where(still[..., None] if np.ndim(value) > t.ndim else still, 0.0, value)


def _keys_inside(node: Keys, t):
    times = np.asarray(node.times, dtype=float)
    values = np.asarray(node.values, dtype=float)
    tt = np.clip(np.asarray(t, dtype=float), times[0], times[-1])
    spline = _interpolator(node)
    if spline is not None:
        return spline(tt, node.order)
    if node.interp == "step":
        index = np.clip(np.searchsorted(times, tt, side="right") - 1, 0, len(times) - 1)
        return values[index] if node.order == 0 else np.zeros_like(values[index])
    # linear (also cubic with two keys): value, or the slope of the segment for order 1
    index = np.clip(np.searchsorted(times, tt, side="right") - 1, 0, max(len(times) - 2, 0))
    if len(times) == 1:
        return values[0] * np.ones_like(tt)[..., None] if values.ndim > 1 else values[0] + 0 * tt
    t0, t1 = times[index], times[index + 1]
    v0, v1 = values[index], values[index + 1]
    if node.order >= 2:
        return np.zeros_like(v0)
    slope = (v1 - v0) / np.asarray(t1 - t0)[..., None] if values.ndim > 1 else (v1 - v0) / (t1 - t0)
    if node.order == 1:
        return slope
    u = (tt - t0)[..., None] if values.ndim > 1 else tt - t0
    return v0 + slope * u


# step of the central differences in Deriv: small against the time scales of a scene, large against rounding
_DERIV_STEP = 1e-4


def _evaluate_numeric_derivative(node: Deriv, env, functions):
    t = np.asarray(env["t"], dtype=float)
    h = _DERIV_STEP
    f = lambda shift: np.asarray(evaluate(node.arg, {**env, "t": t + shift}, functions), dtype=float)
    if node.order == 1:
        # f'(t) = (f(t+h) - f(t-h)) / 2h
        return (f(h) - f(-h)) / (2 * h)
    # f''(t) = (f(t+h) - 2 f(t) + f(t-h)) / h^2
    return (f(h) - 2 * f(0.0) + f(-h)) / (h * h)


# ---- smart constructors: fold constants as the tree is built ---------------------------------------------

ZERO = Const(0.0)
ONE = Const(1.0)


def zero_like(node: Expr) -> Expr:
    """A zero of node's size (a scalar 0 for a scalar or a string)."""
    size = size_of(node) if not isinstance(node, Str) else 0
    return Const(tuple([0.0] * size)) if size else ZERO


def _is_zero(node: Expr) -> bool:
    return isinstance(node, Const) and not isinstance(node.value, tuple) and node.value == 0.0


def _is_one(node: Expr) -> bool:
    return isinstance(node, Const) and not isinstance(node.value, tuple) and node.value == 1.0


def fold(node: Expr) -> Expr:
    """Replace a subtree without variables or runtime signals by its value."""
    if isinstance(node, (Const, Str, Var, Keys)):
        return node
    quick = _fold_plain(node)
    if quick is not None:
        return quick
    if free_vars(node) or _has_unknown_call(node):
        return node
    with np.errstate(all="ignore"):  # log(0), 0/0: a non-finite constant, which the lowering reports
        value = evaluate(node, {})
    return Const(to_tuple(value))


# + - * / on plain floats: Python's arithmetic is the same IEEE double arithmetic as numpy's, without numpy's
# overhead on three numbers (a zero divisor raises ZeroDivisionError, which the lowering reports)
_PLAIN_OPS = {"add": float.__add__, "sub": float.__sub__, "mul": float.__mul__, "div": float.__truediv__}


def _fold_plain(node: Expr) -> Const | None:
    """The common cases of folding, without numpy: an operator on two numbers, a vector of numbers."""
    if type(node) is Op:
        args = node.args
        if not all(type(a) is Const and type(a.value) is float for a in args):
            return _scaled_plain(*args) if node.op == "mul" else None
        if node.op == "neg":
            return Const(-args[0].value)
        op = _PLAIN_OPS.get(node.op)
        return Const(op(args[0].value, args[1].value)) if op else None
    if type(node) is Vec and all(type(i) is Const and type(i.value) is float for i in node.items):
        return Const(tuple(i.value for i in node.items))
    return None


def _scaled_plain(a: Expr, b: Expr) -> Const | None:
    """A vector of numbers times a number (`(1, 2, 3) cm`), component by component as numpy multiplies."""
    if type(a) is not Const or type(b) is not Const:
        return None
    if type(a.value) is float:
        a, b = b, a  # (IEEE multiplication commutes exactly)
    if type(b.value) is float and type(a.value) is tuple and all(type(x) is float for x in a.value):
        return Const(tuple(x * b.value for x in a.value))
    return None


def _has_unknown_call(node: Expr) -> bool:
    """Whether evaluating the expression needs the runtime: a signal, a keyframe table, a numeric derivative."""
    for current in _walk(node):
        if isinstance(current, Call) and current.fn not in SCALAR_FUNCTIONS and current.fn not in VECTOR_FUNCTIONS:
            return True
        if isinstance(current, (Keys, Deriv)):
            return True
    return False


def to_tuple(value):
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return float(array)
    return tuple(to_tuple(v) for v in array)


def add(a: Expr, b: Expr) -> Expr:
    if _is_zero(a) and size_of(b) >= size_of(a):
        return b
    if _is_zero(b) and size_of(a) >= size_of(b):
        return a
    return fold(Op("add", (a, b)))


def sub(a: Expr, b: Expr) -> Expr:
    if _is_zero(b) and size_of(a) >= size_of(b):
        return a
    return fold(Op("sub", (a, b)))


def mul(a: Expr, b: Expr) -> Expr:
    if type(a) is Const and type(b) is Const and type(a.value) is float and type(b.value) is float:
        # two numbers (a value times its unit's factor): the rules below, without an Op to fold
        x, y = a.value, b.value
        return ZERO if x == 0.0 or y == 0.0 else b if x == 1.0 else a if y == 1.0 else Const(x * y)
    if (_is_zero(a) or _is_zero(b)):
        return zero_like(Op("mul", (a, b)))
    if _is_one(a):
        return b
    if _is_one(b):
        return a
    return fold(Op("mul", (a, b)))


def neg(a: Expr) -> Expr:
    return fold(Op("neg", (a,)))



# ---- readable ------------------------------------------------------------------------------------------------

_SYMBOLS = {"add": "+", "sub": "-", "mul": "*", "div": "/", "pow": "^"}


def render(node: Expr, limit: int = 80) -> str:
    """The expression as a reader writes it, in SI units, cut to `limit` characters."""
    text = _render(node, limit + 1)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _render(node: Expr, limit: int) -> str:
    if isinstance(node, Const):
        return _number(node.value)
    if isinstance(node, Var):
        return node.name
    if isinstance(node, Str):
        return f'"{node.value}"'
    if isinstance(node, Guard):
        return _render(node.arg, limit)
    if isinstance(node, Op) and node.op == "neg":
        return "-" + _inner(node.args[0], limit)
    if isinstance(node, Op):
        return f" {_SYMBOLS.get(node.op, node.op)} ".join(_inner(a, limit) for a in node.args)
    if isinstance(node, Call):
        return f"{node.fn}({', '.join(_render(a, limit) for a in node.args)})"
    if isinstance(node, Vec):
        return "(" + ", ".join(_render(i, limit) for i in node.items) + ")"
    if isinstance(node, Keys):
        return f"keys {node.interp} {{...{len(node.times)} keys}}"
    if isinstance(node, Deriv):
        return f"d{node.order}/dt({_render(node.arg, limit)})"
    return type(node).__name__


def _inner(node: Expr, limit: int) -> str:
    text = _render(node, limit)
    return f"({text})" if isinstance(node, Op) and not (node.op == "neg") else text


def _number(value) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(_number(v) for v in value) + ")"
    return f"{value:.6g}"
