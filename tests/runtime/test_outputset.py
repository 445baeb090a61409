"""runtime/outputs/outputset.py: a run's files replace the previous run's as a whole; the user's files stay; what killed
runs leave beside the folder is reclaimed; a folder that is not isaac's is refused. And strict JSON outputs."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main
from isaac_ir.diagnostics import SceneError
from isaac_runtime.outputs import outputset
from isaac_runtime.outputs import finite_or_null, write_json
from isaac_runtime.outputs.outputset import MANIFEST, OutputSet, read_manifest, reclaim

from .test_run import BLOWS_UP

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def write_set(out: Path, files: dict, command: str = "run", keep=None) -> list:
    with OutputSet(out, command, keep=keep) as new:
        paths = []
        for name, text in files.items():
            path = new.path / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            paths.append(path)
        return new.commit(paths, scene="s")


def listing(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != MANIFEST}


def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def leftovers(parent: Path) -> list:
    return sorted(p.name for p in parent.iterdir() if outputset.LEFTOVER.match(p.name))


@pytest.fixture(params=["exchange", "two renames"])
def swap_mode(request, monkeypatch):
    """Every swap test both ways: the one-step exchange (Linux) and the two renames elsewhere."""
    if request.param == "two renames":
        monkeypatch.setattr(outputset, "_exchange_call", None)
    elif outputset._exchange_call is None:
        pytest.skip("no renameat2 here")
    return request.param


def test_a_new_set_replaces_the_old_one_whole_and_keeps_the_users_files(tmp_path, swap_mode):
    out = tmp_path / "out" / "s"
    write_set(out, {"a.txt": "old", "b.txt": "old", "plots/p.png": "old"})
    (out / "notes.txt").write_text("mine")
    (out / "plots" / "mine.png").write_text("mine")
    (out / "drafts").mkdir()
    written = write_set(out, {"a.txt": "new", "c.txt": "new"})
    assert listing(out) == {"a.txt": "new", "c.txt": "new", "notes.txt": "mine", "plots/mine.png": "mine"}
    assert (out / "drafts").is_dir()
    assert read_manifest(out)["files"] == ["a.txt", "c.txt"] and read_manifest(out)["state"] == "whole"
    assert written == [out / "a.txt", out / "c.txt"]
    assert leftovers(out.parent) == [] and not [p for p in out.rglob(".*") if p.name != MANIFEST]


def test_a_set_left_without_commit_leaves_the_old_one(tmp_path):
    out = tmp_path / "s"
    write_set(out, {"a.txt": "old"})
    with pytest.raises(KeyboardInterrupt):
        with OutputSet(out, "run") as new:
            (new.path / "a.txt").write_text("half")
            raise KeyboardInterrupt
    assert listing(out) == {"a.txt": "old"} and leftovers(tmp_path) == []


def test_the_old_folder_is_whole_until_the_new_one_is_complete(tmp_path, monkeypatch, swap_mode):
    out = tmp_path / "s"
    write_set(out, {"a.txt": "old", "b.txt": "old"})
    real = outputset._swap
    seen = {}

    def swap(staging, target):
        seen["old"], seen["new"] = listing(target), listing(staging)
        seen["manifest"] = read_manifest(staging)
        return real(staging, target)

    monkeypatch.setattr(outputset, "_swap", swap)
    write_set(out, {"a.txt": "new", "c.txt": "new"})
    assert seen["old"] == {"a.txt": "old", "b.txt": "old"}
    assert seen["new"] == {"a.txt": "new", "c.txt": "new"} and seen["manifest"]["state"] == "whole"


def test_a_folder_isaac_did_not_write_is_refused(tmp_path, capsys, monkeypatch):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(SceneError, match="holds files isaac did not write"):
        write_set(mine, {"a.txt": "x"})
    assert listing(mine) == {"thesis.tex": "years of work"} and leftovers(tmp_path) == []
    # through the command: exit 2 before anything runs, the folder untouched; the current folder likewise
    code = main(["run", str(SCENES / "pendulum.isaac"), "--out", str(mine), "--until", "0.1"])
    assert code == 2 and "holds files isaac did not write (thesis.tex)" in capsys.readouterr().err
    assert listing(mine) == {"thesis.tex": "years of work"}
    ours = tmp_path / "ours"
    write_set(ours, {"a.txt": "x"})
    monkeypatch.chdir(ours)
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", ".", "--until", "0.1"]) == 2
    assert "is the current folder" in capsys.readouterr().err and listing(ours) == {"a.txt": "x"}


def test_an_earlier_isaacs_folder_is_adopted_and_its_other_files_kept(tmp_path, swap_mode):
    out = tmp_path / "old"
    out.mkdir()
    (out / "ir.json").write_text(json.dumps({"schema": "isaac-ir/1"}))
    (out / "report.json").write_text("{}")
    (out / "viewer.html").write_text("old viewer")
    (out / "notes.txt").write_text("mine")
    write_set(out, {"ir.json": "{}", "report.json": "{}"})
    assert listing(out) == {"ir.json": "{}", "report.json": "{}", "notes.txt": "mine"}  # the old viewer went


def test_an_empty_folder_is_taken(tmp_path):
    (tmp_path / "empty").mkdir()
    write_set(tmp_path / "empty", {"a.txt": "x"})
    assert listing(tmp_path / "empty") == {"a.txt": "x"}


def test_what_killed_runs_left_is_reclaimed(tmp_path):
    out = tmp_path / "s"
    write_set(out, {"a.txt": "set", "b.txt": "set"})
    pid = dead_pid()
    # a staging folder killed while writing: removed
    writing = tmp_path / f".s.isaac-new-{pid}-0000aaaa"
    writing.mkdir()
    (writing / MANIFEST).write_text(json.dumps({"format": outputset.FORMAT, "state": "writing"}))
    (writing / ".trajectory.npz.1a2b3c").write_text("half")
    # an old set killed while it was being removed after the swap, holding a file the user put there meanwhile
    old = tmp_path / f".s.isaac-new-{pid}-0000bbbb"
    old.mkdir()
    (old / MANIFEST).write_text(json.dumps({"format": outputset.FORMAT, "state": "whole", "files": ["a.txt"]}))
    (old / "a.txt").write_text("older")
    (old / "late.txt").write_text("mine, saved during the swap")
    # a whole set whose folder is gone (killed between the two renames): put back
    whole = tmp_path / f".t.isaac-old-{pid}-0000cccc"
    whole.mkdir()
    (whole / MANIFEST).write_text(json.dumps({"format": outputset.FORMAT, "state": "whole", "files": ["x.txt"]}))
    (whole / "x.txt").write_text("t's set")
    # not ours: a name like ours but nothing of ours in it; and one of a live process
    foreign = tmp_path / f".s.isaac-new-{pid}-0000dddd"
    foreign.mkdir()
    (foreign / "thing").write_text("someone else's")
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        live = tmp_path / f".s.isaac-new-{sleeper.pid}-0000eeee"
        live.mkdir()
        (live / MANIFEST).write_text("{}")
        reclaim(tmp_path, again=True)
        assert leftovers(tmp_path) == [foreign.name, live.name]
    finally:
        sleeper.kill()
        sleeper.wait()
    assert listing(out) == {"a.txt": "set", "b.txt": "set", "late.txt": "mine, saved during the swap"}
    assert listing(tmp_path / "t") == {"x.txt": "t's set"}


def test_export_adds_to_the_runs_set_and_the_next_run_replaces_it(tmp_path, capsys):
    scene, out = SCENES / "pendulum.isaac", tmp_path / "o"
    assert main(["run", str(scene), "--out", str(out), "--until", "0.2"]) == 0
    trajectory = (out / "trajectory.npz").read_bytes()
    assert main(["export", str(scene), "--out", str(out), "--format", "gltf"]) == 0
    assert main(["export", str(scene), "--out", str(out), "--format", "rib", "--frames", "0:4"]) == 0
    assert main(["export", str(scene), "--out", str(out), "--format", "rib", "--frames", "5"]) == 0
    manifest = read_manifest(out)
    assert (out / "trajectory.npz").read_bytes() == trajectory  # the run's own files stay in the set
    assert "pendulum.gltf" in manifest["files"] and manifest["run"] == "complete"
    assert sorted(p.name for p in (out / "rib").iterdir()) == ["pendulum.0005.rib"]  # rib/ replaced whole
    assert main(["run", str(scene), "--out", str(out), "--until", "0.1"]) == 0
    assert not (out / "pendulum.gltf").exists() and not (out / "rib").exists()


def test_json_outputs_are_strict_and_non_finite_figures_are_null(tmp_path):
    data = {"a": float("nan"), "b": [np.float64("inf"), 1.5, np.int64(3)], "c": {"d": -np.inf}, "e": np.arange(2.0)}
    assert finite_or_null(data) == {"a": None, "b": [None, 1.5, 3], "c": {"d": None}, "e": [0.0, 1.0]}
    write_json(tmp_path / "x.json", data)
    assert json.loads((tmp_path / "x.json").read_text(), parse_constant=_refuse)["c"]["d"] is None


def _refuse(name):
    raise AssertionError(f"not JSON: {name}")


def test_a_blow_up_writes_a_strict_report_with_its_error(tmp_path, capsys, monkeypatch):
    from isaac_runtime import run

    real = run.simulate

    def blown(scene, options):  # a blow-up whose figures are no longer numbers
        result = real(scene, options)
        result.report.update(energy_drift=float("nan"), energy_drift_relative=float("inf"),
                             max_constraint_error=float("nan"))
        return result

    monkeypatch.setattr(run, "simulate", blown)
    scene = tmp_path / "bad.isaac"
    scene.write_text(BLOWS_UP)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out)]) == 2
    report = json.loads((out / "report.json").read_text(), parse_constant=_refuse)
    assert report["error"].startswith("numerical blow-up at t =")
    assert report["energy_drift"] is None and report["energy_drift_relative"] is None
    assert report["max_constraint_error"] is None
    assert read_manifest(out)["run"] == "blow-up"


def test_sweep_variants_are_stored_whole(tmp_path, swap_mode):
    from isaac.sweep.table import store_outputs
    from isaac.sweep.task import Task

    task = Task(index=0, id="v0", values={"x": "1"})
    target = Path(store_outputs(tmp_path, task, {"report.json": b"{}", "trajectory.npz": b"old"}))
    store_outputs(tmp_path, task, {"report.json": b"{}"})
    assert sorted(p.name for p in target.iterdir()) == [MANIFEST, "report.json"]
    assert leftovers(target.parent) == []


def test_a_temporary_in_an_old_set_killed_while_it_was_marked_is_nobodys(tmp_path):
    # killed while remove_set rewrote the old set's manifest (`removing`): its temporary is isaac's, not the user's
    out = tmp_path / "s"
    write_set(out, {"a.txt": "set"})
    old = tmp_path / f".s.isaac-new-{dead_pid()}-0000ffff"
    old.mkdir()
    (old / MANIFEST).write_text(json.dumps({"format": outputset.FORMAT, "state": "whole", "files": ["a.txt"]}))
    (old / "a.txt").write_text("older")
    (old / f".{MANIFEST}.0123456789ab").write_text("{half a manifest")
    (old / ".a.txt.abcdef012345").write_text("half")
    (old / ".mine.0123456789ab").write_text("the user's, named like a temporary of a file that is not isaac's")
    # killed between the staging folder and its manifest, or between the removal of a set's manifest and of it
    (tmp_path / f".s.isaac-new-{dead_pid()}-0000eeee").mkdir()
    reclaim(tmp_path, again=True)
    assert leftovers(tmp_path) == []
    assert sorted(p.name for p in out.iterdir()) == [".isaac-outputs.json", ".mine.0123456789ab", "a.txt"]


def test_a_run_that_cannot_write_its_report_leaves_the_old_set_and_says_why(tmp_path, capsys, monkeypatch):
    import errno

    from isaac_runtime import run

    out = tmp_path / "out"
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(out), "--until", "0.1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real = run.write_json

    def full_disk(path, data):
        if Path(path).name == "report.json":  # written last: every other file of the new set is there already
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(path, data)

    monkeypatch.setattr(run, "write_json", full_disk)
    capsys.readouterr()
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(out), "--until", "0.2"]) == 2
    err = capsys.readouterr().err
    assert f"error: cannot write the outputs into {out}: No space left on device" in err and "internal" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before and leftovers(tmp_path) == []


def test_a_staging_folder_is_never_taken_for_the_users_files(tmp_path, monkeypatch):
    # a staging folder killed while writing, then a run killed while reclaiming it: its files are the new set's,
    # none goes into the folder (the old set, without sound, stays as it was)
    out = tmp_path / "s"
    write_set(out, {"report.json": "old"})
    staging = tmp_path / f".s.isaac-new-{dead_pid()}-0000abcd"
    staging.mkdir()
    (staging / MANIFEST).write_text(json.dumps({"format": outputset.FORMAT, "state": "writing"}))
    (staging / "audio.wav").write_text("the new set's sound")
    real_unlink = os.unlink

    def killed(path, *args, **kwargs):  # Ctrl-C at the reclaim's first removal
        monkeypatch.setattr(os, "unlink", real_unlink)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "unlink", killed)
    with pytest.raises(KeyboardInterrupt):
        reclaim(tmp_path, again=True)
    assert read_manifest(staging)["state"] == "writing" and (staging / "audio.wav").exists()
    reclaim(tmp_path, again=True)
    assert listing(out) == {"report.json": "old"} and leftovers(tmp_path) == []
