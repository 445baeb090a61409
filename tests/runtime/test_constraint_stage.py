"""The dynamics plan's right-hand side (runtime/dynamics/accelerations.py) against the multiplier equations written
out with dense matrices and forces written out by hand, and the compiled integrators against textbook ones.

    a = a_free + M^-1 J^T lambda,   (J M^-1 J^T) lambda = -bias - J a_free - [kd (J v + ct) + ks C]

(the bracket for rows still assembling, not for held ones).
"""
from __future__ import annotations

import numpy as np
import pytest

from isaac_ir import expr as E
from isaac_lang.load import load_text
from isaac_runtime.core import data as D
from isaac_runtime.core.record import Frames
from isaac_runtime.core.structure import build_active
from isaac_runtime.dynamics import integrate as I
from isaac_runtime.dynamics.accelerations import evaluate_accelerations
from isaac_runtime.plan import PlanOptions, compile_plan
from isaac_runtime.core.rotation import quat_derivative_reference, quat_normalize, quat_to_matrix
from isaac.api import Simulation

from .core_helpers import rows_at

# every family with a position-level row, a velocity row pair, static and kinematic bodies, a moving nail, springs,
# a load and unequal moments (gyroscopic torque); three epochs (rows switch on at 0.5 s and off at 1 s)
SCENE = """
scene stage {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms  stabilize 7 Hz  damping 0.8 }

  body a box { size (0.3, 0.1, 0.05) m  mass 1 kg  at (0, 0, 0) }
  body b box { size (0.2, 0.1, 0.1) m  mass 2 kg  at (0.5, 0, 0) }
  body c sphere { radius 0.05 m  mass 0.5 kg  at (1, 0.2, 0) }
  body d box { size (0.2, 0.2, 0.1) m  mass 1 kg  at (-1, 0, 0) }
  body e box { size (0.2, 0.1, 0.3) m  mass 1 kg  at (-1.3, 0, 0) }
  body k kinematic box { size (0.1, 0.1, 0.1) m  at (2 + 0.1 * sin(t), 0, 0) }
  body f box { size (0.1, 0.3, 0.1) m  mass 1 kg  at (2, -0.3, 0) }
  body base static box { size (1, 0.1, 1) m  at (0, -2, 0) }
  body g cylinder { radius 0.1 m  length 2 cm  mass 0.5 kg  at (3, 0, 0) }
  body h cylinder { radius 0.3 m  length 2 cm  mass 2 kg  at (3.4, 0, 0) }
  body wt sphere { radius 3 cm  mass 1 kg  at (2.9, -0.5, 0) }

  constraint hang nail(a @ (-0.15, 0, 0), (0.1 * sin(3 * t) - 0.15, 0.05 * sin(t), 0) m)
  constraint j point(a @ (0.15, 0, 0), b @ (-0.1, 0, 0)) from 0.5 s
  constraint pl plane(c @ (0, 0, 0), (0, 0.2, 0), y)
  constraint pl2 plane(c @ (0, 0.05, 0), b @ (0, 0, 0), b.y) during 0 s .. 1 s
  constraint o orient(b.z, a.x)
  constraint w weld(d, e) - rz - tx
  constraint de weld(d) - rx - rz - tx - ty
  constraint kf point(f @ (0, 0.15, 0), k @ (0, -0.05, 0))
  constraint on_base point(e @ (0, -0.05, 0), base @ (-1.3, 1.95, 0))
  constraint g_axle nail(g @ (0, 0, 0)) + orient(g.z, x) + orient(g.z, y)
  constraint h_axle nail(h @ (0, 0, 0)) + orient(h.z, x) + orient(h.z, y)
  constraint mesh gear(g.z, 0.1 m, h.z, 0.3 m)
  constraint rope rope(g, (-0.1, 0, 0) m, wt, -y)
  force s spring(c @ (0, 0, 0), b @ (0.1, 0, 0)) { stiffness 50 N/m  damping 0.5 N*s/m }
  force l load(e @ (0, 0.1, 0)) { force (sin(t), 0, 0) N  torque (0, 0, 0.1) N*m }
}
"""
EPOCH_TIMES = (0.25, 0.75, 1.5)

# a branched tree of ball joints hanging from the world
TREE = """
scene tree {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  for i in 0 .. 4 {
    body link{i} box { size (0.2, 2 cm, 3 cm)  mass 0.5 kg  at (0.2 * i + 0.1, 0, 0) }
  }
  body side box { size (2 cm, 0.2, 3 cm)  mass 0.3 kg  at (0.4, -0.1, 0)  collide off }  # it touches link2
  constraint anchor nail(link0 @ (-0.1, 0, 0), (0, 0, 0))
  for i in 0 .. 3 {
    constraint joint{i} point(link{i} @ (0.1, 0, 0), link{i+1} @ (-0.1, 0, 0))
  }
  constraint branch point(side @ (0, 0.1, 0), link1 @ (0.1, 0, 0))
}
"""


def _simulation(text: str, linear: str = "sparse") -> Simulation:
    plan = compile_plan(load_text(text).scene, PlanOptions())
    plan.constraints.linear_solver = linear
    for epoch in plan.constraints.epochs:
        epoch.solver = "none" if not epoch.active.size else linear
    return Simulation(plan)


def _random_state(sim, rng) -> np.ndarray:
    """A packed state near the start, static bodies put, kinematic bodies on their paths (the kernels put them)."""
    y, plan = sim.state.y.copy(), sim.plan
    n, moving = plan.n, plan.dynamic
    y[:n][moving, 0:3] += 0.01 * rng.normal(size=(moving.sum(), 3))
    y[:n][moving, 3:7] = quat_normalize(y[:n][moving, 3:7] + 0.05 * rng.normal(size=(moving.sum(), 4)))
    y[:n][moving, 7:10] = rng.normal(size=(moving.sum(), 3))
    y[:n][moving, 10:13] = 3.0 * rng.normal(size=(moving.sum(), 3))
    return y


def _forces_by_hand(plan, y, t):
    """(F, tau) (n,3) of gravity, springs, loads and the gyroscopic term, written out one body at a time."""
    n = plan.n
    R = quat_to_matrix(y[:n, 3:7])
    F = np.zeros((n, 3)) if plan.forces.weight is None else plan.forces.weight.copy()
    tau = np.zeros((n, 3))

    def point(b, p):
        if b < 0:
            return np.asarray(p, float), np.zeros(3), np.zeros(3)
        r = R[b] @ p
        return y[b, 0:3] + r, r, y[b, 7:10] + np.cross(y[b, 10:13], r)

    s = plan.forces.springs
    for i in range(len(s.body_a) if s is not None else 0):
        pa, ra, va = point(s.body_a[i], s.point_a[i])
        pb, rb, vb = point(s.body_b[i], s.point_b[i])
        d = pb - pa
        u = d / np.linalg.norm(d)
        f = (s.stiffness[i] * (np.linalg.norm(d) - s.rest[i]) + s.damping[i] * (vb - va) @ u) * u
        F[s.body_a[i]] += f
        tau[s.body_a[i]] += np.cross(ra, f)
        if s.body_b[i] >= 0:
            F[s.body_b[i]] -= f
            tau[s.body_b[i]] -= np.cross(rb, f)
    loads = plan.forces.loads
    for i in range(len(loads.body) if loads is not None else 0):
        b = loads.body[i]
        f = np.asarray(E.evaluate(loads.force[i], {"t": t}), float)
        F[b] += f
        tau[b] += np.asarray(E.evaluate(loads.torque[i], {"t": t}), float) + np.cross(R[b] @ loads.point[i], f)
    for b in range(n):
        if plan.dynamic[b]:
            I_world = R[b] @ plan.inertia_body[b] @ R[b].T
            tau[b] -= np.cross(y[b, 10:13], I_world @ y[b, 10:13])
    return F, tau, R


def _dense_reference(sim, act, y, t):
    """(n, 6) accelerations by the equations above, with J (m, 6n) and M^-1 (6n, 6n) as full matrices."""
    plan, c = sim.plan, sim.compiled
    n = plan.n
    table = c.table.evaluate(t, 0.0, 1)
    F, tau, R = _forces_by_hand(plan, y, t)
    M_inv = np.zeros((6 * n, 6 * n))
    acc_free = np.zeros((n, 6))
    for b in range(n):
        I_inv = R[b] @ plan.inv_inertia_body[b] @ R[b].T
        M_inv[6 * b:6 * b + 3, 6 * b:6 * b + 3] = plan.inv_mass[b] * np.eye(3)
        M_inv[6 * b + 3:6 * b + 6, 6 * b + 3:6 * b + 6] = I_inv
        acc_free[b] = np.concatenate((plan.inv_mass[b] * F[b], I_inv @ tau[b]))
    paths = plan.kinematics
    for k, b in enumerate(paths.index if paths is not None else []):
        column = c.model.kinematic.column[k]
        acc_free[b] = np.concatenate((table[0, column + 6:column + 9], table[0, column + 16:column + 19]))
        y[b, 0:3], y[b, 7:10] = table[0, column:column + 3], table[0, column + 3:column + 6]
        y[b, 3:7], y[b, 10:13] = table[0, column + 9:column + 13], table[0, column + 13:column + 16]
    rows = rows_at(c.model, y, t, table)
    active = act.rows
    J = np.zeros((len(active), 6 * n))
    for i, r in enumerate(active):
        for slot in range(2):
            b = rows.row_bodies[r, slot]
            if b >= 0:
                J[i, 6 * b:6 * b + 6] += rows.J[r, slot]
    cons = c.model.constraints
    xdot = y[:n, 7:13].reshape(-1)
    baumgarte = ~act.held * (cons.kd[active] * (J @ xdot + rows.ct[active]) + cons.ks[active] * rows.C[active])
    rhs = -rows.bias[active] - J @ acc_free.reshape(-1) - baumgarte
    lam = np.linalg.lstsq(J @ M_inv @ J.T, rhs, rcond=1e-12)[0]
    return acc_free + (M_inv @ J.T @ lam).reshape(n, 6)


@pytest.mark.parametrize("text", [SCENE, TREE], ids=["scene", "tree"])
@pytest.mark.parametrize("linear", ["sparse", "dense"])
@pytest.mark.parametrize("held", [True, False], ids=["held", "assembling"])
def test_accelerations_match_the_dense_equations(text, linear, held):
    """The compiled stage (forces, rows, sparse or dense Cholesky, M^-1 J^T lambda) gives the accelerations of the
    equations written out with full matrices, for held rows and for rows still assembling."""
    sim = _simulation(text, linear)
    rng = np.random.default_rng(3)
    c = sim.compiled
    cons = c.model.constraints
    for t in EPOCH_TIMES:
        epoch = sim.plan.constraints.epoch_at(t)
        act = build_active(cons, epoch.active, c.model.bodies.dynamic, np.full(len(epoch.active), held),
                           dense=linear == "dense")
        scratch = D.allocate_scratch(sim.plan.n, cons.param, len(cons.row_instance), len(act.Li))
        for _ in range(2):
            y = _random_state(sim, rng)
            acc = np.zeros((sim.plan.n + 1, 6))
            evaluate_accelerations(c.model, act, scratch, y, c.table.evaluate(t, 0.0, 1), acc)
            expected = _dense_reference(sim, act, y.copy(), t)
            scale = max(1.0, np.abs(expected).max())
            np.testing.assert_allclose(acc[:-1], expected, rtol=0, atol=1e-9 * scale)
            assert not acc[-1].any()  # the world row


def test_a_tree_factors_without_fill():
    """Minimum degree on a tree of ball joints: L has exactly the pattern of A's lower triangle."""
    sim = _simulation(TREE)
    c = sim.compiled
    act = c.active(sim.plan.constraints.epochs[0], sim.state.y, 0.0)
    lower = {(int(i), int(j)) for i, j in zip(act.cp_i, act.cp_j)}
    assert len(act.Li) == len(lower)


# -- integrators --------------------------------------------------------------------------------------------


def _kernel_slope(sim, act, scratch, t):
    def slope(y):
        acc = np.zeros((sim.plan.n + 1, 6))
        y = y.copy()
        evaluate_accelerations(sim.compiled.model, act, scratch, y, sim.compiled.table.evaluate(t, 0.0, 1), acc)
        k = np.zeros_like(y)
        k[:, 0:3], k[:, 3:7], k[:, 7:13] = y[:, 7:10], quat_derivative_reference(y[:, 3:7], y[:, 10:13]), acc
        return k
    return slope


def _textbook(name, y, h, slope_at):
    """RK4, explicit midpoint and semi-implicit Euler written out, quaternions renormalized at every stage."""
    def stage(base, k, c):
        out = base + c * k
        out[:, 3:7] = quat_normalize(out[:, 3:7])
        return out
    if name == "rk4":
        k0 = slope_at(0.0)(y)
        k1 = slope_at(0.5)(stage(y, k0, 0.5 * h))
        k2 = slope_at(0.5)(stage(y, k1, 0.5 * h))
        k3 = slope_at(1.0)(stage(y, k2, h))
        return stage(y, (k0 + 2 * k1 + 2 * k2 + k3) / 6.0, h)
    if name == "midpoint":
        return stage(y, slope_at(0.5)(stage(y, slope_at(0.0)(y), 0.5 * h)), h)
    k = slope_at(0.0)(y)
    out = y.copy()
    out[:, 7:13] += h * k[:, 7:13]
    out[:, 0:3] += h * out[:, 7:10]
    w = out[:, 10:13]
    speed = np.linalg.norm(w, axis=1, keepdims=True)
    half = 0.5 * h * speed
    turn = np.concatenate((np.cos(half), np.sin(half) * w / np.where(speed > 0, speed, 1.0)), axis=1)
    from isaac_runtime.core.rotation import quat_multiply
    out[:, 3:7] = quat_normalize(quat_multiply(turn, out[:, 3:7]))
    return out


@pytest.mark.parametrize("name", ["rk4", "midpoint", "euler"])
def test_compiled_integrators_match_textbook_ones(name):
    """One step of the compiled loop (rows assembling: no projection acts) against the integrator written out with
    the compiled accelerations as its slope."""
    sim = _simulation(TREE)
    c = sim.compiled
    cons = c.model.constraints
    act = build_active(cons, sim.plan.constraints.epochs[0].active, c.model.bodies.dynamic)
    h, t = 0.01, 0.0
    y = _random_state(sim, np.random.default_rng(4))
    scratch = D.allocate_scratch(sim.plan.n, cons.param, len(cons.row_instance), len(act.Li))
    expected = _textbook(name, y, h, lambda f: _kernel_slope(sim, act, scratch, t + f * h))
    got = y.copy()
    frames = Frames(np.zeros((0, sim.plan.n + 1, 13)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64),
                    np.zeros((0, len(c.model.constraints.family), 8)), np.zeros(0, np.int64), np.zeros((0, 0, 6)))
    status = np.zeros(4, np.int64)
    I.run(c.model, act, scratch, got, c.tabulate(t, h, 1, I.GRID), I.INTEGRATORS[name], h, 1, np.zeros(0, np.int64),
          frames, status, False, 0, False, False, 0.0, 1.0)  # (no error control: one textbook step)
    assert status[0] == I.DONE
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
