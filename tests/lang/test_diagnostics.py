"""One test per kind of diagnostic: the message, the position (file, line, column) and the hint.

Each case is scene text and a `needle`: the diagnostic must point at the first occurrence of the needle (plus an
offset), so that the expected position reads off the text itself.
"""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from isaac_ir import ir
from isaac_ir.diagnostics import SceneError
from isaac_lang.expand import Limits
from isaac_lang.load import load_scene, load_text

DATA = Path(__file__).resolve().parent / "data"
BOB = "body bob sphere { radius 5 cm  mass 1 kg }"


def diagnostics(text: str, **kw) -> list:
    with pytest.raises(SceneError) as caught:
        load_text(text, "s.isaac", **kw)
    return caught.value.diagnostics


def where(text: str, needle: str, offset: int = 0):
    index = text.index(needle) + offset
    return text.count("\n", 0, index) + 1, index - (text.rfind("\n", 0, index) + 1) + 1


def only(text: str, **kw):
    found = diagnostics(text, **kw)
    assert len(found) == 1, [d.message for d in found]
    return found[0]


def assert_at(diagnostic, text: str, needle: str, offset: int = 0, file: str = "s.isaac"):
    line, col = where(text, needle, offset)
    assert (diagnostic.pos.file, diagnostic.pos.line, diagnostic.pos.col) == (file, line, col), diagnostic


CASES = [
    # id, scene text, needle (where the error points), offset, message, hint (a part of it) or None
    ("syntax error", "scene s {\n  body b sphere { radius 5 cm ) }\n}\n", ")", 0,
     "unexpected `)`; expected", None),
    ("unexpected character", "scene s {\n  body b sphere { radius 5 cm  at [0, 1, 0] }\n}\n", "[", 0,
     "unexpected character `[`", "vectors are written with parentheses"),
    ("unknown name", "let length = 1 m\nscene s {\n  body b sphere { radius lenght  mass 1 kg }\n}\n", "lenght", 0,
     "unknown name `lenght`", "did you mean `length`?"),
    ("unknown body", f"scene s {{\n  {BOB}\n  constraint c nail(bbo @ (0, 0, 0))\n}}\n", "bbo", 0,
     "unknown body `bbo`", "did you mean `bob`?"),
    ("unknown material", "scene s {\n  material steel { density 7800 kg/m3 }\n"
     "  body b sphere { radius 5 cm  material stel }\n}\n", "stel ", 0,
     "unknown material `stel`", "did you mean `steel`?"),
    ("unknown property", "scene s {\n  body b sphere { radus 5 cm  mass 1 kg }\n}\n", "radus", 0,
     "unknown property `radus` in body `b`", "did you mean `radius`?"),
    ("unknown scene setting", "scene s {\n  gravty (0, -9.81, 0) m/s2\n}\n", "gravty", 0,
     "unknown property `gravty` in the scene", "did you mean `gravity`?"),
    ("unknown function", "scene s {\n  body b sphere { radius 5 cm * sinn(1)  mass 1 kg }\n}\n", "sinn", 0,
     "unknown function `sinn`", "did you mean `sin`?"),
    ("missing unit", "scene s {\n  body b sphere { radius 5  mass 1 kg }\n}\n", "5 ", 0,
     "`radius` needs a unit: it is a length", "e.g. `5 m`"),
    ("wrong unit", "scene s {\n  body b sphere { radius 5 s  mass 1 kg }\n}\n", "5 s", 0,
     "`radius` wants a length, not a time", "e.g. `m`"),
    ("scene ends before it starts", "scene s {\n  time 5 s .. 1 s\n}\n", "5 s", 0,
     "the scene ends before it starts", "END after START"),
    ("constraint ends before it starts", f"scene s {{\n  {BOB}\n  constraint c nail(bob) during 3 s .. 1 s\n}}\n",
     "during", 0, "the constraint ends before it starts", "END after START"),
    ("negative mass", "scene s {\n  body b sphere { radius 5 cm  mass -1 kg }\n}\n", "-1 kg", 0,
     "`mass` must be positive", None),
    ("zero mass", "scene s {\n  body b sphere { radius 5 cm  mass 0 kg }\n}\n", "0 kg", 0,
     "`mass` must be positive", None),
    ("nothing can move", "scene s {\n  body a static box { size (1, 1, 1) m }\n"
     "  body b static box { size (1, 1, 1) m }\n"
     "  constraint c point(a @ (0, 0, 0), b @ (0, 0, 0))\n}\n", "point(", 0,
     "this point constraint joins `a` and `b`, none of which can move", "at least one dynamic body"),
    ("duplicate declaration", f"scene s {{\n  {BOB}\n  {BOB}\n}}\n", f"{BOB}\n}}", 0,
     "body `bob` is declared twice", "the first is at s.isaac:2:3"),
    ("missing include", 'include "nope.isaac"\nscene s {\n}\n', '"nope', 0,
     "cannot read `nope.isaac`", "relative to the including file"),
    ("unknown parameter of a part", "part p(x = 1 m) {\n  body b sphere { radius 5 cm  mass 1 kg  at (x, 0, 0) }\n}\n"
     "scene s {\n  use p one(y = 2 m)\n}\n", "y = 2", 0, "part `p` has no parameter `y`", None),
    ("part argument missing", "part p(x) {\n  body b sphere { radius 5 cm  mass 1 kg  at (x, 0, 0) }\n}\n"
     "scene s {\n  use p one()\n}\n", "use p", 0, "part `p` needs a value for `x`", None),
    ("unknown part", "scene s {\n  use pendulm one()\n}\n", "pendulm", 0, "unknown part `pendulm`", None),
    ("subtracting a row that is not there", f"scene s {{\n  {BOB}\n  constraint c nail(bob) - rz\n}}\n", "rz", 0,
     "nothing to subtract: no `rz` row on the left", "rows are tx, ty, tz"),
    ("subtracting something else", f"scene s {{\n  {BOB}\n  constraint c weld(bob) - nail(bob)\n}}\n", "nail(bob)\n", 0,
     "only an element row (tx ty tz rx ry rz) can be subtracted", None),
    ("unknown constraint", f"scene s {{\n  {BOB}\n  constraint c nial(bob)\n}}\n", "nial", 0,
     "unknown constraint `nial`", "did you mean `nail`?"),
    ("a constraint in an expression", f"scene s {{\n  body b sphere {{ radius nail(b)  mass 1 kg }}\n}}\n", "nail", 0,
     "`nail(...)` is a constraint", None),
    ("t where a constant is due", "scene s {\n  body b sphere { radius t * 1 m/s  mass 1 kg }\n}\n", "t *", 0,
     "`t` is not allowed here", None),
    ("unknown shape", "scene s {\n  body b sphear { radius 5 cm  mass 1 kg }\n}\n", "sphear", 0,
     "`sphear` is not a shape or a motion", "did you mean `sphere`?"),
    ("missing shape dimension", "scene s {\n  body b box { mass 1 kg }\n}\n", "b box", 0, "a box needs `size`", None),
    ("no mass", "scene s {\n  body b sphere { radius 5 cm }\n}\n", "b sphere", 0,
     "body `b` needs a mass", "a `density`"),
    ("wrong number of arguments", "scene s {\n  body b sphere { radius 5 cm * sin(1, 2)  mass 1 kg }\n}\n",
     "sin(", 0, "`sin` takes 1 argument(s), got 2", None),
    ("unknown interpolation",
     "scene s {\n  body k kinematic sphere { radius 1 cm  at keys wobbly { 0 s: (0, 0, 0) } }\n}\n",
     "keys", 0, "unknown interpolation `wobbly`", "linear, cubic or step"),
    ("loop bound not whole", "scene s {\n  for i in 0 .. 2.5 {\n  }\n}\n", "2.5", 0,
     "a loop bound must be a whole number", None),
    ("two scenes", "scene a {\n}\nscene b {\n}\n", "b {", 0, "a second scene `b` in one run", "one scene per file"),
    ("no scene", "let x = 1\n", "let", 0, "no `scene NAME { ... }` in this file", None),
    ("unknown wind", f"scene s {{\n  sound hiss on wind(breez) {{ play wind_noise() }}\n}}\n", "breez", 0,
     "unknown wind `breez`", None),
    ("sound without play", f"scene s {{\n  sound hiss on at(1 s) {{ gain 1 }}\n}}\n", "hiss", 0,
     "sound `hiss` has nothing to `play`", None),
    ("a body twice in exclude", f"scene s {{\n  {BOB}\n  exclude bob, bob\n}}\n", "exclude", 0,
     "a body is named twice in `exclude`", None),
    ("dimension mismatch in +", "scene s {\n  body b sphere { radius 1 m + 1 s  mass 1 kg }\n}\n", "1 m +", 0,
     "cannot add a length and a time", None),
    ("division by zero", "scene s {\n  body b sphere { radius 5 cm  mass 1 kg / 0 }\n}\n", "1 kg / 0", 0,
     "this value cannot be computed", None),
    ("name piece not whole",
     "scene s {\n  for i in 0 .. 2 {\n    body b{i/2} sphere { radius 5 cm  mass 1 kg }\n  }\n}\n",
     "b{i/2}", 0, "`{i/2}` in a name must be a whole number", None),
    ("unknown name in a name piece", "scene s {\n  body b{j} sphere { radius 5 cm  mass 1 kg }\n}\n", "b{j}", 0,
     "in `{j}`: unknown name `j`", None),
]


@pytest.mark.parametrize("text,needle,offset,message,hint", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_diagnostic(text, needle, offset, message, hint):
    diagnostic = only(text)
    assert message in diagnostic.message
    assert_at(diagnostic, text, needle, offset)
    if hint is not None:
        assert diagnostic.hint and hint in diagnostic.hint, diagnostic.hint
    assert diagnostic.severity == "error"


def test_the_diagnostic_prints_gcc_style():
    text = f"scene s {{\n  {BOB}\n  constraint c nail(bbo @ (0, 0, 0))\n}}\n"
    with pytest.raises(SceneError) as caught:
        load_text(text, "s.isaac")
    printed = caught.value.format(None)
    assert printed.startswith("s.isaac:3:21: error: unknown body `bbo`")
    from isaac_ir.diagnostics import SourceCache

    sources = SourceCache()
    sources.add("s.isaac", text)
    lines = caught.value.format(sources).splitlines()
    assert lines[1] == "    3 |   constraint c nail(bbo @ (0, 0, 0))"
    assert lines[2] == "      |                     ^~~"
    assert lines[3] == "hint: did you mean `bob`?"


def test_include_cycle():
    diagnostic = only_file(DATA / "cycle_a.isaac")
    assert diagnostic.message == "include cycle: cycle_a.isaac -> cycle_b.isaac -> cycle_a.isaac"
    assert (diagnostic.pos.file, diagnostic.pos.line, diagnostic.pos.col) == ("cycle_b.isaac", 1, 9)


def test_error_inside_an_included_file_points_into_it():
    diagnostic = only_file(DATA / "bad_include.isaac")
    assert diagnostic.message == "unknown property `frction` in material `rubber`"
    text = (DATA / "lib" / "broken.isaac").read_text()
    expected = ("lib/broken.isaac", *where(text, "frction"))
    assert (diagnostic.pos.file, diagnostic.pos.line, diagnostic.pos.col) == expected


def only_file(path: Path):
    with pytest.raises(SceneError) as caught:
        load_scene(path)
    assert len(caught.value.diagnostics) == 1, caught.value.diagnostics
    return caught.value.diagnostics[0]


@pytest.mark.parametrize("text", [
    "scene s {\n  for i in 0 .. 1000000 {\n    body b{i} sphere { radius 5 cm  mass 1 kg }\n  }\n}\n",
    "scene s {\n  for i in 0 .. 10 {\n    for j in 0 .. 1000 {\n      body b{i}_{j} sphere { radius 5 cm  mass 1 kg }\n"
    "    }\n  }\n}\n",
    "scene s {\n  for i in 0 .. 100000000 {\n    for j in 0 .. 100000000 {\n      let x = i * j\n    }\n  }\n}\n",
    "part p() {\n  use p a()\n  use p b()\n}\nscene s {\n  use p top()\n}\n",
])
def test_runaway_expansion_is_an_error_not_a_hang(text):
    begin = time.perf_counter()
    found = diagnostics(text, limits=Limits(max_items=1000))
    assert time.perf_counter() - begin < 5.0
    assert any("beyond the limit of 1000 declarations" in d.message or "nested too deeply" in d.message
               for d in found)
    assert len(found) <= 2  # reported once, not once per iteration
    assert all(d.pos is not None for d in found)


def test_loop_limit_position():
    text = "scene s {\n  for i in 0 .. 1000000 {\n    body b{i} sphere { radius 5 cm  mass 1 kg }\n  }\n}\n"
    diagnostic = only(text, limits=Limits(max_items=1000))
    assert diagnostic.message == "this expands the scene beyond the limit of 1000 declarations"
    assert_at(diagnostic, text, "for i")
    assert "--max-items" in diagnostic.hint


def test_several_errors_in_one_run_in_file_order():
    text = ("scene s {\n  body a sphere { radius 5  mass 1 kg }\n"
            "  body b sphere { radius 5 cm  mass 1 kg  material nope }\n"
            "  constraint c nail(x)\n  body d sphere { radus 5 cm }\n}\n")
    found = diagnostics(text)
    assert [d.message for d in found] == [
        "`radius` needs a unit: it is a length",
        "unknown material `nope`",
        "unknown body `x`",
        "unknown property `radus` in body `d`",
    ]
    assert [d.pos.line for d in found] == [2, 3, 4, 5]


def test_an_error_in_a_part_used_twice_is_reported_once():
    text = "part p() {\n  body b sphere { radius 5  mass 1 kg }\n}\nscene s {\n  use p one()\n  use p two()\n}\n"
    diagnostic = only(text)
    assert_at(diagnostic, text, "5 ")


def test_set_of_an_unknown_parameter():
    found = diagnostics(f"let length = 1 m\nscene s {{\n  {BOB}\n}}\n", overrides={"lenght": "2 m"})
    assert [d.message for d in found] == ["`--set lenght=2 m`: the scene has no parameter `lenght`"]
    assert found[0].hint == "did you mean `length`?"


def test_set_with_a_bad_value():
    found = diagnostics(f"let length = 1 m\nscene s {{\n  {BOB}\n}}\n", overrides={"length": "2 m )"})
    assert found[0].pos.file == "--set length=2 m )" and "unexpected" in found[0].message


def test_set_overrides_a_let():
    text = "let length = 1 m\nscene s {\n  body b sphere { radius 5 cm  mass 1 kg  at (0, -length, 0) }\n}\n"
    plain = load_text(text, "s.isaac").scene
    changed = load_text(text, "s.isaac", overrides={"length": "2.5 m"}).scene
    assert plain.body("b").position.value == (0.0, -1.0, 0.0)
    assert changed.body("b").position.value == (0.0, -2.5, 0.0)
    assert dict(changed.parameters) == {"length": 2.5}
    assert ir.to_json(plain) != ir.to_json(changed)


def test_set_value_with_the_wrong_unit():
    text = "let length = 1 m\nscene s {\n  body b sphere { radius length  mass 1 kg }\n}\n"
    diagnostic = only(text, overrides={"length": "2 s"})
    # the --set's mistake, said at the --set, with where the let it sets is written (issue 32)
    assert diagnostic.message == "`--set length=2 s` gives a time, but `length` is a length (written at s.isaac:1:14)"
    assert diagnostic.pos.file == "--set length=2 s"
