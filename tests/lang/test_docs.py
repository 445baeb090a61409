"""The documentation stays true: every scene a page shows loads without error (a mistake shown on purpose fails
with its message; tests/runtime/test_docs_examples.py runs them all), and docs/language.md names every word of
the vocabulary the front end knows."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from isaac_ir import expr as E
from isaac_ir import units
from isaac_lang import lower, lower_constraints, lower_expr
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_lang.syntax import KEYWORDS

from ..doc_examples import example_folder, scene_examples

ROOT = Path(__file__).resolve().parents[2]
TEXT = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
EXAMPLES = scene_examples()


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return example_folder(tmp_path_factory.mktemp("docs"))


def test_the_reference_has_examples():
    assert len([e for e in EXAMPLES if e.doc == "docs/language.md"]) >= 20
    assert {e.doc for e in EXAMPLES} >= {"docs/language.md", "docs/tutorial.md", "README.md"}


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_every_scene_example_loads(example, folder):
    if example.error is None:
        assert load_text(example.text, "example.isaac", folder=folder).scene.name == example.name
        return
    with pytest.raises(SceneError) as raised:
        load_text(example.text, "example.isaac", folder=folder)
    assert example.error in str(raised.value)


@pytest.mark.parametrize("table,words", [
    ("keywords", KEYWORDS),
    ("settings", lower.SETTINGS), ("solver", lower.SOLVER_PROPS), ("camera", lower.CAMERA_PROPS),
    ("light", lower.LIGHT_PROPS), ("material", lower.MATERIAL_PROPS), ("body", lower.BODY_PROPS),
    ("wind", lower.WIND_PROPS), ("sound", lower.SOUND_PROPS), ("listener", lower.LISTENER_PROPS),
    ("audio", lower.AUDIO_PROPS), ("shapes", lower.SHAPES), ("motions", lower.MOTIONS),
    ("constraint", lower_constraints.CONSTRAINT_PROPS), ("force", lower_constraints.FORCE_PROPS),
    ("library", lower_constraints.LIBRARY), ("functions", E.ARITY), ("constants", E.CONSTANTS),
    ("signals", lower_expr.SIGNAL_FUNCTIONS), ("audio nodes", lower_expr.AUDIO_FUNCTIONS),
    ("audio signals", lower_expr.AUDIO_SIGNALS), ("units", units.UNITS),
])
def test_every_word_of_the_language_is_documented(table, words):
    missing = [w for w in words if f"`{w}" not in TEXT and not re.search(rf"[`\s(]{re.escape(w)}[\s(`,]", TEXT)]
    assert not missing, f"docs/language.md does not mention these {table}: {missing}"
