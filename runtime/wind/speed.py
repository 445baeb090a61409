"""Wind stage, speed: a wind's `speed` expression s(t) compiled once into a closure of a float t.

`E.evaluate` walks the tree at every call (isinstance tests, a list per node, an env dict): about 70 us for
`5 m/s + 2 m/s * sin(2 pi t / 7 s)`, and the force stage asks for s(t) at every RK4 stage. `compile_speed`
walks it once and returns nested closures that do only the arithmetic, with the same numpy functions in the
same order as the evaluator (so the values are the same to the last bit), about 3 us. Never `eval`.

Nodes the closures do not know (keyframes, vectors, numeric derivatives) are left to `E.evaluate`: the
compiled form is a fast path, the evaluator stays the reference (tests compare them).

`SpeedOfTime` remembers its last (t, s): the recorder and the next step's first stage ask for the same t.
"""
from __future__ import annotations

import math
import operator

import numpy as np

from isaac_ir import expr as E

# the evaluator's binary operators (expr._evaluate_op): Python's on floats, np.power for pow
_BINARY = {"add": operator.add, "sub": operator.sub, "mul": operator.mul, "div": operator.truediv, "pow": np.power}


class SpeedOfTime:
    """s(t) of one wind as a float, from its compiled closure; caches the last time asked."""

    __slots__ = ("node", "function", "last_t", "last_value")

    def __init__(self, node: E.Expr, functions: dict | None):
        self.node = node
        self.function = compile_scalar(node, functions)
        self.last_t = math.nan
        self.last_value = 0.0

    def __call__(self, t: float) -> float:
        if t != self.last_t:  # (NaN never equals: the first call always evaluates)
            self.last_value = float(self.function(t))
            self.last_t = t
        return self.last_value


def compile_scalar(node: E.Expr, functions: dict | None = None):
    """A callable f(t) -> the value of `node` at the float time t, equal to E.evaluate(node, {"t": t},
    functions)."""
    if isinstance(node, E.Const) and not isinstance(node.value, tuple):
        value = node.value
        return lambda t: value
    if isinstance(node, E.Var) and node.name == "t":
        return lambda t: t
    if isinstance(node, E.Op):
        return _compile_op(node, functions)
    if isinstance(node, E.Call):
        compiled = _compile_call(node, functions)
        if compiled is not None:
            return compiled
    # the rest (keyframes, vectors, derivatives, other variables, strings): the evaluator itself
    return lambda t: E.evaluate(node, {"t": t}, functions)


def _compile_op(node: E.Op, functions):
    args = [compile_scalar(a, functions) for a in node.args]
    if node.op == "neg":
        (a,) = args
        return lambda t: -a(t)
    a, b = args
    if node.op not in _BINARY:
        return lambda t: E.evaluate(node, {"t": t}, functions)
    op = _BINARY[node.op]
    return lambda t: op(a(t), b(t))


def _compile_call(node: E.Call, functions):
    args = [compile_scalar(a, functions) for a in node.args]
    kwargs = [(k, compile_scalar(v, functions)) for k, v in node.kwargs]
    if functions and node.fn in functions:
        # a signal function (envelope, mic, noise, gust): called as the evaluator calls it, with the env
        fn = functions[node.fn]
        return lambda t: fn({"t": t}, *[a(t) for a in args], **{k: v(t) for k, v in kwargs})
    if node.fn in E.SCALAR_FUNCTIONS and not kwargs:
        fn = E.SCALAR_FUNCTIONS[node.fn]
        if len(args) == 1:
            (a,) = args
            return lambda t: fn(a(t))
        return lambda t: fn(*[a(t) for a in args])
    return None
