"""What may be typed at a place, read from the text before it (which, while typing, seldom parses): the block the
place is in, and the word before it.

    at the top, in `scene { }`, a `part` or a `for`   keywords and scene settings
    in a block (`body b sphere { | }`)                its properties (the checker's table), and names in scope
    after a number (`radius 5 |`)                     units, then the block's properties
    after a key (`material |`, `radius |`)            names in scope (materials after `material`)
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_lang import vocabulary
from isaac_lang.syntax import KEYWORDS

from .index import DECLARATION_TABLES, NESTED_TABLES

# what each kind of item suggests, as LSP's CompletionItemKind numbers name them
KEYWORD, PROPERTY, UNIT, VALUE, FUNCTION = "keyword", "property", "unit", "value", "function"

# words a body's block takes besides properties (isaac.lark: _body_item)
BODY_WORDS = ("part", "for", "let")
# units written after a number: every unit, and the compound ones the front end suggests in its hints
UNITS = tuple(dict.fromkeys(list(U.UNITS) + list(U.EXAMPLE_UNIT.values())))

_COMMENT_OR_STRING = re.compile(r'(#|//)[^\n]*|"[^"\n]*"?')
_NAME_PIECE = re.compile(r"(?<=[A-Za-z0-9_])\{[A-Za-z0-9_+\-*/]*\}")
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_TYPED = re.compile(r"[A-Za-z_][A-Za-z0-9_]*$|$")  # the word being typed
# a number or a bracket, then the letters of a unit being typed, if any: `5 |`, `5c|`, `(0, 1, 0) c|`
_AFTER_NUMBER = re.compile(r"((^|[^A-Za-z_0-9.])\d+(\.\d*)?([eE][+-]?\d+)?|\))\s*[A-Za-z]*$")


@dataclass(frozen=True)
class Suggestion:
    label: str
    kind: str
    detail: str = ""


@dataclass(frozen=True)
class Place:
    """Where the cursor is: the table of the block around it (None at item level), the word before the one
    being typed, and whether that is a number."""

    table: dict | None
    items: bool  # where declarations may stand (top, scene, part, a loop of those)
    previous: str
    after_number: bool
    line_start: bool  # where a statement starts: nothing before the word being typed on its line, or a `{`/`}`


def place_of(text: str, offset: int) -> Place:
    """Read the place of `offset` in `text` (comments, strings and `{i}` name pieces blanked first)."""
    code = _blank(text[:offset])
    before = code[:_TYPED.search(code).start()]
    table, items = _context(_open_blocks(before))
    previous = re.search(r"(\S+)\s*$", before)
    previous = previous.group(1) if previous else ""
    line = before.rsplit("\n", 1)[-1]
    return Place(table, items, previous, _AFTER_NUMBER.search(code) is not None,
                 not line.strip() or previous.endswith(("{", "}")))


def suggestions(place: Place, names: list, materials: list) -> list:
    """The Suggestions for a place; `names`: (name, what) visible there; `materials`: material names."""
    if place.items:
        return _keywords() + [Suggestion(k, PROPERTY, v) for k, v in vocabulary.SETTINGS.items()]
    table = place.table or {}
    properties = [Suggestion(k, PROPERTY, v) for k, v in table.items()]
    if table is vocabulary.BODY_PROPS or table is vocabulary.PART_PROPS:
        properties += [Suggestion(word, KEYWORD) for word in BODY_WORDS]
    if place.after_number:
        return [Suggestion(unit, UNIT, U.describe(U.parse_unit(unit)[1])) for unit in UNITS] + properties
    if place.line_start:
        return properties
    if place.previous == "material":
        return [Suggestion(name, VALUE, "material") for name in materials]
    values = [Suggestion(name, VALUE, what) for name, what in names]
    values += [Suggestion(name, VALUE, "constant") for name in E.CONSTANTS] + [Suggestion("t", VALUE, "time")]
    values += [Suggestion(name, FUNCTION, "function") for name in sorted(E.ARITY)]
    if place.previous in table:  # the value of that key
        return values
    return properties + values


def _keywords() -> list:
    return [Suggestion(word, KEYWORD) for word in KEYWORDS]


def _blank(text: str) -> str:
    """The text with comments, strings and `{i}` pieces of names turned to blanks (newlines kept)."""
    text = _COMMENT_OR_STRING.sub(lambda m: " " * len(m.group(0)), text)
    return _NAME_PIECE.sub(lambda m: " " * len(m.group(0)), text)


def _open_blocks(code: str) -> list:
    """The headers (the text before each `{`) of the blocks still open at the end of `code`, outermost first."""
    stack, start = [], 0
    for match in re.finditer(r"[{}]", code):
        if match.group(0) == "{":
            stack.append(code[start:match.start()])
        elif stack:
            stack.pop()
        start = match.end()
    return stack


def _context(stack: list) -> tuple:
    """(table, items) of the innermost block: loops are transparent; a body's `part NAME SHAPE {` takes a part's
    properties; a declaration its table; a property block (`listener {`) its own."""
    table, items = None, True
    for header in stack:
        words = _WORD.findall(header)
        keyword = next((w for w in reversed(words) if w in _OPENERS), None)
        in_body = table is vocabulary.BODY_PROPS or table is vocabulary.PART_PROPS
        if keyword == "for":
            continue  # a loop: what its enclosing block takes
        if keyword in ("scene", "part") and not in_body:
            table, items = None, True
        elif keyword == "part":
            table, items = vocabulary.PART_PROPS, False
        elif keyword == "solver":
            table, items = vocabulary.SOLVER_PROPS, False
        elif keyword in DECLARATION_TABLES:
            table, items = DECLARATION_TABLES[keyword], False
        elif words and words[-1] in NESTED_TABLES:
            table, items = NESTED_TABLES[words[-1]], False
        else:  # `keys {`, a block of an unknown key: no properties to offer
            table, items = {}, False
    return table, items


_OPENERS = set(DECLARATION_TABLES) | {"solver", "part", "for"}
