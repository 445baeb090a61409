"""`--set NAME=VALUE` against the parameter it overrides: a bare number takes the unit the parameter was written
in, and a value of another kind of quantity is refused naming `--set NAME=VALUE`, not the scene's line."""
from __future__ import annotations

import re

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_ir.diagnostics import Reporter, SourcePos
from isaac_lang.lower_expr import written_unit
from isaac_lang.typed import Typed


# a parameter's name is a NAME of the grammar; longer than this it is not one a scene would write
MAX_SET_NAME = 64
# a value is a short expression (`2 m`, `0.5*pi`); a longer text is a mistake of the shell, not a value
MAX_SET_VALUE = 10_000
_PARAMETER_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
SET_POSITION = SourcePos("--set", 1, 1)


def clipped(text: str, most: int = 40) -> str:
    """A text typed on the command line, short enough to quote in a message."""
    return text if len(text) <= most else text[:most] + f"... ({len(text)} characters)"


def set_problem(name: str, text: str) -> str | None:
    """Why `--set NAME=VALUE` cannot be read at all (a name no parameter can have, a value far too long), or
    None. Checked before the value is parsed, for every path a --set takes (run, golden settings, sweep, fit)."""
    if len(name) > MAX_SET_NAME:
        return f"a parameter's name is at most {MAX_SET_NAME} characters: `{clipped(name)}`"
    if not _PARAMETER_NAME.fullmatch(name):
        return f"`{clipped(name)}` is not a parameter's name (letters, digits and `_`, not starting with a digit)"
    if len(text) > MAX_SET_VALUE:
        return f"the value of `{name}` is {len(text)} characters long, more than the {MAX_SET_VALUE} a value may have"
    return None


def set_label(name: str, text: str) -> str:
    """How a `--set` is named in its diagnostics: as it was typed."""
    return f"--set {name}={text}"


def override_in_unit_written(name: str, given: Typed, written: Typed, written_tree, lowerer, text: str,
                             reporter: Reporter) -> Typed:
    """The value of `--set NAME=VALUE` for the parameter written `let NAME = written`."""
    label = set_label(name, text)
    where = lowerer.pos(written_tree)
    said = f"`{name}` is {_kind_of(written)} (written at {where})" if where else f"`{name}` is {_kind_of(written)}"
    if given.size != written.size:
        raise _refuse(reporter, label, text, f"`{label}` gives {_shape(given)}, but {said}",
                      f"give {_shape(written)}, as the scene does")
    if given.dim is None:
        return _bare_override(name, given, written, written_tree, label, text, said, reporter)
    if written.dim is None or written.dim == U.DIMENSIONLESS:
        if given.dim in (U.DIMENSIONLESS, U.ANGLE) and written.dim is None or given.dim == written.dim:
            return given
        raise _refuse(reporter, label, text, f"`{label}` gives {U.describe(given.dim)}, but {said}",
                      f"drop the unit: `--set {name}={_number_part(text)}`")
    if U.without_angle(given.dim) == U.without_angle(written.dim):
        return given
    unit = written_unit(written_tree) or U.EXAMPLE_UNIT.get(written.dim, U.format_dim(written.dim))
    raise _refuse(reporter, label, text, f"`{label}` gives {U.describe(given.dim)}, but {said}",
                  f"give it in a unit of {U.describe(written.dim)}, e.g. `--set {name}={_number_part(text)}{unit}`")


def _bare_override(name, given, written, written_tree, label, text, said, reporter) -> Typed:
    """A number without a unit: read in the unit the parameter was written in, if it was written in one."""
    if written.dim is None or written.dim == U.DIMENSIONLESS:
        return given
    unit = written_unit(written_tree)
    if unit is not None:
        factor, dim = U.parse_unit(unit)
        return Typed(E.fold(E.mul(given.node, E.Const(factor))), dim)
    example = U.EXAMPLE_UNIT.get(written.dim, U.format_dim(written.dim))
    raise _refuse(reporter, label, text, f"`{label}` has no unit, but {said}, and the scene writes no single unit "
                  "for it to take", f"write the unit, e.g. `--set {name}={text}{example}`")


def _kind_of(value: Typed) -> str:
    return "a plain number" if value.dim is None else U.describe(value.dim)


def _shape(value: Typed) -> str:
    return f"a {value.size}-vector" if value.size else "a single number"


def _number_part(text: str) -> str:
    """`30m` -> `30`: the number of a value as typed, for a hint."""
    head = text.strip()
    while head and (head[-1].isalpha() or head[-1] in "*/^ "):
        head = head[:-1]
    return head or "1"


def _refuse(reporter: Reporter, label: str, text: str, message: str, hint: str):
    return reporter.fatal(message, SourcePos(label, 1, 1, max(1, len(text))), hint)
