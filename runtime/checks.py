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

Before the first step (`unsatisfiable`), constraints that no pose of the bodies satisfies within the limit are
found: the pose that comes closest is found by Gauss-Newton on the rows of each epoch, and what it leaves, out of
the range of J, is an error no run could remove. They are a warning at the first of them, naming all, and the run
goes on (it breaks the tolerance: exit 3); refused (exit 2, `hopeless`) when a constraint cannot act at all at the
start (an axis along the direction it must be perpendicular to), or when the errors left are past a blow-up.
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
        if begin > plan.end:  # switched on after the run (`--until`): one switched on at its last frame is not
            continue  # settled there
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


def conflict_warning(conflict: dict, scene=None) -> str:
    """The warning that names them, at the declaration of the worst (when the scene is given)."""
    kept = ", ".join(f"`{name}` ({conflict['errors'][name]:.3g})" for name in conflict["constraints"])
    kept += " keeps" if len(conflict["constraints"]) == 1 else " keep"
    against = ", ".join(f"`{name}`" for name in conflict["partners"])
    on = ", ".join(f"`{name}`" for name in conflict["bodies"])
    message = (f"constraints that cannot all hold: {kept} an error (m or rad) above {conflict['threshold']:g} "
               f"once settled" + (f", against {against}" if against else "") + (f", on {on}" if on else ""))
    hint = "check their points, axes and targets (two nails that disagree, a doubled orientation)"
    return positioned(message, constraint_source(scene, conflict["constraints"][0]), hint)


def positioned(message: str, source: str | None, hint: str | None = None) -> str:
    """A warning as the run reports it: `file:line:col: message` when its cause's position is known (the IR's
    `source`), and a last line `hint: ...` (isaac_ir.diagnostics.warning_diagnostic reads it back)."""
    from isaac_ir.diagnostics import SourcePos

    where = f"{source}: " if source and SourcePos.parse(source) is not None else ""
    return where + message + (f"\nhint: {hint}" if hint else "")


def constraint_source(scene, name: str) -> str | None:
    """Where the constraint `name` is declared ("file:line:col"), or None."""
    return _source_of(getattr(scene, "constraints", ()), name)


def body_source(scene, name: str) -> str | None:
    """Where the body `name` is declared ("file:line:col"), or None."""
    return _source_of(getattr(scene, "bodies", ()), name)


def _source_of(declarations, name: str) -> str | None:
    return next((d.source for d in declarations if d.name == name), None)


def redundant_warning(plan, dropped: list) -> str:
    """The warning for rows the solver found dependent (J M^-1 J^T singular), naming their constraints when the
    last solve still had them."""
    cons = plan.constraints
    names = sorted({cons.names[cons.row_constraint[r]] for r in dropped if 0 <= r < len(cons.row_constraint)},
                   key=lambda n: _declared_order(plan.scene, n))
    if not names:
        return "redundant constraints: J M^-1 J^T was singular; solved in the least-squares sense"
    return positioned(f"redundant constraints: rows of {', '.join(f'`{n}`' for n in names)} repeat those of other "
                      f"constraints (J M^-1 J^T was singular); solved in the least-squares sense",
                      constraint_source(plan.scene, names[0]),
                      "hold each degree of freedom by one constraint: take the repeated ones out of one of them "
                      "(e.g. `weld(a, b) - rz`), or drop it")


def _declared_order(scene, name: str) -> tuple:
    """Where a constraint is declared, for sorting (file, line, column); undeclared names last."""
    from isaac_ir.diagnostics import SourcePos

    pos = SourcePos.parse(constraint_source(scene, name) or "")
    return (0, pos.file, pos.line, pos.col, name) if pos else (1, "", 0, 0, name)


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


# -- constraints no pose satisfies, found before the first step -----------------------------------------------------

# a least-squares pose of the dynamic bodies that still leaves a row this far off (m or rad; or the limit, when
# higher) is one that no pose satisfies: the run would keep that error whatever it did (a feasible set is closed
# to 1e-12 by Gauss-Newton)
INFEASIBLE_ERROR = CONFLICT_ERROR
# Gauss-Newton iterations towards that pose, at most (a feasible set converges in a handful)
FEASIBILITY_ITERATIONS = 30
# the start is turned this much (rad) first, so that a pose on a singular point of a row (an `orient` axis exactly
# along the direction it must be perpendicular to: a zero gradient) does not stop the search there
FEASIBILITY_NUDGE = 1e-3
# rows times dynamic degrees of freedom above which the dense least squares is not tried (a 1000-link chain)
FEASIBILITY_SIZE = 4_000_000
# the other constraints on their bodies tried one by one as partners of those that keep an error, at most
FEASIBILITY_PARTNERS = 12


def unsatisfiable(sim, limit: float | None) -> dict | None:
    """The constraints that no pose of the dynamic bodies satisfies together with an error below limit (m or rad:
    --max-constraint-error; None, no limit: nothing is refused), in the first epoch (a stretch of time with one set
    of active rows) where there are some, or None. {constraints: names in declaration order;
    errors: name -> its rows' error at the least-squares pose (m or rad), for those that keep one; start: the
    epoch's start (s)}. The named are those that keep an error, and the partners without which they would not.

    min over the pose z of |C(z)|^2 by Gauss-Newton, dz = -J^+ C (J of the dynamic bodies' (v, w)); a row keeps
    an error only when C is out of the range of J there, C - J J^+ C != 0: the rows pull against each other."""
    plan = sim.plan
    cons = plan.constraints
    if cons is None or limit is None:
        return None
    threshold = max(limit, INFEASIBLE_ERROR)
    dynamic = np.flatnonzero(plan.dynamic[:plan.n])
    position_rows = ~sim.compiled.model.constraints.velocity_only
    for epoch in cons.epochs:
        rows = np.asarray([r for r in np.asarray(epoch.active).tolist() if position_rows[r]], np.int64)
        if not len(rows) or not len(dynamic) or len(rows) * 6 * len(dynamic) > FEASIBILITY_SIZE:
            continue
        found = {"start": epoch.start, "limit": limit}
        stuck = _stuck_errors(sim, rows, dynamic, threshold) if epoch.start <= plan.start else {}
        if stuck:  # the pose is known at the start only
            order = [c.name for c in plan.scene.constraints]
            return {**found, "constraints": sorted(stuck, key=order.index), "errors": stuck, "stuck": True}
        errors = _kept_errors(sim, rows, epoch.start, dynamic, threshold)
        if errors:
            named = set(errors) | _partners_in_conflict(sim, rows, epoch.start, dynamic, set(errors), threshold)
            order = [c.name for c in plan.scene.constraints]
            return {**found, "constraints": sorted(named, key=order.index), "errors": errors}
    return None


def _stuck_errors(sim, rows: np.ndarray, dynamic: np.ndarray, threshold: float) -> dict:
    """{constraint name: error} of the rows on a dynamic body that are more than threshold off at the start and
    that no motion changes there (J = 0: a singular pose, an `orient` axis exactly along the direction it must be
    perpendicular to). The solver cannot move them: the dynamics divides by zero, the projection stays put."""
    C, A = _row_evaluator(sim, rows, sim.state.t, dynamic)(sim.state.y)
    on_dynamic = np.isin(np.asarray(sim.plan.constraints.row_bodies)[rows], dynamic).any(axis=1)
    cons = sim.plan.constraints
    errors = {}
    for i in np.flatnonzero(on_dynamic & (np.abs(C) > threshold) & (np.linalg.norm(A, axis=1) <= 1e-9)):
        name = cons.names[cons.row_constraint[rows[i]]]
        errors[name] = max(errors.get(name, 0.0), abs(float(C[i])))
    return errors


def _partners_in_conflict(sim, rows: np.ndarray, t: float, dynamic: np.ndarray, kept: set, threshold) -> set:
    """The other constraints on the kept ones' dynamic bodies without any one of which the kept ones would hold
    (at most FEASIBILITY_PARTNERS of them are tried, nearest in declaration first)."""
    cons = sim.plan.constraints
    name_of = np.asarray([cons.names[cons.row_constraint[r]] for r in rows.tolist()])
    bodies = set(np.asarray(cons.row_bodies)[rows[np.isin(name_of, list(kept))]].ravel().tolist()) & set(
        dynamic.tolist())
    touching = np.isin(np.asarray(cons.row_bodies)[rows], list(bodies)).any(axis=1)
    candidates = [n for n in dict.fromkeys(name_of[touching].tolist()) if n not in kept][:FEASIBILITY_PARTNERS]
    return {n for n in candidates if not set(_kept_errors(sim, rows[name_of != n], t, dynamic, threshold)) & kept}


def _kept_errors(sim, rows: np.ndarray, t: float, dynamic: np.ndarray, threshold: float) -> dict:
    """{constraint name: error} of the rows that stay more than threshold off at the least-squares pose."""
    y = _nudged(sim.state.y, dynamic)
    evaluate = _row_evaluator(sim, rows, t, dynamic)
    C, A = evaluate(y)
    for _ in range(FEASIBILITY_ITERATIONS):
        if np.max(np.abs(C)) < 1e-12:
            break
        step = np.linalg.lstsq(A, -C, rcond=1e-10)[0]
        moved = _line_search(evaluate, y, dynamic, step, float(C @ C))
        if moved is None:
            break
        y, C, A = moved
    evaluate(sim.state.y)  # the scratch back to the live state
    # C - J J^+ C: what no motion of the bodies can reduce; a row without a gradient of its own is not judged
    kept = C - A @ np.linalg.lstsq(A, C, rcond=1e-10)[0]
    judged = np.linalg.norm(A, axis=1) > 1e-9
    cons = sim.plan.constraints
    errors = {}
    for i in np.flatnonzero(judged & (np.abs(kept) > threshold) & (np.abs(C) > threshold)):
        name = cons.names[cons.row_constraint[rows[i]]]
        errors[name] = max(errors.get(name, 0.0), abs(float(C[i])))
    return errors


def _row_evaluator(sim, rows: np.ndarray, t: float, dynamic: np.ndarray):
    """evaluate(y) -> (C (m,), A (m, 6 d)) of the rows at the padded state y and time t: A the rows' J on the
    (v, w) of the d dynamic bodies, 6 columns each."""
    from .core.entries import row_errors

    c = sim.compiled
    model, scratch = c.model, c.scratch
    table = c.table.evaluate(t, 0.0, 1)
    instances = np.unique(model.constraints.row_instance[rows])
    column = np.full(len(sim.state.y) + 1, -1, np.int64)
    column[dynamic] = np.arange(len(dynamic))
    slots = np.asarray(sim.plan.constraints.row_bodies)[rows]  # (m, 2), -1 the world
    where = np.where(slots >= 0, column[slots], -1)  # each slot's dynamic column, -1 none

    def evaluate(y):
        row_errors(model, instances, scratch, y, table)
        C, J = scratch.C[rows].copy(), scratch.J[rows]
        A = np.zeros((len(rows), 6 * len(dynamic)))
        for slot in (0, 1):
            hit = np.flatnonzero(where[:, slot] >= 0)
            for k in range(6):
                A[hit, 6 * where[hit, slot] + k] += J[hit, slot, k]
        return C, A

    return evaluate


def _line_search(evaluate, y, dynamic, step, base: float):
    """(y, C, A) after the longest of step, step/2, ... that lowers |C|^2; None when none does."""
    for scale in 0.5 ** np.arange(12):
        trial = _moved(y, dynamic, scale * step)
        C, A = evaluate(trial)
        if C @ C < base * (1.0 - 1e-12):
            return trial, C, A
    return None


def _moved(y, dynamic, dz):
    """The padded state with each dynamic body moved by dz's (dx, dtheta): x + dx, q <- exp(dtheta / 2) q (a
    world rotation vector dtheta, as w is the world angular velocity)."""
    y = y.copy()
    dz = dz.reshape(-1, 6)
    y[dynamic, 0:3] += dz[:, 0:3]
    for b, theta in zip(dynamic.tolist(), dz[:, 3:6]):
        y[b, 3:7] = _rotated(y[b, 3:7], theta)
    return y


def _rotated(q, theta):
    """exp(theta / 2) q, normalized: q (w, x, y, z) turned by the world rotation vector theta."""
    angle = float(np.linalg.norm(theta))
    if angle < 1e-300:
        return q
    axis = theta / angle
    w, v = math.cos(angle / 2), math.sin(angle / 2) * axis
    # (w1, v1)(w2, v2) = (w1 w2 - v1.v2, w1 v2 + w2 v1 + v1 x v2)
    out = np.concatenate(([w * q[0] - v @ q[1:]], w * q[1:] + q[0] * v + np.cross(v, q[1:])))
    return out / np.linalg.norm(out)


def _nudged(y, dynamic):
    """The state with each dynamic body turned by FEASIBILITY_NUDGE about a fixed, skew axis."""
    axis = np.array([0.6, -0.48, 0.64])
    return _moved(y, dynamic, np.tile(np.concatenate((np.zeros(3), FEASIBILITY_NUDGE * axis)), len(dynamic)))


def hopeless(found: dict) -> bool:
    """Whether constraints that cannot all hold cannot even be run: one that cannot act at the start, or errors in
    the closest pose at or above what the step loop stops as a blow-up (core/record.RUNAWAY_CONSTRAINT_ERROR)."""
    from .core.record import RUNAWAY_CONSTRAINT_ERROR

    return bool(found.get("stuck")) or max(found["errors"].values(), default=0.0) >= RUNAWAY_CONSTRAINT_ERROR


def unsatisfiable_warning(scene, found: dict) -> str:
    """The same finding as a warning of the plan (`file:line:col: message; hint`): the run goes on, names them
    again when it ends, and breaks the tolerance (exit 3)."""
    diagnostic = unsatisfiable_error(scene, found).diagnostics[0]
    return positioned(diagnostic.message, str(diagnostic.pos) if diagnostic.pos else None, diagnostic.hint)


def unsatisfiable_error(scene, found: dict):
    """The SceneError (exit 2) of constraints no pose satisfies: at the first declared, naming them all and where
    the others are declared."""
    from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos

    sources = {c.name: c.source for c in scene.constraints}
    names, errors = found["constraints"], found["errors"]
    listed = " and ".join(", ".join(f"`{n}`" for n in names).rsplit(", ", 1))
    kept = ", ".join(f"`{n}` {errors[n]:.3g}" for n in names if n in errors)
    first = SourcePos.parse(sources.get(names[0]) or "")
    others = "; ".join(f"`{n}` is at {_where(SourcePos.parse(sources.get(n) or ''), first)}" for n in names[1:]
                       if SourcePos.parse(sources.get(n) or ""))
    when = f" from t = {found['start']:g} s" if found["start"] > scene.time.start else ""
    if found.get("stuck"):
        return SceneError([_stuck_diagnostic(names, errors, listed, others, found["limit"], first)])
    if len(names) > 1:
        message = (f"constraints {listed} cannot {'both' if len(names) == 2 else 'all'} hold{when}: in the pose of the "
                   f"bodies that comes closest, errors remain ({kept}, m or rad), above --max-constraint-error "
                   f"{found['limit']:g}")
    else:
        message = (f"constraint `{names[0]}` cannot hold{when}: in every pose its error stays ({kept}, m or rad), "
                   f"above --max-constraint-error {found['limit']:g}")
    hint = ((others + ": " if others else "") + "check their points, axes and targets (two nails that disagree, "
            "a body tied to two places, axes that cannot all be perpendicular), give them `during` windows that do "
            "not overlap, or raise the limit with --max-constraint-error")
    return SceneError([Diagnostic(message, first, hint)])


def _stuck_diagnostic(names: list, errors: dict, listed: str, others: str, limit: float, first):
    from isaac_ir.diagnostics import Diagnostic

    many = len(names) > 1
    said = ("their errors are " + ", ".join(f"`{n}` {errors[n]:.3g}" for n in names) if many
            else f"its error is {errors[names[0]]:.3g}")
    return Diagnostic(
        f"{'constraints' if many else 'constraint'} {listed} cannot act at the start: {said} (m or rad), above "
        f"--max-constraint-error {limit:g}, and no motion of the bodies changes {'them' if many else 'it'} there",
        first, (others + ": " if others else "") + "an axis is exactly along the direction it must be "
        "perpendicular to: turn the body a little with `orient`, or start it where the constraint holds")


def _where(pos, first) -> str:
    """`line L, column C` in the first one's file, else `file:line:col`."""
    if first is not None and pos.file == first.file:
        return f"line {pos.line}, column {pos.col}"
    return str(pos)
