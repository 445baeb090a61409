"""Where a step's time goes: cProfile of the dynamics plan's step loop on the pendulum, the 10-link chain and
the 100-link chain (RK4, 1 ms), own time per function, the top entries. Writes profile.csv; the closing
summary names the top three per scene, which is what "make it fast" should attack next.
"""
from __future__ import annotations

import cProfile
import pstats
from pathlib import Path

from . import common

SCENES = (("pendulum", {}), ("chain", {}), ("chain", {"links": "100"}))
TOP = 12


def profile_scene(name: str, overrides: dict, steps: int) -> list:
    from isaac.api import Simulation

    sim = Simulation(common.plan_for(common.configured(common.load(name, overrides), integrator="rk4"),
                                     "dynamics", 1e-3))
    sim.step()
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(steps):
        sim.step()
    profiler.disable()
    stats = pstats.Stats(profiler)
    total = stats.total_tt
    rows = []
    for (path, line, function), (_, calls, own, cumulative, _) in sorted(stats.stats.items(),
                                                                          key=lambda kv: -kv[1][2])[:TOP]:
        where = Path(path).name if path != "~" else "builtin"
        rows.append({"scene": name + (f" links={overrides['links']}" if overrides else ""),
                     "function": f"{where}:{line}({function})", "calls_per_step": calls / steps,
                     "own_us_per_step": 1e6 * own / steps, "cumulative_us_per_step": 1e6 * cumulative / steps,
                     "share_of_step": own / total if total else 0.0})
    return rows


def run(quick: bool = False, out: Path | None = None) -> dict:
    rows = []
    for name, overrides in SCENES:
        mine = profile_scene(name, overrides, 100 if quick else 500)
        rows += mine
        common.log(f"  {mine[0]['scene']}: " + "; ".join(f"{r['function']} {100 * r['share_of_step']:.0f}%"
                                                         for r in mine[:3]))
    if out is not None:
        common.write_csv(out / "profile.csv", rows)
    return {"rows": rows}
