"""Every scene the documentation shows runs: a short run of each (its first RUN_SECONDS), with no numerical
blow-up and a constraint error that stays small once switched-on constraints have settled (runtime/checks.py).
An example whose constraints cannot all hold, or that blows up, is a documentation bug."""
from __future__ import annotations

import pytest

from isaac_lang.load import load_text
from isaac_runtime.run import RunOptions, simulate

from ..doc_examples import example_folder, scene_examples

# long enough to pass the switch-on of docs/language.md's `windows` example (1 s) and its settling
RUN_SECONDS = 2.0
# a joint that holds keeps 1e-14 .. 1e-6 m; a gap that does not close is centimetres to metres
SETTLED_ERROR = 1e-3
EXAMPLES = [e for e in scene_examples() if e.error is None]


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return example_folder(tmp_path_factory.mktemp("docs"))


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.id for e in EXAMPLES])
def test_every_scene_example_runs(example, folder):
    scene = load_text(example.text, "example.isaac", folder=folder).scene
    until = min(scene.time.end, scene.time.start + RUN_SECONDS)
    result = simulate(scene, RunOptions(until=until, folder=folder))
    assert result.error is None, f"{example.doc} line {example.line}: {result.error}"
    settled = result.report["constraint_error_settled"]
    assert settled is None or settled < SETTLED_ERROR, (
        f"{example.doc} line {example.line} ({example.name}): the constraint error stays at {settled:.3g} "
        f"(t = {result.report['constraint_error_settled_time']:.3g} s): constraints that cannot all hold")
