"""Stage 1, parse: text -> lark parse tree (LALR, positions kept), syntax errors as diagnostics.

The grammar is compiled by lark (`parser()`); a text is parsed by `ParseLoop`, which runs lark's tables
faster, and parsed again by lark itself (`reference_parser()`) only when it has a syntax error, for lark's
description of it.
"""
from __future__ import annotations

import functools
import re
from importlib import resources

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from isaac_ir.diagnostics import Reporter, SourcePos, did_you_mean, source_lines
from isaac_lang.brackets import unclosed_hint
from isaac_lang.parse_loop import ParseLoop, Rejected
from isaac_lang.vocabulary import property_names

KEYWORDS = ("scene", "let", "include", "material", "body", "constraint", "kind", "force", "wind", "sound",
            "camera", "light", "solver", "exclude", "collide", "part", "use",
            "for", "vary", "goal")

# how the grammar's terminals read in an error message
TOKEN_WORDS = {
    "RBRACE": "`}`", "LBRACE": "`{`", "LPAR": "`(`", "RPAR": "`)`", "COMMA": "`,`", "NAME": "a name",
    "NUMBER": "a number", "STRING": "a quoted file name", "UNIT": "a unit", "EQUAL": "`=`", "COLON": "`:`",
    "__ANON_0": "`..`", "AT": "`@`", "PLUS": "`+`", "MINUS": "`-`", "STAR": "`*`", "SLASH": "`/`",
    "TNAME": "a name", "$END": "the end of the file",
}


@functools.lru_cache(maxsize=1)
def parser() -> Lark:
    """The grammar compiled by lark: its tables and tree-building actions drive `parse_loop()`."""
    return _lark(propagate_positions=False)


@functools.lru_cache(maxsize=1)
def parse_loop() -> ParseLoop:
    """The parser of texts (trees with positions)."""
    return ParseLoop(parser())


@functools.lru_cache(maxsize=1)
def reference_parser() -> Lark:
    """lark's own parse, positions included: it describes syntax errors, and tests check the loop against it."""
    return _lark(propagate_positions=True)


def _lark(propagate_positions: bool) -> Lark:
    grammar = resources.files("isaac_lang.grammar").joinpath("isaac.lark").read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", propagate_positions=propagate_positions, start=["start", "expr"],
                maybe_placeholders=True, cache=True)


def parse_text(text: str, file: str, reporter: Reporter) -> Tree | None:
    """Parse a whole file; on a syntax error record a diagnostic and return None."""
    try:
        return parse_loop().parse(text, "start")
    except Rejected:
        pass  # a syntax error: lark describes it
    try:
        return reference_parser().parse(text, start="start")
    except UnexpectedInput as error:
        reporter.error(*describe_syntax_error(error, text, file))
        return None


def parse_expression(text: str) -> Tree:
    """The tree of one expression; raises lark's UnexpectedInput on a syntax error."""
    try:
        return parse_loop().parse(text, "expr")
    except Rejected:
        return reference_parser().parse(text, start="expr")


def describe_syntax_error(error: UnexpectedInput, text: str, file: str):
    """(message, position, hint) for a lark error, in the writer's words."""
    line, col = max(1, error.line), max(1, error.column)
    if isinstance(error, UnexpectedCharacters):
        char = text[error.pos_in_stream] if error.pos_in_stream < len(text) else "?"
        return f"unexpected character {_shown(char)}", SourcePos(file, line, col), _hint_for_character(char)
    if isinstance(error, UnexpectedEOF) or (isinstance(error, UnexpectedToken) and error.token.type == "$END"):
        lines = source_lines(text) or [""]
        pos = SourcePos(file, len(lines), len(lines[-1]) + 1)
        expected = _expected(error)
        hint = unclosed_hint(text, "$END", "", pos.line, pos.col, getattr(error, "expected", None))
        return f"unexpected end of file; expected {expected}", pos, hint
    token = error.token
    misspelled = _misspelled_keyword(token, text)
    if misspelled:
        # `materal steel { ... }` parses as far as the `{`: the mistake is the first word, so point there
        word, word_col, guess = misspelled
        return f"`{word}` is not a keyword", SourcePos(file, token.line, word_col, len(word)), guess
    pos = SourcePos(file, line, col, max(1, len(str(token))))
    message = f"unexpected {_token_text(token)}; expected {_expected(error)}"
    hint = unclosed_hint(text, token.type, str(token), token.line, token.column, getattr(error, "expected", None),
                         is_keyword=token.type == "NAME" and str(token) in KEYWORDS)
    return message, pos, hint or _hint_for_token(token, text, error)


def _shown(char: str) -> str:
    """`x`, or U+000B (a control character, a separator or a blank that a terminal would not show)."""
    if char.isprintable() and not char.isspace():
        return f"`{char}`"
    return f"U+{ord(char):04X}" + (f" (`{char}`)" if char.isprintable() else "")


def _misspelled_keyword(token: Token, text: str):
    """(word, column, hint) when the line of a syntax error opens with a near miss of a keyword."""
    lines = source_lines(text)
    if not token.line or token.line > len(lines):
        return None
    match = re.match(r"\s*([A-Za-z_][A-Za-z0-9_]*)", lines[token.line - 1])
    if not match or match.group(1) in KEYWORDS or match.group(1) in property_names():
        return None
    guess = did_you_mean(match.group(1), KEYWORDS)
    return (match.group(1), match.start(1) + 1, guess) if guess else None


def _expected(error) -> str:
    names = sorted({TOKEN_WORDS.get(name, f"`{name.lower()}`") for name in getattr(error, "expected", ()) or ()})
    if not names:
        return "something else"
    if len(names) > 6:
        return ", ".join(names[:6]) + ", ..."
    return ", ".join(names)


def _token_text(token: Token) -> str:
    if token.type == "$END":
        return "end of file"
    return f"`{token}`"


def _hint_for_character(char: str) -> str | None:
    if char in "[]":
        return "vectors are written with parentheses: (x, y, z)"
    if char == ";":
        return "statements need no `;`: put them on separate lines or just one after another"
    if char == "'":
        return "file names are written in double quotes"
    return None


def _hint_for_token(token: Token, text: str, error) -> str | None:
    """Common mistakes: a keyword where a `}` was due, a body point outside a call (misspelled keywords:
    `_misspelled_keyword`)."""
    if token.type == "NAME" and str(token) in KEYWORDS:
        return "a `}` may be missing before this declaration"
    if token.type == "AT":
        return "`body @ (x, y, z)` names a point of a body; it goes inside a constraint or force call"
    return None
