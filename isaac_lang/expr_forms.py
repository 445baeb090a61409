"""Expressions written out: the canonical JSON of the IR (`to_json`, `from_json`) and a short readable form for
diagnostics (`render`: `1 / (t - 0.1) * 2`). Both are re-exported by isaac_lang.expr."""
from __future__ import annotations

from .expr import Call, Const, Deriv, Expr, Guard, Keys, Op, Str, Var, Vec

# ---- JSON --------------------------------------------------------------------------------------------------

def to_json(node: Expr):
    """Canonical JSON form: a constant is its plain value; anything else an object naming its kind."""
    if isinstance(node, Const):
        return _plain(node.value)
    if isinstance(node, Var):
        return {"var": node.name}
    if isinstance(node, Str):
        return {"str": node.value}
    if isinstance(node, Op):
        return {"op": node.op, "args": [to_json(a) for a in node.args]}
    if isinstance(node, Call):
        out = {"call": node.fn, "args": [to_json(a) for a in node.args]}
        if node.kwargs:
            out["kwargs"] = {k: to_json(v) for k, v in node.kwargs}
        return out
    if isinstance(node, Vec):
        return {"vec": [to_json(i) for i in node.items]}
    if isinstance(node, Keys):
        return {"keys": node.interp, "times": list(node.times), "values": [_plain(v) for v in node.values],
                "order": node.order}
    if isinstance(node, Deriv):
        return {"deriv": to_json(node.arg), "order": node.order}
    raise TypeError(type(node))


def _plain(value):
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def from_json(data) -> Expr:
    """Inverse of to_json (for reading ir.json back)."""
    if isinstance(data, (int, float)):
        return Const(float(data))
    if isinstance(data, list):
        return Const(_tuple(data))
    if "var" in data:
        return Var(data["var"])
    if "str" in data:
        return Str(data["str"])
    if "op" in data:
        return Op(data["op"], tuple(from_json(a) for a in data["args"]))
    if "call" in data:
        kwargs = tuple(sorted((k, from_json(v)) for k, v in data.get("kwargs", {}).items()))
        return Call(data["call"], tuple(from_json(a) for a in data["args"]), kwargs)
    if "vec" in data:
        return Vec(tuple(from_json(i) for i in data["vec"]))
    if "keys" in data:
        return Keys(data["keys"], tuple(data["times"]), tuple(_tuple(v) for v in data["values"]), data["order"])
    if "deriv" in data:
        return Deriv(from_json(data["deriv"]), data["order"])
    raise ValueError(f"not an expression: {data!r}")


def _tuple(value):
    if isinstance(value, list):
        return tuple(_tuple(v) for v in value)
    return float(value)


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
