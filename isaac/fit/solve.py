"""The search of a fit: which optimizer (scipy.optimize), on the parameters scaled to the unit box, until the goals
are met or every method has had its turn.

- one parameter and one goal of one number (an event's time, a component, an angle): a bracketing root finder
  (brentq) on value - target, when the ends of the range bracket the target;
- smooth goals: least squares within the bounds (trust-region reflective), residuals in tolerances, its Jacobian
  by forward differences whose runs go out as one batch (spread over the workers);
- then, for goals that jump (an event that comes or not), a derivative-free search (Nelder-Mead with bounds)
  from the best point so far.

Each method runs to its own tolerances, far below the goals': it stops when every residual is below
CONVERGED tolerances, or when its steps no longer change the parameters.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from isaac_runtime.outputs.goals import residuals

from .evaluate import MISSING, Evaluator

# a method is done when every goal's error is below this fraction of its tolerance
CONVERGED = 1e-6
# forward-difference step of the Jacobian, in the unit box (a millionth of a range's ten-thousandth)
DIFF_STEP = 1e-7
MAX_LEAST_SQUARES_RUNS = 60  # optimizer evaluations (each Jacobian adds one run per parameter)
MAX_DERIVATIVE_FREE_RUNS = 80  # per parameter


class Converged(Exception):
    """Raised from inside an optimizer's function when a point meets every goal far within its tolerance."""


@dataclass
class Search:
    """The state of a fit: the box, the runs, the best point so far, the progress lines."""

    varies: tuple
    evaluator: Evaluator
    say: object  # say(line): the progress of each iteration
    iterations: int = 0
    best: tuple = field(default=(math.inf, None))  # (cost, unit point)
    methods: list = field(default_factory=list)

    # the unit box: u = (x - low) / (high - low)
    def to_si(self, u) -> list:
        return [v.low + float(np.clip(ui, 0.0, 1.0)) * (v.high - v.low) for v, ui in zip(self.varies, u)]

    def to_unit(self, x) -> np.ndarray:
        return np.array([(xi - v.low) / (v.high - v.low) for v, xi in zip(self.varies, x)])

    def residuals_at(self, u, batch=None) -> np.ndarray:
        outcome = self.evaluator.outcome(self.to_si(u)) if batch is None else batch
        return residual_vector(outcome)

    def visit(self, u, method: str) -> np.ndarray:
        """An optimizer's iteration at u: its residuals, a progress line, the best point kept; Converged when
        every goal is met far within its tolerance."""
        self.iterations += 1
        outcome = self.evaluator.outcome(self.to_si(u))
        r = residual_vector(outcome)
        cost = float(np.sum(r * r))
        if cost < self.best[0]:
            self.best = (cost, np.array(u, float))
        self.say(progress_line(self, method, u, outcome))
        if outcome.met() and np.all(np.abs(r) <= CONVERGED):
            raise Converged
        return r


def residual_vector(outcome) -> np.ndarray:
    if outcome.goals is None:
        return np.array([MISSING])
    return np.array([r for record in outcome.goals for r in residuals(record, MISSING)])


def progress_line(search: Search, method: str, u, outcome) -> str:
    values = ", ".join(f"{v.name} = {format_value(x, v)}" for v, x in zip(search.varies, search.to_si(u)))
    if outcome.goals is None:
        told = (outcome.problem or "no run").strip().splitlines()[0]
    else:
        told = "; ".join(goal_progress(record) for record in outcome.goals)
    return f"fit: iteration {search.iterations} ({method}, {search.evaluator.count} runs): {values}: {told}"


def goal_progress(record: dict) -> str:
    """`hit missed (3.2e+02 tol)`: how far the goal is, in its tolerances."""
    far = "no value" if record["error"] is None else f"{record['error'] / record['tolerance']:.3g} tol"
    return f"{record['name']} {'met' if record['met'] else 'missed'} ({far})"


def format_value(si: float, vary) -> str:
    """A value in the unit its range was written in: `7.3 m/s`, `41.5 deg`, `0.31`."""
    from isaac_ir import units as U

    if not vary.unit:
        return f"{si:.10g}"
    # value in the written unit = SI / factor
    return f"{si / U.parse_unit(vary.unit)[0]:.10g} {vary.unit}"


def find(search: Search, goals: tuple) -> None:
    """Run the methods in turn until one meets the goals (search.best then holds its point)."""
    u0 = np.clip(search.to_unit([v.start for v in search.varies]), 0.0, 1.0)
    methods = [least_squares, derivative_free]
    if len(search.varies) == 1 and len(goals) == 1 and _scalar(goals[0]):
        methods.insert(0, bracket)
    for method in methods:
        start = search.best[1] if search.best[1] is not None else u0
        search.methods.append(method.__name__)
        try:
            method(search, start)
        except Converged:
            return
        if search.best[1] is not None and search.evaluator.outcome(search.to_si(search.best[1])).met():
            return


def _scalar(goal) -> bool:
    return goal.kind == "event" or goal.quantity == "angle" or goal.component is not None


def bracket(search: Search, u0) -> None:
    """brentq on the one residual, when the range's ends bracket the target (a missing event: too late)."""
    ends = search.evaluator.outcomes([search.to_si([0.0]), search.to_si([1.0])])

    def signed(outcome) -> float:
        r = residual_vector(outcome)[0]
        return MISSING if abs(r) >= MISSING else r

    low, high = (signed(o) for o in ends)
    if low * high > 0:
        search.say(f"fit: the ends of the range do not bracket the goal ({low:.3g} and {high:.3g} tolerances)")
        return
    optimize.brentq(lambda u: signed_visit(search, u), 0.0, 1.0, xtol=1e-15, rtol=4 * np.finfo(float).eps,
                    maxiter=200)


def signed_visit(search: Search, u: float) -> float:
    r = search.visit([u], "brentq")[0]
    return MISSING if abs(r) >= MISSING else float(r)


def least_squares(search: Search, u0) -> None:
    """Trust-region reflective least squares in the unit box; the Jacobian's runs in one batch."""

    def jacobian(u):
        u = np.asarray(u, float)
        # step toward the inside of the box: u_i + h, or u_i - h at the upper bound
        steps = [DIFF_STEP if ui + DIFF_STEP <= 1.0 else -DIFF_STEP for ui in u]
        points = [u + h * np.eye(len(u))[i] for i, h in enumerate(steps)]
        around = search.evaluator.outcomes([search.to_si(u)] + [search.to_si(p) for p in points])
        r0 = residual_vector(around[0])
        # J_i = (r(u + h e_i) - r(u)) / h
        return np.column_stack([(residual_vector(o) - r0) / h for o, h in zip(around[1:], steps)])

    optimize.least_squares(lambda u: search.visit(u, "least squares"), u0, jac=jacobian, bounds=(0.0, 1.0),
                           method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=MAX_LEAST_SQUARES_RUNS)


def derivative_free(search: Search, u0) -> None:
    """Nelder-Mead within the box on the sum of squared residuals (for goals that jump)."""
    n = len(u0)

    def cost(u):
        r = np.minimum(np.abs(search.visit(u, "Nelder-Mead")), MISSING)
        return float(np.sum(r * r))

    optimize.minimize(cost, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * n,
                      options={"xatol": 1e-14, "fatol": 1e-18, "maxfev": MAX_DERIVATIVE_FREE_RUNS * n})
