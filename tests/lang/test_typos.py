"""Misspelled units and keywords are said as such, at their own place; a mistake inside a loop or a part is
reported once, however many iterations reach it."""
from __future__ import annotations

from pathlib import Path

import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_lang.typos import _unit_guess

ROOT = Path(__file__).resolve().parents[2]
PENDULUM = (ROOT / "scenes" / "pendulum.isaac").read_text(encoding="utf-8")


def diagnostics(text: str) -> list:
    with pytest.raises(SceneError) as raised:
        load_text(text, "p.isaac")
    return raised.value.diagnostics


def where(text: str, needle: str) -> tuple:
    index = text.index(needle)
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


@pytest.mark.parametrize("old,new,typo,guess", [
    ("let theta0 = 60 deg", "let theta0 = 60 dge", "dge", "deg"),  # was "unexpected `=`" a line later
    ("mass 1 kg", "mass 1 kgg", "kgg", "kg"),  # was "unknown property `kgg`"
    ("radius 5 cm", "radius 5 cmm", "cmm", "cm"),  # was "unexpected `1`" a line later
    ("step 1 ms }", "step 1 mss }", "mss", "ms"),
    ("frames 100 Hz", "frames 100 hz", "hz", "Hz"),
    ("gravity (0, -9.81, 0) m/s2", "gravity (0, -9.81, 0) meters", "meters", "m"),
])
def test_a_misspelled_unit_is_reported_at_the_unit(old, new, typo, guess):
    text = PENDULUM.replace(old, new)
    (diagnostic,) = diagnostics(text)
    assert diagnostic.message == f"unknown unit `{typo}`; did you mean `{guess}`?"
    line, col = where(text, new)
    assert (diagnostic.pos.line, diagnostic.pos.col) == (line, col + new.rindex(typo))
    assert diagnostic.pos.length == len(typo)


def test_the_caret_sits_under_the_unit():
    text = PENDULUM.replace("mass 1 kg", "mass 1 kgg")
    (diagnostic,) = diagnostics(text)
    line, col = where(text, "kgg")
    assert (diagnostic.pos.line, diagnostic.pos.col) == (line, col)


def test_words_that_are_not_unit_typos():
    for word in ("mass", "radius", "at", "during", "x", "z", "n", "rest", "m", "m2", "kg/m3"):
        assert _unit_guess(word) is None, word
    assert _unit_guess("mas") is None  # closer to `mass`: the property's typo
    assert _unit_guess("radus") is None


def test_a_property_typo_is_still_a_property_typo():
    text = PENDULUM.replace("radius 5 cm", "radus 5 cm")
    (diagnostic,) = diagnostics(text)
    assert diagnostic.message == "unknown property `radus` in body `bob`"
    assert diagnostic.hint == "did you mean `radius`?"


@pytest.mark.parametrize("old,new,word,guess", [
    ("  body bob sphere {", "  bdy bob sphere {", "bdy", "body"),
    ("  constraint hang nail", "  constrant hang nail", "constrant", "constraint"),
    (", (0, length, 0))\n", ", (0, length, 0)) durng 0 s .. 1 s\n", "durng", "during"),
])
def test_a_misspelled_keyword_is_reported_at_the_word(old, new, word, guess):
    text = PENDULUM.replace(old, new)
    (diagnostic,) = diagnostics(text)
    assert diagnostic.message == f"`{word}` is not a keyword" and diagnostic.hint == f"did you mean `{guess}`?"
    assert (diagnostic.pos.line, diagnostic.pos.col) == where(text, word)


def test_one_diagnostic_per_place_however_many_iterations_reach_it():
    text = """scene loop {
  for i in 0 .. 5 {
    body link{i} sphere { radius 5 cm  mass 1 kg  at (i, 0, 0) }
    constraint c{i} point(link{i} @ (0, 0, 0), lnk{i+1} @ (0, 0, 0))
    body b{i} sphere { radius 5 cm  mass 1 kgg  at (i, 1, 0) }
  }
}
"""
    found = diagnostics(text)
    assert [d.message for d in found] == ["unknown body `lnk1`", "unknown unit `kgg`; did you mean `kg`?"]
    assert [(d.pos.line, d.pos.col) for d in found] == [where(text, "lnk{"), where(text, "kgg")]
    assert "reached 4 more times" in found[0].hint
