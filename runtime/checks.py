"""The tolerances a finished run is held to (`isaac run --max-constraint-error`, exit 3 when one is broken).

A constraint that switches on apart closes along its stabilization curve (docs/solver.md): its error is large at
the switch by design (self-assembly) and decays. What a tolerance judges is the error that stays: the largest
constraint error over the frames outside the settling window after each switch-on (the scene's start included,
where the bodies may be placed a little off their joints). A joint that cannot hold (two nails that disagree, a
body tied to two places) keeps its error and is flagged; a gap that closes is not.

Constraints that cannot all hold are named (`conflicts`), from what the run already has, at frames, never per
step: the row of the largest error at each recorded frame (the kernels record it), and each active row's residual
and the rows the solver dropped as dependent at the end of the run. A settled error above CONFLICT_ERROR (or the
limit, when lower) names the constraints that keep it, with those that share a body with them: a warning on stderr
and in report.json, and in the check (`constraints`).
"""
from __future__ import annotations

import math

import numpy as np

# the largest settled constraint error (m, or rad for orientation rows) a run may keep before it counts as broken:
# far above what a joint that holds keeps (1e-14 .. 1e-6 m; procedural compliance a few mm), far below a 0.5 m gap
DEFAULT_MAX_CONSTRAINT_ERROR = 0.1
# a settled error above this (m or rad; or above the limit when that is lower) is one that stays: its constraints
# are named in a warning. Holding joints keep 1e-14 .. 1e-6 m, the example scenes at most 3e-4 m
CONFLICT_ERROR = 1e-2
# a switched-on row is left this many decay times to close: e^-10 (1 + 10) ~ 5e-4 of the gap for a critically
# damped row (C(s) = C0 (1 + omega s) e^(-omega s))
SETTLE_DECAYS = 10.0


def settling_windows(scene, plan) -> list:
    """[(start, end), ...] s: after the run's start and after each constraint's switch-on, the time its rows are
    given to close: SETTLE_DECAYS over the slow decay rate of C'' + 2 zeta omega C' + omega^2 C = 0."""
    windows = []
    for constraint in scene.constraints:
        begin = max(constraint.start, plan.start)
        if begin >= plan.end:
            continue
        windows.append((begin, begin + SETTLE_DECAYS / _decay_rate(scene, constraint, plan)))
    return _merged(windows)


def _decay_rate(scene, constraint, plan) -> float:
    """The slowest decay rate (1/s) of a row's closing curve: zeta omega below critical damping, and above it
    omega (zeta - sqrt(zeta^2 - 1)), the slow root of s^2 + 2 zeta omega s + omega^2."""
    frequency = constraint.stabilize_frequency or scene.solver.stabilize_frequency or _default_frequency(scene, plan)
    zeta = constraint.damping_ratio if constraint.damping_ratio is not None else scene.solver.damping_ratio
    omega = 2.0 * math.pi * frequency
    zeta = max(float(zeta), 1e-3)
    rate = zeta * omega if zeta < 1.0 else omega * (zeta - math.sqrt(zeta * zeta - 1.0))
    return max(rate, 1e-9)


def _default_frequency(scene, plan) -> float:
    """The frequency a constraint without its own `stabilize` assembles at (constraints/plan.py's rule)."""
    from .constraints.plan import default_stabilization_frequency

    return default_stabilization_frequency(plan.step, scene.solver.stabilization)


def _merged(windows: list) -> list:
    merged = []
    for start, end in sorted(windows):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(end, merged[-1][1]))
        else:
            merged.append((start, end))
    return merged


def settled_error(time: np.ndarray, error: np.ndarray, windows: list) -> tuple:
    """(largest error outside the windows, its time); (None, None) when every frame is inside one (a run too short
    to tell)."""
    time, error = np.asarray(time, float), np.asarray(error, float)
    outside = outside_windows(time, windows)
    values = np.where(outside & np.isfinite(error), error, -np.inf)
    if not outside.any() or not np.isfinite(values).any():
        return None, None
    k = int(np.argmax(values))
    return float(values[k]), float(time[k])


def outside_windows(time: np.ndarray, windows: list) -> np.ndarray:
    """(T,) bool: the frames outside every settling window."""
    time = np.asarray(time, float)
    outside = np.ones(len(time), bool)
    for start, end in windows:
        outside &= ~((time >= start - 1e-12) & (time < end))
    return outside


def constraint_check(report: dict, limit: float | None, conflict: dict | None = None) -> dict:
    """The check of report.json's `checks`: {limit, value, time, ok, constraints}; ok when no limit or nothing
    to judge; constraints: those named by `conflicts` (the ones that keep the error, and their partners)."""
    value, at = report.get("constraint_error_settled"), report.get("constraint_error_settled_time")
    ok = limit is None or value is None or value <= limit
    named = (conflict["constraints"] + conflict["partners"]) if conflict else []
    return {"limit": limit, "value": value, "time": at, "ok": bool(ok), "constraints": named}


def conflicts(plan, recorder, residuals: dict, windows: list, limit: float | None, jacobian=None) -> dict | None:
    """The constraints that keep a settled error above the threshold (module docstring), or None:
    {constraints: names, worst first; errors: name -> largest error (m or rad); partners: the other constraints
    that pull on the same degrees of freedom; bodies: the dynamic bodies of the constraints named}.
    residuals: {global row: |C|} of the active rows at the run's end (Simulation.constraint_residuals);
    jacobian(rows) -> J (m, 2, 6) of those rows there (Simulation.joint_rows): a partner's rows are not
    orthogonal to theirs on a shared body. Without it (or when they are not active at the end), every other
    constraint on their bodies is a partner."""
    cons = plan.constraints
    if cons is None:
        return None
    threshold = CONFLICT_ERROR if limit is None else min(limit, CONFLICT_ERROR)
    k = recorder.count
    time, error, worst = recorder.time[:k], recorder.constraint_error[:k], recorder.worst[:k]
    outside = outside_windows(time, windows)
    kept = [(int(worst[f]), float(error[f])) for f in np.flatnonzero(outside & (error > threshold))]
    if k and outside[k - 1]:  # the end of the run is settled: every row's residual there
        kept += [(row, value) for row, value in residuals.items() if value > threshold]
    errors = {}
    for row, value in kept:
        if 0 <= row < len(cons.row_constraint):
            name = cons.names[cons.row_constraint[row]]
            errors[name] = max(errors.get(name, 0.0), value)
    if not errors:
        return None
    bodies = _bodies_of(plan, set(errors))
    partners = _partners(plan, set(errors), list(residuals), jacobian)
    if partners is None:
        partners = sorted(set(_constraints_on(plan, bodies)) - set(errors))
    return {"constraints": sorted(errors, key=lambda n: -errors[n]), "errors": errors, "partners": partners,
            "bodies": [plan.names[b] for b in sorted(bodies)], "threshold": threshold}


def conflict_warning(conflict: dict) -> str:
    """The warning that names them."""
    kept = ", ".join(f"`{name}` ({conflict['errors'][name]:.3g})" for name in conflict["constraints"])
    kept += " keeps" if len(conflict["constraints"]) == 1 else " keep"
    against = ", ".join(f"`{name}`" for name in conflict["partners"])
    on = ", ".join(f"`{name}`" for name in conflict["bodies"])
    return (f"constraints that cannot all hold: {kept} an error (m or rad) above {conflict['threshold']:g} "
            f"once settled" + (f", against {against}" if against else "") + (f", on {on}" if on else "")
            + ": check their points, axes and targets (two nails that disagree, a doubled orientation)")


def redundant_warning(plan, dropped: list) -> str:
    """The warning for rows the solver found dependent (J M^-1 J^T singular), naming their constraints when the
    last solve still had them."""
    cons = plan.constraints
    names = sorted({cons.names[cons.row_constraint[r]] for r in dropped if 0 <= r < len(cons.row_constraint)})
    if not names:
        return "redundant constraints: J M^-1 J^T was singular; solved in the least-squares sense"
    return (f"redundant constraints: rows of {', '.join(f'`{n}`' for n in names)} repeat those of other "
            f"constraints (J M^-1 J^T was singular); solved in the least-squares sense")


def _partners(plan, names: set, rows: list, jacobian) -> list | None:
    """The constraints active at the end whose rows act on the degrees of freedom of the named ones' rows there
    (J_a . J_b != 0 on a dynamic body they share); None when that cannot be told."""
    cons = plan.constraints
    mine = [r for r in rows if cons.names[cons.row_constraint[r]] in names]
    others = [r for r in rows if cons.names[cons.row_constraint[r]] not in names]
    if jacobian is None or not mine:
        return None
    if not others:
        return []
    J = np.asarray(jacobian(mine + others))
    bodies = np.asarray(cons.row_bodies)
    found = set()
    for j, r in enumerate(others, start=len(mine)):
        for i, c in enumerate(mine):
            if _overlap(plan, bodies[c], J[i], bodies[r], J[j]):
                found.add(cons.names[cons.row_constraint[r]])
                break
    return sorted(found)


def _overlap(plan, bodies_a, J_a, bodies_b, J_b) -> bool:
    """Whether two rows pull on a shared dynamic body's degrees of freedom (their 6-vectors there not orthogonal)."""
    for s, a in enumerate(bodies_a):
        for t, b in enumerate(bodies_b):
            if a == b and 0 <= a < plan.n and plan.dynamic[a]:
                scale = np.linalg.norm(J_a[s]) * np.linalg.norm(J_b[t])
                if scale > 0 and abs(float(np.dot(J_a[s], J_b[t]))) > 1e-9 * scale:
                    return True
    return False


def _bodies_of(plan, names: set) -> set:
    cons = plan.constraints
    rows = [r for r in range(len(cons.row_constraint)) if cons.names[cons.row_constraint[r]] in names]
    return {int(b) for b in np.asarray(cons.row_bodies)[rows].ravel() if 0 <= b < plan.n and plan.dynamic[b]}


def _constraints_on(plan, bodies: set) -> list:
    cons = plan.constraints
    touching = np.isin(np.asarray(cons.row_bodies), list(bodies)).any(axis=1)
    return [cons.names[cons.row_constraint[r]] for r in np.flatnonzero(touching)]
