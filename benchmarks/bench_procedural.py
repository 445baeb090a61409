"""Benchmark: the two solver plans side by side, wall time against error, on the chain and the pendulum.

    python benchmarks/bench_procedural.py [--sim-time 4] [--out benchmarks/results] [--quick]

Every run steps the scene's first --sim-time seconds (Simulation.advance_to: the step is the one asked for,
not cut at the 100 Hz frames as `isaac run` would) at one setting: the dynamics plan (RK4 + Baumgarte) at
several steps h, the procedural plan at several steps h and substeps. Runs of the two plans alternate, in one
process, so that a busy machine slows both alike; wall and CPU time are both recorded.
Errors, observed after every step: chain, the largest joint gap (any joint or the nail) and energy change
(relative to m g extent, as report.json); pendulum, the period against the elliptic integral (relative), the
nail gap and energy. A run that blows up (or whose joints open by more than 1 m) is listed as failed.

Speed at equal error: for each plan, the cost of reaching a joint error E is the least wall time of its runs
with error <= E; for the dynamics plan it is also interpolated (log-log) between the runs that bracket E, so
its step grid does not count against it. The ratio at E = 1 mm is printed and saved as the last CSV lines,
with the same comparison at equal energy drift (1e-3), the error the procedural plan pays with instead.
Writes bench_procedural.csv and bench_procedural.png in --out.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.special import ellipk

from isaac_lang.load import load_scene
from isaac_runtime.plan import PlanOptions, compile_plan
from isaac_runtime.core.rotation import quat_rotate
from isaac_runtime.core.build import energy_scale
from isaac_runtime.simulation import NumericalError, Simulation

SCENES = Path(__file__).resolve().parents[1] / "scenes"
G = 9.81
TARGET_ERROR = 1e-3  # m: the joint error at which the plans are compared
PENDULUM_TIME = 7.0  # s: three periods, for the period error
ENERGY_BOUND = 1e-3  # relative energy drift at which the plans are compared too

# (plan, step s, substeps or None)
CHAIN_RUNS = [("dynamics", h, None) for h in (0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 1 / 60)] + [
    ("procedural", h, n) for h in (0.01, 1 / 60, 1 / 30) for n in (1, 2, 5, 20)]
PENDULUM_RUNS = [("dynamics", h, None) for h in (0.001, 0.002, 0.005, 0.01, 1 / 60)] + [
    ("procedural", h, n) for h in (0.01, 1 / 60, 1 / 30) for n in (1, 5, 20)]
QUICK = {"chain": [("dynamics", 0.004, None), ("dynamics", 0.005, None), ("dynamics", 0.006, None),
                   ("procedural", 0.01, 1), ("procedural", 0.01, 20)],
         "pendulum": [("dynamics", 0.005, None), ("procedural", 0.01, 5)]}


def with_substeps(scene, substeps):
    if substeps is None:
        return scene
    return dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, substeps=substeps))


class ChainError:
    """After every step: the largest joint gap (any joint or the nail) and energy change."""

    def __init__(self, sim):
        n = sim.plan.n
        self.a, self.b = np.arange(n - 1), np.arange(1, n)
        self.plus, self.minus = np.tile([0.1, 0.0, 0.0], (n - 1, 1)), np.tile([-0.1, 0.0, 0.0], (n - 1, 1))
        self.e0, self.joint, self.energy = sim.energy(), 0.0, 0.0

    def __call__(self, sim, h):
        s = sim.state
        gaps = s.x[self.a] + quat_rotate(s.q[self.a], self.plus) - s.x[self.b] - quat_rotate(s.q[self.b], self.minus)
        nail = s.x[0] + quat_rotate(s.q[0], np.array([-0.1, 0.0, 0.0]))
        self.joint = max(self.joint, float(np.sqrt((gaps * gaps).sum(axis=1)).max()), float(np.linalg.norm(nail)))
        self.energy = max(self.energy, abs(sim.energy() - self.e0))

    def result(self, sim) -> dict:
        return {"joint_error": self.joint, "energy_drift": self.energy / energy_scale(sim.plan)}


class PendulumError(ChainError):
    """After every step: the nail gap, energy change, and the upward zero crossings of x (for the period)."""

    NAILED = np.array([-math.sin(math.radians(60)), math.cos(math.radians(60)), 0.0])

    def __init__(self, sim):
        self.e0, self.joint, self.energy, self.last, self.crossings = sim.energy(), 0.0, 0.0, None, []

    def __call__(self, sim, h):
        s = sim.state
        nail = s.x[0] + quat_rotate(s.q[0], self.NAILED)
        self.joint = max(self.joint, float(np.linalg.norm(nail - [0.0, 1.0, 0.0])))
        self.energy = max(self.energy, abs(sim.energy() - self.e0))
        x = float(s.x[0, 0])
        if self.last is not None and self.last[1] < 0.0 <= x:  # linear between steps
            t0, x0 = self.last
            self.crossings.append(t0 + (s.t - t0) * (-x0 / (x - x0)))
        self.last = (s.t, x)

    def result(self, sim) -> dict:
        c = self.crossings
        exact = 4 * math.sqrt(1.001 / G) * ellipk(math.sin(math.radians(30)) ** 2)
        period = (c[-1] - c[0]) / (len(c) - 1) if len(c) >= 2 else float("nan")
        return {**super().result(sim), "period_error": abs(period / exact - 1.0)}


def one_run(scene, plan, step, substeps, sim_time, measure) -> dict:
    """Step the scene for sim_time at one setting: Simulation.advance_to in one go, so the step is the one
    asked for (`isaac run` would cut it at every frame), the errors observed after every step."""
    sim = Simulation(compile_plan(with_substeps(scene, substeps), PlanOptions(solver=plan, step=step)))
    observer = measure(sim)
    sim.observers.append(observer)
    failed = False
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        sim.advance_to(sim.plan.start + sim_time)
    except (NumericalError, FloatingPointError):
        failed = True
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    row = {"plan": plan, "step": step, "substeps": substeps or "", "wall_s": wall, "cpu_s": cpu,
           "steps": sim.state.steps, "failed": failed, "joint_error": float("nan"), "period_error": float("nan"),
           "energy_drift": float("nan")}
    if not failed:
        row.update(observer.result(sim))
        row["failed"] = not np.isfinite(row["joint_error"]) or row["joint_error"] > 1.0  # came apart
    return row


def interleaved(runs):
    """Alternate the plans' runs: dynamics, procedural, dynamics, ..."""
    dyn = [r for r in runs if r[0] == "dynamics"]
    pro = [r for r in runs if r[0] == "procedural"]
    out = []
    for i in range(max(len(dyn), len(pro))):
        out += dyn[i:i + 1] + pro[i:i + 1]
    return out


def cost_at(rows, plan, error, key="wall_s", interpolate=False, metric="joint_error") -> tuple:
    """(seconds, how) the plan needs for metric <= error; interpolated log-log for the dynamics plan."""
    ok = [r for r in rows if r["plan"] == plan and not r["failed"] and np.isfinite(r[metric])]
    good = [r for r in ok if r[metric] <= error]
    if not good:
        return float("nan"), "none reaches it"
    best = min(good, key=lambda r: r[key])
    if interpolate:
        worse = [r for r in ok if r[metric] > error and r[key] < best[key]]
        if worse:
            w = max(worse, key=lambda r: r[key])  # the dearest run above the bound that is cheaper than best
            f = math.log(error / best[metric]) / math.log(w[metric] / best[metric])
            return math.exp(math.log(best[key]) + f * (math.log(w[key]) - math.log(best[key]))), (
                f"interpolated between h = {best['step'] * 1e3:.3g} ms and {w['step'] * 1e3:.3g} ms")
    return best[key], f"h = {best['step'] * 1e3:.3g} ms" + (f" x {best['substeps']}" if best["substeps"] else "")


def compare(rows, metric, bound, key) -> str:
    p, p_how = cost_at(rows, "procedural", bound, key, metric=metric)
    d, d_how = cost_at(rows, "dynamics", bound, key, interpolate=True, metric=metric)
    d_run, d_run_how = cost_at(rows, "dynamics", bound, key, metric=metric)
    return (f"chain, {metric} <= {bound:g}, {key}: procedural {p:.3g} s ({p_how}); dynamics {d:.3g} s ({d_how}), "
            f"{d_run:.3g} s as run ({d_run_how}); ratio {d / p:.1f} (as run {d_run / p:.1f})")


def table(rows) -> str:
    lines = [f"{'scene':<9}{'plan':<11}{'h ms':>7}{'sub':>5}{'wall s':>9}{'cpu s':>8}{'joint err':>11}"
             f"{'period err':>12}{'energy':>10}"]
    for r in rows:
        fmt = lambda v: "failed" if r["failed"] else f"{v:.2e}"  # noqa: E731
        lines.append(f"{r['scene']:<9}{r['plan']:<11}{r['step'] * 1e3:>7.3g}{str(r['substeps']):>5}"
                     f"{r['wall_s']:>9.2f}{r['cpu_s']:>8.2f}{fmt(r['joint_error']):>11}"
                     f"{fmt(r['period_error']) if r['scene'] == 'pendulum' else '':>12}{fmt(r['energy_drift']):>10}")
    return "\n".join(lines)


def plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8))
    panels = ((axes[0], "chain", "joint_error", "largest joint gap (m)", TARGET_ERROR),
              (axes[1], "chain", "energy_drift", "energy drift (relative)", ENERGY_BOUND),
              (axes[2], "pendulum", "period_error", "period error (relative)", None))
    for ax, scene, key, label, bound in panels:
        for plan, marker, colour in (("dynamics", "o", "tab:blue"), ("procedural", "s", "tab:orange")):
            mine = [r for r in rows if r["scene"] == scene and r["plan"] == plan and not r["failed"]]
            ax.loglog([r["wall_s"] for r in mine], [max(r[key], 1e-16) for r in mine], marker, color=colour,
                      label=f"{plan}" + (" (h ms x substeps)" if plan == "procedural" else " (h ms)"))
            for r in mine:
                ax.annotate(f"{r['step'] * 1e3:.3g}" + (f"x{r['substeps']}" if r["substeps"] else ""),
                            (r["wall_s"], max(r[key], 1e-16)), fontsize=7, xytext=(3, 3), textcoords="offset points")
        if bound is not None:
            ax.axhline(bound, color="grey", lw=0.8, ls="--")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(label)
        ax.set_title(f"{scene}: {label.split(' (')[0]} against wall time", fontsize=10)
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=8)
    failed = [f"{r['scene']} {r['plan']} {r['step'] * 1e3:.3g} ms" for r in rows if r["failed"]]
    if failed:
        fig.text(0.01, 0.01, "failed (blew up): " + ", ".join(failed), fontsize=8)
    fig.tight_layout(rect=(0, 0.04 if failed else 0, 1, 1))
    fig.savefig(path, dpi=110)


def read_csv(path: Path) -> list:
    lines = [line for line in path.read_text().splitlines() if line and not line.startswith("#")]
    keys = lines[0].split(",")
    rows = []
    for line in lines[1:]:
        row = dict(zip(keys, line.split(",")))
        for k in ("step", "wall_s", "cpu_s", "joint_error", "period_error", "energy_drift"):
            row[k] = float(row[k])
        row["failed"] = row["failed"] == "True"
        row["substeps"] = int(row["substeps"]) if row["substeps"] else ""
        rows.append(row)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-time", type=float, default=4.0, help="simulated seconds per run (default 4)")
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent / "results"))
    parser.add_argument("--quick", action="store_true", help="a handful of runs (a smoke test of the script)")
    parser.add_argument("--replot", metavar="CSV", help="only redraw the plot of an earlier run's CSV")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.replot:
        plot(read_csv(Path(args.replot)), out / "bench_procedural.png")
        return 0
    rows = []
    for name, runs, measure in (("chain", CHAIN_RUNS, ChainError), ("pendulum", PENDULUM_RUNS, PendulumError)):
        sim_time = args.sim_time if name == "chain" else max(args.sim_time, PENDULUM_TIME)
        scene = load_scene(SCENES / f"{name}.isaac").scene
        for plan, step, substeps in interleaved(QUICK[name] if args.quick else runs):
            row = one_run(scene, plan, step, substeps, sim_time, measure)
            row["scene"] = name
            rows.append(row)
            print(table([row]).splitlines()[1], flush=True)
    chain = [r for r in rows if r["scene"] == "chain"]
    summary = [compare(chain, "joint_error", TARGET_ERROR, key) for key in ("wall_s", "cpu_s")]
    # the joint gap is not the procedural plan's only error: the same comparison at equal energy drift
    summary.append(compare(chain, "energy_drift", ENERGY_BOUND, "wall_s"))
    print("\n" + table(rows) + "\n\n" + "\n".join(summary))
    keys = ["scene", "plan", "step", "substeps", "wall_s", "cpu_s", "steps", "failed", "joint_error", "period_error",
            "energy_drift"]
    lines = [",".join(keys)] + [",".join(str(r[k]) for k in keys) for r in rows] + ["# " + s for s in summary]
    (out / "bench_procedural.csv").write_text("\n".join(lines) + "\n")
    plot(rows, out / "bench_procedural.png")
    print(f"\nwrote {out / 'bench_procedural.csv'} and {out / 'bench_procedural.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
