"""Work-precision: wall time against error on the scenes with a known answer (cases.py), for each solver plan,
integrator and step size, with the peers (peers.py) run side by side at the same steps.

For every case and step h (1e-1 .. 1e-4 s) the runs follow one another in one process, ours first (dynamics
rk4, midpoint, euler; procedural), then MuJoCo and PyBullet: a load spike on a shared machine hits neighbours
alike. A run is one Simulation.advance_to from the scene's start to the case's end: once with the state probed
every ~1 ms for the errors, then without the probe for the time (best of three when it is shorter than a
second; the probe is a per-step observer, which takes the steps one call at a time), as the peers are timed;
also given as wall seconds per simulated second ("cost", the x axis of the plot) and per step.

Writes work_precision.csv (one row per run), peer_ratios.csv (peers.py: ratios at equal step and at equal
error) and work_precision.png (one panel per error: error against cost, a line per configuration through its
step sizes).
"""
from __future__ import annotations

import math
from pathlib import Path

from . import common
from .cases import CASES, Case

# the large steps are where a fourth-order method reaches the equal-error targets (peers.py TARGETS, 1e-6 and
# 1e-3): RK4 with the projection holds the pendulums' period to 1e-8 at 1e-2, so a grid that stops there
# prices our 1e-6 at a step four times smaller than it needs
STEPS = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4)
# (plan, integrator) of ours; "rk4 10Hz": RK4 with the stabilization frequency fixed at 10 Hz instead of the
# default tied to the step (f = 1 / (20 h)), which costs RK4 its order (docs/performance.md); "rk4 fixed": RK4
# without its error control (`tolerance 0`), every step taken as it is, as the peers' RK4 takes it (the default
# takes a step whose error estimate passes 3e-6 again in substeps: at 30 to 100 ms steps on the pendulums most)
OURS = (("dynamics", "rk4"), ("dynamics", "midpoint"), ("dynamics", "euler"), ("procedural", "xpbd"),
        ("dynamics", "rk4 10Hz"), ("dynamics", "rk4 fixed"))
FIXED_STABILIZATION = 10.0  # Hz
# the quick mode: fewer steps and configurations (a smoke run of everything, not the committed numbers)
QUICK_STEPS = (3e-2, 1e-2, 3e-3, 1e-3)
QUICK_OURS = {3e-2: OURS[:1] + OURS[5:], 1e-2: OURS[:1] + OURS[2:4] + OURS[5:], 3e-3: OURS[:1] + OURS[2:4],
              1e-3: OURS[:1] + OURS[4:5]}

KEYS = ["case", "engine", "model", "integrator", "step", "steps", "sim_time", "wall_s", "cpu_s", "step_us", "cost",
        "status"]


def row_of(case: Case, outcome: common.Outcome) -> dict:
    row = {"case": case.name, "engine": outcome.engine, "model": outcome.model, "integrator": outcome.integrator,
           "step": outcome.step, "steps": outcome.steps, "sim_time": outcome.sim_time, "wall_s": outcome.wall_s,
           "cpu_s": outcome.cpu_s, "step_us": outcome.step_us, "cost": outcome.cost, "status": outcome.status}
    errors = {}
    if outcome.ok and outcome.trajectory is not None:
        try:
            errors = case.measure(outcome.trajectory)
        except Exception as error:  # noqa: BLE001
            row["status"] = f"bug: measuring: {type(error).__name__}: {error}"
    for metric in case.metrics:
        row[metric] = float(errors.get(metric, math.nan))
    return row


def run_ours(case: Case, plan: str, integrator: str, h: float) -> dict:
    import dataclasses

    scene = case.load()
    if plan == "dynamics":
        base, _, variant = integrator.partition(" ")
        scene = common.configured(scene, integrator=base)
        if variant == "fixed":  # no error control
            scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, tolerance=0.0))
        elif variant:  # a fixed stabilization frequency for every constraint that does not set its own
            scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver,
                                                                          stabilize_frequency=FIXED_STABILIZATION))
    outcome = common.run_isaac(scene, plan, h, case.until)
    outcome.integrator = integrator
    return row_of(case, outcome)


def run(quick: bool = False, cases=None, peers: bool = True, out: Path | None = None) -> dict:
    from . import peers as peer_module

    cases = cases or CASES
    rows = []
    for case in cases:
        for h in (QUICK_STEPS if quick else STEPS):
            for plan, integrator in (QUICK_OURS[h] if quick else OURS):
                rows.append(run_ours(case, plan, integrator, h))
                _log(rows[-1])
            if peers:
                for row in peer_module.peer_rows(case, h, case.until):
                    rows.append(row)
                    _log(row)
    ratio_rows = peer_module.ratios(rows, cases) if peers else []
    result = {"rows": rows, "ratios": ratio_rows, "floors": peer_module.floors() if peers else {}}
    if out is not None:
        write(result, cases, out)
    return result


def write(result: dict, cases, out: Path) -> list:
    from .peers import RATIO_KEYS

    metrics = list(dict.fromkeys(m for c in cases for m in c.metrics))
    paths = [common.write_csv(out / "work_precision.csv", result["rows"], KEYS + metrics)]
    if result["ratios"]:
        paths.append(common.write_csv(out / "peer_ratios.csv", result["ratios"], RATIO_KEYS))
    paths.append(plot(result["rows"], cases, out / "work_precision.png"))
    return paths


def _log(row: dict) -> None:
    errors = " ".join(f"{k}={row[k]:.2e}" for k in row if k not in KEYS and isinstance(row[k], float))
    common.log(f"  {row['case']:<13}{row['engine']:<9}{row['model']:<11}{row['integrator']:<9}h={row['step']:<7g}"
               f"{row['step_us']:>10.1f} us/step  {errors}" + ("" if row["status"] == "ok" else f"  [{row['status']}]"))


STYLE = {("isaac", "dynamics"): ("tab:blue", "-"), ("isaac", "procedural"): ("tab:cyan", "-"),
         ("mujoco", "reduced"): ("tab:red", "--"), ("mujoco", "maximal"): ("tab:orange", "--"),
         ("pybullet", "reduced"): ("tab:green", ":"), ("pybullet", "maximal"): ("tab:olive", ":")}
MARKERS = {"rk4": "o", "midpoint": "^", "euler": "s", "xpbd": "D", "rk4 10Hz": "P", "rk4 fixed": "x"}


def panels(cases) -> list:
    return [(c, m) for c in cases for m in c.metrics[:2] if not (c.scene == "pendulum" and m != "period_error")
            and not (c.scene == "windmill" and m != "period_error")]


def plot(rows: list, cases, path: Path) -> Path:
    plt = common.pyplot()
    chosen = panels(cases)
    cols = 3
    fig, axes = plt.subplots(math.ceil(len(chosen) / cols), cols, figsize=(15, 4.2 * math.ceil(len(chosen) / cols)),
                             squeeze=False)
    for ax, (case, metric) in zip(axes.flat, chosen):
        mine = [r for r in rows if r["case"] == case.name]
        for key in dict.fromkeys((r["engine"], r["model"], r["integrator"]) for r in mine):
            runs = sorted((r for r in mine if (r["engine"], r["model"], r["integrator"]) == key
                           and r["status"] == "ok" and math.isfinite(r[metric])), key=lambda r: r["cost"])
            if not runs:
                continue
            colour, line = STYLE.get(key[:2], ("grey", "-"))
            ax.loglog([r["cost"] for r in runs], [max(r[metric], 1e-16) for r in runs], line,
                      marker=MARKERS.get(key[2], "o"), color=colour, ms=4, lw=1, label=" ".join(key))
        ax.set_title(f"{case.name}: {metric}", fontsize=10)
        ax.set_xlabel("wall s per simulated s")
        ax.set_ylabel(metric)
        ax.grid(True, which="both", lw=0.3)
    for ax in axes.flat[len(chosen):]:
        ax.axis("off")
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=6, fontsize=8)
    fig.suptitle("Work-precision: error against wall time, step sizes 1e-1 .. 1e-4 s (points along each line)")
    fig.tight_layout(rect=(0, 0.05, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
