"""Commands: every shipped scene's whole `isaac run` command, as a user types it, against issue 29's budget

    budget = 0.5 s + simulated time / 20        (the clock: 30 s of it in 2 s)

Each scene (scenes/*.isaac) is run once to fill the caches (numba's compiled core, Python's bytecode), then
REPEATS times in a fresh process, `isaac run scenes/X.isaac --out <tmp>`, timed from the outside (process start
to exit, what /usr/bin/time says); the best of the repeats is kept, the machine being shared. Python's bytecode is
written (PYTHONDONTWRITEBYTECODE unset), as a user's install has it.

    python -m benchmarks.commands [--only NAME ...] [--repeats N] [--out DIR]
    isaac bench --only commands

Writes commands.csv (scene, simulated_s, budget_s, wall_s (best), all_s, within) and prints the table.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from . import common

REPEATS = 3
QUICK_REPEATS = 1
# the budget's terms (issue 29): a fixed start and a twentieth of the simulated time
FIXED_S = 0.5
PER_SIMULATED_S = 1.0 / 20.0
KEYS = ["scene", "simulated_s", "budget_s", "wall_s", "all_s", "within"]


def shipped() -> list:
    return sorted(common.SCENES.glob("*.isaac"))


def simulated_time(path: Path) -> float:
    """The scene's simulated time, end - start, from its plan (as `isaac run` would take it)."""
    scene = common.load(path.stem)
    return float(scene.time.end - scene.time.start)


def budget(simulated: float) -> float:
    return FIXED_S + PER_SIMULATED_S * simulated


def time_command(path: Path, out: Path) -> float:
    """Wall time of one `isaac run` of the scene, in a fresh process; inf when it fails."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    command = [sys.executable, "-m", "isaac", "run", str(path), "--out", str(out), "-q"]
    started = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        common.log(f"  {path.stem}: exit {done.returncode}: {done.stderr.strip().splitlines()[-1:]}")
        return float("inf")
    return wall


def measure(path: Path, repeats: int) -> dict:
    simulated = simulated_time(path)
    with tempfile.TemporaryDirectory(prefix=f"isaac-bench-{path.stem}-") as folder:
        out = Path(folder) / "out"
        time_command(path, out)  # the caches filled (a first run on a machine compiles)
        walls = [time_command(path, out) for _ in range(repeats)]
    best = min(walls)
    return {"scene": path.stem, "simulated_s": simulated, "budget_s": budget(simulated), "wall_s": best,
            "all_s": " ".join(f"{w:.2f}" for w in walls), "within": best <= budget(simulated)}


def table(rows: list) -> str:
    lines = [f"{'scene':<14}{'simulated':>10}{'budget':>9}{'wall':>9}  {'':<9}runs",
             f"{'':<14}{'s':>10}{'s':>9}{'s':>9}"]
    for r in rows:
        verdict = "ok" if r["within"] else f"x{r['wall_s'] / r['budget_s']:.1f}"
        lines.append(f"{r['scene']:<14}{r['simulated_s']:>10.3g}{r['budget_s']:>9.2f}{r['wall_s']:>9.2f}  "
                     f"{verdict:<9}{r['all_s']}")
    within = sum(bool(r["within"]) for r in rows)
    lines.append(f"{within} of {len(rows)} scenes within budget")
    return "\n".join(lines)


def run(quick: bool = False, out: Path | None = None, only: list | None = None, repeats: int | None = None) -> dict:
    out = Path(out) if out else common.RESULTS
    out.mkdir(parents=True, exist_ok=True)
    paths = [p for p in shipped() if not only or p.stem in only]
    rows = []
    for path in paths:
        rows.append(measure(path, repeats or (QUICK_REPEATS if quick else REPEATS)))
        r = rows[-1]
        common.log(f"  {r['scene']}: {r['wall_s']:.2f} s (budget {r['budget_s']:.2f} s)")
    common.write_csv(out / "commands.csv", rows, KEYS)
    common.log(table(rows))
    return {"rows": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help="these scenes (names without .isaac)")
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    result = run(out=args.out, only=args.only, repeats=args.repeats)
    return 0 if all(r["within"] for r in result["rows"]) else 1


if __name__ == "__main__":
    sys.exit(main())
