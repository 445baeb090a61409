"""Peers side by side: the known-answer scenes in MuJoCo and PyBullet (the optional `bench` extra), and every
figure as a ratio to ours.

`run_peer` builds one model (benchmarks/peer_mujoco.py, peer_bullet.py; settings that would spoil the
comparison are listed there), runs it once with the probe to measure its errors (cases.py, the functions that
judge our runs), then again without the probe, best of up to three, for its time. Ratios (`ratios`):

- at equal step: peer time per step / ours, and peer error / ours, integrators matched (MuJoCo RK4 with our
  rk4; MuJoCo Euler and PyBullet, both semi-implicit Euler, with our euler);
- at equal error: the wall time per simulated second each needs to reach an error E (log-log interpolation
  between the two runs of its step grid that bracket E; ours: the best of our integrators, peers: the best of
  theirs, per formulation). Blank when either never reaches E on the grid.
A ratio above 1 means the peer is slower (time) or less accurate (error) than ours.
"""
from __future__ import annotations

import math
import time

from . import common
from .cases import Case
from .mechanisms import Mechanism, mechanism

# (engine, formulation, integrator) for every peer configuration
CONFIGS = [("mujoco", "reduced", "rk4"), ("mujoco", "reduced", "euler"), ("mujoco", "maximal", "rk4"),
           ("mujoco", "maximal", "euler"), ("pybullet", "reduced", "euler"), ("pybullet", "maximal", "euler")]
# our integrator compared with each peer integrator at equal step
MATCH = {"rk4": "rk4", "euler": "euler"}
# errors at which costs are compared
TARGETS = (1e-3, 1e-6)


def runner_class(engine: str):
    if engine == "mujoco":
        from . import peer_mujoco

        return peer_mujoco.Runner if peer_mujoco.available() else None
    from . import peer_bullet

    return peer_bullet.Runner if peer_bullet.available() else None


def configs_for(m: Mechanism, engines=("mujoco", "pybullet")) -> list:
    out = []
    for engine, formulation, integrator in CONFIGS:
        if engine not in engines or runner_class(engine) is None:
            continue
        if (formulation == "reduced" and not m.reduced) or (formulation == "maximal" and not m.maximal):
            continue
        if engine == "pybullet" and any(t.start > 0 for t in m.ties):
            continue  # no stabilization curve to switch on (peer_bullet.py)
        out.append((engine, formulation, integrator))
    return out


def run_peer(m: Mechanism, engine: str, formulation: str, integrator: str, h: float, until: float,
             probe: bool = True) -> common.Outcome:
    """One peer run: errors from a probed pass, time from the best of up to REPEATS unprobed passes."""
    Runner = runner_class(engine)
    out = common.Outcome(engine, formulation, integrator, h)
    steps = int(round(until / h))
    try:
        if probe:
            runner = Runner(m, formulation, integrator, h)
            every = common.sample_every(h)
            p = common.Probe(len(m.physics.names), common.probe_capacity(until, h, every), every)
            p.record(*runner.sample())
            runner.advance(steps, p, every)
            out.trajectory = p.trajectory()
            if not runner.finite():
                out.status = "non-finite state (the peer reports no error)"
        best = (math.inf, math.inf)
        for _ in range(common.REPEATS):
            runner = Runner(m, formulation, integrator, h)
            wall, cpu = time.perf_counter(), time.process_time()
            runner.advance(steps)
            best = min(best, (time.perf_counter() - wall, time.process_time() - cpu))
            if best[0] > common.REPEAT_BELOW:
                break
        out.wall_s, out.cpu_s = best
        out.steps, out.sim_time = steps, steps * h
    except Exception as error:  # noqa: BLE001 (a peer that cannot build or run this is a result)
        out.status = f"peer failed: {type(error).__name__}: {str(error).strip().splitlines()[0]}"
    return out


def peer_rows(case: Case, h: float, until: float, engines=("mujoco", "pybullet")) -> list:
    """Every peer configuration of this case at step h, as work-precision rows."""
    from .work_precision import row_of

    try:
        m = mechanism(case)
    except ValueError:
        return []
    rows = []
    for engine, formulation, integrator in configs_for(m, engines):
        outcome = run_peer(m, engine, formulation, integrator, h, until)
        rows.append(row_of(case, outcome))
    return rows


# -- ratios ----------------------------------------------------------------------------------------------------


def _usable(r: dict, metric: str) -> bool:
    v = r.get(metric, math.nan)
    return r["status"] == "ok" and isinstance(v, float) and math.isfinite(v) and math.isfinite(r["cost"])


def cost_at(rows: list, metric: str, target: float) -> tuple:
    """(wall s per simulated s, label) to reach metric <= target: for each integrator, its cheapest run that does,
    or the log-log interpolation between that run and the next larger step of the same integrator (which does
    not); the cheapest integrator wins."""
    best = (math.nan, "not reached")
    for integrator in dict.fromkeys(r["integrator"] for r in rows):
        line = sorted((r for r in rows if r["integrator"] == integrator), key=lambda r: r["step"])
        cost, label = _line_cost_at(line, metric, target)
        if math.isfinite(cost) and not cost >= best[0]:
            best = (cost, label)
    return best


def _line_cost_at(line: list, metric: str, target: float) -> tuple:
    """line: the runs of one configuration, by increasing step."""
    reached = [k for k, r in enumerate(line) if _usable(r, metric) and r[metric] <= target]
    if not reached:
        return math.nan, "not reached"
    k = min(reached, key=lambda i: line[i]["cost"])
    r = line[k]
    label = f"{r['integrator']} h={r['step']:g}"
    if k + 1 < len(line) and _usable(line[k + 1], metric) and r[metric] > 0 and line[k + 1]["cost"] < r["cost"]:
        w = line[k + 1]  # the next larger step misses the target: interpolate between the two
        f = math.log(target / r[metric]) / math.log(w[metric] / r[metric])
        cost = math.exp(math.log(r["cost"]) + f * (math.log(w["cost"]) - math.log(r["cost"])))
        return cost, f"{label}..{w['step']:g} interpolated"
    return r["cost"], label


def peer_label(r: dict) -> str:
    return f"{r['engine']} {r['model']} {r['integrator']}"


def ratios(rows: list, cases: list) -> list:
    """The ratio table (one row per comparison) from the work-precision rows of one run."""
    out = []
    for case in cases:
        mine = [r for r in rows if r["case"] == case.name and r["engine"] == "isaac" and r["model"] == "dynamics"]
        peers = [r for r in rows if r["case"] == case.name and r["engine"] != "isaac"]
        for metric in case.metrics[:2]:
            out += _equal_step(case, metric, mine, peers)
            out += _equal_error(case, metric, mine, peers)
    return out


def _equal_step(case, metric, mine, peers) -> list:
    out = []
    for p in peers:
        ours = [r for r in mine if r["integrator"] == MATCH.get(p["integrator"]) and r["step"] == p["step"]]
        if not ours or p["status"] != "ok" or ours[0]["status"] != "ok":
            continue
        o = ours[0]
        out.append({"case": case.name, "metric": metric, "peer": peer_label(p), "ours": f"isaac {o['integrator']}",
                    "basis": "equal step", "step": p["step"], "target": math.nan,
                    "peer_time": p["step_us"], "our_time": o["step_us"], "time_ratio": p["step_us"] / o["step_us"],
                    "peer_error": p[metric], "our_error": o[metric], "error_ratio": _ratio(p[metric], o[metric])})
    return out


def _equal_error(case, metric, mine, peers) -> list:
    out = []
    groups = {}
    for p in peers:
        groups.setdefault((p["engine"], p["model"]), []).append(p)
    for target in TARGETS:
        ours, our_how = cost_at(mine, metric, target)
        for (engine, model), runs in groups.items():
            theirs, their_how = cost_at(runs, metric, target)
            out.append({"case": case.name, "metric": metric, "peer": f"{engine} {model} ({their_how})",
                        "ours": f"isaac ({our_how})", "basis": "equal error", "step": math.nan, "target": target,
                        "peer_time": theirs, "our_time": ours, "time_ratio": theirs / ours if ours > 0 else math.nan,
                        "peer_error": math.nan, "our_error": math.nan, "error_ratio": math.nan})
    return out


def _ratio(a: float, b: float) -> float:
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.nan
    floor = 1e-16  # errors at round-off are all alike
    return max(a, floor) / max(b, floor)


RATIO_KEYS = ["case", "metric", "basis", "step", "target", "peer", "ours", "peer_time", "our_time", "time_ratio",
              "peer_error", "our_error", "error_ratio"]


def floors() -> dict:
    """Per-step cost of an empty model in each peer: the fixed overhead under their figures."""
    out = {}
    try:
        import mujoco

        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
        data = mujoco.MjData(model)
        wall, _ = common.best_time(lambda: [mujoco.mj_step(model, data) for _ in range(2000)])
        out["mujoco_empty_step_us"] = 1e6 * wall / 2000
    except ImportError:
        pass
    try:
        from . import peer_bullet

        out["pybullet_empty_step_us"] = 1e6 * peer_bullet.per_step_floor()
    except ImportError:
        pass
    return out
