"""The time derivative of an IR expression tree (expr.py), as a new tree: exact where the function has a closed form
(sums, products, quotients, constant powers, the chain rule of sin, cos, exp, log, sqrt and tan, keyframe tables one
order up), else a `Deriv` node that the evaluator takes by central differences."""
from __future__ import annotations

from isaac_ir.expr import (ONE, ZERO, Call, Const, Deriv, Expr, Guard, Keys, Op, Str, Var, Vec, zero_like, add,
                           free_vars, mul, neg, sub)


def derivative(node: Expr, var: str = "t") -> Expr:
    """d node / d var as a new tree (exact where the function has a closed form)."""
    if isinstance(node, (Const, Str)):
        return zero_like(node)
    if isinstance(node, Var):
        return ONE if node.name == var else ZERO
    if isinstance(node, Vec):
        return Vec(tuple(derivative(i, var) for i in node.items))
    if isinstance(node, Op):
        return _derivative_op(node, var)
    if isinstance(node, Keys):
        return Keys(node.interp, node.times, node.values, node.order + 1)
    if isinstance(node, Call) and node.fn in _CHAIN_RULES and var not in _kwarg_vars(node):
        inner = node.args[0]
        return mul(_CHAIN_RULES[node.fn](inner), derivative(inner, var))
    if isinstance(node, Deriv):
        return Deriv(node.arg, node.order + 1)
    if isinstance(node, Guard):
        return Guard(derivative(node.arg, var), f"the rate of {node.what}", node.source)
    if var not in free_vars(node) and not isinstance(node, Call):
        return zero_like(node)
    return Deriv(node, 1)


def _kwarg_vars(node: Call) -> frozenset:
    return frozenset().union(*(free_vars(v) for _, v in node.kwargs)) if node.kwargs else frozenset()


def _derivative_op(node: Op, var: str) -> Expr:
    if node.op == "neg":
        return neg(derivative(node.args[0], var))
    a, b = node.args
    da, db = derivative(a, var), derivative(b, var)
    if node.op == "add":
        return add(da, db)
    if node.op == "sub":
        return sub(da, db)
    if node.op == "mul":
        # (ab)' = a'b + ab'
        return add(mul(da, b), mul(a, db))
    if node.op == "div":
        # (a/b)' = (a'b - ab') / b^2
        return Op("div", (sub(mul(da, b), mul(a, db)), mul(b, b)))
    if node.op == "pow" and isinstance(b, Const):
        # (a^n)' = n a^(n-1) a'
        return mul(mul(b, Op("pow", (a, Const(b.value - 1.0)))), da)
    return Deriv(node, 1)


_CHAIN_RULES = {
    "sin": lambda u: Call("cos", (u,)),
    "cos": lambda u: neg(Call("sin", (u,))),
    "exp": lambda u: Call("exp", (u,)),
    "log": lambda u: Op("div", (ONE, u)),
    "sqrt": lambda u: Op("div", (Const(0.5), Call("sqrt", (u,)))),
    "tan": lambda u: Op("div", (ONE, mul(Call("cos", (u,)), Call("cos", (u,))))),
}
