"""The values of a scene's `let`s, evaluated by the front end's expression lowering (isaac_lang.lower_expr), and
quantities written back in SI units (`let arm = 80 cm` -> `0.8 m`).

A `let` is evaluated with the `let`s declared before it in its scope and the scopes around it, in the order the
expander binds them. One inside a part or a loop depends on values only an instance or an iteration gives: it
has no value of its own (`None`), and a hover shows its expression instead.
"""
from __future__ import annotations

import math

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_ir.diagnostics import Reporter, SceneError
from isaac_lang.lower_expr import CONTEXTS, ExprLowerer, Scope, Typed

from .index import SceneIndex

# the SI unit written for each dimension: the front end's example unit when it is SI (m/s2, N*m, kg*m2), else a
# named unit of factor 1 (Pa, Hz, J), else a product of base units (unit_of)
SI_NAMES = {dim: unit for dim, unit in U.EXAMPLE_UNIT.items() if U.parse_unit(unit)[0] == 1.0}
SI_NAMES.update({dim: name for name, (factor, dim) in reversed(list(U.UNITS.items()))
                 if factor == 1.0 and name != "dB" and dim not in SI_NAMES})


def let_values(index: SceneIndex) -> dict:
    """Definition id -> Typed for every `let` that has a value of its own (those outside parts and loops)."""
    values: dict = {}
    scope = Scope()
    lets = sorted((d for d in index.definitions if d.kind == "let" and not d.scope), key=lambda d: d.order)
    for definition in lets:
        typed = evaluate(definition.tree.children[1], scope)
        if typed is not None:
            scope.values[definition.name] = typed
            values[id(definition)] = typed
    return values


def evaluate(value_tree, scope: Scope) -> Typed | None:
    """The value of an expression's tree in a scope; None when it cannot be computed there (an error, a name it
    lacks)."""
    try:
        return ExprLowerer("<hover>", Reporter()).lower(value_tree, scope, CONTEXTS[True, True])
    except (SceneError, ArithmeticError, ValueError, TypeError):
        return None


def format_typed(typed: Typed) -> str:
    """A value in SI with its unit: `0.8 m`, `(0, -9.81, 0) m/s2`, `0.5236 rad (30 deg)`, `2 + t` for an
    expression of time."""
    node = typed.node
    if isinstance(node, E.Str):
        return f'"{node.value}"'
    if not isinstance(node, E.Const):
        return _expression_text(node) + _unit_suffix(typed.dim)
    text = format_number(node.value) + _unit_suffix(typed.dim)
    if typed.dim == U.ANGLE and not isinstance(node.value, tuple):
        text += f" ({format_number(math.degrees(node.value))} deg)"
    return text


def format_number(value) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(format_number(v) for v in value) + ")"
    if isinstance(value, float) and value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return f"{value:.6g}"


def unit_of(dim) -> str:
    """The SI unit of a dimension (`m`, `kg*m2`, `N`); '' for a plain number."""
    if dim is None or dim == U.DIMENSIONLESS:
        return ""
    return SI_NAMES.get(dim) or U.format_dim(dim)


def _unit_suffix(dim) -> str:
    unit = unit_of(dim)
    return f" {unit}" if unit else ""


def _expression_text(node) -> str:
    """An expression of t (a kinematic path, a changing speed) in the front end's readable form."""
    from isaac_ir.expr import render

    return render(node)
