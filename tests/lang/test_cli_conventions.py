"""The command line's conventions: --version, `python -m isaac`, -q/-v, option values with units and checked
where they are given, exit codes 0/1/2/3, warnings on stderr (--strict: errors), assets read by `check`, extras
checked with the plan, outputs named after the scene's file, honouring the umask, and clearing only their own."""
from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from importlib.metadata import requires
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
ISAAC = Path(sys.executable).with_name("isaac")
SWING = """scene swing {
  time 0 s .. 1 s
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) m }
  constraint hang nail(bob @ (-1, 0, 0) m, (0, 0, 0))
}
"""


def with_line(text: str, line: str) -> str:
    """The scene with one more declaration before its closing brace."""
    return text.rstrip().removesuffix("}") + line + "\n}\n"


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def scene_file(tmp_path, text=SWING, name="swing.isaac") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# -- version, python -m, verbosity ---------------------------------------------------------------------------

def test_version_and_python_dash_m():
    done = subprocess.run([str(ISAAC), "--version"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith("isaac ")
    done = subprocess.run([sys.executable, "-m", "isaac", "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "golden" in done.stdout and "run" in done.stdout
    done = subprocess.run([sys.executable, "-m", "isaac", "check", str(SCENES / "pendulum.isaac")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "ok" in done.stdout


def test_quiet_and_verbose(tmp_path, capsys):
    scene = scene_file(tmp_path)
    code, out, err = run_cli(capsys, "-qq", "run", scene, "--out", tmp_path / "a", "--until", "0.1")
    assert code == 0 and out == "" and err == ""
    code, out, err = run_cli(capsys, "run", "-v", scene, "--out", tmp_path / "b", "--until", "0.1")
    assert code == 0 and "wrote" in out and "trajectory.npz" in out and "stages:" in err


# -- option values ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["--step", "0"], ["--until", "-1"], ["--step", "-1 ms"], ["--step", "-1", "ms"],
                                  ["--step", "nan"], ["--until", "inf"], ["--step", "1 m"], ["--step", "1 mss"],
                                  ["--max-constraint-error", "0"], ["--max-items", "0"], ["--step", "-1"],
                                  ["--until", "nan"], ["--max-constraint-error", "nan"], ["--step", "-inf"]])
def test_a_bad_option_value_is_exit_2_with_a_message(tmp_path, argv):
    scene = scene_file(tmp_path)
    done = subprocess.run([str(ISAAC), "run", str(scene), "--out", str(tmp_path / "o"), *argv], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert "error:" in done.stderr and "Traceback" not in done.stderr and "internal error" not in done.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value, message", [
    ("restitution 2", "`restitution` must be between 0 and 1, got 2"),
    ("restitution -0.1", "`restitution` must be between 0 and 1, got -0.1"),
    ("friction -1", "`friction` must be 0 or more, got -1")])
def test_a_contact_coefficient_that_cannot_be_meant_is_refused_at_its_position(tmp_path, capsys, value, message):
    material = f"  material m {{ density 1000 kg/m3  {value} }}"
    scene = scene_file(tmp_path, with_line(SWING, material))
    column = material.index(value.split()[1]) + 1
    for argv in (["check", scene], ["run", scene, "--out", tmp_path / "o"]):
        code, out, err = run_cli(capsys, *argv)
        assert code == 2 and err.startswith(f"{scene}:5:{column}: error: {message}"), err
        assert f"    5 | {material}" in err and "hint: " in err
    assert not (tmp_path / "o").exists()
    edge = with_line(SWING, "  material m { restitution 1  friction 0 }")
    assert run_cli(capsys, "check", scene_file(tmp_path, edge))[0] == 0  # the ends of the ranges are meant


def test_step_and_until_take_units(tmp_path, capsys):
    scene = scene_file(tmp_path)
    assert run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--step", "2 ms", "--until", "200ms")[0] == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["step"] == pytest.approx(0.002) and report["simulated_time"] == pytest.approx(0.2)
    assert run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--step", "1", "ms", "--until", "0.1")[0] == 0
    assert json.loads((tmp_path / "o" / "report.json").read_text())["step"] == pytest.approx(0.001)


def test_until_before_the_scene_starts(tmp_path, capsys):
    scene = scene_file(tmp_path, SWING.replace("time 0 s .. 1 s", "time 2 s .. 3 s"))
    code, out, err = run_cli(capsys, "run", scene, "--until", "1 s")
    assert code == 2 and "is not after the scene's start (2 s)" in err


# -- exit 3, warnings, --strict --------------------------------------------------------------------------------

def test_constraints_no_pose_satisfies_are_named_at_their_position_and_exit_3(tmp_path, capsys):
    # two nails of one point 0.5 m apart: the closest pose leaves 0.25 m on each, above the limit (0.1 m)
    scene = scene_file(tmp_path, with_line(SWING, "  constraint other nail(bob @ (-1, 0, 0) m, (0, 0.5, 0) m)"))
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--until", "0.5")
    assert code == 3 and "Traceback" not in err
    assert err.startswith(f"{scene}:4:3: warning: constraints `hang` and `other` cannot both hold: in the pose of "
                          "the bodies that comes closest, errors remain (`hang` 0.25, `other` 0.25, m or rad)")
    assert "`other` is at line 5, column 3" in err and "above --max-constraint-error 0.1" in err
    report = json.loads((tmp_path / "o" / "report.json").read_text())  # the run went on, and says so
    assert report["checks"]["max_constraint_error"]["ok"] is False and "cannot both hold" in report["warnings"][0]
    # a limit that allows it lets it run, said on stderr (and in report.json) with both constraints named
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--until", "0.5",
                             "--max-constraint-error", "off")
    assert code == 0 and "warning: constraints that cannot all hold: `other` (0.5)" in err and "`hang`" in err
    assert run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--until", "0.5",
                   "--max-constraint-error", "2 m")[0] == 0


CRUSH = """scene crush {
  time 0 s .. 1 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 2 ms }
  material pine { density 500 kg/m3  friction 0.5  restitution 0.3 }
  material lead { density 50000 kg/m3  friction 0.5  restitution 0 }
  body floor plane { material pine }
  for i in 0 .. 2 {
    for j in 0 .. 2 {
      for l in 0 .. 2 {
        body b{i}_{j}_{l} box { size (8, 8, 8) cm  material pine  at ((i - 0.5) * 12 cm, 5 cm + l * 12 cm, (j - 0.5) * 12 cm) }
      }
    }
  }
  body slab box { size (30, 10, 30) cm  material lead  at (0, 60, 0) cm }
}
"""


# 32 such boxes under a 1250 kg slab: an island of 33 bodies, more than capture/islands.py solves whole (32)
CRUSH_WIDE = (CRUSH.replace("for i in 0 .. 2 {", "for i in 0 .. 4 {").replace("for j in 0 .. 2 {", "for j in 0 .. 4 {")
              .replace("(i - 0.5) * 12 cm", "(i - 1.5) * 12 cm").replace("(j - 0.5) * 12 cm", "(j - 1.5) * 12 cm")
              .replace("size (30, 10, 30) cm  material lead", "size (50, 10, 50) cm  material lead"))


def test_contacts_deeper_than_the_depth_limit_exit_3_at_the_deepest_pair(tmp_path, capsys):
    """A 1250 kg slab of lead dropped on 32 boxes of 0.26 kg, at 2 ms: too many bodies for the island to be solved
    whole, and the capturing path's sweeps leave the boxes several mm into one another (4900 times lighter than what
    presses them). A finished run that broke the 1 mm depth limit exits 3 with an error at the first body of the
    deepest pair; every output is written."""
    scene = scene_file(tmp_path, CRUSH_WIDE, "crush.isaac")
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--no-viewer")
    assert code == 3 and "Traceback" not in err
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    check, contact = report["checks"]["contact"], report["contact"]
    assert contact["path"] == "capturing" and check["ok"] is False and check["depth_limit"] == 1e-3
    assert check["deepest"] == contact["deepest"] > 2e-3 and check["steps_too_deep"] == contact["steps_too_deep"] > 0
    first = min(contact["deepest_pair"])  # the boxes are declared in name order, all on line 11
    assert f"{scene}:11:9: error: bodies interpenetrated by more than 1 mm in {check['steps_too_deep']} steps; " \
           f"deepest {contact['deepest'] * 1e3:.3g} mm" in err and f"`{first}`" in err
    assert "hint: a smaller step, or thicker bodies, keeps them apart" in err
    assert (tmp_path / "o" / "trajectory.npz").exists() and (tmp_path / "o" / "events.json").exists()


def test_a_slab_of_lead_on_eight_light_boxes_rests_at_its_height(tmp_path, capsys):
    """The 450 kg slab on eight boxes of 0.26 kg (1760 times lighter): their island is solved whole
    (capture/newton.py), and the slab rests on the boxes' top faces, its centre at 16 + 5 cm, within 0.15 mm, with no
    contact 0.15 mm deep (it sank several mm into them, exit 3, before)."""
    scene = scene_file(tmp_path, CRUSH, "crush.isaac")
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--no-viewer")
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert code == 0 and report["contact"]["islands_solved_whole"] > 0 and report["contact"]["deepest"] < 1.5e-4
    with np.load(tmp_path / "o" / "trajectory.npz") as run:
        slab = run["position"][-1, -1]
        assert abs(slab[1] - 0.21) < 1.5e-4 and np.abs(run["linear_velocity"][-1, -1]).max() < 1e-3


def test_verbose_says_which_contact_path_the_run_took_and_why(tmp_path, capsys):
    scene = scene_file(tmp_path, CRUSH, "crush.isaac")
    code, out, err = run_cli(capsys, "run", "-v", scene, "--out", tmp_path / "o", "--no-viewer")
    said = [line for line in out.splitlines() if line.startswith("contacts: ")]
    # (the boxes land on one another first)
    assert code == 0 and len(said) == 1 and said[0].startswith("contacts: the capturing path from t = 0.1")
    assert "(an impact between moving bodies `b0_0_0` and `b0_0_1`" in said[0] and "islands solved whole" in said[0]


def test_a_capturing_run_within_the_depth_limit_is_ok(tmp_path, capsys):
    """The same boxes without the slab: within the limit, checks.contact ok and exit 0."""
    scene = scene_file(tmp_path, CRUSH.replace("  body slab box", "  # body slab box"), "boxes.isaac")
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--no-viewer")
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["contact"]["path"] == "capturing"  # (eight boxes landing on one another)
    assert report["checks"]["contact"] == {"depth_limit": 1e-3, "deepest": report["contact"]["deepest"],
                                           "steps_too_deep": 0, "ok": True}
    assert report["contact"]["deepest"] < 1e-3 and code == 0 and "error" not in err


def test_constraints_that_part_during_the_run_exit_3(tmp_path, capsys):
    # the second nail's target leaves the first's at 5 m/s for 0.1 s: both hold at the start, 0.5 m apart later
    moving = "  constraint other nail(bob @ (-1, 0, 0), (0, min(t, 0.1 s) * 5 m/s, 0))"
    scene = scene_file(tmp_path, with_line(SWING, moving))
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--until", "0.5", "--no-viewer")
    assert code == 3 and "above --max-constraint-error 0.1 (constraints `other`, `hang`)" in err
    assert f"{scene}:5:3: warning: constraints that cannot all hold: `other`" in err and "Traceback" not in err
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["checks"]["max_constraint_error"]["ok"] is False
    assert report["constraint_error_settled"] == pytest.approx(0.5, abs=1e-3)
    assert run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--until", "0.5", "--no-viewer",
                   "--max-constraint-error", "off")[0] == 0


def test_a_gap_that_closes_is_not_a_broken_tolerance(tmp_path, capsys):
    # selfassembly: 0.4 m apart when the joint switches on at 1 s, closed by 1.8 s
    code, out, err = run_cli(capsys, "run", SCENES / "selfassembly.isaac", "--out", tmp_path / "o")
    assert code == 0, err
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["max_constraint_error"] > 0.3 and report["constraint_error_settled"] < 1e-3


def test_warnings_go_to_stderr_and_strict_makes_them_errors(tmp_path, capsys):
    text = with_line(SWING.replace("constraint hang nail", "solver dynamics { step 20 ms }\n  constraint hang nail"),
                     "  constraint late nail(bob) from 5 s")
    scene = scene_file(tmp_path, text)
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--max-constraint-error", "off")
    assert code == 0
    assert f"{scene}:6:3: warning: constraint `late` starts after the scene ends" in err
    assert f"{scene}: warning: the step (0.02 s) is longer than a frame" in err
    assert any("longer than a frame" in w for w in json.loads((tmp_path / "o" / "report.json").read_text())["warnings"])
    code, out, err = run_cli(capsys, "check", scene, "--strict")
    assert code == 2 and f"{scene}:6:3: error: constraint `late` starts after the scene ends" in err
    scene.write_text(text.replace("\n  constraint late nail(bob) from 5 s", ""), encoding="utf-8")
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o", "--strict")
    assert code == 2 and "error: the step (0.02 s) is longer than a frame" in err


# -- assets and extras -------------------------------------------------------------------------------------------

MESH = """scene rocks {
  time 0 s .. 0.5 s
  body floor plane { }
  body rock mesh { file "assets/rock.obj"  mass 2 kg  inertia (0.1, 0.2, 0.3) kg*m2  at (0, 1, 0) }
  body ball sphere { radius 5 cm  mass 1 kg  at (0, 2, 0) }
}
"""


def test_check_reads_every_asset(tmp_path, capsys):
    scene = scene_file(tmp_path, MESH, "rocks.isaac")
    code, out, err = run_cli(capsys, "check", scene)
    assert code == 2 and "Traceback" not in err
    col = MESH.splitlines()[3].index('"assets') + 1
    assert f"{scene}:4:{col}: error: no such mesh file: `assets/rock.obj`" in err
    assert "      | " + " " * (col - 1) + "^~~~~~~~~~~~~~~~~\n" in err
    code, out, err = run_cli(capsys, "run", scene, "--out", tmp_path / "o")
    assert code == 2 and "no such mesh file" in err and not (tmp_path / "o").exists()
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "rock.obj").write_bytes((SCENES / "assets" / "icosahedron.obj").read_bytes())
    assert run_cli(capsys, "check", scene)[0] == 0
    (tmp_path / "breath.wav").write_text("not a sound")
    scene.write_text(with_line(MESH, '  sound s on always { play envelope("breath.wav") * noise() }'))
    code, out, err = run_cli(capsys, "check", scene)
    assert code == 2 and "cannot read `breath.wav` as sound" in err


def test_a_missing_extra_is_found_with_the_plan_before_the_run(tmp_path):
    scene = scene_file(tmp_path, MESH.replace("assets/rock.obj", "rock.obj"), "rocks.isaac")
    (tmp_path / "rock.obj").write_bytes((SCENES / "assets" / "icosahedron.obj").read_bytes())
    program = ("import sys; sys.modules['fcl'] = None; sys.modules['matplotlib'] = None\n"
               "from isaac.cli import main; sys.exit(main(sys.argv[1:]))")
    done = subprocess.run([sys.executable, "-c", program, "run", str(scene), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "python-fcl" in done.stderr and "pip install 'isaac[mesh]'" in done.stderr
    assert not (tmp_path / "o").exists()  # nothing was simulated
    done = subprocess.run([sys.executable, "-c", program, "run", str(SCENES / "pendulum.isaac"), "--plots",
                           "--out", str(tmp_path / "p")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and "pip install 'isaac[plots]'" in done.stderr and not (tmp_path / "p").exists()


def test_soundfile_is_a_core_dependency():
    core = [r for r in requires("isaac") if "extra ==" not in r]
    assert any(r.startswith("soundfile") for r in core)


# -- outputs ------------------------------------------------------------------------------------------------------

def test_outputs_are_named_after_the_file_and_honour_the_umask(tmp_path, capsys, monkeypatch):
    scene = scene_file(tmp_path, SWING, "my_swing.isaac")  # the scene inside is `swing`
    monkeypatch.chdir(tmp_path)
    old = os.umask(0o022)
    try:
        assert run_cli(capsys, "run", "my_swing.isaac", "--until", "0.1")[0] == 0
    finally:
        os.umask(old)
    out = tmp_path / "out" / "my_swing"
    assert (out / "trajectory.npz").is_file() and not (tmp_path / "out" / "swing").exists()
    for path in out.iterdir():
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path


def test_a_run_replaces_its_own_files_and_keeps_the_users(tmp_path, capsys):
    from isaac_runtime.outputs.outputset import MANIFEST

    out = tmp_path / "o"
    assert run_cli(capsys, "run", SCENES / "bar.isaac", "--out", out, "--until", "0.3", "--plots")[0] == 0
    assert (out / "audio.wav").is_file() and (out / "plots" / "spectrogram.png").is_file()
    (out / "notes.txt").write_text("mine")
    (out / "plots" / "mine.png").write_text("mine")
    assert run_cli(capsys, "run", scene_file(tmp_path), "--out", out, "--until", "0.1", "--no-viewer")[0] == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [MANIFEST, "events.json", "ir.json", "notes.txt", "plots", "report.json", "trajectory.npz"]
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["mine.png"]
    assert (out / "notes.txt").read_text() == "mine"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries beside it


def test_export_frames_that_select_nothing(tmp_path, capsys):
    scene = scene_file(tmp_path)
    out = tmp_path / "o"
    assert run_cli(capsys, "run", scene, "--out", out, "--until", "0.2")[0] == 0
    code, _, err = run_cli(capsys, "export", scene, "--format", "rib", "--out", out, "--frames", "9999")
    assert code == 2 and "--frames 9999 selects no frame: the run has 13 frames, 0 to 12" in err
    assert "Traceback" not in err and "internal error" not in err


def test_the_parser_knows_the_runtimes_default_limit():
    from isaac import cli
    from isaac_runtime import checks

    from isaac_runtime.run import RunOptions

    # not given: the run takes RunOptions' default, the runtime's one definition of the limit
    assert not hasattr(cli.build_parser().parse_args(["run", "scene.isaac"]), "max_constraint_error")
    assert RunOptions().max_constraint_error == checks.DEFAULT_MAX_CONSTRAINT_ERROR == 0.1
    assert cli.build_parser().parse_args(["run", "s.isaac", "--max-constraint-error", "off"]).max_constraint_error is None
