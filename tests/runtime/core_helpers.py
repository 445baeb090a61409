"""Helpers for the tests of the compiled core: a model of given constraint families over free bodies, and the
core's own evaluation of their rows at a state (through the entry point the runtime uses)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from isaac_runtime.constraints.plan import row_count
from isaac_runtime.core import data as D
from isaac_runtime.core import model as M
from isaac_runtime.core.entries import row_errors
from isaac_runtime.wind.kernels import empty_wind_model


def free_bodies(n: int, mass=None, inertia=None, dynamic=None) -> M.Bodies:
    """n bodies (plus the world row) with the given masses (default 1 kg), body-frame inertias (default I) and
    dynamic flags (default all), no gravity."""
    plan = SimpleNamespace(
        n=n, inv_mass=None, mass=np.ones(n) if mass is None else np.asarray(mass, float),
        inertia_body=np.tile(np.eye(3), (n, 1, 1)) if inertia is None else np.asarray(inertia, float),
        dynamic=np.ones(n, bool) if dynamic is None else np.asarray(dynamic, bool),
        forces=SimpleNamespace(weight=None, gyroscopic=None))
    plan.inv_mass = np.where(plan.dynamic, 1.0 / plan.mass, 0.0)
    plan.inv_inertia_body = np.where(plan.dynamic[:, None, None], np.linalg.inv(plan.inertia_body), 0.0)
    return M.build_bodies(plan)


def constraint_plan(families) -> SimpleNamespace:
    """The parts of a ConstraintPlan that core.model.pack_constraints reads, for families laid end to end."""
    offsets, total = [], 0
    for fam in families:
        offsets.append(total)
        total += row_count(fam)
    zeros = np.zeros(total)
    return SimpleNamespace(families=list(families), family_offsets=offsets, total_rows=total, row_ks=zeros,
                           row_kd=zeros, row_compliance=zeros)


def model_of(families, n: int, bodies: M.Bodies | None = None) -> M.Model:
    """A model of n free bodies (or `bodies`) and the given constraint families, nothing else."""
    z = np.zeros(0, np.int64)
    cons = M.pack_constraints(constraint_plan(families), [])
    return M.Model(n, free_bodies(n) if bodies is None else bodies, M.Kinematic(z, z, np.zeros(0, np.bool_)),
                   M.Springs(np.zeros((0, 2), np.int64), np.zeros((0, 2, 3)), np.zeros(0), np.zeros(0), np.zeros(0)),
                   M.Loads(z, np.zeros((0, 3)), z), cons, empty_wind_model(), 0, 0, M.no_shapes(n), M.no_pairs(), 0.0)


def packed_state(x, q, v, w) -> np.ndarray:
    """y (n+1, 13) with the world row."""
    n = len(x)
    y = np.zeros((n + 1, D.PACKED))
    y[:n, D.X], y[:n, D.Q], y[:n, D.V], y[:n, D.W] = x, q, v, w
    y[n, 3] = 1.0
    return y


def rows_at(model: M.Model, y: np.ndarray, t: float = 0.0, table: np.ndarray | None = None) -> SimpleNamespace:
    """C, J (M,2,6), ct, bias, row_bodies (M,2), velocity_only (M,) of every row at state y, time t, as the core
    computes them (table: the time table's row at t, when the model has moving parameters)."""
    cons = model.constraints
    rows = len(cons.row_instance)
    s = D.allocate_scratch(model.n, cons.param, rows)
    table = np.array([[t]]) if table is None else table
    row_errors(model, np.arange(len(cons.family), dtype=np.int64), s, y, table)
    return SimpleNamespace(C=s.C[:rows].copy(), J=s.J[:rows].copy(), ct=s.ct[:rows].copy(),
                           bias=s.bias[:rows].copy(), row_bodies=cons.body[cons.row_instance],
                           velocity_only=cons.velocity_only.copy())
