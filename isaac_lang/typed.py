"""A lowered value: an expression tree with its dimension, what every lowering step hands the next."""

from __future__ import annotations

from dataclasses import dataclass

from isaac_ir import expr as E


@dataclass(frozen=True)
class Typed:
    """An expression with its dimension (a diagnostic about it points at the parse tree it came from)."""

    node: E.Expr
    dim: tuple | None

    @property
    def size(self) -> int:
        node = self.node
        if type(node) is E.Const:  # most values: answered without hashing the node for size_of's cache
            return len(node.value) if type(node.value) is tuple else 0
        return E.size_of(node)
