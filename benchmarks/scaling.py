"""Scaling: per-step cost against the number of bodies, for each solver.

Chains of 1, 10, 100 and 1000 links (scenes/chain.isaac with --set links=N: a `for` loop scene) and complete
binary trees of 1, 15, 127 and 1023 bodies (generated text: small spheres joined by ball joints), stepped with
the dynamics plan (RK4, 1 ms) under each linear solver (auto: what the plan picks; dense, sparse, tree forced)
and with the procedural plan. Per-step cost: after two warm-up steps (the first builds the solver's pattern),
windows of steps of at least WINDOW seconds, the best of three. Dense is left out above DENSE_MAX_LINKS links
(O(rows^3) per solve). The peers' chains (reduced and maximal) are timed the same way for context.

The figure the issue checks: the 1000-link chain's per-step cost over the 100-link chain's (linear: ~10,
allowed: 12), for every solver. Writes scaling.csv and scaling.png.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from . import common

CHAIN_SIZES = (1, 10, 100, 1000)
TREE_SIZES = (1, 15, 127, 1023)
QUICK_TREE_SIZES = (1, 15, 127)
SOLVERS = (("dynamics", "auto"), ("dynamics", "dense"), ("dynamics", "sparse"), ("dynamics", "tree"),
           ("procedural", "-"))
DENSE_MAX_LINKS = 100
STEP = 1e-3
# steps per timed call of ours
BATCH = 50
WINDOW = 0.5  # s of wall time per timing window (at least 3 steps)
QUICK_WINDOW = 0.15
PEER_CONFIGS = (("mujoco", "reduced", "rk4"), ("mujoco", "maximal", "rk4"), ("pybullet", "reduced", "euler"),
                ("pybullet", "maximal", "euler"))
# the quick mode leaves out the peers' 1000-link chains (MuJoCo's reduced chain: ~10 s per RK4 step, O(n^3))
QUICK_PEER_LINKS = 100
LINEAR_BOUND = 12.0  # the 1000-link chain may cost at most this many times the 100-link chain


def chain_scene(links: int):
    return common.load("chain", {"links": str(links)})


def tree_text(count: int, spacing: float = 0.2) -> str:
    """A complete binary tree of `count` small spheres (heap order: node i's children are 2i+1, 2i+2), the root
    nailed at its centre, each child joined to its parent by a ball joint halfway between them."""
    lines = ["scene tree {", "  time 0 s .. 1 s", "  frames 100 Hz", "  gravity (0, -9.81, 0) m/s2",
             "  solver dynamics { integrator rk4  step 1 ms }"]
    pos = []
    for i in range(count):
        depth = int(math.floor(math.log2(i + 1)))
        slot = i + 1 - 2**depth
        x = (slot + 0.5) / 2**depth * spacing * 2**min(depth, 6) - spacing * 2**min(depth, 6) / 2
        pos.append((x, -spacing * depth, 0.0))
        lines.append(f"  body n{i} sphere {{ radius 1 cm  mass 0.1 kg  at ({x:.9g}, {-spacing * depth:.9g}, 0)"
                     f"  collide off }}")
    lines.append("  constraint root nail(n0 @ (0, 0, 0), (0, 0, 0))")
    for i in range(1, count):
        p = (i - 1) // 2
        mid = [(a + b) / 2 for a, b in zip(pos[i], pos[p])]
        arm_c = ", ".join(f"{m - c:.9g}" for m, c in zip(mid, pos[i]))
        arm_p = ", ".join(f"{m - c:.9g}" for m, c in zip(mid, pos[p]))
        lines.append(f"  constraint j{i} point(n{i} @ ({arm_c}), n{p} @ ({arm_p}))")
    lines.append("}")
    return "\n".join(lines) + "\n"


def per_step(step, window: float) -> tuple:
    """(best seconds per step, steps timed): two warm-up steps (the first builds the solver's pattern), then
    three windows of at least `window` seconds (at least 3 steps each), the best; a step slower than the
    window is timed once more and that is all."""
    step()
    begin = time.perf_counter()
    step()
    first = time.perf_counter() - begin
    if first > window:
        return first, 2
    best, total = math.inf, 0
    for _ in range(3):
        steps, begin = 0, time.perf_counter()
        while steps < 3 or time.perf_counter() - begin < window:
            step()
            steps += 1
        best = min(best, (time.perf_counter() - begin) / steps)
        total += steps
    return best, total


def measure_ours(shape: str, size: int, scene, plan: str, linear: str, window: float) -> dict:
    from isaac_runtime.simulation import NumericalError, Simulation

    row = {"shape": shape, "bodies": size, "engine": "isaac", "solver": plan, "linear": linear, "step_us": math.nan,
           "steps": 0, "rows": 0, "chosen": "", "status": "ok"}
    try:
        configured = common.configured(scene, linear=linear) if plan == "dynamics" else scene
        sim = Simulation(common.plan_for(configured, plan, STEP))
        # many steps per call, as a run takes them (the compiled loop returns to Python only at its ends)
        cost, calls = per_step(lambda: sim.advance_to(sim.state.t + BATCH * STEP), window)
        row["step_us"], row["steps"] = 1e6 * cost / BATCH, calls * BATCH
        c = sim.plan.constraints
        row["rows"] = c.total_rows if c is not None else 0
        row["chosen"] = c.epochs[0].solver if (c is not None and plan == "dynamics") else plan
    except NumericalError as error:
        row["status"] = f"numerical error: {error}"
    except Exception as error:  # noqa: BLE001
        row["status"] = f"bug: {type(error).__name__}: {error}"
    return row


def measure_peer(size: int, engine: str, formulation: str, integrator: str, window: float) -> dict:
    from .mechanisms import chain_mechanism
    from .peers import runner_class

    row = {"shape": "chain", "bodies": size, "engine": engine, "solver": formulation, "linear": integrator,
           "step_us": math.nan, "steps": 0, "rows": 0, "chosen": "", "status": "ok"}
    try:
        runner = runner_class(engine)(chain_mechanism(size), formulation, integrator, STEP)
        best, total = per_step(lambda: runner.advance(1), window)
        row["step_us"], row["steps"] = 1e6 * best, total
    except Exception as error:  # noqa: BLE001 (PyBullet refuses multibodies of more than 128 links)
        row["status"] = f"peer failed: {type(error).__name__}: {str(error).strip().splitlines()[0]}"
    return row


def run(quick: bool = False, out: Path | None = None, peers: bool = True) -> dict:
    from .peers import runner_class

    window = QUICK_WINDOW if quick else WINDOW
    rows = []
    shapes = [("chain", CHAIN_SIZES, chain_scene),
              ("tree", QUICK_TREE_SIZES if quick else TREE_SIZES, lambda n: common.load_source(tree_text(n), "tree.isaac"))]
    for shape, sizes, build in shapes:
        for size in sizes:
            scene = build(size)
            for plan, linear in SOLVERS:
                if linear == "dense" and size > DENSE_MAX_LINKS:
                    continue
                rows.append(measure_ours(shape, size, scene, plan, linear, window))
                _log(rows[-1])
            if shape == "chain" and peers:
                for engine, formulation, integrator in PEER_CONFIGS:
                    if runner_class(engine) is not None and not (quick and size > QUICK_PEER_LINKS):
                        rows.append(measure_peer(size, engine, formulation, integrator, window))
                        _log(rows[-1])
    result = {"rows": rows, "growth": growth(rows)}
    if out is not None:
        write(result, out)
    return result


def growth(rows: list) -> list:
    """Per-step cost ratio between consecutive sizes (x10) per configuration, and whether 1000/100 <= 12."""
    out = []
    keys = dict.fromkeys((r["shape"], r["engine"], r["solver"], r["linear"]) for r in rows)
    for key in keys:
        mine = sorted((r for r in rows if (r["shape"], r["engine"], r["solver"], r["linear"]) == key),
                      key=lambda r: r["bodies"])
        for small, big in zip(mine, mine[1:]):
            ratio = big["step_us"] / small["step_us"]
            out.append({"shape": key[0], "engine": key[1], "solver": key[2], "linear": key[3],
                        "from": small["bodies"], "to": big["bodies"], "ratio": ratio,
                        "within_bound": bool(ratio <= LINEAR_BOUND) if big["bodies"] >= 1000 else ""})
    return out


KEYS = ["shape", "bodies", "engine", "solver", "linear", "chosen", "rows", "step_us", "steps", "status"]


def write(result: dict, out: Path) -> list:
    return [common.write_csv(out / "scaling.csv", result["rows"], KEYS),
            common.write_csv(out / "scaling_growth.csv", result["growth"]),
            plot(result["rows"], out / "scaling.png")]


def plot(rows: list, path: Path) -> Path:
    plt = common.pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    for ax, shape in zip(axes, ("chain", "tree")):
        mine = [r for r in rows if r["shape"] == shape and r["status"] == "ok" and math.isfinite(r["step_us"])]
        for key in dict.fromkeys((r["engine"], r["solver"], r["linear"]) for r in mine):
            pts = sorted((r for r in mine if (r["engine"], r["solver"], r["linear"]) == key), key=lambda r: r["bodies"])
            style = "-" if key[0] == "isaac" else "--"
            ax.loglog([r["bodies"] for r in pts], [r["step_us"] for r in pts], style, marker="o", ms=4,
                      label=" ".join(k for k in key if k != "-"))
        anchor = [r for r in mine if (r["engine"], r["linear"]) == ("isaac", "auto") and r["bodies"] >= 100]
        if anchor:  # slope 1 through our plan's largest size: what linear growth would look like
            n, t = anchor[-1]["bodies"], anchor[-1]["step_us"]
            ax.loglog([10, 1000], [t * 10 / n, t * 1000 / n], color="grey", lw=0.8, ls=":", label="linear growth")
        ax.set_xlabel("bodies")
        ax.set_ylabel("wall time per step (us)")
        ax.set_title(f"{shape}: per-step cost (RK4 for ours and MuJoCo, 1 ms)")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _log(row: dict) -> None:
    common.log(f"  {row['shape']:<6}{row['bodies']:>6} {row['engine']:<9}{row['solver']:<11}{row['linear']:<7}"
               f"{row['chosen']:<11}{row['step_us']:>12.1f} us/step" +
               ("" if row["status"] == "ok" else f"  [{row['status']}]"))
