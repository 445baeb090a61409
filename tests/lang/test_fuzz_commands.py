"""Fuzzing the commands other than check and run (issue 31): export, golden, sweep and fit, each given hostile
option values and hostile files beside the scene (trajectories, golden settings, golden data). Every command
ends in exit 0 (or 3: a golden mismatch, a goal missed), or exit 2 with a `file:line:col` position or
one naming the option (`--out ...`), never a traceback or exit 1, never a leak, within 20 s.

The default run is seeded and quick: each case has at least one hostile option or file, so it is refused before
any run, in this process. `-m slow` draws fresh cases, some of them entirely valid (they run), each in an
`isaac` process of its own under the issue's 20 s and 4 GB. From the shell:

    python -m tests.lang.test_fuzz_commands [COUNT] [SEED]
"""
from __future__ import annotations

import io
import random
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from . import hostile
from .hostile import BODY, SECRET, Case, scene

FIT_PART = ("vary x in 0.5 .. 2", "goal high: ball.position.y at 0.1 s = 0.9 m within 1 cm")
SCENE_TEXT = "let x = 1\n" + scene("body floor plane { }", BODY.replace("(0, 1, 0)", "(0, x, 0)"), *FIT_PART)
# values for any option: empty, not a number, out of range, too long, control characters, paths that are not
# places to write, addresses that are not addresses
HOSTILE_VALUES = ["", "0", "-1", "1e400", "nan", "inf", "x" * 300, "\x00", "a\x00b", "\x1b[2J", "/proc/self",
                  "/dev/null", "/", "f", "../outside", "gopher://x:1", "tcp://", "10000", "1..2/100000",
                  "99999999999999999999", "1e-300", "-0", "{}", "[]", "x=", "=1", "x=1..", "x=1,,2", "y=1"]
FORMATS = ["gltf", "glb", "rib"]
GOOD = {"--format": FORMATS, "--out": ["out"], "--workers": ["1", "2"], "--random": ["2"],
        "--set": ["x=1,2", "x=0.5..1.5/2", "x=1"], "--until": ["0.1", "0.1 s"], "--step": ["1 ms"]}
COMMANDS = {"export": ["--format", "--out", "--trajectory", "--until"], "golden": ["--set", "--update"],
            "sweep": ["--set", "--workers", "--random", "--out", "--scheduler"],
            "fit": ["--out", "--workers", "--scheduler", "--set"]}


def _npz(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def hostile_trajectory(rng: random.Random) -> bytes | str | tuple:
    """A trajectory.npz gone wrong: not an npz, arrays missing, other bodies, shapes that disagree, NaN."""
    frames = rng.choice([0, 1, 2, 5])
    arrays = {"time": np.linspace(0, 0.1, frames), "bodies": np.array(["floor", "ball"]),
              "position": np.zeros((frames, 2, 3)), "orientation": np.tile([1.0, 0, 0, 0], (frames, 2, 1))}
    how = rng.choice(["text", "drop", "bodies", "shape", "nan", "huge time", "strings", "symlink", "fifo"])
    if how == "text":
        return "not a trajectory\n"
    if how == "symlink":
        return ("<symlink>", "/proc/self/environ")
    if how == "fifo":
        return "<fifo>"
    if how == "drop":
        arrays.pop(rng.choice(sorted(arrays)))
    elif how == "bodies":
        arrays["bodies"] = np.array(["floor", "nobody"])
    elif how == "shape":
        arrays["position"] = np.zeros((frames + 1, 3))
    elif how == "nan" and frames:
        arrays["position"][-1, 1, 1] = np.nan
    elif how == "huge time":
        arrays["time"] = np.full(frames, 1e308)
    elif how == "strings":
        arrays["time"] = np.array(["a"] * frames)
    return _npz(**arrays)


def hostile_golden_settings(rng: random.Random) -> str:
    key, value = rng.choice([("run", "every"), ("run", "samples"), ("run", "until"), ("run", "times"),
                             ("tolerance", "position"), ("tolerance", "energy"), ("set", "x")]), \
        rng.choice(["1e-300", "0", "-1", "inf", "nan", '"x"', "[]", "[1e308, -1]", "1e12", "{ a = 1 }", '"\\u0000"'])
    return f"[{key[0]}]\n{key[1]} = {value}\n"


def hostile_golden_data(rng: random.Random) -> dict:
    section = rng.choice(["ir", "trajectory", "events", "report", "audio", "meta", "positions"])
    value = rng.choice(["[]", "{}", '"x"', "1e999", '{"time": "soon", "bodies": []}', '{"time": [1, 0]}',
                        '{"time": [0.1], "bodies": {"ball": {"position": ["a"]}}}', "[" * 5000, "null", '{"a": ['])
    return {f"s.golden/{name}.json": "{}" for name in ("ir",)} | {f"s.golden/{section}.json": value}


def draw_case(rng: random.Random, hostile_only: bool) -> Case:
    """One command line, with its files; hostile_only: at least one option or file is hostile (quick)."""
    command = rng.choice(sorted(COMMANDS))
    files = {"s.isaac": SCENE_TEXT, "f": "a file"}
    args = [command, "SCENE"]
    options = rng.sample(COMMANDS[command], rng.randint(1, len(COMMANDS[command])))
    spoiled = False
    for option in options:
        if option == "--update":
            args.append(option)
            continue
        if option == "--trajectory":
            files["t.npz"] = hostile_trajectory(rng)
            args += [option, "t.npz"]
            spoiled = True
            continue
        bad = rng.random() < 0.5 or (hostile_only and not spoiled and option == options[-1])
        args += [option, rng.choice(HOSTILE_VALUES) if bad else rng.choice(GOOD.get(option, ["1"]))]
        spoiled |= bad
    if command == "export" and "--format" not in args:
        args += ["--format", rng.choice(FORMATS)]
    if command == "golden":
        if rng.random() < 0.5 or (hostile_only and not spoiled):
            files["s.golden.toml"] = hostile_golden_settings(rng)
        else:
            files |= hostile_golden_data(rng)
    return Case(" ".join(repr(a)[:40] for a in args), files, args, usage=True, expect="any")


def for_a_process(case: Case) -> Case:
    """The case with the NUL bytes of its arguments written out: an argument vector cannot hold one (a shell
    cannot give it; the in-process cases do)."""
    return Case(case.name, case.files, [a.replace("\x00", "%00") for a in case.args], usage=True, expect="any")


def verdict(case: Case, code, output: str) -> str:
    """ok, or what went wrong: a leak, a traceback (or exit 1), an exit 2 that names neither a place in a file
    nor an option, another exit code."""
    if SECRET in output:
        return "leak"
    if code == 1 or "Traceback" in output:
        return "traceback"
    if code in (0, 3):  # 3: a golden mismatch, a goal missed (a check that ran and failed)
        return "ok"
    if code != 2:
        return f"exit {code}"
    if hostile.POSITIONED.search(output):
        return "ok"
    errors = [line for line in output.splitlines() if hostile.USAGE.match(line) and "error" in line]
    return "ok" if any("--" in line for line in errors) else "unpositioned"


def in_its_own_process(case: Case, root: Path):
    """The case in an `isaac` process (tests/lang/hostile.py: 20 s, 4 GB), judged by verdict() above; a hang or a
    leak as hostile.py finds them (it sees stdout too)."""
    outcome = hostile.run_case(case, root)
    if outcome.verdict in ("hang", "leak"):
        return outcome
    return hostile.Outcome(verdict(case, outcome.code, outcome.stderr), outcome.code, outcome.stderr,
                           outcome.seconds)


def in_process(case: Case, root: Path, monkeypatch) -> tuple:
    """The case through isaac.cli.main in this process: (verdict, exit code, output, seconds)."""
    from isaac.cli import main

    path = hostile.materialize(case, root)
    monkeypatch.chdir(path.parent)
    monkeypatch.setenv("ISAAC_HOSTILE_SECRET", SECRET)
    args = [str(path) if a == "SCENE" else a for a in case.args]
    started = time.monotonic()
    out, err = io.StringIO(), io.StringIO()
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setattr(sys, "stderr", err)
    try:
        code = main(args)
    except SystemExit as stop:
        code = stop.code
    finally:
        monkeypatch.undo()
    output = out.getvalue() + err.getvalue()
    return verdict(case, code, output), code, output, time.monotonic() - started


QUICK = [draw_case(random.Random(seed), hostile_only=True) for seed in range(30)]


@pytest.mark.parametrize("case", QUICK, ids=[f"{i}-{c.args[0]}" for i, c in enumerate(QUICK)])
def test_a_hostile_command_line_ends_cleanly(case, tmp_path, monkeypatch):
    import isaac.fit.solve as solve
    import isaac.sweep.driver as driver

    # the quick cases are refused before any work; a search or a sweep that starts is one that ran
    monkeypatch.setattr(solve, "find", lambda *a, **k: pytest.fail("the search started"))
    monkeypatch.setattr(driver, "sweep", lambda *a, **k: pytest.fail("the sweep started"))
    outcome, code, output, seconds = in_process(case, tmp_path, monkeypatch)
    assert outcome == "ok", f"{outcome} (exit {code}, {seconds:.1f} s) {case.args}: {output[-1500:]}"
    assert seconds < hostile.TIMEOUT


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(200))
def test_a_fresh_command_line_ends_cleanly_in_its_own_process(seed, tmp_path):
    case = for_a_process(draw_case(random.Random(10_000 + seed + int(time.time()) // 86400), hostile_only=False))
    outcome = in_its_own_process(case, tmp_path)
    assert outcome.verdict == "ok", f"{outcome.verdict} (exit {outcome.code}, {outcome.seconds:.1f} s) " \
                                    f"{case.args}: {outcome.stderr[-1500:]}"


def main() -> int:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    bad = 0
    for index in range(count):
        case = for_a_process(draw_case(random.Random(seed * 1_000_003 + index), hostile_only=False))
        with tempfile.TemporaryDirectory() as tmp:
            outcome = in_its_own_process(case, Path(tmp))
        if outcome.verdict != "ok":
            bad += 1
            print(f"{outcome.verdict:12} {outcome.code!s:5} {outcome.seconds:5.1f}s  {case.args}: "
                  f"{outcome.stderr[-300:]}", flush=True)
    print(f"{bad} of {count} not ok")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
