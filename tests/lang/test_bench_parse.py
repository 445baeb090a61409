"""The parse benchmark stays runnable: its generated scene loads, and a small run prints its numbers."""
from __future__ import annotations

import importlib.util
from pathlib import Path

from isaac_lang.load import load_text

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_parse.py"


def load_bench():
    spec = importlib.util.spec_from_file_location("bench_parse", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_generated_scene_loads():
    bench = load_bench()
    text = bench.generate(400)
    assert text.count("\n") >= 400
    scene = load_text(text, "big.isaac").scene
    groups = sum(1 for b in scene.bodies if b.name.startswith("b"))
    assert len(scene.constraints) == groups and len(scene.forces) == groups
    assert len(scene.bodies) == 1 + 3 * groups  # ground, and per group a bead and two bricks from the loop


def test_a_small_run_prints_lines_per_second(capsys):
    assert load_bench().main(["--lines", "200", "--repeat", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("lines ") and "lines/s" in out
