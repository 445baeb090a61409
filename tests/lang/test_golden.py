"""Golden canonical IR of every example scene (scenes/golden/<name>.ir.json), compared structurally: same keys,
same strings and booleans, floats equal to a relative tolerance of 1e-12. A mismatch names the key path.

After a deliberate change of the IR or of a scene: `python tests/lang/regen_goldens.py`, then review the diff.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from isaac_lang import ir
from isaac_lang.load import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "scenes").glob("*.isaac"))
REGEN = "python tests/lang/regen_goldens.py"
REL_TOL = 1e-12


def first_difference(expected, actual, path="$"):
    """The key path of the first difference between two JSON values, with what differs; None when equal."""
    if isinstance(expected, dict) and isinstance(actual, dict):
        for key in sorted(set(expected) | set(actual)):
            if key not in actual:
                return f"{path}.{key}: missing (golden has {expected[key]!r})"
            if key not in expected:
                return f"{path}.{key}: not in the golden (value {actual[key]!r})"
            found = first_difference(expected[key], actual[key], f"{path}.{key}")
            if found:
                return found
        return None
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return f"{path}: {len(actual)} items, the golden has {len(expected)}"
        for i, (e, a) in enumerate(zip(expected, actual)):
            found = first_difference(e, a, f"{path}[{i}]")
            if found:
                return found
        return None
    numbers = (int, float)
    if isinstance(expected, numbers) and isinstance(actual, numbers) \
            and not isinstance(expected, bool) and not isinstance(actual, bool):
        if math.isclose(expected, actual, rel_tol=REL_TOL, abs_tol=1e-300):
            return None
        return f"{path}: {actual!r}, the golden has {expected!r}"
    if expected != actual or type(expected) is not type(actual):
        return f"{path}: {actual!r}, the golden has {expected!r}"
    return None


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_scene_matches_its_golden_ir(scene):
    golden = ROOT / "scenes" / "golden" / f"{scene.stem}.ir.json"
    assert golden.exists(), f"no golden IR for {scene.name}: run `{REGEN}`"
    actual = json.loads(ir.to_json(load_scene(scene).scene))
    expected = json.loads(golden.read_text(encoding="utf-8"))
    difference = first_difference(expected, actual)
    assert difference is None, (f"{scene.name}: the IR differs from {golden.relative_to(ROOT)} at {difference}\n"
                                f"if the change is meant, regenerate with `{REGEN}` and review the diff")


def test_every_golden_has_a_scene():
    stems = {p.stem for p in SCENES}
    orphans = [g.name for g in (ROOT / "scenes" / "golden").glob("*.ir.json") if g.name[:-len(".ir.json")] not in stems]
    assert not orphans, f"goldens without a scene: {orphans}"


def test_the_ir_is_canonical_and_versioned():
    scene = load_scene(ROOT / "scenes" / "pendulum.isaac").scene
    text = ir.to_json(scene)
    data = json.loads(text)
    assert data["schema"] == ir.SCHEMA == "isaac-ir/1"
    assert text == json.dumps(data, sort_keys=True, indent=1)  # sorted keys, stable layout
    assert ir.to_json(load_scene(ROOT / "scenes" / "pendulum.isaac").scene) == text  # deterministic
    assert data["bodies"][0]["source"] == "pendulum.isaac:19:3"  # positions kept, relative to the scene


def test_the_comparison_names_the_key_path():
    golden = {"bodies": [{"mass": 1.0, "name": "bob"}], "seed": 0}
    assert first_difference(golden, {"bodies": [{"mass": 1.0 + 1e-14, "name": "bob"}], "seed": 0}) is None
    assert first_difference(golden, {"bodies": [{"mass": 1.1, "name": "bob"}], "seed": 0}) \
        == "$.bodies[0].mass: 1.1, the golden has 1.0"
    assert "missing" in first_difference(golden, {"bodies": [{"mass": 1.0, "name": "bob"}]})
    assert first_difference({"a": True}, {"a": 1}) is not None
