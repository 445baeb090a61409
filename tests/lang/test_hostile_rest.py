"""Issue 31, the rest: expansion that stops early, big meshes, golden data of the wrong shape, `--set` names and
values, and the inputs and outputs of fit, live and bench. Each test reproduces a hostile input and asserts a
positioned exit 2 (or a clean exit 0) in little time."""
from __future__ import annotations

import re
import time

from isaac.cli import main

BALL = "body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) m }"
POSITIONED = re.compile(r"^\S+:\d+:\d+: error: ", re.MULTILINE)


def _exit_code(args) -> int:
    try:
        return main(args)
    except SystemExit as stop:  # argparse's refusal of an option
        return stop.code


def _check(args, capsys):
    started = time.monotonic()
    code = _exit_code(args)
    captured = capsys.readouterr()
    return code, captured.out + captured.err, time.monotonic() - started


# -- 1. expansion: a time budget, and a cycle that stops at once ------------------------------------------------

def test_an_include_cycle_inside_nested_loops_stops_at_once(tmp_path, capsys):
    (tmp_path / "a.isaac").write_text('scene s {\n  for i in 0 .. 100 { for j in 0 .. 100 { include "b.isaac" } }\n'
                                      f"  {BALL}\n}}\n")
    (tmp_path / "b.isaac").write_text('for k in 0 .. 100 { include "a.isaac" }\n')
    code, output, seconds = _check(["check", str(tmp_path / "a.isaac")], capsys)
    assert code == 2 and "include cycle: a.isaac -> b.isaac -> a.isaac" in output, output
    assert re.search(r"b\.isaac:1:\d+: error: include cycle", output), output
    assert seconds < 3, seconds


def test_expansion_stops_at_its_time_budget_where_it_is(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text(f"scene s {{\n  for i in 0 .. 400 {{ for j in 0 .. 400 {{ let x = i * j + sin(i) }} }}\n"
                     f"  {BALL}\n}}\n")
    code, output, seconds = _check(["check", str(scene), "--expand-seconds", "0.05"], capsys)
    assert code == 2 and "took more than 0.05 s; stopped here" in output, output
    assert POSITIONED.search(output) and "--expand-seconds" in output, output
    assert seconds < 3, seconds


def test_expand_seconds_must_be_a_time_above_zero(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text(f"scene s {{ {BALL} }}\n")
    for bad in ("0", "-1", "nan", "2 kg"):
        try:
            code = main(["check", str(scene), "--expand-seconds", bad])
        except SystemExit as stop:
            code = stop.code
        assert code == 2, bad
        assert "--expand-seconds" in capsys.readouterr().err


# -- 2, 3. meshes: a budget of triangles, checked as the file is read; coordinates bounded --------------------

MESH_BODY = 'scene s {{ body rock mesh {{ file "m.{ext}"  mass 1 kg  inertia (1, 1, 1) kg*m2 }} }}\n'


def _grid_obj(triangles: int) -> str:
    """An OBJ of a strip of at least `triangles` triangles, written fast."""
    count = triangles // 2 + 1
    vertices = "".join(f"v {i} 0 0\nv {i} 1 0\n" for i in range(count + 1))
    faces = "".join(f"f {2 * i + 1} {2 * i + 2} {2 * i + 3}\nf {2 * i + 2} {2 * i + 4} {2 * i + 3}\n"
                    for i in range(count))
    return vertices + faces


def test_a_mesh_of_too_many_triangles_is_refused_at_its_file_property_quickly(tmp_path, capsys):
    from isaac_ir.meshfile import MAX_MESH_TRIANGLES

    (tmp_path / "s.isaac").write_text(MESH_BODY.format(ext="obj"))
    (tmp_path / "m.obj").write_text(_grid_obj(MAX_MESH_TRIANGLES + 10))
    code, output, seconds = _check(["check", str(tmp_path / "s.isaac")], capsys)
    assert code == 2 and f"more than {MAX_MESH_TRIANGLES} triangles" in output, output
    assert re.search(r"s\.isaac:1:\d+: error: cannot use the mesh file `m.obj`", output), output
    assert seconds < 5, seconds


def test_a_binary_stl_of_too_many_triangles_is_refused_before_its_corners_are_merged(tmp_path, capsys):
    import numpy as np

    from isaac_ir.meshfile import MAX_MESH_TRIANGLES

    count = MAX_MESH_TRIANGLES + 1
    record = np.zeros(count, np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")]))
    record["corners"] = np.random.default_rng(1).random((count, 3, 3))
    (tmp_path / "m.stl").write_bytes(b"\0" * 80 + count.to_bytes(4, "little") + record.tobytes())
    (tmp_path / "s.isaac").write_text(MESH_BODY.format(ext="stl"))
    code, output, _ = _check(["check", str(tmp_path / "s.isaac")], capsys)
    assert code == 2 and f"more than {MAX_MESH_TRIANGLES} triangles" in output, output


def test_mesh_coordinates_beyond_the_bound_of_lengths_say_so(tmp_path, capsys):
    (tmp_path / "s.isaac").write_text(MESH_BODY.format(ext="obj"))
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1e200 0 0\nv 0 1e200 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    code, output, _ = _check(["check", str(tmp_path / "s.isaac")], capsys)
    assert code == 2 and "vertex 2 is at (1e+200, 0, 0): a coordinate beyond ±1e+12" in output, output
    assert "flat" not in output and POSITIONED.search(output), output


# -- 4. golden data: valid JSON of the wrong shape --------------------------------------------------------------

def _recorded_goldens(tmp_path):
    from . import hostile_beside

    scene = tmp_path / "s.isaac"
    scene.write_text(hostile_beside.GOLDEN_SCENE)
    assert main(["golden", str(scene), "--update"]) == 0
    return scene, sorted((tmp_path / "s.golden").glob("*.json"))


def _reshaped(value, how: str):
    """The golden value with its shape broken: a list for an object, strings for numbers, a key dropped."""
    if how == "list":
        return [value]
    if how == "string":
        return "x"
    if how == "numbers as strings":
        if isinstance(value, dict):
            return {k: _reshaped(v, how) for k, v in value.items()}
        if isinstance(value, list):
            return [_reshaped(v, how) for v in value]
        return "1" if isinstance(value, (int, float)) and not isinstance(value, bool) else value
    if how == "keys dropped" and isinstance(value, dict):
        return {k: v for k, v in list(value.items())[1:]}
    return {}


def test_golden_data_of_the_wrong_shape_is_a_positioned_exit_2_never_a_bug(tmp_path, capsys):
    import json

    scene, files = _recorded_goldens(tmp_path)
    capsys.readouterr()
    for path in files:
        original = path.read_text()
        for how in ("list", "string", "numbers as strings", "keys dropped", "empty"):
            path.write_text(json.dumps(_reshaped(json.loads(original), how)))
            code, output, _ = _check(["golden", str(scene)], capsys)
            assert code in (0, 2, 3), f"{path.name} {how}: exit {code}: {output[-1500:]}"
            assert "Traceback" not in output and "internal error" not in output, output
            if code == 2:
                assert re.search(r"s\.golden/\w+\.json:\d+:\d+: error: ", output), f"{path.name} {how}: {output}"
        path.write_text(original)
    assert main(["golden", str(scene)]) == 0


def test_golden_update_writes_over_goldens_of_the_wrong_shape(tmp_path, capsys):
    scene, _ = _recorded_goldens(tmp_path)
    (tmp_path / "s.golden" / "trajectory.json").write_text('{"time": "soon", "bodies": []}')
    assert main(["golden", str(scene)]) == 2
    assert "s.golden/trajectory.json:1:1: error: the golden file does not hold" in capsys.readouterr().err
    assert main(["golden", str(scene), "--update"]) == 0
    assert main(["golden", str(scene)]) == 0


# -- 5. --set: names and values bounded, refused naming --set ---------------------------------------------------

SET_SCENE = f"let x = 1\nscene s {{ {BALL} }}\n"


def test_a_set_name_too_long_or_not_a_name_is_refused_naming_set(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text(SET_SCENE)
    for command in ("check", "run"):
        for item, said in (("x" * 10_000 + "=1", "at most 64 characters"), ("1x=1", "is not a parameter's name"),
                           ("x=" + "1+" * 10_000 + "1", "more than the 10000 a value may have")):
            code, output, seconds = _check([command, str(scene), "--set", item], capsys)
            assert code == 2 and output.startswith("--set:1:1: error: ") and said in output, output
            assert len(output) < 600 and seconds < 5, output


def test_a_set_value_with_a_nul_byte_or_beyond_a_double_is_positioned(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text(SET_SCENE)
    for value in ("1\0 2", "1e400", "\0"):
        code, output, _ = _check(["check", str(scene), "--set", f"x={value}"], capsys)
        assert code == 2 and re.search(r"^--set x=.*:1:\d+: error: ", output, re.MULTILINE), output


def test_a_sweep_set_name_too_long_is_refused_naming_set(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text(SET_SCENE)
    code, output, _ = _check(["sweep", str(scene), "--set", "x" * 10_000 + "=1,2"], capsys)
    assert code == 2 and "--set: a parameter's name is at most 64 characters" in output and len(output) < 600


# -- 6. fit, live --mic FILE, bench: inputs and outputs checked before any work -------------------------------

FIT_SCENE = """let speed = 2 m/s
scene s {
  time 0 s .. 0.5 s
  body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) m  velocity (speed, 0, 0) }
  vary speed in 1 m/s .. 5 m/s
  goal hit: ball.position.x at 0.4 s = 1.2 m within 1 cm
}
"""


def _no_search(monkeypatch):
    import pytest

    import isaac.fit.solve as solve

    monkeypatch.setattr(solve, "find", lambda *a, **k: pytest.fail("the search started"))


def test_fit_refuses_its_scene_and_options_before_the_search(tmp_path, capsys, monkeypatch):
    _no_search(monkeypatch)
    cases = {"no vary": (FIT_SCENE.replace("  vary speed in 1 m/s .. 5 m/s\n", ""), [], "no `vary`"),
             "no goal": (FIT_SCENE.replace("  goal hit", "  # goal hit"), [], "no `goal`"),
             "bounds reversed": (FIT_SCENE.replace("1 m/s .. 5 m/s", "5 m/s .. 1 m/s"), [], "the range is empty"),
             "goal late": (FIT_SCENE.replace("at 0.4 s", "at 7 s"), [], "outside the scene's time"),
             "too many workers": (FIT_SCENE, ["--workers", "100000"], "--workers 100000"),
             "unknown scheduler": (FIT_SCENE, ["--scheduler", "gopher://x:1"], "unknown scheme")}
    for name, (text, extra, said) in cases.items():
        scene = tmp_path / "s.isaac"
        scene.write_text(text)
        code, output, _ = _check(["fit", str(scene), *extra], capsys)
        assert code == 2 and said in output, f"{name}: {output}"
        if "--" not in said and "scheme" not in said:
            assert POSITIONED.search(output), f"{name}: {output}"


def test_fit_refuses_an_output_folder_it_cannot_write_before_the_search(tmp_path, capsys, monkeypatch):
    import pytest

    import isaac.writable

    _no_search(monkeypatch)
    scene = tmp_path / "s.isaac"
    scene.write_text(FIT_SCENE)
    monkeypatch.setattr(isaac.writable, "_probe", lambda folder: f"`{folder}` is not writable (Read-only)")
    code, output, _ = _check(["fit", str(scene), "--out", str(tmp_path / "out")], capsys)
    assert code == 2 and "--out" in output and "is not writable" in output, output
    assert _exit_code(["fit", str(scene), "--out", "/proc/self"]) == 2


def test_a_rehearsal_file_that_is_not_usable_sound_is_refused_naming_mic(tmp_path):
    import numpy as np
    import pytest
    import soundfile

    from isaac.live_command import check_mic_file
    from isaac_ir.diagnostics import SceneError

    soundfile.write(tmp_path / "nan.wav", np.array([0.1, np.nan, 0.2] * 100), 8000, subtype="FLOAT")
    soundfile.write(tmp_path / "empty.wav", np.zeros(0), 8000)
    soundfile.write(tmp_path / "ok.wav", 0.3 * np.sin(np.arange(800) / 10), 8000)
    (tmp_path / "text.wav").write_text("not audio\n")
    import os

    os.mkfifo(tmp_path / "pipe.wav")
    for name, said in (("nan.wav", "is not a number"), ("empty.wav", "holds no samples"),
                       ("text.wav", "cannot read it as sound"), ("pipe.wav", "FIFO"), ("none.wav", "")):
        with pytest.raises(SceneError) as refused:
            check_mic_file(str(tmp_path / name))
        text = str(refused.value.diagnostics[0].message)
        assert text.startswith("--mic `") and said in text, text
    check_mic_file(str(tmp_path / "ok.wav"))
    check_mic_file("a device name")  # no file, no sound suffix: a device, left to the live stage


def test_a_rehearsal_file_of_too_many_samples_is_refused(tmp_path, monkeypatch):
    import numpy as np
    import pytest
    import soundfile

    import isaac.live_command as live
    from isaac_ir.diagnostics import SceneError

    soundfile.write(tmp_path / "long.wav", np.zeros((1000, 2)), 8000)
    monkeypatch.setattr(live, "MAX_MIC_SAMPLES", 1000)
    with pytest.raises(SceneError, match="2000 samples, more than the 1000"):
        live.check_mic_file(str(tmp_path / "long.wav"))


def test_bench_and_live_refuse_an_output_that_is_a_file(tmp_path, capsys):
    (tmp_path / "f").write_text("a file")
    (tmp_path / "s.isaac").write_text(FIT_SCENE)
    for args in (["bench", "--quick", "--out", str(tmp_path / "f")],
                 ["live", str(tmp_path / "s.isaac"), "--no-browser", "--out", str(tmp_path / "f")]):
        assert _exit_code(args) == 2 and "--out" in capsys.readouterr().err


# -- 2b. the viewer's geometry: bounded, simplified, said -------------------------------------------------------

def _sphere(rings: int):
    from isaac_runtime.export.geometry import TriMesh
    import numpy as np

    theta, phi = np.meshgrid(np.linspace(0, np.pi, rings), np.linspace(0, 2 * np.pi, 2 * rings), indexing="ij")
    positions = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(2 * rings - 1), indexing="ij")
    a, b = i * 2 * rings + j, i * 2 * rings + j + 1
    c, d = a + 2 * rings, b + 2 * rings
    triangles = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).reshape(-1, 3)
    return TriMesh(positions, positions.copy(), triangles)


def test_a_surface_beyond_its_share_of_the_viewer_is_simplified_and_said():
    import numpy as np

    from isaac_runtime.viewer.simplify import MIN_SHARE, triangle_share, within_share

    mesh = _sphere(300)  # about 360,000 triangles
    simplified, said = within_share(mesh, triangle_share(200))
    assert len(simplified.triangles) <= max(MIN_SHARE, 1_000_000 // 200) < len(mesh.triangles)
    assert said.startswith(f"{len(simplified.triangles)} of its {len(mesh.triangles)} triangles"), said
    assert np.all(np.isfinite(simplified.positions)) and simplified.triangles.max() < len(simplified.positions)
    assert np.allclose(np.linalg.norm(simplified.positions, axis=1), 1, atol=0.05)  # still the sphere
    same, nothing = within_share(mesh, len(mesh.triangles))
    assert same is mesh and nothing == ""
