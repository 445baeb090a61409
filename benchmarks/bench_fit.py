"""Benchmark of `isaac fit`: runs (simulations) per fit on docs/goals.md's examples, and the wall time with the
runs in process, on 1 and on 2 Dask workers.

    python benchmarks/bench_fit.py [--workers 0,1,2]

Measured on the 2-core CI machine, other work running (in process): throw through a point (2 parameters, least
squares) 19 runs; slide to a mark (1 parameter, brentq) 9 runs; drop on a beat (1 parameter, event goal, brentq)
4 runs; wall in process 1.63, 0.96, 0.11 s; on one Dask worker 2.70, 3.12, 2.09 s (the cluster's start-up).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def examples() -> list:
    sys.path.insert(0, str(ROOT))
    from tests.doc_examples import scene_examples

    return [e for e in scene_examples() if e.doc == "docs/goals.md"]


def measure(example, workers: int) -> dict:
    from isaac.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.isaac"
        scene.write_text(example.text)
        more = ["--workers", str(workers)] if workers else []
        started = time.perf_counter()
        code = main(["-qq", "fit", str(scene), "--out", str(Path(tmp) / "out"), *more])
        wall = time.perf_counter() - started
        found = json.loads((Path(tmp) / "out" / "fit.json").read_text())
    return {"example": example.name, "workers": workers, "exit": code, "runs": found["runs"],
            "iterations": found["iterations"], "wall": round(wall, 3)}


@pytest.mark.bench
def test_runs_per_fit():
    for example in examples():
        row = measure(example, 0)
        assert row["exit"] == 0 and row["runs"] < 60, row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="0,1,2", help="0: in process")
    args = parser.parse_args()
    for workers in (int(w) for w in args.workers.split(",")):
        for example in examples():
            print(json.dumps(measure(example, workers)))


if __name__ == "__main__":
    main()
