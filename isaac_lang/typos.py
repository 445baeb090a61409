"""Misspelled units, said as such: "unknown unit `dge`; did you mean `deg`?" at the unit's own place.

The lexer knows units only as the words of its UNIT terminal, so `30 dge` lexes as a number and a name: the
parser then stumbles a line later ("unexpected `=`"), or lowering sees a property `dge` ("unknown property"). After
a stage fails, `explain_unit_typos` looks at the text for a word right after a number or a `)` on the same line
(where only a unit, a property, a setting or a keyword may stand) that is none of those and reads like a unit; a
diagnostic at that word, or a syntax error just after it, is replaced by the unit's.
"""
from __future__ import annotations

import difflib
import functools
import re
from dataclasses import dataclass

from isaac_ir import units as U
from isaac_ir.diagnostics import Diagnostic, SceneError, SourceCache, SourcePos

# a syntax error up to this many lines after a misspelled unit is taken for its echo
ECHO_LINES = 3
# how alike a word and a unit must be (difflib's ratio) to be taken for it
UNIT_CUTOFF = 0.6
# a word that opens with a unit (`mss`) is that unit unless a property is clearly closer (`radus`: radius)
PREFIX_BONUS = 0.1

# a number or a `)`, blanks, then a word: the one place a unit stands
_AFTER_VALUE = re.compile(r"(?:(?<![A-Za-z0-9_.])(?:\d+(?:\.\d+)?|\.\d+)(?:[eE][+-]?\d+)?|\))[ \t]*"
                          r"([A-Za-z_][A-Za-z0-9_]*)")
_STRING_OR_COMMENT = re.compile(r'"[^"\n]*"|(?:#|//)[^\n]*')


@dataclass(frozen=True)
class UnitTypo:
    pos: SourcePos
    word: str
    guess: str

    def diagnostic(self) -> Diagnostic:
        return Diagnostic(f"unknown unit `{self.word}`; did you mean `{self.guess}`?", self.pos,
                          "units follow a number directly: 5 cm, 30 deg, 9.81 m/s2 (docs/language.md, Units)")


def explain_unit_typos(error: SceneError, sources: SourceCache) -> SceneError:
    """The error with each diagnostic that a misspelled unit caused replaced by the unit's (one per typo)."""
    out, used = [], set()
    for diagnostic in error.diagnostics:
        typo = _cause(diagnostic, sources)
        if typo is None:
            out.append(diagnostic)
        elif typo.pos not in used:
            used.add(typo.pos)
            out.append(typo.diagnostic())
    return SceneError(out) if used else error


def _cause(diagnostic: Diagnostic, sources: SourceCache) -> UnitTypo | None:
    pos = diagnostic.pos
    if pos is None:
        return None
    typos = unit_typos(sources.lines(pos.file) or [], pos.file)
    for typo in typos:
        if (typo.pos.line, typo.pos.col) == (pos.line, pos.col):
            return typo
    if not _is_syntax_error(diagnostic):
        return None
    before = [t for t in typos if (t.pos.line, t.pos.col) < (pos.line, pos.col) and pos.line - t.pos.line <= ECHO_LINES]
    return before[-1] if before else None


def _is_syntax_error(diagnostic: Diagnostic) -> bool:
    """The parser's messages (syntax.describe_syntax_error)."""
    return diagnostic.message.startswith("unexpected ") or diagnostic.message.endswith("is not a keyword")


def unit_typos(lines: list, file: str) -> list:
    """Every word of the text that stands where a unit goes and reads like a misspelled one, in file order."""
    found = []
    for number, line in enumerate(lines, start=1):
        code = _STRING_OR_COMMENT.sub(lambda m: " " * len(m.group(0)), line)
        for match in _AFTER_VALUE.finditer(code):
            word = match.group(1)
            guess = _unit_guess(word)
            if guess is not None:
                found.append(UnitTypo(SourcePos(file, number, match.start(1) + 1, len(word)), word, guess))
    return found


@functools.lru_cache(maxsize=512)
def _unit_guess(word: str) -> str | None:
    """The unit `word` misspells, or None: a real unit, a word of the language, or nothing close."""
    if len(word) < 2 or word in _language_words() or _is_unit(word):
        return None
    if word.lower() in SPELLED_OUT:
        return SPELLED_OUT[word.lower()]
    unit = _closest(word, U.UNITS)
    if unit is None:
        return None
    # a near miss of a property (`mas` for `mass`) is the property's typo, reported as such; a word that opens
    # with a unit of two letters or more (`mss`: `ms` with a letter too many) leans to the unit
    other = _closest(word, _language_words())
    if other is not None and _ratio(word, other) > _ratio(word, unit) + (PREFIX_BONUS * _opens_with(word, unit)):
        return None
    return unit


# units written out, or in another convention
SPELLED_OUT = {
    "sec": "s", "secs": "s", "second": "s", "seconds": "s", "msec": "ms", "millisecond": "ms", "milliseconds": "ms",
    "meter": "m", "meters": "m", "metre": "m", "metres": "m", "kilogram": "kg", "kilograms": "kg", "kgs": "kg",
    "gram": "g", "grams": "g", "degree": "deg", "degrees": "deg", "degs": "deg", "radian": "rad", "radians": "rad",
    "hertz": "Hz", "newton": "N", "newtons": "N", "joule": "J", "joules": "J", "watt": "W", "watts": "W",
    "pascal": "Pa", "decibel": "dB", "decibels": "dB",
}


def _closest(word: str, candidates) -> str | None:
    """The candidate most like word (difflib's ratio, case aside for words of two letters or more, at least
    UNIT_CUTOFF); of equals, the one that opens the word (`cmm` is `cm` with a letter too many, not `mm`)."""
    scored = [(_ratio(word, c), _opens_with(word, c), c) for c in candidates]
    best = max((s for s in scored if s[0] >= UNIT_CUTOFF), default=None, key=lambda s: (s[0], s[1]))
    return best[2] if best else None


def _opens_with(word: str, unit: str) -> bool:
    return len(unit) >= 2 and word.lower().startswith(unit.lower())


def _is_unit(word: str) -> bool:
    try:
        U.parse_unit(word)
    except U.UnitError:
        return False
    return True


def _ratio(a: str, b: str) -> float:
    if len(a) >= 2 and len(b) >= 2:
        a, b = a.lower(), b.lower()
    return difflib.SequenceMatcher(None, a, b).ratio()


@functools.lru_cache(maxsize=1)
def _language_words() -> frozenset:
    """Words that may follow a value: keywords, properties, settings, and the grammar's other words."""
    from isaac_lang.syntax import KEYWORDS
    from isaac_lang.vocabulary import property_names

    return frozenset(KEYWORDS) | property_names() | {"in", "during", "from", "until", "on", "world", "keys"}
