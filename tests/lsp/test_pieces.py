"""The language server's pieces, in process: checking, the index, values, hover, completion, the outline."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from isaac.lsp.checking import check_text
from isaac.lsp.completion import place_of, suggestions
from isaac.lsp.hover import hover_text
from isaac.lsp.index import Definition, PropertyKey, Reference, build_index
from isaac.lsp.symbols import outline
from isaac.lsp.values import format_typed, let_values
from isaac_lang import vocabulary
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_scene

ROOT = Path(__file__).resolve().parents[2]

PARTS = """\
let spacing = 0.5 m
let tilt = 30 deg
kind slider(a) = weld(a) - tx
material wood { density 600 kg/m3 }
part arm(base, reach = 40 cm) {
  let half = reach / 2
  body tip sphere { radius 2 cm  mass 0.1 kg  at (reach, 0, 0) }
  constraint pin point(tip @ (0, 0, 0), base @ (reach, 0, 0))
}
scene s {
  time 0 s .. 1 s
  body post static box { size (0.1, 1, 0.1) m  material wood }
  use arm left(base = post)
  for i in 0 .. 3 {
    body link{i} box { size (1, 2, 3) cm  mass 10 g  at (i * spacing, 0, 0) }
  }
  constraint slide slider(left.tip)
  constraint hold nail(link2 @ (0, 0, 0), (0, 0, 0))
}
"""


def index_of(text: str, path: Path = Path("/scenes/s.isaac")):
    return build_index(text, path, lambda p: None)


def find(index, line: int, word: str, nth: int = 0):
    """The index item at the nth `word` of a 1-based line of the root file."""
    text = index.files[index.root].split("\n")[line - 1]
    col = -1
    for _ in range(nth + 1):
        col = text.index(word, col + 1)
    return index.at(index.root, line, col + 1)


# -- checking: the diagnostics `isaac check` reports, at its places ----------------------------------------------

MISTAKES = [
    "  body b sphere { radius 10  mass 1 kg }",  # a length without its unit
    "  body b sphere { radius 1 kg  mass 1 kg }",  # a mass for a length
    "  body b sphere { radius 1 cm  mass 1 kg  velocity (0, 1, 0) m }",  # a length for a velocity
    "  body b sphere { radius 1 cm  mass 1 kg  at (0, 1 m, 2 s) }",  # components that disagree
    "  body b sphere { radus 1 cm  mass 1 kg }",  # a misspelled property
    "  body b sphere { radius 1 cm  mass 1 kg }\n  constraint c nail(bb @ (0, 0, 0), (0, 0, 0))",  # unknown body
]


@pytest.mark.parametrize("body", MISTAKES)
def test_check_reports_what_isaac_check_reports_at_the_same_place(body, tmp_path):
    text = f"let h = 1 m\nscene s {{\n  time 0 s .. 1 s\n{body}\n}}\n"
    path = tmp_path / "s.isaac"
    path.write_text(text)
    with pytest.raises(SceneError) as cli:
        load_scene(path)
    found = check_text(text, path)
    assert found.scene is None
    expected = [(d.pos.line, d.pos.col, d.pos.length, d.message) for d in cli.value.diagnostics]
    assert [(f.diagnostic.pos.line, f.diagnostic.pos.col, f.diagnostic.pos.length, f.diagnostic.message)
            for f in found.findings] == expected
    assert all(f.path == path for f in found.findings)


def test_check_reads_the_text_given_not_the_file(tmp_path):
    path = tmp_path / "s.isaac"
    path.write_text("scene s { body b sphere { radius 1  mass 1 kg } }\n")
    assert check_text("scene s { body b sphere { radius 1 cm  mass 1 kg } }\n", path).findings == []


def test_check_reads_an_open_include_from_memory(tmp_path):
    (tmp_path / "sizes.isaac").write_text("let r = 1\n")
    text = 'include "sizes.isaac"\nscene s { body b sphere { radius r  mass 1 kg } }\n'
    assert check_text(text, tmp_path / "s.isaac").findings  # the file's `r` has no unit
    fixed = {(tmp_path / "sizes.isaac").resolve(): "let r = 1 cm\n"}
    assert check_text(text, tmp_path / "s.isaac", fixed).findings == []


def test_warnings_are_findings_with_their_place(tmp_path):
    text = "scene s {\n  time 0 s .. 1 s\n  body b static sphere { radius 1 cm  drag 0.5 }\n}\n"
    found = check_text(text, tmp_path / "s.isaac")
    assert found.scene is not None
    (warning,) = found.findings
    assert warning.diagnostic.severity == "warning" and warning.diagnostic.pos.line == 3


# -- the index --------------------------------------------------------------------------------------------------


def test_definitions_of_every_kind_and_their_uses():
    index = index_of(PARTS)
    kinds = {d.name: d.kind for d in index.definitions}
    assert kinds["spacing"] == "let" and kinds["wood"] == "material" and kinds["slider"] == "kind"
    assert kinds["arm"] == "part" and kinds["left"] == "instance" and kinds["tip"] == "body"
    assert kinds["pin"] == "constraint" and kinds["link{i}"] == "body" and kinds["s"] == "scene"
    spacing = index.resolve(find(index, 15, "spacing"))
    assert spacing.span.line == 1
    assert [r.span.line for r in index.uses(spacing)] == [15]
    assert index.resolve(find(index, 12, "wood")).kind == "material"
    assert index.resolve(find(index, 17, "slider")).span.line == 3  # a kind, used as a call
    assert index.resolve(find(index, 13, "arm")).kind == "part"


def test_scopes_members_and_names_made_in_loops():
    index = index_of(PARTS)
    assert index.resolve(find(index, 17, "tip")).span.line == 7  # left.tip: `tip` of part `arm`
    assert index.resolve(find(index, 17, "left")).kind == "instance"
    assert index.resolve(find(index, 18, "link2")).name == "link{i}"  # made by the loop
    assert index.resolve(find(index, 15, "i *")).kind == "loop variable"
    assert index.resolve(find(index, 7, "reach")).kind == "parameter"  # the part's, not a scene name
    assert index.resolve(find(index, 8, "base")).kind == "parameter"
    assert index.resolve(find(index, 8, "tip")).span.line == 7
    assert index.resolve(find(index, 18, "nail")) is None  # the library's, declared nowhere


def test_names_across_nested_includes(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "one.isaac").write_text('include "two.isaac"\nlet width = 3 cm\n')
    (tmp_path / "a" / "two.isaac").write_text("material steel { density 7800 kg/m3 }\n")
    text = 'include "a/one.isaac"\nscene s { body b box { size (width, 1 cm, 1 cm)  material steel } }\n'
    index = build_index(text, tmp_path / "s.isaac", lambda p: p.read_text() if p.is_file() else None)
    steel = index.resolve(find(index, 2, "steel"))
    assert steel.span.path == (tmp_path / "a" / "two.isaac").resolve() and steel.span.line == 1
    assert index.include_of(steel.span.path).span.line == 1  # through the root's include on line 1
    width = index.resolve(find(index, 2, "width"))
    assert width.span.path.name == "one.isaac" and width.span.line == 2


def test_a_text_that_does_not_parse_has_an_empty_index():
    index = index_of("scene s { body b sphere { radius 1 cm ")
    assert index.definitions == [] and index.at(index.root, 1, 17) is None


def test_every_shipped_scene_indexes_and_its_body_names_resolve():
    for path in sorted((ROOT / "scenes").glob("*.isaac")):
        index = build_index(path.read_text(), path.resolve(), lambda p: p.read_text() if p.is_file() else None)
        assert index.trees[path.resolve()] is not None, path
        bodies = {d.name for d in index.definitions if d.kind == "body"}
        for reference in index.references:
            if reference.name in bodies and reference.owner is None:
                assert index.resolve(reference) is not None, (path, reference)


# -- values and hover -------------------------------------------------------------------------------------------


def test_values_in_si_with_their_units():
    index = index_of(PARTS + "let area = 20 cm * 30 cm\nlet g = (0, -9.81, 0) m/s2\nlet n = 3\n")
    values = {d.name: format_typed(values) for d in index.definitions
              for values in [let_values(index).get(id(d))] if values is not None}
    assert values["spacing"] == "0.5 m"
    assert values["tilt"].startswith("0.523599 rad") and "(30 deg)" in values["tilt"]
    assert values["area"] == "0.06 m2" and values["g"] == "(0, -9.81, 0) m/s2" and values["n"] == "3"
    assert "half" not in values  # inside a part: it depends on the instance


def test_hover_of_a_let_a_body_and_a_property(tmp_path):
    path = tmp_path / "s.isaac"
    index = build_index(PARTS, path, lambda p: None)
    values = let_values(index)
    scene = check_text(PARTS, path).scene
    assert scene is not None
    text = hover_text(index, find(index, 15, "spacing"), values, scene)
    assert "let spacing = 0.5 m" in text and "spacing = 0.5 m" in text
    post = hover_text(index, find(index, 12, "post"), values, scene)
    assert "static box" in post and "size (0.1, 1, 0.1) m" in post and "mass: 0.06 kg" not in post
    link = hover_text(index, find(index, 18, "link2"), values, scene)  # 1 x 2 x 3 cm, 10 g
    assert "mass: 0.01 kg" in link and "inertia: principal moments" in link
    radius = find(index, 7, "radius")
    assert isinstance(radius, PropertyKey) and radius.table is vocabulary.BODY_PROPS
    text = hover_text(index, radius, values, scene)
    assert vocabulary.BODY_PROPS["radius"] in text and "a length" in text and "0.02 m" in text


# -- completion -------------------------------------------------------------------------------------------------


def labels_at(text: str, names=(), materials=()):
    offset = text.index("|")
    return {s.label for s in suggestions(place_of(text.replace("|", ""), offset), list(names), list(materials))}


@pytest.mark.parametrize("text, table", [
    ("scene s {\n  body b sphere {\n    |\n  }\n}", vocabulary.BODY_PROPS),
    ("scene s {\n  for i in 0 .. 2 { body link{i} box { m|", vocabulary.BODY_PROPS),
    ("scene s {\n  body h { part x sphere { | } }", vocabulary.PART_PROPS),
    ("scene s {\n  material m {\n    |", vocabulary.MATERIAL_PROPS),
    ("# a { in a comment\nscene s { constraint c nail(b @ (0, 0, 0), (0, 0, 0)) { |", vocabulary.CONSTRAINT_PROPS),
    ('scene s { listener { "{" |', vocabulary.LISTENER_PROPS),
])
def test_completion_offers_the_properties_of_the_block(text, table):
    labels = labels_at(text)
    assert set(table) <= labels
    assert "gravity" not in labels


def test_completion_at_item_level_units_and_names():
    assert {"body", "material", "constraint", "let", "gravity", "time"} <= labels_at("scene s {\n  |\n}")
    after_number = labels_at("scene s { body b sphere { radius 10 |")
    assert {"cm", "m", "mm", "kg/m3"} <= after_number and "mass" in after_number
    assert "cm" in labels_at("scene s { body b sphere { radius 10c|")
    value = labels_at("scene s { body b sphere { at (0, |", names=[("arm", "let")])
    assert "arm" in value and "pi" in value and "cm" not in value
    assert labels_at("scene s { body b sphere { material |", materials=["steel"]) == {"steel"}


# -- the outline, and what the server imports -------------------------------------------------------------------


def test_outline_nests_declarations_in_the_scene():
    items = outline(index_of(PARTS))
    names = [(i.name, i.kind) for i in items]
    assert ("arm", "part") in names and ("s", "scene") in names and ("spacing", "let") in names
    scene = next(i for i in items if i.kind == "scene")
    inside = {(c.name, c.kind) for c in scene.children}
    assert {("post", "body"), ("left", "instance"), ("slide", "constraint"), ("link{i}", "body")} <= inside


def test_the_server_never_imports_the_engine():
    code = ("import sys, isaac.lsp.server; "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('isaac_runtime', 'numba')]; "
            "print(bad); sys.exit(1 if bad else 0)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
