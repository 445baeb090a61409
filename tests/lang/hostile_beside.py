"""Hostile inputs, second pass (issue 31): the files beside a scene (golden settings and data, meshes,
recordings, trajectories given to export), numbers that parse but break a formula, and the commands other than
check and run (export, golden, sweep). Same rules as tests/lang/hostile.py: exit 0, or exit 2 with a clean
diagnostic, within 20 s; no traceback, no file's contents it may not read.

    python -m tests.lang.hostile_beside            # every case, one line each, and the totals
"""
from __future__ import annotations

import io
import sys
import tempfile
from pathlib import Path

import numpy as np

from .hostile import BODY, SECRET, TETRA, Case, run_case, scene

FLOOR = "body floor plane { }"
IMPACT = "sound knock on collide() { play impact() * impulse }"
# a scene whose goldens are quick to make: a ball dropped on a floor for a fifth of a second
GOLDEN_SCENE = scene(FLOOR, BODY)


def _npz(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def _trajectory(body: str = "ball", value: float = 0.0) -> bytes:
    """A trajectory.npz as `isaac run` writes it, of two frames: the scene's floor and `body`."""
    names = np.array(["floor", body])
    position = np.zeros((2, 2, 3)) + value
    orientation = np.tile([1.0, 0, 0, 0], (2, 2, 1))
    return _npz(time=np.array([0.0, 0.1]), bodies=names, position=position, orientation=orientation)


def golden_cases() -> list:
    """Golden settings and golden data: confined, bounded, numbers checked."""
    update = ["golden", "SCENE", "--update"]
    toml = "s.golden.toml"
    out = [
        Case("golden settings a symlink to /proc/self/environ", {"s.isaac": GOLDEN_SCENE,
                                                                  toml: ("<symlink>", "/proc/self/environ")}, update),
        Case("golden settings a symlink outside", {"s.isaac": GOLDEN_SCENE, toml: ("<symlink>", "../secret.toml")},
             update, outside={"secret.toml": f"[run]\n{SECRET} = 1\n"}),
        Case("golden settings a fifo", {"s.isaac": GOLDEN_SCENE, toml: "<fifo>"}, update),
        Case("golden settings not UTF-8", {"s.isaac": GOLDEN_SCENE, toml: b"[run]\nuntil = \"\xff\"\n"}, update),
        Case("golden every 1e-9", {"s.isaac": GOLDEN_SCENE, toml: "[run]\nevery = 1e-9\n"}, update),
        Case("golden every 1e-300", {"s.isaac": GOLDEN_SCENE, toml: "[run]\nevery = 1e-300\n"}, update),
        Case("golden samples 1e12", {"s.isaac": GOLDEN_SCENE, toml: "[run]\nsamples = 1000000000000\n"}, update),
        Case("golden times 1e6 entries", {"s.isaac": GOLDEN_SCENE,
                                          toml: "[run]\ntimes = [" + ", ".join(["0.1"] * 1_000_000) + "]\n"}, update),
        Case("golden until 1e300", {"s.isaac": GOLDEN_SCENE, toml: "[run]\nuntil = 1e300\n"}, update, expect="any"),
        Case("golden tolerance inf", {"s.isaac": GOLDEN_SCENE, toml: "[tolerance]\nposition = inf\n"}, update),
        Case("golden data a symlink to /proc/self/environ",
             {"s.isaac": GOLDEN_SCENE, "s.golden/ir.json": "{}", "s.golden/trajectory.json":
              ("<symlink>", "/proc/self/environ")}, ["golden", "SCENE"]),
        Case("golden data outside", {"s.isaac": GOLDEN_SCENE, "s.golden/ir.json": ("<symlink>", "../../secret.json")},
             ["golden", "SCENE"], outside={"secret.json": f'{{"{SECRET}": [1, 2'}),
        Case("golden data garbage", {"s.isaac": GOLDEN_SCENE, "s.golden/ir.json": "{\"a\": [1, 2, }"},
             ["golden", "SCENE"]),
    ]
    return out


def mesh_and_number_cases() -> list:
    """Values that parse but break a formula, each where it is written."""
    body_on_mesh = 'body rock mesh {{ file "m.obj"  mass 1 kg  inertia (1, 1, 1) kg*m2  at (0, 1, 0) }}'
    return [
        Case("mesh face index 1e20", {"s.isaac": scene(body_on_mesh.format()),
                                      "m.obj": TETRA.replace("f 2 3 4", "f 2 3 100000000000000000000")},
             ["check", "SCENE"]),
        Case("mesh face index -1e20", {"s.isaac": scene(body_on_mesh.format()),
                                       "m.obj": TETRA.replace("f 2 3 4", "f 2 3 -100000000000000000000")},
             ["check", "SCENE"]),
        Case("mesh coordinates 1e200 with inertia", {"s.isaac": scene(body_on_mesh.format()), "m.obj": TETRA.replace(
            "v 1 0 0", "v 1e200 0 0").replace("v 0 1 0", "v 0 1e200 0")}, ["check", "SCENE"]),
        Case("include a symlink to itself", {"s.isaac": 'include "loop.isaac"\n' + scene(BODY),
                                             "loop.isaac": ("<symlink>", "loop.isaac")}, ["check", "SCENE"]),
        Case("include a NUL byte", {"s.isaac": 'include "a\\u0000b.isaac"\n' + scene(BODY)}, ["check", "SCENE"]),
        Case("include a raw NUL byte", {"s.isaac": 'include "a\x00b.isaac"\n' + scene(BODY)}, ["check", "SCENE"]),
        Case("wind speed divided by 0 s", {"s.isaac": scene(BODY, "wind w { direction (1, 0, 0)  "
                                                                  "speed sin(2 * pi * t / 0 s) * 1 m/s }")},
             ["run", "SCENE"]),
        Case("young 0 GPa with an impact sound", {"s.isaac": scene(
            "material m { young 0 GPa  poisson 0.3 }", "body floor plane { material m }",
            BODY.replace("}", " material m }"), IMPACT)}, ["run", "SCENE"]),
        Case("cubic keys at 1e308", {"s.isaac": scene("body k box kinematic { size (1, 1, 1) m  at keys cubic "
                                                      "{ 0 s: (0, 1e308, 0) m, 0.1 s: (0, -1e308, 0) m, "
                                                      "0.2 s: (0, 1e308, 0) m } }", BODY)}, ["run", "SCENE"]),
        Case("sound delay 1e9 s", {"s.isaac": scene(FLOOR, BODY, "sound d on always { play delay(sine(440), 1e9 s) }")},
             ["run", "SCENE"]),
        Case("blow-up beside an unrelated nail", {"s.isaac": scene(
            FLOOR, "body bob sphere { radius 5 cm  mass 1 kg  at (3, 1, 0) }", "constraint hang nail(bob @ (0, 0.1, 0))",
            "body ball sphere { radius 5 cm  mass 1 kg  at (0, -1, 0)  velocity (0, 1e300, 0) m/s }")},
             ["run", "SCENE"]),
        Case("a ball under the floor beside an unrelated nail", {"s.isaac": scene(
            FLOOR, "body bob sphere { radius 5 cm  mass 1 kg  at (3, 1, 0) }", "constraint hang nail(bob @ (0, 0.1, 0))",
            "body ball sphere { radius 5 cm  mass 1 kg  at (0, -0.04, 0) }")}, ["run", "SCENE"], expect="any"),
        Case("gear ratio 3e8 in the viewer", {"s.isaac": scene(
            "body a cylinder { radius 1 m  length 1 cm  mass 1 kg }",
            "body b cylinder { radius 1 m  length 1 cm  mass 1 kg  at (3, 0, 0) }",
            "constraint g gear(a.z, 3e8 m, b.z, 1 m)")}, ["run", "SCENE", "--viewer"], expect="any"),
        Case("--set with a 10000-character name", {"s.isaac": scene(BODY)},
             ["check", "SCENE", "--set", "x" * 10_000 + "=1"], usage=True),
    ]


def command_cases() -> list:
    """export, sweep and golden: inputs and outputs checked before any work."""
    ok = {"s.isaac": "let x = 1\n" + scene(FLOOR, BODY)}
    export = ["export", "SCENE", "--format", "gltf", "--out", "exported", "--trajectory", "t.npz"]
    out = [
        Case("export a text trajectory", {**ok, "t.npz": "not a trajectory\n"}, export, usage=True),
        Case("export an npz without time", {**ok, "t.npz": _npz(x=np.zeros(3))}, export, usage=True),
        Case("export an npz of other bodies", {**ok, "t.npz": _trajectory("somebody")}, export, usage=True),
        Case("export an npz with NaN", {**ok, "t.npz": _trajectory(value=float("nan"))}, export, usage=True),
        Case("export an npz with NaN to RIB", {**ok, "t.npz": _trajectory(value=float("nan"))},
             [*export[:3], "rib", *export[4:]], usage=True),
        Case("export a trajectory symlink to /proc", {**ok, "t.npz": ("<symlink>", "/proc/self/environ")}, export,
             usage=True),
        Case("export a trajectory fifo", {**ok, "t.npz": "<fifo>"}, export, usage=True),
        Case("sweep scheduler of an unknown scheme", ok, ["sweep", "SCENE", "--set", "x=1,2",
                                                          "--scheduler", "gopher://x:1"], usage=True),
        Case("sweep scheduler without a port", ok, ["sweep", "SCENE", "--set", "x=1,2", "--scheduler", "tcp://"],
             usage=True),
        Case("sweep --out a file", {**ok, "f": "a file"}, ["sweep", "SCENE", "--set", "x=1,2", "--out", "f"],
             usage=True),
        Case("sweep --out /proc/self", ok, ["sweep", "SCENE", "--set", "x=1,2", "--out", "/proc/self"], usage=True),
        Case("sweep --workers 10000", ok, ["sweep", "SCENE", "--set", "x=1,2", "--workers", "10000"], usage=True),
        Case("sweep 100000 variants", ok, ["sweep", "SCENE", "--set", "x=1..2/100000"], usage=True),
        Case("sweep 1e6 random variants", ok, ["sweep", "SCENE", "--set", "x=1..2", "--random", "1000000"],
             usage=True),
        Case("export --out a file", {**ok, "f": "a file"}, ["export", "SCENE", "--format", "gltf", "--out", "f"],
             usage=True),
        Case("run --set with a 10000-character name", ok, ["run", "SCENE", "--set", "y" * 10_000 + "=1"],
             usage=True),
    ]
    return out


def cases() -> list:
    return golden_cases() + mesh_and_number_cases() + command_cases()


def main() -> int:
    selected = sys.argv[1:]
    bad = 0
    for case in cases():
        if selected and not any(s in case.name for s in selected):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            outcome = run_case(case, Path(tmp))
        first = next((line for line in outcome.stderr.splitlines() if "error" in line), outcome.stderr[-150:])
        print(f"{outcome.verdict:12} {outcome.code!s:5} {outcome.seconds:5.1f}s  {case.name}: {first[:150]}",
              flush=True)
        bad += outcome.verdict != "ok"
    print(f"{bad} not ok")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
