"""Reading a `{ name value ... }` block against the vocabulary of what may stand in it."""
from __future__ import annotations

import math

from lark import Token, Tree

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_ir.diagnostics import did_you_mean
from isaac_lang.lower_expr import CONTEXTS, ExprContext, ExprLowerer, Scope, Typed, range_ends

TRUE_WORDS = {"on", "true", "yes"}
FALSE_WORDS = {"off", "false", "no"}


class Props:
    """The properties of one block. `vocabulary` maps each allowed name to what it means (for hints/docs)."""

    def __init__(self, block: Tree | None, vocabulary: dict, what: str, lowerer: ExprLowerer, scope: Scope,
                 items=None, keywords=()):
        self.keywords = keywords  # declaration keywords a misspelled name may have meant
        self.what = what
        self.lowerer = lowerer
        self.scope = scope
        self.vocabulary = vocabulary
        self.entries: dict[str, tuple] = {}
        self.owner = block
        children = items if items is not None else (block.children if block is not None else [])
        for prop in children:
            self._add(prop)

    def _add(self, prop: Tree) -> None:
        key_tree, value = prop.children
        key = key_tree.children[0] if isinstance(key_tree, Tree) else key_tree
        name = str(key)
        if name not in self.vocabulary:
            hint = (did_you_mean(name, list(self.vocabulary) + list(self.keywords))
                    or "allowed here: " + ", ".join(sorted(self.vocabulary)))
            if any(hint == f"did you mean `{word}`?" for word in self.keywords):  # `bdy bob sphere { ... }`
                raise self.lowerer.fail(f"`{name}` is not a keyword", key, hint)
            raise self.lowerer.fail(f"unknown property `{name}` in {self.what}", key, hint)
        if name in self.entries:
            raise self.lowerer.fail(f"`{name}` is given twice in {self.what}", key)
        self.entries[name] = (value, key)

    def has(self, name: str) -> bool:
        return name in self.entries

    def node(self, name: str):
        return self.entries[name][0]

    def key(self, name: str):
        return self.entries[name][1]

    def typed(self, name: str, ctx: ExprContext | None = None) -> Typed:
        value = self.node(name)
        if isinstance(value, Tree) and value.data in ("block", "range"):
            raise self.lowerer.fail(f"`{name}` takes a single value here", self.key(name))
        return self.lowerer.lower(value, self.scope, ctx or CONTEXTS[False, False])

    # -- typed getters ------------------------------------------------------------------------------------

    def scalar(self, name: str, dim, default=None, *, bare_ok=False, time=False, signals=False, minimum=None):
        """A number in SI; with time=True the result may be an expression of t (else a float).

        minimum: a constant must be finite and at least this (the hint says what the bound means)."""
        if name not in self.entries:
            return default
        value = self.typed(name, CONTEXTS[time, signals])
        node = self.lowerer.coerce(value, dim, f"`{name}`", self.node(name), 0, bare_ok)
        if time or signals:
            return node
        constant = self._constant(node, name)
        if minimum is not None and not minimum[0] <= constant < math.inf:
            raise self.lowerer.fail(f"`{name}` must be a number of at least {minimum[0]:g}", self.node(name),
                                    minimum[1])
        return constant

    def vector(self, name: str, dim, default=None, *, size=3, time=False):
        if name not in self.entries:
            return default
        value = self.typed(name, CONTEXTS[time, False])
        node = self.lowerer.coerce(value, dim, f"`{name}`", self.node(name), size)
        if time:
            return node
        return self._constant(node, name)

    def _constant(self, node: E.Expr, name: str):
        if not isinstance(node, E.Const):
            raise self.lowerer.fail(f"`{name}` must be constant here (it cannot depend on t)", self.node(name))
        return node.value

    def word(self, name: str, choices, default=None) -> str | None:
        if name not in self.entries:
            return default
        value = self.node(name)
        text = _bare_name(value)
        if text is None and not choices:
            raise self.lowerer.fail(f"`{name}` takes a name", value)
        if text is None or (choices and text not in choices):
            raise self.lowerer.fail(f"`{name}` must be one of: {', '.join(choices)}", value,
                                    did_you_mean(text or "", choices) if text else None)
        return text

    def boolean(self, name: str, default: bool) -> bool:
        if name not in self.entries:
            return default
        text = _bare_name(self.node(name))
        if text in TRUE_WORDS:
            return True
        if text in FALSE_WORDS:
            return False
        raise self.lowerer.fail(f"`{name}` is on or off", self.node(name))

    def integer(self, name: str, default: int, minimum: int = 0) -> int:
        if name not in self.entries:
            return default
        value = self.scalar(name, U.DIMENSIONLESS)
        if value != int(value) or value < minimum:
            raise self.lowerer.fail(f"`{name}` must be a whole number of at least {minimum}", self.node(name))
        return int(value)

    def string(self, name: str, default=None) -> str | None:
        if name not in self.entries:
            return default
        value = self.typed(name)
        if not isinstance(value.node, E.Str):
            raise self.lowerer.fail(f"`{name}` takes a quoted file name", self.node(name))
        return value.node.value

    def range(self, name: str, dim):
        """`name a .. b` -> (a, b) as constants in SI."""
        if name not in self.entries:
            return None
        value = self.node(name)
        if not (isinstance(value, Tree) and value.data == "range"):
            raise self.lowerer.fail(f"`{name}` takes a range: `{name} START .. END`", value)
        typed_ends = range_ends(self.lowerer, value.children, self.scope, CONTEXTS[False, False])
        return tuple(self.lowerer.constant(typed, dim, f"`{name}`", tree)
                     for typed, tree in zip(typed_ends, value.children))

    def block(self, name: str, vocabulary: dict, what: str) -> "Props":
        if name not in self.entries:
            return Props(None, vocabulary, what, self.lowerer, self.scope)
        value = self.node(name)
        if not (isinstance(value, Tree) and value.data == "block"):
            raise self.lowerer.fail(f"`{name}` takes a block: `{name} {{ ... }}`", value)
        return Props(value, vocabulary, what, self.lowerer, self.scope)


def _bare_name(tree) -> str | None:
    if isinstance(tree, Tree) and tree.data == "name_ref" and len(tree.children) == 1:
        return str(tree.children[0])
    return None
