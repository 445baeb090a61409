"""`isaac golden` as a user meets it: in a fresh folder with a copy of a scene, record, check, edit, check again.
Exit codes: 0 within tolerances (or written), 3 a mismatch, 2 a problem with the scene, its settings or goldens."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from isaac.cli import main

ROOT = Path(__file__).resolve().parents[2]
ISAAC = Path(sys.executable).with_name("isaac")
SWING = """# a pendulum
let theta0 = 60 deg

scene swing {
  time 0 s .. 2 s
  frames 50 Hz
  body bob sphere { radius 5 cm  mass 1 kg  at (sin(theta0), 1 - cos(theta0), 0) }
  constraint hang nail(bob @ (-sin(theta0), cos(theta0), 0), (0, 1, 0))
}
"""
# a ball that strikes a ringing bar: impacts, contact and sound
BELL = """scene bell {
  time 0 s .. 1 s
  frames 100 Hz
  material brass { density 8500 kg/m3  restitution 0.8 }
  body ball sphere { radius 2 cm  mass 50 g  at (0, 0.3, 0)  material brass }
  body bar box static { size (40, 2, 4) cm  at (0, 0, 0)  material brass  modes ((523, 3, 1), (1410, 6, 0.5)) }
  sound ding on collide(ball, bar) { play modal(bar) * impulse  gain -12 dB }
}
"""


def isaac(*argv, cwd: Path):
    """The installed command, as a user runs it: (exit code, stdout, stderr)."""
    done = subprocess.run([str(ISAAC), *argv], cwd=cwd, capture_output=True, text=True, timeout=300)
    return done.returncode, done.stdout, done.stderr


def run_cli(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def swing(tmp_path):
    path = tmp_path / "swing.isaac"
    path.write_text(SWING, encoding="utf-8")
    return path


def test_record_check_comment_then_a_change_that_fails(swing, capsys, monkeypatch):
    folder = swing.parent
    code, out, err = isaac("golden", "swing.isaac", "--update", cwd=folder)  # the installed command
    assert code == 0, err
    assert sorted(p.name for p in (folder / "swing.golden").iterdir()) == [
        "events.json", "ir.json", "meta.json", "positions.json", "report.json", "trajectory.json"]
    monkeypatch.chdir(folder)
    assert run_cli(capsys, "golden", "swing.isaac")[0] == 0
    swing.write_text("# a comment line\n" + SWING, encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", "swing.isaac")
    assert code == 0, out + err
    assert "positions are kept apart" in out
    swing.write_text(SWING.replace("radius 5 cm", "radius 6 cm"), encoding="utf-8")
    code, out, err = isaac("golden", "swing.isaac", cwd=folder)
    assert code == 3 and "Traceback" not in out + err
    assert "golden mismatch" in out
    assert "bodies[bob].shape.radius: 0.06, the golden has 0.05" in out
    assert "position of `bob`: off by up to" in out


def test_the_goldens_hold_no_positions_and_no_wall_clock(swing, capsys):
    assert run_cli(capsys, "golden", str(swing), "--update")[0] == 0
    folder = swing.parent / "swing.golden"
    assert "source" not in (folder / "ir.json").read_text()
    positions = json.loads((folder / "positions.json").read_text())
    assert positions["bodies[bob]"] == "swing.isaac:7:3" and positions["file"] == "swing.isaac"
    report = json.loads((folder / "report.json").read_text())
    assert "wall_time" not in report and report["steps"] > 0
    trajectory = json.loads((folder / "trajectory.json").read_text())
    assert trajectory["time"][0] == 0.0 and trajectory["time"][-1] == pytest.approx(2.0)
    assert len(trajectory["bodies"]["bob"]["orientation"][0]) == 4


def test_tolerances_and_sampling_from_the_toml_beside_the_scene(swing, capsys):
    (swing.parent / "swing.golden.toml").write_text(
        '[run]\nuntil = "1 s"\nevery = "0.25 s"\n\n[tolerance]\nposition = "1 m"\norientation = "90 deg"\n'
        'linear_velocity = "10 m/s"\nangular_velocity = "100 rad/s"\nenergy = 1\nir = 1\n', encoding="utf-8")
    assert run_cli(capsys, "golden", str(swing), "--update")[0] == 0
    trajectory = json.loads((swing.parent / "swing.golden" / "trajectory.json").read_text())
    assert trajectory["time"] == [0.0, 0.25, 0.5, 0.75, 1.0]
    swing.write_text(SWING.replace("radius 5 cm", "radius 6 cm"), encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", str(swing))
    assert code == 0, out + err  # the loose tolerances let the bigger bob pass


def test_a_mistake_in_the_toml_is_a_positioned_error(swing, capsys):
    toml = swing.parent / "swing.golden.toml"
    toml.write_text('[tolerance]\nposition = "1 mm"\nposiiton = 1e-3\n', encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", str(swing), "--update")
    assert code == 2 and "Traceback" not in err
    assert f"{toml}:3:1: error: unknown tolerance `posiiton`" in err and "did you mean `position`?" in err
    toml.write_text('[tolerance]\nposition = "1 s"\n', encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", str(swing), "--update")
    assert code == 2 and "`position` wants a length, not a time" in err


def test_no_goldens_yet_and_a_broken_scene(swing, capsys):
    code, out, err = run_cli(capsys, "golden", str(swing))
    assert code == 2 and "no golden files" in err and "--update" in err
    swing.write_text(SWING.replace("nail(bob", "nail(bbo"), encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", str(swing), "--update")
    assert code == 2 and "unknown body `bbo`" in err and "Traceback" not in err


def test_set_overrides_are_recorded_and_a_different_one_is_named(swing, capsys):
    assert run_cli(capsys, "golden", str(swing), "--update", "--set", "theta0=30 deg")[0] == 0
    meta = json.loads((swing.parent / "swing.golden" / "meta.json").read_text())
    assert meta["run"]["set"] == {"theta0": "30 deg"}
    assert run_cli(capsys, "golden", str(swing), "--set", "theta0=30 deg")[0] == 0
    code, out, err = run_cli(capsys, "golden", str(swing))
    assert code == 3
    assert "the goldens were made with --set theta0=30 deg" in out
    assert "parameters.theta0" in out


def test_events_and_sound_are_kept_and_compared(tmp_path, capsys):
    scene = tmp_path / "bell.isaac"
    scene.write_text(BELL, encoding="utf-8")
    assert run_cli(capsys, "golden", str(scene), "--update")[0] == 0
    folder = tmp_path / "bell.golden"
    events = json.loads((folder / "events.json").read_text())
    audio = json.loads((folder / "audio.json").read_text())
    assert events["impact_count"] >= 1 and events["impacts"][0]["bodies"] == ["ball", "bar"]
    assert audio["onsets"] and audio["onsets"][0] == pytest.approx(events["impacts"][0]["time"], abs=0.01)
    assert any(abs(p["frequency"] - 523) < 2 for p in audio["peaks"])
    assert run_cli(capsys, "golden", str(scene))[0] == 0
    scene.write_text(BELL.replace("(523, 3, 1)", "(587, 3, 1)").replace("restitution 0.8", "restitution 0.5"))
    code, out, err = run_cli(capsys, "golden", str(scene))
    assert code == 3
    assert "spectral peak at 52" in out and "impacts:" in out and "onsets" in out


def test_several_scenes_and_the_worst_code(swing, tmp_path, capsys):
    other = tmp_path / "other.isaac"
    other.write_text(SWING.replace("scene swing", "scene other"), encoding="utf-8")
    assert run_cli(capsys, "golden", str(swing), str(other), "--update")[0] == 0
    other.write_text(SWING.replace("scene swing", "scene other").replace("1 kg", "2 kg"), encoding="utf-8")
    code, out, err = run_cli(capsys, "golden", str(swing), str(other))
    assert code == 3 and "swing.isaac: golden ok" in out and "other.isaac: golden mismatch" in out
    code, out, err = run_cli(capsys, "golden", str(swing), str(tmp_path / "missing.isaac"))
    assert code == 2 and "no such scene file" in err
