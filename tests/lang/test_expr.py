"""Expression trees (isaac_ir/expr.py): evaluation (scalar and vectorized over t), every function, keyframe
tables, the symbolic time derivative against finite differences, constant folding and the JSON round trip."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isaac_ir import expr as E
from isaac_ir.derivative import derivative
from isaac_ir.expr_forms import from_json, to_json
from isaac_ir.diagnostics import Reporter
from isaac_lang.lower_expr import ExprContext, ExprLowerer, Scope, Typed
from isaac_lang.syntax import parse_expression

T = np.linspace(0.1, 2.9, 15)
t = E.Var("t")


def node(text: str) -> E.Expr:
    """An expression of the language, lowered; `u` is t as a plain number (so that any power is allowed)."""
    scope = Scope()
    scope.values["u"] = Typed(t, None)
    return ExprLowerer("<test>", Reporter()).lower(parse_expression(text), scope, ExprContext(time=True)).node


def at(expr: E.Expr, times):
    return np.asarray(E.evaluate(expr, {"t": times}), dtype=float)


# -- evaluation -------------------------------------------------------------------------------------------

def test_scalar_and_vectorized_evaluation():
    f = node("2 * u + sin(u)")
    assert isinstance(E.evaluate(f, {"t": 0.5}), float)
    assert E.evaluate(f, {"t": 0.5}) == pytest.approx(1.0 + math.sin(0.5))
    assert at(f, T).shape == (15,)
    np.testing.assert_allclose(at(f, T), 2 * T + np.sin(T), rtol=1e-14)


def test_vectors_over_an_array_of_times():
    v = node("(u, 2 * u, 1)")
    assert at(v, 0.5).shape == (3,)
    assert at(v, T).shape == (15, 3)
    np.testing.assert_allclose(at(v, T), np.stack([T, 2 * T, np.ones_like(T)], axis=1))
    scaled = node("u * (1, 2, 3)")  # a scalar of shape (T,) meets a vector: (T, 3)
    np.testing.assert_allclose(at(scaled, T), T[:, None] * np.array([1.0, 2.0, 3.0]))
    shifted = node("(1, 2, 3) + (u, u, u) / 2")
    np.testing.assert_allclose(at(shifted, T), np.array([1.0, 2.0, 3.0]) + T[:, None] / 2)


def test_unknown_variables_and_functions_are_evaluation_errors():
    with pytest.raises(E.EvaluationError):
        E.evaluate(E.Var("x"), {"t": 0.0})
    with pytest.raises(E.EvaluationError):
        E.evaluate(E.Call("envelope", (E.Str("breath.wav"),)), {"t": 0.0})


def test_runtime_signal_functions():
    envelope = E.Call("envelope", (E.Str("breath.wav"),), (("gain", E.Const(2.0)),))
    functions = {"envelope": lambda env, name, gain: gain * np.sin(env["t"])}
    np.testing.assert_allclose(E.evaluate(envelope, {"t": T}, functions), 2 * np.sin(T))
    # no closed-form derivative: central differences of the signal
    np.testing.assert_allclose(E.evaluate(derivative(envelope), {"t": T}, functions), 2 * np.cos(T), rtol=1e-6)


# -- every function ---------------------------------------------------------------------------------------

S = np.linspace(-0.9, 0.9, 11)  # inside the domain of asin and acos
FUNCTIONS = {
    "sin": ("sin(u)", np.sin), "cos": ("cos(u)", np.cos), "tan": ("tan(u)", np.tan), "exp": ("exp(u)", np.exp),
    "log": ("log(u + 2)", lambda x: np.log(x + 2)), "sqrt": ("sqrt(u + 2)", lambda x: np.sqrt(x + 2)),
    "abs": ("abs(u)", np.abs), "floor": ("floor(3 * u)", lambda x: np.floor(3 * x)),
    "sign": ("sign(u)", np.sign), "asin": ("asin(u)", np.arcsin), "acos": ("acos(u)", np.arccos),
    "atan": ("atan(u)", np.arctan), "atan2": ("atan2(u, 0.5)", lambda x: np.arctan2(x, 0.5)),
    "min": ("min(u, 0.2)", lambda x: np.minimum(x, 0.2)), "max": ("max(u, 0.2)", lambda x: np.maximum(x, 0.2)),
    "clamp": ("clamp(u, -0.5, 0.5)", lambda x: np.clip(x, -0.5, 0.5)),
    "lerp": ("lerp(1, 3, u)", lambda x: 1 + 2 * x),
    "smoothstep": ("smoothstep(-0.5, 0.5, u)",
                   lambda x: np.clip(x + 0.5, 0, 1) ** 2 * (3 - 2 * np.clip(x + 0.5, 0, 1))),
    "step": ("step(0.1, u)", lambda x: (x >= 0.1).astype(float)),
    "length": ("length((u, 2, 2))", lambda x: np.sqrt(x * x + 8)),
    "normalize": ("normalize((u, 0, 1))",
                  lambda x: np.stack([x, 0 * x, 1 + 0 * x], -1) / np.sqrt(x * x + 1)[:, None]),
    "dot": ("dot((u, 1, 0), (2, 3, 4))", lambda x: 2 * x + 3),
    "cross": ("cross((1, 0, 0), (0, u, 0))", lambda x: np.stack([0 * x, 0 * x, x], -1)),
    "euler": ("euler(0, 0, (u) rad)",
              lambda x: np.stack([np.cos(x / 2), 0 * x, 0 * x, np.sin(x / 2)], -1)),
    "axis_angle": ("axis_angle((0, 0, 2), (u) rad)",
                   lambda x: np.stack([np.cos(x / 2), 0 * x, 0 * x, np.sin(x / 2)], -1)),
    "quat": ("quat(1, u, 0, 0)", lambda x: np.stack([1 + 0 * x, x, 0 * x, 0 * x], -1) / np.sqrt(1 + x * x)[:, None]),
}


def test_every_function_is_covered():
    assert set(FUNCTIONS) == set(E.ARITY) == set(E.SCALAR_FUNCTIONS) | set(E.VECTOR_FUNCTIONS)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_function(name):
    text, reference = FUNCTIONS[name]
    f = node(text)
    vectorized = at(f, S)
    np.testing.assert_allclose(vectorized, reference(S), rtol=1e-12, atol=1e-14)
    one_by_one = np.array([at(f, float(s)) for s in S])
    np.testing.assert_allclose(one_by_one, vectorized, rtol=1e-12, atol=1e-14)


def test_euler_angles_compose_x_then_y_then_z():
    # extrinsic x, then y, then z: q = qz * qy * qx
    def q_axis(axis, angle):
        return np.r_[math.cos(angle / 2), math.sin(angle / 2) * np.asarray(axis, float)]

    def q_mul(a, b):
        w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
        return np.r_[w1 * w2 - v1 @ v2, w1 * v2 + w2 * v1 + np.cross(v1, v2)]

    ax, ay, az = 0.3, -0.7, 1.1
    expected = q_mul(q_axis((0, 0, 1), az), q_mul(q_axis((0, 1, 0), ay), q_axis((1, 0, 0), ax)))
    np.testing.assert_allclose(E.evaluate(E.Call("euler", (E.Const(ax), E.Const(ay), E.Const(az))), {}), expected)


# -- keyframes --------------------------------------------------------------------------------------------

TIMES = (0.0, 1.0, 3.0)


def keys(interp, values=(0.0, 2.0, 1.0)):
    return E.Keys(interp, TIMES, values)


def test_linear_keys_and_their_derivative():
    k = keys("linear")
    np.testing.assert_allclose(at(k, np.array([-1.0, 0.0, 0.5, 1.0, 2.0, 3.0, 4.0])),
                               [0.0, 0.0, 1.0, 2.0, 1.5, 1.0, 1.0])
    np.testing.assert_allclose(at(derivative(k), np.array([-1.0, 0.5, 2.0, 4.0])), [0.0, 2.0, -0.5, 0.0])
    np.testing.assert_allclose(at(derivative(derivative(k)), np.array([0.5, 2.0])), [0.0, 0.0])


def test_step_keys_hold_until_the_next_key():
    k = keys("step")
    np.testing.assert_allclose(at(k, np.array([-1.0, 0.0, 0.99, 1.0, 2.9, 3.0, 5.0])),
                               [0.0, 0.0, 0.0, 2.0, 2.0, 1.0, 1.0])
    np.testing.assert_allclose(at(derivative(k), np.array([0.5, 2.0])), [0.0, 0.0])


def test_cubic_keys_are_a_natural_spline_through_the_keys():
    from scipy.interpolate import CubicSpline

    k = keys("cubic")
    spline = CubicSpline(TIMES, (0.0, 2.0, 1.0), bc_type="natural")
    inside = np.linspace(0.0, 3.0, 31)
    np.testing.assert_allclose(at(k, inside), spline(inside), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(at(derivative(k), inside), spline(inside, 1), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(at(derivative(derivative(k)), inside), spline(inside, 2), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(at(k, np.array(TIMES)), (0.0, 2.0, 1.0), atol=1e-14)
    # held before the first key and after the last: value clamped, derivatives zero
    np.testing.assert_allclose(at(k, np.array([-1.0, 4.0])), [0.0, 1.0], atol=1e-14)
    np.testing.assert_allclose(at(derivative(k), np.array([-1.0, 4.0])), [0.0, 0.0])


def test_vector_keys_and_a_single_key():
    k = E.Keys("linear", (0.0, 2.0), ((0.0, 0.0, 0.0), (2.0, 4.0, 0.0)))
    assert E.size_of(k) == 3
    np.testing.assert_allclose(at(k, np.array([1.0])), [[1.0, 2.0, 0.0]])
    np.testing.assert_allclose(at(derivative(k), 1.0), [1.0, 2.0, 0.0])
    single = E.Keys("cubic", (1.0,), ((1.0, 2.0, 3.0),))
    np.testing.assert_allclose(at(single, T), np.tile([1.0, 2.0, 3.0], (15, 1)))
    np.testing.assert_allclose(at(derivative(single), T), np.zeros((15, 3)))


def test_keys_from_the_language():
    k = node("keys cubic { 0 s: 0, 1 s: 2, 3 s: 1 }")
    assert k == keys("cubic")
    assert node("keys { 0 s: (0, 0, 0) m, 500 ms: (1, 0, 0) m }") == \
        E.Keys("linear", (0.0, 0.5), ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)))


# -- the time derivative ----------------------------------------------------------------------------------

DERIVATIVE_CASES = [
    "sin(u)", "u * u * u", "sin(u) * cos(2 * u)", "1 / (1 + u * u)", "u ^ 3", "(1 + u) ^ 2.5", "exp(sin(u))",
    "sqrt(1 + u * u)", "log(2 + cos(u))", "tan(u / 3)", "sin(u) / (2 + cos(u))", "-u * exp(-u)",
    "cos(sin(cos(u)))", "(sin(u), u ^ 2, 1)", "3 * (u, 1, -u) - (1, 1, 1) * u", "2 ^ u", "u ^ u",
    "abs(u - 1.5)", "smoothstep(0, 4, u)", "atan2(u, 2)", "keys cubic { 0 s: 0, 1 s: 2, 3 s: 1 }",
]


@pytest.mark.parametrize("text", DERIVATIVE_CASES)
def test_derivative_matches_central_differences(text):
    f = node(text)
    h = 1e-6
    # f'(t) ~ (f(t + h) - f(t - h)) / 2h
    numeric = (at(f, T + h) - at(f, T - h)) / (2 * h)
    np.testing.assert_allclose(at(derivative(f), T), numeric, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("text", ["sin(u) * u", "1 / (1 + u * u)", "(u ^ 3, exp(-u), 0)", "sqrt(1 + u * u)"])
def test_second_derivative_matches_central_differences(text):
    f = node(text)
    h = 1e-4
    # f''(t) ~ (f(t + h) - 2 f(t) + f(t - h)) / h^2
    numeric = (at(f, T + h) - 2 * at(f, T) + at(f, T - h)) / (h * h)
    np.testing.assert_allclose(at(derivative(derivative(f)), T), numeric, rtol=1e-4, atol=1e-4)


def test_derivative_is_exact_where_it_can_be():
    assert derivative(E.Const(2.0)) == E.Const(0.0)
    assert derivative(E.Const((1.0, 2.0, 3.0))) == E.Const((0.0, 0.0, 0.0))
    assert derivative(t) == E.Const(1.0)
    assert derivative(node("3 * u")) == E.Const(3.0)
    assert derivative(node("sin(u)")) == E.Call("cos", (t,))
    assert not any(isinstance(n, E.Deriv) for n in _walk(derivative(node("sin(u) / (1 + u ^ 2)"))))
    assert isinstance(derivative(node("abs(u)")), E.Deriv)  # no closed form: numeric
    assert derivative(E.Deriv(t, 1)) == E.Deriv(t, 2)


def _walk(n):
    yield n
    for child in E._children(n):
        yield from _walk(child)


# -- folding ----------------------------------------------------------------------------------------------

def test_constants_fold_as_the_tree_is_built():
    assert E.add(E.Const(1.0), E.Const(2.0)) == E.Const(3.0)
    assert E.mul(t, E.Const(0.0)) == E.Const(0.0)
    assert E.mul(E.Const(1.0), t) is t
    assert E.add(E.Const(0.0), t) is t
    assert E.sub(t, E.Const(0.0)) is t
    assert E.neg(E.Const(2.0)) == E.Const(-2.0)
    assert E.fold(E.Call("sin", (E.Const(0.0),))) == E.Const(0.0)
    assert E.fold(E.Vec((E.Const(1.0), E.Const(2.0)))) == E.Const((1.0, 2.0))
    assert E.mul(E.Const((1.0, 2.0, 3.0)), E.Const(0.0)) == E.Const((0.0, 0.0, 0.0))


def test_folding_leaves_time_and_signals_alone():
    assert node("2 * pi * 3") == E.Const(6 * math.pi)
    assert node("sin(pi / 2) * u") == t
    assert node("(1, 2, 3) * 2 + (u, 0, 0)") == E.Op("add", (E.Const((2.0, 4.0, 6.0)), E.Vec((t, E.Const(0.0),
                                                                                             E.Const(0.0)))))
    envelope = E.Call("envelope", (E.Str("b.wav"),))
    assert E.fold(E.Op("mul", (envelope, E.Const(2.0)))) == E.Op("mul", (envelope, E.Const(2.0)))
    assert E.free_vars(node("sin(u) + u * 2")) == {"t"}
    assert E.is_constant(node("e * tau"))


def test_static_sizes():
    assert E.size_of(node("u")) == 0
    assert E.size_of(node("(u, 1, 2)")) == 3
    assert E.size_of(node("length((u, 1, 2))")) == 0
    assert E.size_of(node("euler(u, 0, 0)")) == 4
    assert E.size_of(node("u * (1, 2)")) == 2


# -- JSON -------------------------------------------------------------------------------------------------

FINITE = st.floats(allow_nan=False, allow_infinity=False, width=64)
LEAVES = st.one_of(
    FINITE.map(E.Const),
    st.tuples(FINITE, FINITE, FINITE).map(E.Const),
    st.just(t),
    st.sampled_from(["breath.wav", "bar", ""]).map(E.Str),
    st.builds(lambda v: E.Keys("cubic", (0.0, 1.0), ((v, 0.0, 1.0), (1.0, v, 0.0)), 1), FINITE),
)


def _branches(children):
    return st.one_of(
        st.builds(lambda op, a, b: E.Op(op, (a, b)), st.sampled_from(["add", "sub", "mul", "div", "pow"]),
                  children, children),
        children.map(lambda a: E.Op("neg", (a,))),
        st.builds(lambda fn, args: E.Call(fn, tuple(args)), st.sampled_from(["sin", "min", "clamp", "modal"]),
                  st.lists(children, max_size=3)),
        st.builds(lambda a, b: E.Call("envelope", (a,), (("gain", b),)), children, children),
        st.lists(children, min_size=2, max_size=4).map(lambda items: E.Vec(tuple(items))),
        children.map(lambda a: E.Deriv(a, 2)),
    )


EXPRESSIONS = st.recursive(LEAVES, _branches, max_leaves=12)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(EXPRESSIONS)
def test_json_round_trip(expression):
    data = json.loads(json.dumps(to_json(expression), allow_nan=False))
    assert from_json(data) == expression


def test_json_forms():
    assert to_json(E.Const(2.0)) == 2.0
    assert to_json(E.Const(((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)))) == [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    assert to_json(node("sin(u)")) == {"call": "sin", "args": [{"var": "t"}]}
    assert to_json(keys("step")) == {"keys": "step", "times": [0.0, 1.0, 3.0], "values": [0.0, 2.0, 1.0],
                                       "order": 0}
    with pytest.raises(ValueError):
        from_json({"what": 1})
