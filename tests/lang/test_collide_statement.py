"""`collide a, b [window]`: the syntax, the IR, each positioned error, and the warning for a sound trigger that
can never fire (docs/language.md "Collide", docs/collisions.md "What can collide")."""
from __future__ import annotations

import json

import pytest

from isaac_ir import ir
from isaac_ir.diagnostics import SceneError, SourceCache, warning_diagnostic
from isaac_lang.load import load_text

from .test_diagnostics import only

HEAD = """scene s {
  time 0 s .. 2 s
  body wall static box { size (0.2, 1, 0.2)  at (0.1, 0.5, 0) }
  body floor static box { size (2, 0.1, 2)  at (0, -0.05, 0) }
  body ball sphere { radius 5 cm  mass 0.2 kg  at (-0.6, 1, 0) }
  body ghost sphere { radius 5 cm  mass 0.2 kg  at (1, 1, 0)  collide off }
  constraint string point(ball @ (0.5, 0, 0), wall @ (-0.2, 0.5, 0))
"""


def scene(*lines: str) -> str:
    return HEAD + "".join(f"  {line}\n" for line in lines) + "}\n"


# ---- syntax and IR ---------------------------------------------------------------------------------------------

def test_collide_lowers_to_the_ir_with_its_window():
    loaded = load_text(scene("collide ball, wall", "collide ball, floor during 0.5 s .. 1 s"), "s.isaac")
    first, second = loaded.scene.collides
    assert first == ir.Collide(("ball", "wall"), "s.isaac:8:3")
    assert (second.bodies, second.start, second.end) == (("ball", "floor"), 0.5, 1.0)
    data = json.loads(ir.to_json(loaded.scene))
    assert data["collides"][0] == {"bodies": ["ball", "wall"], "source": "s.isaac:8:3", "start": "-inf",
                                   "end": "inf"}
    assert data["collides"][1]["start"] == 0.5 and data["collides"][1]["end"] == 1.0


def test_a_scene_without_collide_has_no_collides_key_in_its_ir():
    """The canonical IR of a scene without the statement is what it was before the statement existed."""
    data = json.loads(ir.to_json(load_text(scene(), "s.isaac").scene))
    assert "collides" not in data


@pytest.mark.parametrize("window,start,end", [("from 1 s", 1.0, float("inf")), ("until 1 s", 0.0, 1.0)])
def test_collide_takes_every_window_form(window, start, end):
    (c,) = load_text(scene(f"collide ball, wall {window}"), "s.isaac").scene.collides
    assert (c.start, c.end) == (start, end)


def test_collide_of_a_group_and_in_a_loop():
    text = HEAD + "  for i in 0 .. 3 {\n    body b{i} sphere { radius 1 cm  mass 1 kg  at (i, 3, 0) }\n  }\n" \
        "  for i in 0 .. 2 {\n    collide b{i}, b{i+1}, wall\n  }\n}\n"
    collides = load_text(text, "s.isaac").scene.collides
    assert [c.bodies for c in collides] == [("b0", "b1", "wall"), ("b1", "b2", "wall")]


def test_collide_is_still_a_body_property_and_a_sound_trigger():
    text = scene("body bob sphere { radius 5 cm  mass 1 kg  at (0, 3, 0)\n    collide off }",
                 "sound s on collide(ball, floor) { play impulse }", "collide ball, wall")
    loaded = load_text(text, "s.isaac")
    assert not loaded.scene.body("bob").collide
    assert loaded.scene.sounds[0].trigger == "collide"
    assert len(loaded.scene.collides) == 1


# ---- positioned errors -------------------------------------------------------------------------------------------

ERRORS = [
    ("unknown body", "collide ball, wal", "wal\n", "unknown body `wal`", "did you mean `wall`?"),
    ("one body", "collide ball", "collide ball", "`collide` names at least two bodies", "write `collide a, b`"),
    ("collide off", "collide ball, ghost", "ghost\n", "body `ghost` has `collide off`: it collides with nothing",
     "remove `collide off` from `ghost`"),
    ("both static", "collide wall, floor", "floor\n", "`wall` and `floor` can never touch: neither of them is dynamic",
     "one of its bodies is dynamic"),
    ("named twice", "collide ball, wall, ball", "ball\n", "`ball` is named twice in `collide`", None),
    ("window after the scene", "collide ball, wall during 3 s .. 4 s", "during", "the window 3 s .. 4 s is outside "
     "the scene's time (0 s .. 2 s)", "within `time 0 s .. 2 s`"),
    ("window before the scene", "collide ball, wall until -1 s", "until", "is outside the scene's time", None),
    ("window backwards", "collide ball, wall during 1 s .. 0.5 s", "during", "ends before it starts", None),
    ("exclude at the same time", "collide ball, wall during 0.5 s .. 1 s\n  exclude wall, ball during 0.8 s .. 2 s",
     "collide ball", "`collide` and `exclude` both name `ball` and `wall` at the same time",
     "the `exclude` is at s.isaac:9:3"),
    ("exclude for the whole run", "exclude ball, wall, floor\n  collide ball, wall", "collide ball",
     "`collide` and `exclude` both name `ball` and `wall` at the same time", "the `exclude` is at s.isaac:8:3"),
]


@pytest.mark.parametrize("line,needle,message,hint", [e[1:] for e in ERRORS], ids=[e[0] for e in ERRORS])
def test_each_error_is_positioned(line, needle, message, hint):
    text = scene(line)
    found = only(text)
    assert message in found.message
    # at the needle's first occurrence after the scene's head
    index = text.index(needle, len(HEAD))
    line_no = text.count("\n", 0, index) + 1
    col = index - (text.rfind("\n", 0, index) + 1) + 1
    assert (found.pos.file, found.pos.line, found.pos.col) == ("s.isaac", line_no, col), found
    if hint is not None:
        assert hint in found.hint


def test_an_exclude_in_another_window_is_no_error():
    loaded = load_text(scene("collide ball, wall during 0 s .. 1 s", "exclude ball, wall during 1 s .. 2 s"),
                       "s.isaac")
    assert len(loaded.scene.collides) == 1 and len(loaded.scene.exclusions) == 1


def test_the_error_prints_with_a_caret():
    text = scene("collide ball, ghost")
    with pytest.raises(SceneError) as raised:
        load_text(text, "s.isaac")
    sources = SourceCache()
    sources.add("s.isaac", text)
    printed = raised.value.format(sources)
    assert "s.isaac:8:17: error: body `ghost` has `collide off`" in printed
    assert "  collide ball, ghost" in printed and "^~~~~" in printed and "hint: remove `collide off`" in printed


# ---- sound triggers that can never fire ----------------------------------------------------------------------------

def warnings_of(*lines: str) -> list:
    return load_text(scene(*lines), "s.isaac").warnings


NEVER = [
    ("joined for the whole run", "collide(ball, wall)", (), "constraint `string` joins them for the whole run",
     "write `collide ball, wall`"),
    ("contact, joined", "contact(wall, ball)", (), "constraint `string` joins them", "write `collide wall, ball`"),
    ("exclude without a window", "collide(ball, floor)", ("exclude floor, ball",),
     "the `exclude` at s.isaac:8:3 excludes them for the whole run", "take one of them out of that `exclude`"),
    ("both static", "collide(wall, floor)", (), "neither of them is dynamic", "one of its bodies is dynamic"),
    ("collide off", "collide(ball, ghost)", (), "`ghost` has `collide off`", "remove `collide off` from `ghost`"),
]


@pytest.mark.parametrize("trigger,extra,message,hint", [n[1:] for n in NEVER], ids=[n[0] for n in NEVER])
def test_a_trigger_that_can_never_fire_is_warned_at_the_trigger(trigger, extra, message, hint):
    lines = (*extra, f"sound clang on {trigger} {{ play impulse }}")
    found = [w for w in warnings_of(*lines) if "never plays" in w]
    assert len(found) == 1, warnings_of(*lines)
    diagnostic = warning_diagnostic(found[0])
    line_no = HEAD.count("\n") + len(extra) + 1
    col = len("  sound clang on ") + 1
    assert (diagnostic.pos.file, diagnostic.pos.line, diagnostic.pos.col) == ("s.isaac", line_no, col)
    assert "sound `clang` never plays" in diagnostic.message and message in diagnostic.message
    assert hint in diagnostic.hint


@pytest.mark.parametrize("lines", [
    ("collide ball, wall",),  # the `collide` gives the pair back
    ("collide ball, wall during 0.5 s .. 1 s",),  # for a while: it can fire then
    ("exclude ball, floor during 0 s .. 1 s",),  # a window: the pair collides after it
], ids=["collide", "collide with a window", "windowed exclude"])
def test_no_warning_when_the_trigger_can_fire(lines):
    pair = "ball, wall" if "wall" in lines[0] else "ball, floor"
    assert not [w for w in warnings_of(*lines, f"sound clang on collide({pair}) {{ play impulse }}")
                if "never plays" in w]


def test_a_constraint_for_part_of_the_run_does_not_warn():
    text = scene("constraint hold point(ball @ (0, 0, 0), floor @ (0, 1, 0)) during 0 s .. 1 s",
                 "sound clang on collide(ball, floor) { play impulse }")
    assert not [w for w in load_text(text, "s.isaac").warnings if "never plays" in w]
