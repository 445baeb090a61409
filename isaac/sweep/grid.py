"""Sweep stage 1, the grid: `--set NAME=...` specifications -> the list of variants (NAME -> value text).

    theta0=10deg,45deg,90deg          a list: these values
    theta0=10deg..120deg/30           a range: 30 values, both ends included (evenly spaced)
    theta0=10deg..120deg              a range to draw from (--random N: uniform between the ends)

Several `--set`s make the product of their lists, in the order given (the first varies slowest). With
`--random N --seed S` there are N variants instead, each drawing every parameter: a range uniformly, a list by
picking one of its values. Every value stays text of the language (`13.793103448275861 deg`), so a variant is
exactly what `isaac run --set NAME=VALUE` would run; `si_value` gives its number in SI units for the table.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass

from lark.exceptions import UnexpectedInput

from isaac_ir.diagnostics import Diagnostic, Reporter, SceneError
from isaac_lang.overrides import clipped, set_problem

# a range `A..B` or `A..B/N`: N is a whole number after the last slash (so B itself cannot end in `/integer`)
# the most variants one sweep may run (docs/budgets.md): at a second each, almost three hours on one core; a
# count above it is refused before anything is expanded or started
MAX_VARIANTS = 10_000
_RANGE = re.compile(r"^(?P<low>.+?)\.\.(?P<high>.+?)(?:/\s*(?P<count>\d+))?\s*$")
# a number and an optional unit, as a range's end is usually written (`10deg`, `2.5 m`, `-3`)
_QUANTITY = re.compile(r"^\s*(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>[A-Za-z][\w/]*)?\s*$")


@dataclass(frozen=True)
class Axis:
    """One `--set`: a parameter and its values (a list), or the ends of a range to draw from (random sweeps)."""

    name: str
    values: tuple = ()  # value texts, in order
    low: str | None = None  # a range without a count: its ends (texts), drawn from by --random
    high: str | None = None

    @property
    def continuous(self) -> bool:
        return self.low is not None


def usage(message: str, hint: str | None = None) -> SceneError:
    """A problem on the command line (exit 2), printed like any diagnostic."""
    return SceneError([Diagnostic(message, None, hint)])


def parse_axis(item: str) -> Axis:
    """`NAME=V1,V2,...`, `NAME=A..B/N` or `NAME=A..B` -> an Axis (values checked as expressions)."""
    name, sep, spec = item.partition("=")
    name = name.strip()
    if not sep or not name or not spec.strip():
        raise usage(f"--set wants NAME=V1,V2,... or NAME=A..B/N, got `{clipped(item)}`",
                    "e.g. --set theta0=10deg,45deg,90deg or --set theta0=10deg..120deg/30")
    problem = set_problem(name, "")  # the values are checked one by one below
    if problem is not None:
        raise usage(f"--set: {problem}", "parameters are the scene's top-level `let`s")
    items = split_top_level(spec)
    if len(items) == 1:
        match = _RANGE.match(items[0])
        if match and match["count"] is None:
            si_range(name, match["low"], match["high"])  # checked now, drawn later
            return Axis(name, low=match["low"].strip(), high=match["high"].strip())
    values = []
    for text in items:
        values.extend(_expand_item(name, text))
    return Axis(name, tuple(values))


def _expand_item(name: str, text: str) -> list:
    """One comma-separated item: a value, or `A..B/N` (N values)."""
    match = _RANGE.match(text)
    if match is None:
        si_value(text, name)  # a syntax error in a value is the command line's, reported now
        return [text]
    if match["count"] is None:
        raise usage(f"--set {name}: `{text}` is a range without a count inside a list",
                    "give the number of values, e.g. 10deg..120deg/30 (or use a lone range with --random N)")
    count = int(match["count"])
    if count < 1:
        raise usage(f"--set {name}: `{text}` asks for {count} values", "the count after `/` is at least 1")
    check_variant_count(count, f"--set {name}: `{text}`")
    low, high, unit, scale = si_range(name, match["low"], match["high"])
    import numpy as np

    return [format_value(v, unit) for v in np.linspace(low / scale, high / scale, count)]


def split_top_level(spec: str) -> list:
    """Split at commas outside brackets (a vector value `(0, 1, 0)` stays one value)."""
    items, depth, start = [], 0, 0
    for k, char in enumerate(spec):
        if char in "([":
            depth += 1
        elif char in ")]":
            depth -= 1
        if char == "," and depth == 0:
            items.append(spec[start:k])
            start = k + 1
    items.append(spec[start:])
    items = [item.strip() for item in items]
    if any(not item for item in items):
        raise usage(f"--set: an empty value in `{spec}`", "separate the values with single commas")
    return items


def si_value(text: str, name: str = "") -> float | None:
    """The value of an expression in SI units, or None when it is not a plain number (a vector, a call of t);
    a syntax error in it is a usage error."""
    return _lowered(text, name)[0]


def _lowered(text: str, name: str) -> tuple:
    """(SI value or None, dimension or None: a bare number) of a value as the language reads it."""
    from isaac_ir.expr import Const
    from isaac_lang.lower_expr import ExprContext, ExprLowerer, Scope
    from isaac_lang.syntax import parse_expression

    label = f"--set {name}"
    try:
        tree = parse_expression(text)
    except UnexpectedInput:
        raise usage(f"--set {name}: `{text}` is not a value of the language",
                    "write a number with its unit, e.g. 10deg or 2.5 m") from None
    try:
        typed = ExprLowerer(label, Reporter()).lower(tree, Scope(), ExprContext())
    except SceneError as error:
        raise usage(f"--set {name}: `{text}`: {error}") from None
    value = typed.node.value if type(typed.node) is Const else None
    return (float(value) if isinstance(value, (int, float)) else None), typed.dim


def si_range(name: str, low_text: str, high_text: str) -> tuple:
    """(low, high) in SI, the unit the values are written in, and its SI factor: the unit of the low end
    (`10deg..120deg` -> degrees), or the high end's when the low end is written without one."""
    (low, low_dim), (high, high_dim) = _lowered(low_text, name), _lowered(high_text, name)
    if low is None or high is None:
        raise usage(f"--set {name}: the ends of `{low_text}..{high_text}` must be plain numbers",
                    "e.g. 10deg..120deg/30")
    if low_dim is not None and high_dim is not None and low_dim != high_dim:
        raise usage(f"--set {name}: the ends of `{low_text}..{high_text}` are not the same kind of quantity",
                    "give both ends in units of one kind, e.g. 10deg..2rad/5")
    for text in (low_text, high_text):
        match = _QUANTITY.match(text)
        if match and match["unit"]:
            return low, high, match["unit"], si_value(f"1 {match['unit']}", name)
    if _QUANTITY.match(low_text) and _QUANTITY.match(high_text):
        return low, high, "", 1.0
    raise usage(f"--set {name}: write the ends of `{low_text}..{high_text}` as a number and a unit",
                "e.g. 10deg..120deg/30 or 0.5m..2m/4")


def format_value(number: float, unit: str) -> str:
    """A value as text of the language that reads back to the same float (repr round-trips)."""
    number = float(number)
    return f"{number!r} {unit}" if unit else repr(number)


def check_variant_count(count: int, what: str) -> None:
    """A sweep's size bounded before its variants are made (a product of three lists of 1000 is 10^9)."""
    if count > MAX_VARIANTS:
        raise usage(f"{what} make {count:,} variants, more than the {MAX_VARIANTS:,} a sweep may run",
                    "sweep fewer values, or split the sweep into several with --out of their own")


def product(axes: list) -> list:
    """Every combination of the axes' values: a list of {name: text}, the first axis varying slowest."""
    for axis in axes:
        if axis.continuous:
            raise usage(f"--set {axis.name}: the range `{axis.low}..{axis.high}` needs a count",
                        f"e.g. {axis.name}={axis.low}..{axis.high}/10, or draw from it with --random N --seed S")
    check_variant_count(math.prod(len(axis.values) for axis in axes), "the --set values")
    names = [axis.name for axis in axes]
    return [dict(zip(names, combo)) for combo in itertools.product(*(axis.values for axis in axes))]


def draws(axes: list, count: int, seed: int) -> list:
    """`count` random variants, each drawing every axis in order from one generator seeded with `seed`
    (the same seed, the same variants, on any machine)."""
    import numpy as np

    if count < 1:
        raise usage(f"--random {count}: the number of draws is at least 1")
    check_variant_count(count, f"--random {count}")
    rng = np.random.default_rng(seed)
    ranges = {axis.name: si_range(axis.name, axis.low, axis.high) for axis in axes if axis.continuous}
    variants = []
    for _ in range(count):
        variant = {}
        for axis in axes:
            if axis.continuous:
                low, high, unit, scale = ranges[axis.name]
                variant[axis.name] = format_value(rng.uniform(low / scale, high / scale), unit)
            else:
                variant[axis.name] = axis.values[int(rng.integers(len(axis.values)))]
        variants.append(variant)
    return variants


def variants_of(grid) -> list:
    """The Python API's grid -> variants: {name: [values]} (a product; a value may be a number or text, a
    string may be a `--set` spec such as "10deg..120deg/30") or a list of {name: value} (those variants)."""
    if isinstance(grid, dict):
        axes = []
        for name, values in grid.items():
            if isinstance(values, str):
                axes.append(parse_axis(f"{name}={values}"))
            else:
                axes.append(Axis(name, tuple(_text(v, name) for v in values)))
        return product(axes)
    return [{name: _text(value, name) for name, value in variant.items()} for variant in grid]


def _text(value, name: str) -> str:
    text = value if isinstance(value, str) else repr(float(value))
    si_value(text, name)
    return text
