"""Benchmark of the dynamics plan's step (runtime/dynamics.py + integrate.py): wall time per RK4 step.

    python benchmarks/bench_step.py [--sim-time 1.0] [--csv out.csv]

Scenes: scenes/pendulum.isaac (1 body, 3 rows, dense solver), scenes/chain.isaac (10 links, 30 rows, dense)
and the same chain with links = 100 built in code (300 rows, sparse solver). Each scene is stepped over
--sim-time seconds of simulated time after a few warm-up steps (the first step builds the solver's pattern);
the table gives the mean wall time per step in ms (--cpu: process CPU time instead, steadier on a busy
machine).
"""
import argparse
import sys
import time
from pathlib import Path

from isaac_lang.load import load_scene, load_text
from isaac_runtime.plan import PlanOptions, compile_plan
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[1] / "scenes"
WARMUP_STEPS = 5


def scenes():
    """(label, ir.Scene) of every benchmarked scene."""
    chain = (SCENES / "chain.isaac").read_text()
    return [
        ("pendulum", load_scene(SCENES / "pendulum.isaac").scene),
        ("chain 10", load_scene(SCENES / "chain.isaac").scene),
        ("chain 100", load_text(chain, name="chain.isaac", overrides={"links": "100"}, folder=SCENES).scene),
    ]


def time_steps(scene, sim_time: float, clock=time.perf_counter) -> tuple:
    """(steps, rows, seconds per step) of stepping `scene` for sim_time simulated seconds after a warm-up."""
    plan = compile_plan(scene, PlanOptions(solver="dynamics"))
    sim = Simulation(plan)
    for _ in range(WARMUP_STEPS):
        sim.step()
    start_steps, t0 = sim.state.steps, sim.state.t
    begin = clock()
    sim.advance_to(t0 + sim_time)
    wall = clock() - begin
    steps = sim.state.steps - start_steps
    rows = plan.constraints.total_rows if plan.constraints is not None else 0
    return steps, rows, wall / steps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-time", type=float, default=1.0, help="simulated seconds per scene (default 1)")
    parser.add_argument("--cpu", action="store_true", help="time with process CPU time, not wall time")
    parser.add_argument("--csv", help="also write the table as CSV to this file")
    args = parser.parse_args(argv)
    lines = ["scene,rows,steps,ms_per_step"]
    print(f"{'scene':<12}{'rows':>6}{'steps':>8}{'ms/step':>10}")
    for label, scene in scenes():
        steps, rows, per_step = time_steps(scene, args.sim_time, time.process_time if args.cpu else time.perf_counter)
        print(f"{label:<12}{rows:>6}{steps:>8}{1e3 * per_step:>10.3f}", flush=True)
        lines.append(f"{label},{rows},{steps},{1e3 * per_step:.4f}")
    if args.csv:
        Path(args.csv).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
