"""Golden canonical IR of every example scene (scenes/<name>.golden/ir.json, written by `isaac golden --update`):
what the scene means, without the source positions (kept apart in positions.json), so that a comment or a moved
declaration changes nothing. Compared structurally: floats to a relative 1e-9, a difference named by its key path.

The whole golden of each scene (IR, trajectory, events, report, audio) is checked by the pytest plugin
(scenes/<name>.isaac::golden); this file checks the IR alone, without running anything.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from isaac_ir import ir
from isaac.golden.canonical import split, without_positions
from isaac.golden.compare import compare_ir
from isaac.golden.store import golden_folder
from isaac_lang.load import load_scene, load_text

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "scenes").glob("*.isaac"))
REGEN = "isaac golden --update scenes/*.isaac"


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_scene_matches_its_golden_ir(scene):
    golden = golden_folder(scene) / "ir.json"
    assert golden.exists(), f"no golden for {scene.name}: run `{REGEN}`"
    meaning, positions = split(ir.to_data(load_scene(scene).scene))
    differences = compare_ir(json.loads(golden.read_text(encoding="utf-8")), meaning, 1e-9)
    assert not differences, (f"{scene.name}: the IR differs from {golden.relative_to(ROOT)}: "
                             + "; ".join(map(str, differences)) + f"\nif the change is meant: `{REGEN}`")
    assert positions["file"] == scene.name


def test_every_golden_has_a_scene():
    stems = {p.stem for p in SCENES}
    orphans = [g.name for g in (ROOT / "scenes").glob("*.golden") if g.name[:-len(".golden")] not in stems]
    assert not orphans, f"goldens without a scene: {orphans}"


def test_the_ir_is_canonical_and_versioned():
    scene = load_scene(ROOT / "scenes" / "pendulum.isaac").scene
    text = ir.to_json(scene)
    data = json.loads(text)
    assert data["schema"] == ir.SCHEMA == "isaac-ir/1"
    assert text == json.dumps(data, sort_keys=True, indent=1)  # sorted keys, stable layout
    assert ir.to_json(load_scene(ROOT / "scenes" / "pendulum.isaac").scene) == text  # deterministic
    assert data["bodies"][0]["source"] == "pendulum.isaac:19:3"  # positions kept, relative to the scene


def test_comments_and_blank_lines_move_positions_only():
    text = (ROOT / "scenes" / "pendulum.isaac").read_text(encoding="utf-8")
    edited = "# a comment\n\n" + text.replace("  body bob", "  # the bob\n  body bob")
    before = split(ir.to_data(load_text(text, "pendulum.isaac", folder=ROOT / "scenes").scene))
    after = split(ir.to_data(load_text(edited, "pendulum.isaac", folder=ROOT / "scenes").scene))
    assert before[0] == after[0]
    assert before[1]["bodies[bob]"] == "pendulum.isaac:19:3" and after[1]["bodies[bob]"] == "pendulum.isaac:22:3"
    assert "source" not in json.dumps(before[0])


def test_a_mesh_file_is_meaning_and_stays():
    meaning, positions = split({"file": "a.isaac", "bodies": [{"name": "rock", "source": "a.isaac:3:3",
                                                               "shape": {"file": "assets/rock.obj"}}]})
    assert meaning == {"bodies": [{"name": "rock", "shape": {"file": "assets/rock.obj"}}]}
    assert positions == {"file": "a.isaac", "bodies[rock]": "a.isaac:3:3"}


def test_the_comparison_names_the_key_path():
    golden = {"bodies": [{"mass": 1.0, "name": "bob"}], "seed": 0}
    assert compare_ir(golden, {"bodies": [{"mass": 1.0 + 1e-14, "name": "bob"}], "seed": 0}, 1e-9) == []
    (found,) = compare_ir(golden, {"bodies": [{"mass": 1.1, "name": "bob"}], "seed": 0}, 1e-9)
    assert str(found) == "ir: bodies[bob].mass: 1.1, the golden has 1.0 (+10%)"
    assert "gone" in str(compare_ir(golden, {"bodies": [{"mass": 1.0, "name": "bob"}]}, 1e-9)[0])
    assert compare_ir({"a": True}, {"a": 1}, 1e-9)


def test_named_items_are_matched_by_name():
    golden = {"bodies": [{"name": "a", "mass": 1.0}, {"name": "b", "mass": 2.0}]}
    actual = {"bodies": [{"name": "a", "mass": 1.0}, {"name": "new", "mass": 5.0}, {"name": "b", "mass": 2.0}]}
    found = [str(f) for f in compare_ir(golden, actual, 1e-9)]
    assert found == ["ir: bodies[new]: new (not in the golden)"]


def test_warnings_lose_their_positions():
    assert without_positions("pendulum.isaac:5:3: constraint `c` starts after the scene ends") == \
        "constraint `c` starts after the scene ends"
