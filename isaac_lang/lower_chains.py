"""Lowering of operator chains by loops, not by recursion: `a + b - c + ...`, `a * b / c ...`, `- - x`, `a ^ b ^ c`.

The parse of a sum of n terms is a tree n levels deep (`+` is left-associative), and so is a tower of powers
(right-associative) or n unary minuses. Lowering walks such a chain's spine with a loop, so that a 10,000-term
sum is no deeper for Python than one term; the checks (units, vector sizes) and the folding of constants happen
term by term, in the order written, each error at the part of the chain it is about, as a recursive walk would.

The expression a chain lowers to stays shallow too: as long as the partial result is a constant, each term folds
into it (exactly the written order of operations); once it is not, a chain with more than BALANCED_FROM terms
left is built as a balanced tree of those terms (a + (b + c) + ...: the same sum, rounded differently, log2(n)
deep), so that evaluating it, differentiating it and printing it as JSON never recurse n levels either.
"""
from __future__ import annotations

import math

from lark import Tree

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_lang.dimension_hints import sum_mismatch
from isaac_lang.typed import Typed

# terms left in a chain from which its expression is built balanced rather than leaning left
BALANCED_FROM = 32
# the highest tower of powers that are not constants (a^b^c...: each power one level deeper, as the runtime
# evaluates it; lower_expr.MAX_EXPR_DEPTH bounds the whole expression)
MAX_TOWER = 64


def lower_sum(lowerer, tree, scope, ctx):
    """`a + b - c ...` (a chain of `add` and `sub`)."""
    spine = _left_spine(tree, ("add", "sub"))
    first = lowerer.lower(spine[-1].children[0], scope, ctx)
    dim, size, terms = first.dim, first.size, []
    for node in reversed(spine):  # from the innermost (leftmost) operation out
        term = lowerer.lower(node.children[1], scope, ctx)
        try:
            dim = U.unify(dim, term.dim)
        except U.UnitError:
            message, hint = sum_mismatch(node.data, dim, term.dim, node.children[0], node.children[1])
            raise lowerer.fail(message, node, hint) from None
        if size and term.size and size != term.size:
            raise lowerer.fail(f"cannot combine a {size}-vector and a {term.size}-vector", node)
        size = size or term.size
        terms.append((node, node.data == "sub", term.node))
    build = {False: E.add, True: E.sub}
    return _typed(lowerer, _fold_chain(lowerer, first.node, terms, build, E.add, tree), dim)


def lower_product(lowerer, tree, scope, ctx):
    """`a * b / c ...` (a chain of `mul` and `div`)."""
    spine = _left_spine(tree, ("mul", "div"))
    first = lowerer.lower(spine[-1].children[0], scope, ctx)
    dim, size, terms = first.dim, first.size, []
    for node in reversed(spine):
        term = lowerer.lower(node.children[1], scope, ctx)
        divide = node.data == "div"
        if divide and term.size:
            raise lowerer.fail("cannot divide by a vector", node)
        if not divide and size and term.size:
            raise lowerer.fail("cannot multiply two vectors with `*`", node, "use dot(a, b) or cross(a, b)")
        dim = U.combine(dim, term.dim, -1 if divide else +1)
        size = size or term.size
        terms.append((node, divide, term.node))
    _check_divisors(lowerer, first.node, terms)
    build = {False: E.mul, True: _divide}
    return _typed(lowerer, _fold_chain(lowerer, first.node, terms, build, E.mul, tree), dim)


def _check_divisors(lowerer, first, terms: list) -> None:
    """A constant 0 divisor in a chain that varies (`t / 0 s`): not folded like `1 / 0`, it would divide by zero
    at every step of the run; refused at the divisor."""
    if all(type(node) is E.Const for node in [first] + [term for _, _, term in terms]):
        return  # folded now: the fold reports it as a value that cannot be computed
    for node, divide, term in terms:
        if divide and type(term) is E.Const and term.value == 0:
            raise lowerer.fail("this divides by zero", node.children[1], "the divisor is a constant 0: "
                               "is a unit or a `let` missing?")


def lower_negation(lowerer, tree, scope, ctx):
    """`- - ... x`: n minuses are one when n is odd, none when it is even (a negation is exact)."""
    count = 0
    while isinstance(tree, Tree) and tree.data == "neg":
        count, tree = count + 1, tree.children[0]
    value = lowerer.lower(tree, scope, ctx)
    return value if count % 2 == 0 else _typed(lowerer, E.neg(value.node), value.dim)


def lower_power(lowerer, tree, scope, ctx):
    """`a ^ b ^ c ...` (right-associative): the bases in the order written, then the powers from the right."""
    spine = [tree]
    while isinstance(spine[-1].children[1], Tree) and spine[-1].children[1].data == "pow":
        spine.append(spine[-1].children[1])
    bases = [lowerer.lower(node.children[0], scope, ctx) for node in spine]
    value = lowerer.lower(spine[-1].children[1], scope, ctx)
    varying = 0  # powers of powers that are not constants: each one level deeper
    for node, base in zip(reversed(spine), reversed(bases)):
        value = _power(lowerer, base, value, node)
        varying = 0 if type(value.node) is E.Const else varying + 1
        if varying > MAX_TOWER:
            raise lowerer.fail(f"this tower of powers is more than {MAX_TOWER} powers of powers high", node,
                               "the runtime evaluates expressions at most 100 operations deep")
    return value


def _power(lowerer, base, exponent, node):
    if exponent.dim not in (None, U.DIMENSIONLESS):
        raise lowerer.fail("an exponent must be a plain number", node.children[1])
    dim = base.dim
    if base.dim not in (None, U.DIMENSIONLESS):
        if not isinstance(exponent.node, E.Const):
            raise lowerer.fail("a quantity with a unit needs a constant exponent", node.children[1])
        try:
            dim = U.scale_dim(base.dim, exponent.node.value)
        except U.UnitError as error:
            raise lowerer.fail(str(error), node) from None
    folded = _checked(lowerer, lambda: E.fold(E.Op("pow", (base.node, exponent.node))), node)
    return _typed(lowerer, folded, dim)


def _fold_chain(lowerer, node, terms, build, join, tree):
    """The chain's expression: terms (spine node, inverse?, expression) applied to `node` in order while the
    result is a constant; the rest as a balanced tree when it is long (module docstring)."""
    k = 0
    while k < len(terms) and (type(node) is E.Const or len(terms) - k <= BALANCED_FROM):
        spine_node, inverse, term = terms[k]
        node = _checked(lowerer, lambda: build[inverse](node, term), spine_node)
        k += 1
    if k == len(terms):
        return node
    # node op (t1 op t2 ...) with the inverse terms gathered: a + (b + d) - (c + e), a * (b * d) / (c * e)
    forward = [term for _, inverse, term in terms[k:] if not inverse]
    backward = [term for _, inverse, term in terms[k:] if inverse]
    if forward:
        node = _checked(lowerer, lambda: join(node, _balanced(forward, join)), tree)
    if backward:
        node = _checked(lowerer, lambda: build[True](node, _balanced(backward, join)), tree)
    return node


def _balanced(items: list, join):
    """items[0] join items[1] join ... as a tree log2(n) deep (pairs, then pairs of pairs)."""
    while len(items) > 1:
        items = [join(items[i], items[i + 1]) if i + 1 < len(items) else items[i] for i in range(0, len(items), 2)]
    return items[0]


def _divide(a, b):
    return E.fold(E.Op("div", (a, b)))


def _checked(lowerer, build, node):
    """build(), with a constant that cannot be computed or is not finite reported at node."""
    try:
        value = build()
    except (ArithmeticError, ValueError) as error:  # 1/0, an overflow of ** ...
        raise lowerer.fail(f"this value cannot be computed ({error})", node) from None
    if type(value) is E.Const and not _finite(value.value):
        raise lowerer.fail("this value is not a finite number", node,
                           "check for a division by zero, log(0) or a number too large")
    return value


def _finite(value) -> bool:
    if isinstance(value, tuple):
        return all(_finite(v) for v in value)
    return not isinstance(value, float) or math.isfinite(value)


def _left_spine(tree, kinds) -> list:
    """The chain's operations from the outermost (the whole chain) in: each one's left child is the next."""
    spine = [tree]
    while isinstance(spine[-1].children[0], Tree) and spine[-1].children[0].data in kinds:
        spine.append(spine[-1].children[0])
    return spine


def _typed(lowerer, node, dim):
    return Typed(node, dim)
