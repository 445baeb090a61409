"""Fuzzing the front end: token-level mutations of the example scenes must give a valid IR or a SceneError whose
every diagnostic has a position, never another exception (a traceback is a bug in isaac, not in the scene).

The default run is derandomized (the same ~300 examples every time, so CI is deterministic); the `slow` variant
explores 10,000 fresh ones: `pytest tests/lang/test_fuzz.py -m slow`.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from isaac_lang import ir
from isaac_lang.diagnostics import SceneError
from isaac_lang.expand import Limits
from isaac_lang.load import load_text

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"
DATA_DIR = Path(__file__).resolve().parent / "data"
# the seeds: the example scenes and the test fixtures (includes, parts, every construct), by path
SEEDS = {path: path.read_text(encoding="utf-8")
         for path in sorted(SCENES_DIR.glob("*.isaac")) + sorted(DATA_DIR.glob("*.isaac"))}
LINES = sorted({line for text in SEEDS.values() for line in text.splitlines() if line.strip()})

# words, numbers (with exponents), `..`, strings, comments, whitespace, any other single character
TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:\{[^}\s]*\}[A-Za-z0-9_]*)*|\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|\.\.|"[^"\n]*"'
                   r"|(?:#|//)[^\n]*|\s+|.", re.S)

KEYWORDS = ["scene", "let", "include", "material", "body", "constraint", "kind", "force", "wind", "sound", "camera",
            "light", "solver", "exclude", "part", "use", "for", "in", "during", "from", "until", "on", "world", "keys",
            "static", "kinematic", "sphere", "box", "plane", "mesh", "nail", "point", "orient", "weld", "gear", "rope",
            "tx", "rz", "t", "pi", "sin", "envelope", "modal", "impulse", "always", "collide", "spring", "load"]
NUMBERS = ["0", "1", "-1", "0.5", ".5", "1e400", "1e-400", "1e308", "100000000", "2147483648", "3.14159", "0.0"]
UNITS = ["m", "cm", "kg", "s", "ms", "deg", "rad", "Hz", "N", "kg/m3", "m/s2", "N*s/m", "GPa", "dB", "rad/s"]
GARBAGE = list("{}()[],;:@.=+-*/^#\"'\\$%&|~`?!<>") + ["..", "->", "\n", "\t", "é", "∞", "\x00", "{i}", "x{", "}{"]
INSERTS = KEYWORDS + NUMBERS + UNITS + GARBAGE


def tokens(text: str) -> list:
    return TOKEN.findall(text)


@st.composite
def mutated_scene(draw):
    path = draw(st.sampled_from(sorted(SEEDS)))
    toks = tokens(SEEDS[path])
    for _ in range(draw(st.integers(1, 4))):
        if not toks:
            break
        kind = draw(st.sampled_from(["delete", "duplicate", "swap", "truncate", "insert", "replace", "splice"]))
        i = draw(st.integers(0, len(toks) - 1))
        if kind == "delete":
            del toks[i]
        elif kind == "duplicate":
            toks.insert(i, toks[i])
        elif kind == "swap":
            j = draw(st.integers(0, len(toks) - 1))
            toks[i], toks[j] = toks[j], toks[i]
        elif kind == "truncate":
            toks = toks[:i]
        elif kind == "splice":  # a line of another scene, dropped anywhere
            toks.insert(i, "\n" + draw(st.sampled_from(LINES)) + "\n")
        else:
            word = draw(st.sampled_from(INSERTS) | st.text(max_size=3))
            spaced = draw(st.booleans())
            piece = f" {word} " if spaced else word
            if kind == "insert":
                toks.insert(i, piece)
            else:
                toks[i] = piece
    return path, "".join(toks)


def check_outcome(path: Path, text: str) -> None:
    """Either a scene whose IR prints, or a SceneError with positioned diagnostics; nothing else."""
    try:
        loaded = load_text(text, path.name, folder=path.parent, limits=Limits(max_items=2000))
    except SceneError as error:
        assert error.diagnostics, "a SceneError without diagnostics"
        for diagnostic in error.diagnostics:
            pos = diagnostic.pos
            assert pos is not None, f"no position: {diagnostic.message}"
            assert pos.file and pos.line >= 1 and pos.col >= 1, f"bad position {pos}: {diagnostic.message}"
        error.format()  # printing the diagnostics must work too
        return
    ir.to_json(loaded.scene)


@settings(max_examples=300, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
def test_mutated_scenes_load_or_report(case):
    check_outcome(*case)


@pytest.mark.slow
@settings(max_examples=10_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
def test_mutated_scenes_load_or_report_at_scale(case):
    check_outcome(*case)


def test_the_tokenizer_round_trips():
    for text in SEEDS.values():
        assert "".join(tokens(text)) == text


@pytest.mark.parametrize("text", [
    "scene s { for i in 0 .. 1e400 { } }",
    "scene s { body b sphere { radius 1 m  mass 0/0 kg } }",
    "scene s { body b sphere { radius 1e400 m  mass 1 kg } }",
    "scene s { body b{1e400} sphere { radius 1 m  mass 1 kg } }",
    "scene s { body b{+} sphere { radius 1 m  mass 1 kg } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg  orient quat(0, 0, 0, 0) } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg  at (log(0), 0, 0) } }",
    "scene s { seed 1e400 }",
    "scene s { frames 0/0 }",
    "part p() { use p a()  use p b() }\nscene s { use p top() }",
    "scene s { for i in 0 .. 100000 { for j in 0 .. 100000 { let x = 1 } } }",
])
def test_crashes_found_by_the_fuzzer_stay_fixed(text):
    with pytest.raises(SceneError) as caught:
        load_text(text, "s.isaac", limits=Limits(max_items=2000))
    assert all(d.pos is not None for d in caught.value.diagnostics)
