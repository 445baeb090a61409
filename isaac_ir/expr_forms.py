"""Expressions written out as the canonical JSON of the IR (`to_json`, `from_json`). The short readable form of
diagnostics (`render`: `1 / (t - 0.1) * 2`) is isaac_ir.expr's own."""
from __future__ import annotations

from isaac_ir.expr import Call, Const, Deriv, Expr, Keys, Op, Str, Var, Vec

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
