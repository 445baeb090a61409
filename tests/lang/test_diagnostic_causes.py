"""Issue 32, the rest: each diagnostic points at its cause, with the line, a caret and a hint (brackets left
open, dimensions that do not match, run-time warnings, scenes loaded from text)."""
from __future__ import annotations

import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text


def load_error(text: str, name: str = "x.isaac") -> str:
    with pytest.raises(SceneError) as caught:
        load_text(text, name, assets=False)
    return caught.value.format()


# -- brackets left open --------------------------------------------------------------------------------------

def test_a_brace_where_a_parenthesis_is_due_names_the_open_parenthesis():
    text = ("scene s {\n  time 0 .. 1 s\n  body b sphere {\n    radius 1 cm\n    at (0, 1, 0 }\n  }\n}\n")
    err = load_error(text)
    assert "x.isaac:5:17: error: unexpected `}`" in err
    assert "hint: the `(` opened at 5:8 is not closed: add `)` before this `}`" in err


def test_an_unclosed_body_brace_is_blamed_on_the_body_not_the_scene():
    text = ("scene s {\n  time 0 .. 1 s\n  body b sphere { radius 1 cm\n    mass 1 kg\n}\n")
    err = load_error(text)
    assert "unexpected end of file" in err
    assert "hint: the `{` opened at 3:17 is not closed: add `}`" in err
    assert "1:9" not in err


def test_an_unclosed_brace_inside_nested_braces_is_the_one_blamed():
    text = ("scene s {  # { in a comment\n  time 0 .. 1 s\n  body a sphere {\n    radius 1 cm\n"
            "    sound \"{.wav\"\n  }\n  body b sphere {\n    radius 1 cm\n    at (0, 1, 0) m\n}\n")
    err = load_error(text)
    assert "hint: the `{` opened at 7:17 is not closed: add `}`" in err


def test_a_declaration_inside_an_unclosed_parenthesis_names_it():
    text = ("scene s {\n  time 0 .. 1 s\n  body b sphere {\n    radius 1 cm\n    at (0, 1, 0\n"
            "    mass 1 kg\n  }\n}\n")
    err = load_error(text)
    assert "hint: the `(` opened at 5:8 is not closed: add `)` before this line" in err


def test_a_closing_parenthesis_inside_braces_names_the_open_brace():
    text = "scene s {\n  time 0 .. 1 s\n  body b sphere { radius 1 cm ) }\n}\n"
    err = load_error(text)
    assert "hint: the `{` opened at 3:17 is not closed: add `}` before this `)`" in err


# -- a scene loaded from text ----------------------------------------------------------------------------------

def test_a_scene_loaded_from_text_formats_its_errors_with_the_line_and_caret():
    text = "scene s {\n  time 0 .. 1 s\n  body b sphere { radius 10 }\n}\n"
    err = load_error(text, "<scene>")
    assert err.startswith("<scene>:3:26: error:")
    assert "    3 |   body b sphere { radius 10 }" in err
    assert "      |                          ^" in err


# -- dimensions that do not match ------------------------------------------------------------------------------

SCENE_WITH = "scene s {{\n  time 0 .. 1 s\n  let h = 1 m\n  let t = 2 s\n  let x = {}\n}}\n"


@pytest.mark.parametrize("expr, message, hint", [
    ("h + 2 s", "cannot add a length and a time",
     "both sides of `+` must have the same dimension: here a length and a time; did you mean `2 m`?"),
    ("h - 2 s", "cannot subtract a time from a length",
     "both sides of `-` must have the same dimension: here a length and a time; did you mean `2 m`?"),
    ("3 kg + h", "cannot add a mass and a length",
     "both sides of `+` must have the same dimension: here a mass and a length; did you mean `3 m`?"),
    ("h - t", "cannot subtract a time from a length",
     "check the unit of each side (`h` is a length, `t` is a time)"),
    ("min(h, 3 s)", "`min`: cannot mix a length and a time",
     "the arguments of `min` must have the same dimension: here a length and a time; did you mean `3 m`?"),
    ("(h, 2 s, 0 m)", "vector components disagree: a length and a time",
     "the components of a vector must have the same dimension: here a length and a time; did you mean `2 m`?"),
])
def test_a_dimension_mismatch_says_what_must_agree(expr, message, hint):
    err = load_error(SCENE_WITH.format(expr))
    assert f"x.isaac:5:11: error: {message}" in err
    assert f"    5 |   let x = {expr}" in err
    assert "hint: " in err and hint in err
