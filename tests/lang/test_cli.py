"""The `isaac` command on the example scenes and on damaged copies of the pendulum: exit codes, JSON on stdout,
gcc-style diagnostics with a caret on stderr, never a traceback."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from isaac.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "scenes").glob("*.isaac"))
PENDULUM = (ROOT / "scenes" / "pendulum.isaac").read_text(encoding="utf-8")
ISAAC = Path(sys.executable).with_name("isaac")


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def damaged(tmp_path, old: str, new: str) -> Path:
    assert PENDULUM.count(old) == 1, old
    path = tmp_path / "pendulum.isaac"
    path.write_text(PENDULUM.replace(old, new), encoding="utf-8")
    return path


def line_col_of(text: str, needle: str, offset: int = 0):
    """1-based line and column of the first `needle` in text (plus offset characters)."""
    index = text.index(needle) + offset
    line = text.count("\n", 0, index) + 1
    return line, index - (text.rfind("\n", 0, index) + 1) + 1


def assert_diagnostic(err: str, path: Path, line: int, col: int, message: str):
    """`path:line:col: error: message`, the source line, a caret under the column, no traceback."""
    assert "Traceback" not in err
    head = f"{path}:{line}:{col}: error: "
    assert head in err, f"expected `{head}` in:\n{err}"
    lines = err.splitlines()
    i = next(i for i, l in enumerate(lines) if l.startswith(head))
    assert message in lines[i], lines[i]
    source, caret = lines[i + 1], lines[i + 2]
    assert source.startswith(f"{line:>5} | ")
    assert re.fullmatch(r" {5} \| *\^~*", caret), caret
    assert caret.index("^") - len("      | ") + 1 == col, caret


# -- parse and check --------------------------------------------------------------------------------------

def test_parse_prints_the_pendulum_ir(capsys):
    code, out, err = run_cli(capsys, "parse", str(ROOT / "scenes" / "pendulum.isaac"))
    assert code == 0, err
    data = json.loads(out)
    (bob,) = data["bodies"]
    assert bob["name"] == "bob" and bob["mass"] == 1.0 and bob["shape"]["radius"] == pytest.approx(0.05)
    (hang,) = data["constraints"]
    (term,) = hang["terms"]
    assert term["family"] == "nail" and term["bodies"] == ["bob"]
    assert term["params"]["target"] == [0.0, 1.0, 0.0]


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_parse_and_check_every_scene(capsys, scene):
    code, out, err = run_cli(capsys, "parse", str(scene))
    assert code == 0, err
    assert json.loads(out)["schema"] == "isaac-ir/1"
    code, out, err = run_cli(capsys, "check", str(scene))
    assert code == 0, err
    assert "ok" in out


def test_the_installed_command_runs():
    scene = ROOT / "scenes" / "pendulum.isaac"
    result = subprocess.run([str(ISAAC), "check", str(scene)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "pendulum.isaac: ok (1 body, 1 constraint)" in result.stdout


def test_the_installed_command_reports_a_damaged_scene(tmp_path):
    path = damaged(tmp_path, "radius 5 cm", "radius 5")
    result = subprocess.run([str(ISAAC), "parse", str(path)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and result.stdout == ""
    line, col = line_col_of(path.read_text(), "radius 5", len("radius "))
    assert_diagnostic(result.stderr, path, line, col, "`radius` needs a unit")


def test_set_overrides_a_parameter(capsys):
    code, out, err = run_cli(capsys, "parse", str(ROOT / "scenes" / "pendulum.isaac"), "--set", "length=2 m")
    assert code == 0, err
    data = json.loads(out)
    assert data["parameters"]["length"] == 2.0
    assert data["constraints"][0]["terms"][0]["params"]["target"] == [0.0, 2.0, 0.0]


def test_set_of_an_unknown_parameter(capsys):
    code, out, err = run_cli(capsys, "check", str(ROOT / "scenes" / "pendulum.isaac"), "--set", "lenght=2m")
    assert code == 2 and "Traceback" not in err
    assert "`--set lenght=2m`: the scene has no parameter `lenght`" in err
    assert "did you mean `length`?" in err


def test_set_without_equals_and_missing_file(capsys, tmp_path):
    code, _, err = run_cli(capsys, "check", str(ROOT / "scenes" / "pendulum.isaac"), "--set", "length")
    assert code == 2 and "--set wants NAME=VALUE" in err
    code, _, err = run_cli(capsys, "check", str(tmp_path / "nope.isaac"))
    assert code == 2 and "no such scene file" in err


def test_max_items_limits_the_expansion(capsys):
    code, _, err = run_cli(capsys, "check", str(ROOT / "scenes" / "chain.isaac"), "--max-items", "5")
    assert code == 2 and "beyond the limit of 5 declarations" in err and "Traceback" not in err


# -- damaged pendulums ------------------------------------------------------------------------------------

def test_missing_closing_brace(capsys, tmp_path):
    path = tmp_path / "pendulum.isaac"
    text = PENDULUM.rstrip()
    assert text.endswith("}")
    path.write_text(text[:-1], encoding="utf-8")
    code, _, err = run_cli(capsys, "check", str(path))
    assert code == 2
    lines = text[:-1].splitlines()
    assert_diagnostic(err, path, len(lines), len(lines[-1]) + 1, "unexpected end of file")
    scene_line, scene_col = line_col_of(PENDULUM, "scene pendulum {", len("scene pendulum "))
    assert f"the `{{` opened at {scene_line}:{scene_col} is not closed: add `}}`" in err


def test_unknown_body_in_a_constraint(capsys, tmp_path):
    path = damaged(tmp_path, "nail(bob @", "nail(bbo @")
    code, _, err = run_cli(capsys, "check", str(path))
    assert code == 2
    line, col = line_col_of(path.read_text(), "bbo @")
    assert_diagnostic(err, path, line, col, "unknown body `bbo`")
    assert "hint: did you mean `bob`?" in err


def test_length_without_unit(capsys, tmp_path):
    path = damaged(tmp_path, "radius 5 cm", "radius 5")
    code, _, err = run_cli(capsys, "check", str(path))
    assert code == 2
    line, col = line_col_of(path.read_text(), "radius 5", len("radius "))
    assert_diagnostic(err, path, line, col, "`radius` needs a unit: it is a length")
    assert "e.g. `5 m`" in err


@pytest.mark.parametrize("old,new", [
    ("  body bob sphere {", "  bdy bob sphere {"),
    ("  material steel {", "  materal steel {"),
    ("  constraint hang", "  constrant hang"),
])
def test_misspelled_keyword(capsys, tmp_path, old, new):
    path = damaged(tmp_path, old, new)
    code, _, err = run_cli(capsys, "check", str(path))
    assert code == 2
    word = new.split()[0]
    line, col = line_col_of(path.read_text(), new, 2)
    assert_diagnostic(err, path, line, col, f"`{word}`")
    assert f"did you mean `{old.split()[0]}`?" in err
