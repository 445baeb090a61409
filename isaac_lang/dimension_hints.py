"""Hints for values of two dimensions where one is due: `h + 2 s`, `min(1 m, 2 s)`, `(1 m, 2 s, 0 m)`.

The hint says what must agree and, when one side is a number written with its unit, the same number in the
unit of the other side (`did you mean `2 m`?`).
"""
from __future__ import annotations

from lark import Token, Tree

from isaac_ir import units as U

OPERATION_WORDS = {"add": "add", "sub": "subtract"}


def sum_mismatch(operation: str, left_dim, right_dim, left_tree, right_tree) -> tuple:
    """(message, hint) for `left + right` or `left - right` of two dimensions."""
    left, right = U.describe(left_dim), U.describe(right_dim)
    if operation == "sub":
        message = f"cannot subtract {right} from {left}"
    else:
        message = f"cannot add {left} and {right}"
    symbol = "-" if operation == "sub" else "+"
    agree = f"both sides of `{symbol}` must have the same dimension: here {left} and {right}"
    return message, agree + _suggestion((left_tree, left_dim), (right_tree, right_dim))


def arguments_mismatch(fn: str, first_dim, other_dim, first_tree, other_tree) -> tuple:
    """(message, hint) for a function whose arguments must share one dimension (min, max, clamp, lerp...)."""
    first, other = U.describe(first_dim), U.describe(other_dim)
    message = f"`{fn}`: cannot mix {first} and {other}"
    agree = f"the arguments of `{fn}` must have the same dimension: here {first} and {other}"
    return message, agree + _suggestion((first_tree, first_dim), (other_tree, other_dim))


def components_mismatch(first_dim, other_dim, first_tree, other_tree, what: str = "components of a vector") -> str:
    """The hint for the items of a vector (or of a keyframe table) of two dimensions."""
    first, other = U.describe(first_dim), U.describe(other_dim)
    agree = f"the {what} must have the same dimension: here {first} and {other}"
    return agree + _suggestion((first_tree, first_dim), (other_tree, other_dim))


def _suggestion(first: tuple, second: tuple) -> str:
    """`; did you mean `2 m`?` when the second side (else the first) is a number with its unit, rewritten in a
    unit of the other side's dimension; else a reminder of what each named value is. Each side: (tree, dim)."""
    for (tree, _), (_, other_dim) in ((second, first), (first, second)):
        rewritten = _rewritten(tree, other_dim)
        if rewritten:
            return f"; did you mean `{rewritten}`?"
    names = [f"`{_name(tree)}` is {U.describe(dim)}" for tree, dim in (first, second) if _name(tree)]
    return "; check the unit of each side" + (f" ({', '.join(names)})" if names else "")


def _rewritten(tree, dim) -> str | None:
    """`2 m` for the tree of `2 s` and a length: the number the user wrote, in a unit of the other dimension."""
    if dim is None or not isinstance(tree, Tree) or tree.data != "quantity":
        return None
    number = tree.children[0]
    if not isinstance(number, Token) or number.type != "NUMBER":
        return None
    unit = U.EXAMPLE_UNIT.get(dim, U.format_dim(dim))
    return f"{number} {unit}"


def _name(tree) -> str | None:
    if isinstance(tree, Tree) and tree.data == "name_ref" and len(tree.children) == 1:
        return str(tree.children[0])
    return None
