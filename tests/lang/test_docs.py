"""docs/language.md stays true: every ```isaac block that declares a scene loads without error (includes resolve
against tests/lang/data, where the example's lib/materials.isaac lives), and the reference names every
vocabulary the front end knows."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from isaac_lang import expr as E
from isaac_lang import lower, lower_constraints, lower_expr, units
from isaac_lang.load import load_text
from isaac_lang.syntax import KEYWORDS

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "language.md"
DATA = Path(__file__).resolve().parent / "data"
TEXT = DOC.read_text(encoding="utf-8")
BLOCKS = re.findall(r"^```isaac\n(.*?)^```", TEXT, re.S | re.M)
SCENES = [b for b in BLOCKS if re.search(r"\bscene\s+\w+\s*\{", b)]


def test_the_reference_has_examples():
    assert len(SCENES) >= 20


@pytest.mark.parametrize("block", SCENES, ids=[re.search(r"\bscene\s+(\w+)", b).group(1) for b in SCENES])
def test_every_scene_example_loads(block):
    loaded = load_text(block, "example.isaac", folder=DATA)
    assert loaded.scene.name


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
