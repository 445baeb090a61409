"""The hostile-input corpus (tests/lang/hostile.py): every case ends in exit 0 or exit 2 with a clean, positioned
diagnostic, never a traceback, a hang or a file's contents it may not read.

The default run takes the cases that only read the scene (check, parse, plan) in this process, through the CLI's
main(); `-m slow` runs the whole corpus, `run` cases included, each in its own `isaac` process under the issue's
bounds (20 s, 4 GB of address space).
"""
from __future__ import annotations

import os

import pytest

from isaac.cli import main
from isaac_ir.files import Confinement

from . import hostile

CASES = hostile.cases()
# read-only cases that take more than a second (a 20 MB include, a 3-million-vertex mesh, a 2 MB line)
HEAVY = {"include a huge file", "mesh too many vertices", "a 2 MB line", "nested loops"}
QUICK = [c for c in CASES if c.args[0] in ("check", "parse", "plan") and c.name not in HEAVY]


def _ids(cases):
    return [c.name for c in cases]


def test_the_corpus_covers_every_kind_of_the_issue():
    names = " ".join(_ids(CASES))
    for kind in ("include /etc/passwd", "fifo", "/dev/zero", "huge", "UTF-8", "in a loop", "mesh empty", "mesh flat",
                 "nan vertex", "out of range", "scale 0", "text file", "mesh missing", "subnormal", "1e-300",
                 "frames 1e9", "audio rate 1e12", "step 1e-12", "substeps 1e9", "iterations 1e9", "overlapping",
                 "10000-term", "unary minuses", "power tower", "deep parentheses", "--step 0", "--until -1",
                 "--out /dev/null", "form feed"):
        assert kind in names, kind


@pytest.mark.parametrize("case", QUICK, ids=_ids(QUICK))
def test_a_hostile_input_ends_in_a_clean_diagnostic(case, tmp_path, capsys, monkeypatch):
    path = hostile.materialize(case, tmp_path)
    monkeypatch.chdir(path.parent)
    args = [str(path) if a == "SCENE" else a for a in case.args]
    code = main(args)
    captured = capsys.readouterr()
    output = captured.out + captured.err
    assert "internal error" not in output, output
    assert hostile.verdict(case, code, output) == "ok", f"exit {code}: {output[-2000:]}"


def test_an_include_in_a_loop_is_read_once(tmp_path, monkeypatch):
    reads = []
    original = Confinement.read_text
    monkeypatch.setattr(Confinement, "read_text", lambda self, path, *a: reads.append(path) or original(
        self, path, *a))
    (tmp_path / "x.isaac").write_text("let y = 1\n")
    scene = tmp_path / "s.isaac"
    scene.write_text('scene s {\n  for i in 0 .. 500 { include "x.isaac" }\n}\n')
    assert main(["check", str(scene)]) == 0
    assert sorted(p.name for p in reads) == ["s.isaac", "x.isaac"]


def test_a_fifo_is_never_opened(tmp_path, monkeypatch):
    """Opening a FIFO for reading blocks until a writer comes: the check must refuse it from its stat alone."""
    opened = []
    real_open = os.open
    monkeypatch.setattr(os, "open", lambda path, *a, **k: opened.append(str(path)) or real_open(path, *a, **k))
    os.mkfifo(tmp_path / "pipe.isaac")
    os.mkfifo(tmp_path / "pipe.obj")
    scene = tmp_path / "s.isaac"
    scene.write_text('include "pipe.isaac"\nscene s { body m mesh { file "pipe.obj"  mass 1 kg  inertia (1, 1, 1) '
                     'kg*m2 } }\n')
    assert main(["check", str(scene)]) == 2
    assert not any("pipe" in p for p in opened)


def test_an_outside_include_shows_nothing_of_the_file(tmp_path, capsys):
    (tmp_path / "secret.isaac").write_text(f"{hostile.SECRET} {{\n")
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "s.isaac").write_text('include "../secret.isaac"\nscene s { }\n')
    assert main(["check", str(folder / "s.isaac")]) == 2
    err = capsys.readouterr().err
    assert "s.isaac:1:9: error: cannot read" in err and "outside the scene's folder" in err
    assert hostile.SECRET not in err
    # named with --include-path, the same file is read (and its syntax error shown, with its line)
    assert main(["check", str(folder / "s.isaac"), "--include-path", str(tmp_path)]) == 2
    assert hostile.SECRET in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_a_hostile_input_in_its_own_process(case, tmp_path):
    outcome = hostile.run_case(case, tmp_path)
    assert outcome.verdict == "ok", f"{outcome.verdict} (exit {outcome.code}, {outcome.seconds:.1f} s): " \
                                    f"{outcome.stderr[-2000:]}"


BALL = "body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) }"
OVER = [  # (budget, the scene's settings that go over it, the budgets to lift for the plan to be made)
    ("steps", "time 0 s .. 10 s\n solver dynamics { step 1 us }\n" + BALL, "steps=off,work=off"),
    ("frames", "time 0 s .. 20 s\n frames 1e5 Hz\n" + BALL, "frames=off"),
    ("work", "time 0 s .. 100 s\n solver dynamics { step 1 ms }\n for i in 0 .. 100 { body b{i} sphere { radius 5 cm  "
     "mass 1 kg  at (i, 0, 0) } }", "work=off"),
    ("samples", "time 0 s .. 20 s\n audio { rate 1e7 Hz }\n" + BALL + "\n sound hum on always { play sine(440) }",
     "samples=off,memory=off"),
    ("substeps", "time 0 s .. 10 s\n solver procedural { substeps 100000 }\n" + BALL, "substeps=off,iterations=off"),
    ("contacts", "for i in 0 .. 50 { body b{i} sphere { radius 1 m  mass 1 kg  at (0, 0, 0) } }", "contacts=off"),
]


@pytest.mark.parametrize("name,settings,lift", OVER, ids=[o[0] for o in OVER])
def test_every_budget_refuses_at_its_setting_and_can_be_lifted(name, settings, lift, tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text("scene s {\n " + settings + "\n}\n")
    assert main(["plan", str(scene)]) == 2
    err = capsys.readouterr().err
    assert f"{scene}:" in err and "the budget of" in err and f"--budget {name}=" in err, err
    assert main(["plan", str(scene), "--budget", lift]) == 0, capsys.readouterr().err


def test_every_budget_is_documented():
    from isaac_runtime.plan.budgets import DEFAULTS

    text = (hostile.Path(__file__).resolve().parents[2] / "docs" / "budgets.md").read_text(encoding="utf-8")
    for name in DEFAULTS:
        assert f"| `{name}` |" in text, name


def test_a_blow_up_is_positioned_and_its_report_is_strict_json(tmp_path, capsys):
    import json

    scene = tmp_path / "s.isaac"
    scene.write_text("scene s {\n  time 0 s .. 0.1 s\n  body ball sphere { radius 5 cm  mass 1 kg  "
                     "velocity (1e300, 0, 0) m/s }\n}\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--no-viewer"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{scene}:3:3: error: numerical blow-up at t = "), err
    assert "body `ball`" in err and "Warning" not in err
    report = json.loads((tmp_path / "out" / "report.json").read_text(), parse_constant=lambda name: 1 / 0)
    assert "numerical blow-up" in report["error"]
    assert report["energy_drift"] is None  # NaN after the blow-up: null, and the file still loads
