"""Runs killed at random moments (SIGKILL and SIGINT) while they write into a folder that holds another scene's
outputs: every time, the folder holds exactly one run's files, whole (the old scene's or the new one's, every
file of it from that one run), no temporaries, and the user's own file; what the killed runs left beside it is
reclaimed by the next run. Half the kills land anywhere in a run, half while its files are being written (once
its staging folder appears). `isaac export` into a run's folder and a sweep's variant folders (and its table)
are killed the same way. `-m slow` kills sixty runs and thirty of each other; the default run kills a few.
"""
from __future__ import annotations

import base64
import json
import os
import random
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from isaac_runtime.outputs.outputset import LEFTOVER, MANIFEST, read_manifest

pytestmark = pytest.mark.skipif(os.name == "nt", reason="POSIX signals")

SCENES = Path(__file__).resolve().parents[2] / "scenes"
# the two scenes that take turns: each run goes into a folder holding the other's outputs
RUNS = {"pendulum": ("pendulum.isaac", "theta0", "deg", ("--until", "2")),  # no sound
        "bar": ("bar.isaac", "drop", "cm", ())}  # a sound: audio.wav, embedded in the viewer
NOTE = "the user's own notes"


def command(scene: str, value: float, out: Path) -> list:
    file, parameter, unit, extra = RUNS[scene]
    return [sys.executable, "-m", "isaac.cli", "run", str(SCENES / file), "--out", str(out),
            "--set", f"{parameter}={value:g}{unit}", "-q", *extra]


def one_run(folder: Path) -> tuple:
    """(scene, its parameter value in SI) of the one run whose files the folder holds; fails on anything else."""
    manifest = read_manifest(folder)
    assert manifest and manifest["state"] == "whole", manifest
    present = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}
    assert present - {MANIFEST, "notes.txt"} == set(manifest["files"]), "files beside the set, or missing ones"
    assert (folder / "notes.txt").read_text() == NOTE
    strict = dict(parse_constant=lambda name: pytest.fail(f"not JSON: {name}"))
    ir = json.loads((folder / "ir.json").read_text(), **strict)
    report = json.loads((folder / "report.json").read_text(), **strict)
    json.loads((folder / "events.json").read_text(), **strict)
    assert report["scene"] == ir["name"] == manifest["scene"]
    with np.load(folder / "trajectory.npz", allow_pickle=False) as data:
        assert list(data["bodies"]) == [body["name"] for body in ir["bodies"]]
        assert len(data["time"]) == report["frames"]
        position = np.asarray(data["position"], np.float32)
    viewer = (folder / "viewer.html").read_text()
    shown = re.search(r'"position":"([A-Za-z0-9+/=]*)"', viewer).group(1)
    assert np.array_equal(np.frombuffer(base64.b64decode(shown), "<f4"), position.ravel()), "another run's viewer"
    assert ("audio.wav" in present) == bool(ir["sounds"])
    if ir["sounds"]:
        heard = re.search(r'"audio":"data:audio/wav;base64,([A-Za-z0-9+/=]*)"', viewer).group(1)
        assert base64.b64decode(heard) == (folder / "audio.wav").read_bytes(), "another run's sound"
    parameter = RUNS[ir["name"]][1]
    return ir["name"], round(ir["parameters"][parameter], 7)


def si(scene: str, value: float) -> float:
    return round(float(np.radians(value) if RUNS[scene][2] == "deg" else value / 100), 7)


def staging_of(parent: Path, name: str, pid: int) -> bool:
    prefix = f".{name}.isaac-new-{pid}-"
    return any(entry.startswith(prefix) for entry in os.listdir(parent))


def run_and_kill(args: list, parent: Path, name: str, how: signal.Signals, delay: float, in_write: bool,
                 rng: random.Random) -> int:
    """Start a run; kill it `delay` s after it starts, or (in_write) that long after its staging folder appears."""
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    started = time.monotonic()
    if in_write:
        while process.poll() is None and not staging_of(parent, name, process.pid):
            time.sleep(0.0005)
        started = time.monotonic()
    while process.poll() is None and time.monotonic() - started < delay:
        time.sleep(0.0005)
    if process.poll() is None:
        process.send_signal(how)
    return process.wait(timeout=120)


def calibrate(out: Path) -> tuple:
    """(seconds of a whole run, seconds of its writing) of each scene, measured once."""
    times = {}
    for scene in RUNS:
        process = subprocess.Popen(command(scene, 10.0, out), stdout=subprocess.DEVNULL)
        started = time.monotonic()
        while process.poll() is None and not staging_of(out.parent, out.name, process.pid):
            time.sleep(0.0005)
        writing = time.monotonic()
        assert process.wait(timeout=300) == 0
        done = time.monotonic()
        times[scene] = (done - started, max(done - writing, 0.01))
    return times


def kill_runs(tmp_path: Path, kills: int, seed: int) -> dict:
    rng = random.Random(seed)
    out = tmp_path / "out" / "shared"
    out.parent.mkdir()
    times = calibrate(out)  # leaves the bar's outputs in the folder
    (out / "notes.txt").write_text(NOTE)
    held = one_run(out)
    tally = {"kills": 0, "old": 0, "new": 0, "in_write": 0}
    for attempt in range(kills):
        scene = "pendulum" if held[0] == "bar" else "bar"
        value = round(rng.uniform(5, 60), 3)
        how = (signal.SIGKILL, signal.SIGINT)[attempt % 2]
        in_write = attempt % 4 >= 2
        whole, writing = times[scene]
        delay = rng.uniform(0, writing * 1.2) if in_write else rng.uniform(0, whole * 1.1)
        run_and_kill(command(scene, value, out), out.parent, out.name, how, delay, in_write, rng)
        now = one_run(out)
        assert now in (held, (scene, si(scene, value))), f"attempt {attempt}: {now}, neither {held} nor this run"
        tally["kills"] += 1
        tally["new" if now != held else "old"] += 1
        tally["in_write"] += in_write
        held = now
        inside = [p.name for p in out.iterdir() if p.name.startswith(".") and p.name != MANIFEST]
        assert not inside, f"temporaries in the folder: {inside}"
    # a run to the end reclaims every leftover of the killed ones beside the folder
    scene = "pendulum" if held[0] == "bar" else "bar"
    assert subprocess.run(command(scene, 33.0, out), stdout=subprocess.DEVNULL, timeout=300).returncode == 0
    assert one_run(out) == (scene, si(scene, 33.0))
    assert not [p.name for p in out.parent.iterdir() if LEFTOVER.match(p.name)], "leftovers not reclaimed"
    return tally


def test_runs_killed_at_random_leave_one_whole_set(tmp_path):
    tally = kill_runs(tmp_path, kills=6, seed=20)
    assert tally["kills"] == 6


@pytest.mark.slow
def test_sixty_runs_killed_at_random_leave_one_whole_set(tmp_path):
    tally = kill_runs(tmp_path, kills=60, seed=2020)
    print(f"kills: {tally}")
    # the kills must have reached both outcomes, or the test proved nothing about the swap
    assert tally["old"] > 0 and tally["new"] > 0


# -- isaac export: its files join the run's set, or replace the export of the set ------------------------------------

EXPORTS = {"rib 0:40": ("--format", "rib", "--frames", "0:40"), "rib 0:150": ("--format", "rib", "--frames", "0:150"),
           "gltf": ("--format", "gltf")}


def export_command(kind: str, out: Path) -> list:
    return [sys.executable, "-m", "isaac.cli", "export", str(SCENES / "pendulum.isaac"), "--out", str(out),
            *EXPORTS[kind], "-q"]


def exported(folder: Path) -> tuple:
    """(the RIB files, whether the glTF is there) of the folder, after checking it holds one whole run's set."""
    one_run(folder)
    rib = frozenset(p.name for p in (folder / "rib").iterdir()) if (folder / "rib").is_dir() else frozenset()
    return rib, (folder / "pendulum.gltf").is_file()


def kill_exports(tmp_path: Path, kills: int, seed: int) -> dict:
    rng = random.Random(seed)
    out = tmp_path / "out" / "shared"
    out.parent.mkdir()
    assert subprocess.run([sys.executable, "-m", "isaac.cli", "run", str(SCENES / "pendulum.isaac"), "--out",
                           str(out), "--until", "2", "-q"], timeout=300).returncode == 0
    (out / "notes.txt").write_text(NOTE)
    files, seconds = {}, {}
    for kind in EXPORTS:  # each export once to the end: its files, and how long it takes
        started = time.monotonic()
        assert subprocess.run(export_command(kind, out), stdout=subprocess.DEVNULL, timeout=300).returncode == 0
        seconds[kind] = time.monotonic() - started
        files[kind] = exported(out)[0] if kind.startswith("rib") else None
    held = exported(out)
    tally = {"kills": 0, "old": 0, "new": 0}
    for attempt in range(kills):
        kind = rng.choice([k for k in EXPORTS if (files[k] or held[0]) != held[0] or k == "gltf" and not held[1]]
                          or list(EXPORTS))
        new = (files[kind], held[1]) if kind.startswith("rib") else (held[0], True)
        how = (signal.SIGKILL, signal.SIGINT)[attempt % 2]
        run_and_kill(export_command(kind, out), out.parent, out.name, how, rng.uniform(0, seconds[kind] * 1.1),
                     False, rng)
        now = exported(out)
        assert now in (held, new), f"attempt {attempt} ({kind}): {len(now[0])} RIB files, glTF {now[1]}"
        tally["kills"] += 1
        tally["new" if now != held else "old"] += 1
        held = now
        inside = [p.name for p in out.rglob(".*") if p.name != MANIFEST]
        assert not inside, f"temporaries in the folder: {inside}"
    assert subprocess.run(export_command("rib 0:40", out), stdout=subprocess.DEVNULL, timeout=300).returncode == 0
    assert exported(out)[0] == files["rib 0:40"]
    assert not [p.name for p in out.parent.iterdir() if LEFTOVER.match(p.name)], "leftovers not reclaimed"
    return tally


def test_exports_killed_at_random_leave_one_whole_set(tmp_path):
    assert kill_exports(tmp_path, kills=4, seed=21)["kills"] == 4


@pytest.mark.slow
def test_thirty_exports_killed_at_random_leave_one_whole_set(tmp_path):
    tally = kill_exports(tmp_path, kills=30, seed=2121)
    print(f"export kills: {tally}")
    assert tally["old"] > 0 and tally["new"] > 0


# -- a sweep's kept outputs and its table ---------------------------------------------------------------------------

# what a sweep's client does with each finished variant and at its end (isaac/sweep/driver.py), without the Dask
# cluster: every file of a variant starts with the generation that wrote it
SWEEP_WRITER = textwrap.dedent("""
    import sys
    from pathlib import Path

    import numpy as np
    import pandas as pd

    from isaac.sweep.table import store_outputs, write_table
    from isaac.sweep.task import Task

    folder, generation = Path(sys.argv[1]), int(sys.argv[2])
    rng = np.random.default_rng(generation)
    print("writing", flush=True)
    for i in range(3):
        files = {name: f"{generation}\\n".encode() + rng.bytes(400_000)
                 for name in ("trajectory.npz", "events.json", "ir.json", "report.json")}
        store_outputs(folder, Task(index=i, id=f"v{i}", values={"x": str(i)}), files)
    write_table(pd.DataFrame({"variant": [0, 1, 2], "generation": [generation] * 3}), folder)
""")
VARIANT_FILES = {"trajectory.npz", "events.json", "ir.json", "report.json"}


def sweep_state(folder: Path) -> tuple:
    """(the generation of each variant's set, None where there is none), after checking each is one whole set and
    the table is whole."""
    generations = []
    for i in range(3):
        variant = folder / "variants" / f"v{i}"
        if not variant.exists():
            generations.append(None)
            continue
        manifest = read_manifest(variant)
        assert manifest and manifest["state"] == "whole" and set(manifest["files"]) == VARIANT_FILES
        assert {p.name for p in variant.iterdir()} == VARIANT_FILES | {MANIFEST}, "temporaries or missing files"
        heads = {(variant / name).read_bytes().split(b"\n", 1)[0] for name in VARIANT_FILES}
        assert len(heads) == 1, f"v{i} mixes the files of generations {heads}"
        generations.append(int(heads.pop()))
    if (folder / "sweep.parquet").exists():
        import pandas as pd

        assert len(set(pd.read_parquet(folder / "sweep.parquet")["generation"])) == 1
    return tuple(generations)


def kill_sweeps(tmp_path: Path, kills: int, seed: int) -> dict:
    rng = random.Random(seed)
    folder = tmp_path / "sweep"

    def writer(generation: int) -> list:
        return [sys.executable, "-c", SWEEP_WRITER, str(folder), str(generation)]

    def start(generation: int) -> tuple:
        """The writer's process, once it has its modules and begins to write."""
        process = subprocess.Popen(writer(generation), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        assert process.stdout.readline() == "writing\n"
        return process, time.monotonic()

    process, started = start(1)
    assert process.wait(timeout=300) == 0
    writing = time.monotonic() - started
    held = sweep_state(folder)
    assert held == (1, 1, 1)
    tally = {"kills": 0, "old": 0, "new": 0}
    for attempt in range(kills):
        generation = attempt + 2
        how = (signal.SIGKILL, signal.SIGINT)[attempt % 2]
        process, started = start(generation)
        delay = rng.uniform(0, 1.2 * writing)
        while process.poll() is None and time.monotonic() - started < delay:
            time.sleep(0.0005)
        if process.poll() is None:
            process.send_signal(how)
        process.wait(timeout=120)
        now = sweep_state(folder)
        for i, (before, after) in enumerate(zip(held, now)):
            assert after in (before, generation), f"attempt {attempt}: v{i} holds generation {after}"
        # the variants are written in order: a new one only after every one before it
        assert list(now) == [generation] * now.count(generation) + list(held[now.count(generation):])
        tally["kills"] += 1
        tally["new" if generation in now else "old"] += 1
        held = now
    assert subprocess.run(writer(99), timeout=300).returncode == 0
    assert sweep_state(folder) == (99, 99, 99)
    leftovers = {p.name: (sorted(q.name for q in p.iterdir()), read_manifest(p))
                 for p in (folder / "variants").iterdir() if LEFTOVER.match(p.name)}
    assert not leftovers, f"leftovers not reclaimed: {leftovers}"
    assert sorted(p.name for p in folder.iterdir()) == ["sweep.csv", "sweep.parquet", "variants"]
    return tally


def test_sweep_outputs_killed_at_random_stay_whole(tmp_path):
    assert kill_sweeps(tmp_path, kills=4, seed=22)["kills"] == 4


@pytest.mark.slow
def test_thirty_sweep_writes_killed_at_random_stay_whole(tmp_path):
    tally = kill_sweeps(tmp_path, kills=30, seed=2222)
    print(f"sweep kills: {tally}")
    assert tally["old"] > 0 and tally["new"] > 0
