"""Issue 32, a newcomer's first hour: each stumble, kept fixed (units and --set, the command line's habits,
--until past the end, plurals)."""
from __future__ import annotations

from pathlib import Path

import pytest

from isaac.cli import main

ROOT = Path(__file__).resolve().parents[2]
PENDULUM = (ROOT / "scenes" / "pendulum.isaac").read_text(encoding="utf-8")


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def swing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "swing.isaac").write_text(PENDULUM, encoding="utf-8")
    return tmp_path / "swing.isaac"


def test_a_mistyped_command_gets_did_you_mean(capsys, swing):
    code, _, err = run_cli(capsys, "rnu", "swing.isaac")
    assert code == 2
    assert "hint: did you mean `run`?" in err


def test_a_mistyped_option_gets_did_you_mean(capsys, swing):
    code, _, err = run_cli(capsys, "check", "swing.isaac", "--strikt")
    assert code == 2
    assert "hint: did you mean `--strict`?" in err


def test_a_scene_named_without_its_extension_is_found(capsys, swing):
    code, out, _ = run_cli(capsys, "check", "swing")
    assert code == 0
    assert out.startswith("swing.isaac: ok (1 body, 1 constraint)")


def test_set_takes_the_unit_the_parameter_was_written_in(capsys, swing):
    code, out, _ = run_cli(capsys, "parse", "swing.isaac", "--set", "theta0=30")
    assert code == 0
    assert '"theta0"' in out and "0.5235987755982988" in out  # 30 deg, not 30 rad


def test_set_with_a_wrong_dimension_names_the_set(capsys, swing):
    code, _, err = run_cli(capsys, "check", "swing.isaac", "--set", "theta0=30m")
    assert code == 2
    assert err.startswith("--set theta0=30m:1:1: error: `--set theta0=30m` gives a length, but `theta0` is an angle")
    assert "hint: give it in a unit of an angle, e.g. `--set theta0=30deg`" in err
    assert "sin" not in err


def test_set_refuses_a_bare_number_where_the_scene_writes_no_single_unit(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = PENDULUM.replace("let length = 1 m", "let length = 2 * 50 cm")
    (tmp_path / "p.isaac").write_text(text, encoding="utf-8")
    code, _, err = run_cli(capsys, "check", "p.isaac", "--set", "length=2")
    assert code == 2
    assert "`--set length=2` has no unit, but `length` is a length" in err
    assert "hint: write the unit, e.g. `--set length=2m`" in err
    assert "has no parameter" not in err


def test_an_unknown_set_names_the_whole_set(capsys, swing):
    code, _, err = run_cli(capsys, "check", "swing.isaac", "--set", "lenght=2m")
    assert code == 2
    assert "`--set lenght=2m`: the scene has no parameter `lenght`" in err
    assert "did you mean `length`?" in err


def test_until_past_the_end_runs_to_the_end_and_says_so(capsys, swing):
    code, out, err = run_cli(capsys, "run", "swing.isaac", "--until", "100", "--no-viewer")
    assert code == 0
    assert "--until 100 s is past the scene's end (10 s): running to the end, 10 s" in err
    assert "10000 steps" in out


def test_interrupted_run_says_the_outputs_were_kept(capsys, swing, monkeypatch):
    import isaac.cli as cli

    def interrupt(args, sources):
        raise KeyboardInterrupt

    monkeypatch.setitem(cli.COMMANDS, "run", interrupt)
    code, _, err = run_cli(capsys, "run", "swing.isaac")
    assert code == 130
    assert "the previous outputs in out/swing/ were kept whole" in err
