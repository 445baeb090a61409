"""Contact: heaps of spheres or boxes dropped into a bin, ours side by side with MuJoCo at the same step.

The scene is tests/runtime/test_capture.py's `heap`: spheres of radius 5 cm (or 10 cm boxes) on a grid of 13 cm,
layered, each layer shifted 1 cm in x so nothing stacks perfectly, dropped onto a floor plane inside a bin of four
wall planes; density 1000 kg/m3, friction 0.5, restitution 0.3, 2 s of simulated time. The bin is the test's
(+-0.35 m) as long as the grid fits in it (up to 4 x 4 per layer); wider grids get a bin just wider than the grid
(`bin_half_width`), since the test's bin would start the outer columns inside a wall.

Ours: `solver dynamics { integrator rk4  step 1 ms }` (and, with --solver procedural or both,
`solver procedural { step 10 ms  substeps 10 }`), built with Simulation.from_text, then advance_to(2 s) timed
(in chunks of CHUNK s, so that a run over --limit seconds of wall time is cut short: its time is then
extrapolated to 2 s and the row says so). After the run, contact_report(): path, deepest, steps_creating_energy.

MuJoCo: the same pile in MJCF (free bodies, the same geoms and masses, a floor and four wall planes, friction 0.5,
default solref/solimp: MuJoCo has no restitution coefficient), timestep 1 ms, RK4 and Euler, 2000 mj_step calls
timed one by one in this process (a run over --limit is cut short and extrapolated, as ours); deepest =
-min(contact.dist) over all steps taken.

    python -m benchmarks.contact [--solver dynamics|procedural|both] [--quick] [--limit S] [--boxes-1000]
                                 [--only KIND:COUNT ...] [--out DIR]

Writes benchmarks/results/contact.csv (rows of other plans already there are kept) and prints a table and the
scaling figure t(1000 spheres) / t(125 spheres) per step for each engine.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from . import common

UNTIL = 2.0
STEP = 1e-3
CHUNK = 0.1  # s of simulated time per advance_to call of ours
LIMIT = 120.0  # s of wall time before a run of ours is cut short (and extrapolated)
SPHERES = (8, 27, 64, 125, 216, 1000)
BOXES = (8, 27, 64, 125)
QUICK_SPHERES = (8, 27, 64)
QUICK_BOXES = (8, 27)
SPACING, RADIUS, SIDE = 0.13, 0.05, 0.1
TEST_BIN = 0.35
PLANS = {"dynamics": "solver dynamics { integrator rk4  step 1 ms }",
         "procedural": "solver procedural { step 10 ms  substeps 10 }"}
MATERIAL = "density 1000 kg/m3  friction 0.5  restitution 0.3"
KEYS = ["scene", "kind", "count", "engine", "plan/integrator", "step", "steps", "wall_s", "per_step_us",
        "ratio_to_mujoco_rk4", "deepest_mm", "energy_note/path"]


# -- the scene -------------------------------------------------------------------------------------------------


def grid(count: int) -> list:
    """The centres (x, y, z) of the heap, y up: the test's layout."""
    side = math.ceil(count ** (1 / 3))
    out = []
    for k in range(count):
        i, j, l = k % side, (k // side) % side, k // (side * side)
        out.append((round((i - side / 2) * SPACING + 0.01 * l, 3), round(0.1 + SPACING * l, 3),
                    round((j - side / 2) * SPACING, 3)))
    return out


def bin_half_width(count: int) -> float:
    """The test's 0.35 m while the grid (and a 2 cm gap) fits inside it, else just wider than the grid."""
    centres = np.array(grid(count))
    reach = np.abs(centres[:, [0, 2]]).max() + RADIUS + 0.02
    return TEST_BIN if reach <= TEST_BIN else round(reach + 0.03, 3)


def heap_text(count: int, kind: str, plan: str = "dynamics", until: float = UNTIL) -> str:
    w = bin_half_width(count)
    walls = ("  body floor plane { material m }\n"
             f"  body wx0 plane {{ normal (1, 0, 0)  at ({-w}, 0, 0) m  material m }}\n"
             f"  body wx1 plane {{ normal (-1, 0, 0)  at ({w}, 0, 0) m  material m }}\n"
             f"  body wz0 plane {{ normal (0, 0, 1)  at (0, 0, {-w}) m  material m }}\n"
             f"  body wz1 plane {{ normal (0, 0, -1)  at (0, 0, {w}) m  material m }}")
    shape = "sphere { radius 5 cm" if kind == "sphere" else "box { size (0.1, 0.1, 0.1) m"
    lines = [f"  body p{k} {shape}  material m  at ({x:.3f}, {y:.3f}, {z:.3f}) m }}"
             for k, (x, y, z) in enumerate(grid(count))]
    return (f"scene heap {{\n  time 0 s .. {until} s\n  frames 100 Hz\n  gravity (0, -9.81, 0) m/s2\n"
            f"  {PLANS[plan]}\n  material m {{ {MATERIAL} }}\n{walls}\n" + "\n".join(lines) + "\n}\n")


def heap_mjcf(count: int, kind: str, integrator: str) -> str:
    """The same heap for MuJoCo, in the same (y up) frame: gravity along -y, the planes' normals as z axes."""
    w = bin_half_width(count)
    geom = (f'type="sphere" size="{RADIUS}"' if kind == "sphere" else
            f'type="box" size="{SIDE / 2} {SIDE / 2} {SIDE / 2}"')
    bodies = "".join(f'<body pos="{x} {y} {z}"><freejoint/><geom {geom} density="1000"/></body>'
                     for x, y, z in grid(count))
    planes = (f'<geom type="plane" size="0 0 1" zaxis="0 1 0"/>'
              f'<geom type="plane" size="0 0 1" pos="{-w} 0 0" zaxis="1 0 0"/>'
              f'<geom type="plane" size="0 0 1" pos="{w} 0 0" zaxis="-1 0 0"/>'
              f'<geom type="plane" size="0 0 1" pos="0 0 {-w}" zaxis="0 0 1"/>'
              f'<geom type="plane" size="0 0 1" pos="0 0 {w}" zaxis="0 0 -1"/>')
    return (f'<mujoco><option timestep="{STEP}" integrator="{integrator}" gravity="0 -9.81 0"/>'
            f'<size memory="256M"/><default><geom friction="0.5 0.005 0.0001"/></default>'
            f'<worldbody>{planes}{bodies}</worldbody></mujoco>')


# -- runs ------------------------------------------------------------------------------------------------------


def warm_up(kinds, plans) -> None:
    """Load numba's cached code (the first run ever compiles, ~100 s) on a tiny heap of each kind and plan."""
    from isaac.api import Simulation

    for kind in kinds:
        for plan in plans:
            begin = time.perf_counter()
            # 8 bodies: the exact path, then the capturing path from the first impact (t ~ 0.12 s); 27: capturing
            Simulation.from_text(heap_text(8, kind, plan, until=0.2)).advance_to(0.2)
            Simulation.from_text(heap_text(27, kind, plan, until=0.05)).advance_to(0.05)
            common.log(f"  warm-up {kind} {plan}: {time.perf_counter() - begin:.1f} s")


def run_ours(count: int, kind: str, plan: str, limit: float) -> dict:
    from isaac.api import Simulation

    row = {"scene": f"heap-{kind}-{count}", "kind": kind, "count": count, "engine": "isaac",
           "plan/integrator": "dynamics rk4" if plan == "dynamics" else "procedural xpbd",
           "step": "1 ms" if plan == "dynamics" else "10 ms / 10 substeps"}
    try:
        sim = Simulation.from_text(heap_text(count, kind, plan))
    except Exception as error:  # noqa: BLE001 (a scene the runtime refuses is a result)
        message = " ".join(str(error).split())[:300]
        return {**row, "steps": 0, "wall_s": math.nan, "per_step_us": math.nan, "deepest_mm": math.nan,
                "energy_note/path": f"REFUSED: {type(error).__name__}: {message}"}
    wall, t, note = 0.0, 0.0, ""
    try:
        while t < UNTIL - 1e-12:
            t = min(UNTIL, t + CHUNK)
            begin = time.perf_counter()
            sim.advance_to(t)
            wall += time.perf_counter() - begin
            if wall > limit and t < UNTIL - 1e-12:
                note = f"cut at t={t:.2f} s after {wall:.0f} s; time extrapolated to 2 s; "
                break
    except Exception as error:  # noqa: BLE001 (a failure is a result)
        note = f"FAILED at t~{t:.2f} s: {type(error).__name__}: {str(error)[:200]}; "
    reached = sim.state.t - sim.plan.start
    steps = int(sim.state.steps)
    row["steps"] = steps
    row["wall_s"] = wall * UNTIL / reached if reached > 0 else math.nan
    row["per_step_us"] = 1e6 * wall / steps if steps else math.nan
    report = sim.contact_report() or {}
    deepest = report.get("deepest")
    row["deepest_mm"] = 1e3 * deepest if deepest is not None else math.nan
    parts = [f"path={report.get('path')}"]
    if "why" in report:
        parts.append(f"why={report['why']}")
    if "steps_creating_energy" in report:
        parts.append(f"steps_creating_energy={report['steps_creating_energy']}")
    row["energy_note/path"] = note + " ".join(parts)
    row["_report"] = report
    return row


def run_mujoco(count: int, kind: str, integrator: str, limit: float = LIMIT) -> dict:
    import mujoco

    model = mujoco.MjModel.from_xml_string(heap_mjcf(count, kind, integrator))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    steps = int(round(UNTIL / STEP))
    wall, deepest, note = 0.0, 0.0, ""
    for k in range(steps):
        begin = time.perf_counter()
        mujoco.mj_step(model, data)
        wall += time.perf_counter() - begin
        n = data.ncon
        if n:
            deepest = min(deepest, float(data.contact.dist[:n].min()))
        if not np.isfinite(data.qpos).all():
            note = f"diverged at step {k}; "
            break
        if wall > limit and k + 1 < steps:
            note = f"cut at t={data.time:.3f} s after {wall:.0f} s; time extrapolated to 2 s; "
            break
    done = k + 1
    if data.warning[mujoco.mjtWarning.mjWARN_CONTACTFULL].number:
        note += "contact buffer full; "
    return {"scene": f"heap-{kind}-{count}", "kind": kind, "count": count, "engine": "mujoco",
            "plan/integrator": integrator.lower(), "step": "1 ms", "steps": done, "wall_s": wall * steps / done,
            "per_step_us": 1e6 * wall / done, "deepest_mm": -1e3 * deepest,
            "energy_note/path": note + "restitution n/a (default solref 0.02 1)"}


# -- driver ----------------------------------------------------------------------------------------------------


def cases(quick: bool, boxes_1000: bool, only=None) -> list:
    if only:
        return [(kind, int(n)) for kind, n in (o.split(":") for o in only)]
    spheres, boxes = (QUICK_SPHERES, QUICK_BOXES) if quick else (SPHERES, BOXES + ((1000,) if boxes_1000 else ()))
    return [("sphere", n) for n in spheres] + [("box", n) for n in boxes]


def scaling(rows: list) -> list:
    """Per-step cost of 1000 spheres over 125 spheres, per engine and plan (linear in bodies: 8)."""
    out = []
    by = {(r["engine"], r["plan/integrator"], r["kind"], int(r["count"])): r for r in rows}
    for engine, plan in dict.fromkeys((r["engine"], r["plan/integrator"]) for r in rows):
        big, small = by.get((engine, plan, "sphere", 1000)), by.get((engine, plan, "sphere", 125))
        if big and small:
            out.append({"engine": engine, "plan/integrator": plan,
                        "per_step_us_125": small["per_step_us"], "per_step_us_1000": big["per_step_us"],
                        "ratio_1000_over_125": big["per_step_us"] / small["per_step_us"]})
    return out


def merge(path: Path, rows: list) -> list:
    """The rows measured now, plus the rows of `path` for (scene, engine, plan) not measured now."""
    fresh = {(r["scene"], r["engine"], r["plan/integrator"]) for r in rows}
    old = common.read_csv(path) if path.exists() else []
    kept = [r for r in old if (r.get("scene"), r.get("engine"), r.get("plan/integrator")) not in fresh]
    for r in kept:
        r["count"] = int(r["count"])
    order = {"sphere": 0, "box": 1}
    return sorted(kept + rows, key=lambda r: (order.get(r["kind"], 2), int(r["count"]), r["engine"] != "mujoco",
                                               r["plan/integrator"]))


def table(rows: list) -> str:
    head = f"{'scene':<16} {'engine':<7} {'plan':<16} {'wall_s':>8} {'us/step':>9} {'x mj rk4':>8} {'deep mm':>8}  note"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['scene']:<16} {r['engine']:<7} {r['plan/integrator']:<16} {r['wall_s']:>8.3f} "
                     f"{r['per_step_us']:>9.1f} {r.get('ratio_to_mujoco_rk4', math.nan):>8.2f} "
                     f"{r['deepest_mm']:>8.3f}  {r['energy_note/path']}")
    return "\n".join(lines)


def run(quick: bool = False, out: Path | None = None, solvers=("dynamics",), limit: float = LIMIT,
        boxes_1000: bool = False, only=None) -> dict:
    out = Path(out) if out else common.RESULTS
    path = out / "contact.csv"
    todo = cases(quick, boxes_1000, only)
    warm_up(sorted({k for k, _ in todo}, reverse=True), solvers)
    rows = []
    try:
        import mujoco  # noqa: F401 (the `bench` extra; without it our rows alone, their ratios NaN)
        peers = ("RK4", "Euler")
    except ImportError:
        peers = ()
    for kind, count in todo:
        mj = [run_mujoco(count, kind, integ, limit) for integ in peers]
        ours = [run_ours(count, kind, plan, limit) for plan in solvers]
        for r in mj + ours:
            r["ratio_to_mujoco_rk4"] = r["wall_s"] / mj[0]["wall_s"] if mj else math.nan
            r.pop("_report", None)
            common.log(f"  {r['scene']:<16} {r['engine']:<7} {r['plan/integrator']:<16} {r['wall_s']:8.3f} s  "
                       f"{r['per_step_us']:9.1f} us/step  x{r['ratio_to_mujoco_rk4']:.2f}  "
                       f"deepest {r['deepest_mm']:.3f} mm  {r['energy_note/path']}")
        rows += mj + ours
        common.write_csv(path, merge(path, mj + ours), KEYS)  # after each scene: a cut-short session keeps rows
    everything = common.read_csv(path)
    for r in everything:
        r["count"] = int(r["count"])
    return {"rows": everything, "scaling": scaling(everything), "path": path}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.contact", description=__doc__.splitlines()[0])
    parser.add_argument("--solver", choices=("dynamics", "procedural", "both"), default="dynamics")
    parser.add_argument("--quick", action="store_true", help="spheres 8, 27, 64 and boxes 8, 27 only")
    parser.add_argument("--limit", type=float, default=LIMIT,
                        help=f"wall seconds before a run of ours is cut short and extrapolated (default {LIMIT:g})")
    parser.add_argument("--boxes-1000", action="store_true", help="also 1000 boxes")
    parser.add_argument("--only", action="append", metavar="KIND:COUNT",
                        help="just this heap (repeatable), e.g. box:1000; other rows of contact.csv are kept")
    parser.add_argument("--out", default=None, help="output folder (default benchmarks/results)")
    args = parser.parse_args(argv)
    solvers = ("dynamics", "procedural") if args.solver == "both" else (args.solver,)
    result = run(args.quick, args.out, solvers, args.limit, args.boxes_1000, args.only)
    print(table(result["rows"]))
    print("\nscaling, per step: 1000 spheres / 125 spheres (8x the bodies)")
    for s in result["scaling"]:
        print(f"  {s['engine']:<7} {s['plan/integrator']:<16} {s['per_step_us_125']:9.1f} -> "
              f"{s['per_step_us_1000']:9.1f} us/step: x{s['ratio_1000_over_125']:.2f}")
    print(f"\nwrote {result['path']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
