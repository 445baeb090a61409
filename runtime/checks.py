"""The tolerances a finished run is held to (`isaac run --max-constraint-error`, exit 3 when one is broken).

A constraint that switches on apart closes along its stabilization curve (docs/solver.md): its error is large at
the switch by design (self-assembly) and decays. What a tolerance judges is the error that stays: the largest
constraint error over the frames outside the settling window after each switch-on (the scene's start included,
where the bodies may be placed a little off their joints). A joint that cannot hold (two nails that disagree, a
body tied to two places) keeps its error and is flagged; a gap that closes is not.
"""
from __future__ import annotations

import math

import numpy as np

# the largest settled constraint error (m, or rad for orientation rows) a run may keep before it counts as broken:
# far above what a joint that holds keeps (1e-14 .. 1e-6 m; procedural compliance a few mm), far below a 0.5 m gap
DEFAULT_MAX_CONSTRAINT_ERROR = 0.1
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
    outside = np.ones(len(time), bool)
    for start, end in windows:
        outside &= ~((time >= start - 1e-12) & (time < end))
    values = np.where(outside & np.isfinite(error), error, -np.inf)
    if not outside.any() or not np.isfinite(values).any():
        return None, None
    k = int(np.argmax(values))
    return float(values[k]), float(time[k])


def constraint_check(report: dict, limit: float | None) -> dict:
    """The check of report.json's `checks`: {limit, value, time, ok}; ok when no limit or nothing to judge."""
    value, at = report.get("constraint_error_settled"), report.get("constraint_error_settled_time")
    ok = limit is None or value is None or value <= limit
    return {"limit": limit, "value": value, "time": at, "ok": bool(ok)}
