"""Which `{` or `(` a syntax error leaves open: the text scanned up to the error (comments and strings skipped).

The innermost bracket still open is usually the one to close; but when a `}` that stands first on its line
closes a `{` opened on a line indented deeper, that `{` was most likely the one left open (the `}` was meant for
an outer brace), and the first such `{` of the file is blamed instead.
"""
from __future__ import annotations

from dataclasses import dataclass

from isaac_ir.diagnostics import source_lines

CLOSER = {"{": "}", "(": ")"}
OPENER = {closer: opener for opener, closer in CLOSER.items()}


@dataclass(frozen=True)
class Bracket:
    char: str
    line: int
    col: int
    indent: int

    @property
    def closer(self) -> str:
        return CLOSER[self.char]

    def not_closed(self, before: str = "") -> str:
        """The hint naming this bracket."""
        where = f" before {before}" if before else ""
        return f"the `{self.char}` opened at {self.line}:{self.col} is not closed: add `{self.closer}`{where}"


@dataclass
class Scan:
    """The brackets open at a point of the text, innermost last, and those a less indented `}` closed."""

    open: list
    misclosed: list

    def innermost(self, char: str | None = None) -> Bracket | None:
        for bracket in reversed(self.open):
            if char is None or bracket.char == char:
                return bracket
        return None

    def to_blame(self) -> Bracket | None:
        """The bracket most likely left open: the first closed by a `}` of a shallower line, else the innermost."""
        return self.misclosed[0] if self.misclosed else self.innermost()


def scan_brackets(text: str, line: int | None = None, col: int | None = None) -> Scan:
    """The brackets of text open just before (line, col) (the whole text when line is None)."""
    scan = Scan([], [])
    for number, source in enumerate(source_lines(text), start=1):
        if line is not None and number > line:
            break
        stop = col - 1 if (line is not None and number == line) else len(source)
        _scan_line(source[:stop], number, _indent(source), scan)
    return scan


def _scan_line(code: str, number: int, indent: int, scan: Scan) -> None:
    in_string = False
    for index, char in enumerate(code):
        if char == '"':
            in_string = not in_string
        elif in_string:
            continue
        elif char == "#" or code.startswith("//", index):
            return
        elif char in CLOSER:
            scan.open.append(Bracket(char, number, index + 1, indent))
        elif char in OPENER:
            _close(scan, char, number, indent, first_on_line=not code[:index].strip())


def _close(scan: Scan, closer: str, number: int, indent: int, first_on_line: bool) -> None:
    bracket = scan.innermost(OPENER[closer])
    if bracket is None:
        return
    while scan.open and scan.open[-1] is not bracket:  # brackets of the other kind left open inside it
        scan.open.pop()
    scan.open.pop()
    if closer == "}" and first_on_line and bracket.line != number and bracket.indent > indent:
        scan.misclosed.append(bracket)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" \t"))


def unclosed_hint(text: str, token_type: str, token: str, line: int, col: int, expected,
                  is_keyword: bool = False) -> str | None:
    """A hint naming the bracket a syntax error at (line, col) leaves open, or None when none seems to be: at
    the end of the file, at a closer of the other kind, or at a keyword or the first word of a line where a
    closer could stand."""
    expected = set(expected or ())
    if token_type == "$END":
        bracket = scan_brackets(text).to_blame()
        return bracket.not_closed() if bracket else None
    scan = scan_brackets(text, line, col)
    if token in OPENER:
        return _stray_closer_hint(scan, token)
    first_on_line = _first_on_line(text, line, col)
    bracket = scan.to_blame()
    if bracket is None or not ({"RBRACE", "RPAR"} & expected) or not (first_on_line or is_keyword):
        return None
    return bracket.not_closed(before="this line" if first_on_line else f"`{token}`")


def _stray_closer_hint(scan: Scan, closer: str) -> str:
    inner = scan.innermost()
    if inner is not None and inner.char != OPENER[closer]:
        return inner.not_closed(before=f"this `{closer}`")
    return f"no `{OPENER[closer]}` is open here for this `{closer}` to close: remove it"


def _first_on_line(text: str, line: int, col: int) -> bool:
    lines = source_lines(text)
    return 1 <= line <= len(lines) and not lines[line - 1][:col - 1].strip()
