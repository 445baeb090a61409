"""docs/outputs.md stays true: every file `isaac run` writes, and every field of each, is documented there."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from isaac.cli import main
from isaac_runtime.outputs import OWNED_FILES, OWNED_PLOTS
from isaac_runtime.outputs.outputset import MANIFEST

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "outputs.md").read_text(encoding="utf-8")


def keys(value, prefix=""):
    """Every key of a JSON value, nested ones too."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield key
            yield from keys(item)
    elif isinstance(value, list):
        for item in value:
            yield from keys(item)


def test_every_output_file_and_field_is_documented(tmp_path, capsys):
    out = tmp_path / "out"
    # collisions, contact, sound: every file and every field
    assert main(["run", str(ROOT / "scenes" / "bar.isaac"), "--out", str(out), "--until", "0.4", "--plots"]) == 0
    written = {p.name for p in out.iterdir()} | {f"plots/{p.name}" for p in (out / "plots").iterdir()}
    assert written == set(OWNED_FILES) | {"plots", MANIFEST} | {f"plots/{name}" for name in OWNED_PLOTS}
    for name in OWNED_FILES + OWNED_PLOTS + (MANIFEST,):
        assert f"{name}" in DOC, f"docs/outputs.md does not name {name}"
    undocumented = [k for k in set(keys(json.loads((out / "report.json").read_text()))) if f"`{k}`" not in DOC]
    assert not undocumented, f"report.json fields not in docs/outputs.md: {undocumented}"
    events = json.loads((out / "events.json").read_text())
    assert events and not [k for k in set(keys(events)) if f"`{k}`" not in DOC]
    with np.load(out / "trajectory.npz", allow_pickle=False) as data:
        assert not [k for k in data.files if f"`{k}`" not in DOC]


def test_every_field_and_state_of_the_manifest_is_documented(tmp_path, capsys):
    from isaac_runtime.outputs.outputset import read_manifest
    from isaac.sweep.table import store_outputs
    from isaac.sweep.task import Task

    out = tmp_path / "out"
    assert main(["run", str(ROOT / "scenes" / "pendulum.isaac"), "--out", str(out), "--until", "0.1"]) == 0
    store_outputs(tmp_path / "sweep", Task(index=0, id="v0", values={"x": "1"}), {"report.json": b"{}"})
    manifests = [read_manifest(out), read_manifest(tmp_path / "sweep" / "variants" / "v0")]
    fields = {key for manifest in manifests for key in manifest}
    assert {"format", "state", "command", "pid", "written", "files", "scene", "run", "variant"} <= fields
    assert not [k for k in fields if f"`{k}`" not in DOC], "manifest fields not in docs/outputs.md"
    for word in ("`writing`", "`whole`", "`removing`", "`adopted`", "`isaac-outputs/1`", "`.NAME.isaac-new-*`"):
        assert word in DOC, f"docs/outputs.md does not say {word}"
