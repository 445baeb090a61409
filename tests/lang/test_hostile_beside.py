"""The second-pass corpus (tests/lang/hostile_beside.py): files beside a scene, numbers that break a formula,
and the commands other than check and run. By default the cases refused before any run, in this process;
`-m slow` every case in an `isaac` process of its own (20 s, 4 GB)."""
from __future__ import annotations

import os
import tempfile

import pytest

from isaac.cli import main

from . import hostile, hostile_beside

CASES = hostile_beside.cases()
QUICK = [c for c in CASES if c.expect == "error" and c.args[0] != "run"]


def _ids(cases):
    return [c.name for c in cases]


def test_the_corpus_covers_every_kind_of_the_issue():
    names = " ".join(_ids(CASES))
    for kind in ("golden settings a symlink to /proc", "golden every 1e-9", "golden every 1e-300", "golden data",
                 "face index 1e20", "coordinates 1e200", "symlink to itself", "NUL byte", "divided by 0 s",
                 "young 0 GPa", "cubic keys at 1e308", "delay 1e9 s", "text trajectory", "without time",
                 "other bodies", "with NaN", "scheduler of an unknown scheme", "sweep --out a file",
                 "--workers 10000", "100000 variants", "gear ratio 3e8", "10000-character name", "unrelated nail"):
        assert kind in names, kind


@pytest.mark.parametrize("case", QUICK, ids=_ids(QUICK))
def test_a_hostile_file_or_command_ends_in_a_clean_diagnostic(case, tmp_path, capsys, monkeypatch):
    path = hostile.materialize(case, tmp_path)
    monkeypatch.chdir(path.parent)
    monkeypatch.setenv("ISAAC_HOSTILE_SECRET", hostile.SECRET)
    code = main([str(path) if a == "SCENE" else a for a in case.args])
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert "internal error" not in output, output
    assert hostile.verdict(case, code, output) == "ok", f"exit {code}: {output[-2000:]}"


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_a_hostile_file_or_command_in_its_own_process(case, tmp_path):
    outcome = hostile.run_case(case, tmp_path)
    assert outcome.verdict == "ok", f"{outcome.verdict} (exit {outcome.code}, {outcome.seconds:.1f} s): " \
                                    f"{outcome.stderr[-2000:]}"


def test_golden_update_refuses_a_folder_it_cannot_write_before_the_run(tmp_path, capsys, monkeypatch):
    """Root passes the permission bits of a read-only folder, so the refusal is simulated where the probe
    makes its file; the run must not start."""
    import isaac.golden

    scene = tmp_path / "s.isaac"
    scene.write_text(hostile_beside.GOLDEN_SCENE)

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    monkeypatch.setattr(isaac.golden, "make_record", lambda *a, **k: pytest.fail("the run started"))
    assert main(["golden", str(scene), "--update"]) == 2
    err = capsys.readouterr().err
    assert "--update: the golden folder" in err and "is not writable" in err, err


def test_sweep_refuses_its_output_folder_before_any_variant(tmp_path, capsys, monkeypatch):
    import isaac.sweep.driver as driver

    scene = tmp_path / "s.isaac"
    scene.write_text("let x = 1\n" + hostile_beside.GOLDEN_SCENE)
    (tmp_path / "taken").write_text("a file")
    monkeypatch.setattr(driver, "sweep", lambda *a, **k: pytest.fail("the sweep started"))
    assert main(["sweep", str(scene), "--set", "x=1,2", "--out", str(tmp_path / "taken")]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_a_symlink_loop_and_a_nul_byte_are_refused_by_the_one_confinement(tmp_path):
    from isaac_ir.files import Confinement, FileRefused

    os.symlink("loop.obj", tmp_path / "loop.obj")
    confinement = Confinement.for_scene(tmp_path)
    for name in ("loop.obj", "a\0b.obj"):
        with pytest.raises(FileRefused):
            confinement.read_bytes(tmp_path / name, 1 << 20)


def test_a_blow_up_without_a_declared_culprit_names_the_fastest_body(monkeypatch):
    from types import SimpleNamespace

    import numpy as np

    from isaac_runtime import blowup

    y = np.zeros((2, 13))
    y[1, 7:10] = np.nan  # the second body's velocity
    bodies = [SimpleNamespace(name="floor", source="s.isaac:3:3"), SimpleNamespace(name="ball", source="s.isaac:4:3")]
    sim = SimpleNamespace(_status=np.array([99, 5, 7, 0]), state=SimpleNamespace(t=0.1, steps=5, y=y),
                          plan=SimpleNamespace(scene=SimpleNamespace(bodies=bodies)))
    # a diagnosis that fails (as on a contact row of no constraint) still gives a positioned report
    monkeypatch.setattr(blowup, "_measured_failure", lambda sim: (_ for _ in ()).throw(AttributeError("row")))
    found = blowup.failure(sim)
    assert found.source == "s.isaac:4:3" and "`ball`" in str(found), str(found)
