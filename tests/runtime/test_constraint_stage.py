"""runtime/dynamics.py and integrate.py: the fast constraint stage against the multiplier equations written out
with dense matrices, and the packed integrators against plain ones.

    a = a_free + M^-1 J^T lambda,   (J M^-1 J^T) lambda = -bias - J a_free - kd (J v + ct) - ks C
"""
from __future__ import annotations

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime import dynamics as dynamics_module
from isaac_runtime.constraints.layout import WORLD
from isaac_runtime.integrate import INTEGRATORS, Stages
from isaac_runtime.plan import PlanOptions, compile_plan
from isaac_runtime.rotation import quat_derivative_reference, quat_normalize, quat_to_matrix
from isaac_runtime.simulation import Simulation

# every family with a position-level row, a velocity row pair, static and kinematic bodies, a moving nail, springs,
# a load and unequal moments (gyroscopic torque); three epochs (rows switch on at 0.5 s and off at 1 s)
SCENE = """
scene stage {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }

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

# a branched tree of ball joints hanging from the world: the graph the tree solver takes
TREE = """
scene tree {
  time 0 s .. 2 s
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  for i in 0 .. 4 {
    body link{i} box { size (0.2, 2 cm, 3 cm)  mass 0.5 kg  at (0.2 * i + 0.1, 0, 0) }
  }
  body side box { size (2 cm, 0.2, 3 cm)  mass 0.3 kg  at (0.4, -0.1, 0) }
  constraint anchor nail(link0 @ (-0.1, 0, 0), (0, 0, 0))
  for i in 0 .. 3 {
    constraint joint{i} point(link{i} @ (0.1, 0, 0), link{i+1} @ (-0.1, 0, 0))
  }
  constraint branch point(side @ (0, 0.1, 0), link1 @ (0.1, 0, 0))
}
"""


def _simulation(linear_solver: str, text: str = SCENE) -> Simulation:
    plan = compile_plan(load_text(text).scene, PlanOptions())
    plan.constraints.linear_solver = linear_solver
    return Simulation(plan)


def _random_state(sim, rng):
    s, plan = sim.state, sim.plan
    x = s.x + 0.01 * rng.normal(size=s.x.shape)
    q = quat_normalize(s.q + 0.05 * rng.normal(size=s.q.shape))
    v, w = rng.normal(size=s.v.shape), 3.0 * rng.normal(size=s.w.shape)
    # static bodies stay put
    x[~plan.dynamic], q[~plan.dynamic], v[~plan.dynamic], w[~plan.dynamic] = s.x[~plan.dynamic], \
        s.q[~plan.dynamic], 0.0, 0.0
    return x, q, v, w


def _dense_reference(sim, t, x, q, v, w, epoch):
    """a, alpha by the equations above, with J (m, 6n) and M^-1 (6n, 6n) as full matrices."""
    plan, dynamics, c = sim.plan, sim.dynamics, sim.plan.constraints
    n = plan.n
    a_free, alpha_free = np.zeros((n, 3)), np.zeros((n, 3))
    x, q, v, w = x.copy(), q.copy(), v.copy(), w.copy()
    dynamics.accelerations(t, x, q, v, w, a_free, alpha_free, None)  # forces only (and kinematic paths)
    block = dynamics.rows_at(dynamics.frame(x, q, v, w, t))
    active = epoch.active
    J = np.zeros((len(active), 6 * n))
    for r, row in enumerate(active):
        for slot in range(2):
            body = block.row_bodies[row, slot]
            if body != WORLD:
                J[r, 6 * body: 6 * body + 6] += block.J[row, slot]
    M_inv = np.zeros((6 * n, 6 * n))
    R = quat_to_matrix(q)
    for body in range(n):
        M_inv[6 * body: 6 * body + 3, 6 * body: 6 * body + 3] = plan.inv_mass[body] * np.eye(3)
        M_inv[6 * body + 3: 6 * body + 6, 6 * body + 3: 6 * body + 6] = R[body] @ plan.inv_inertia_body[body] @ R[body].T
    xdot = np.concatenate((v, w), axis=1).reshape(-1)
    acc_free = np.concatenate((a_free, alpha_free), axis=1).reshape(-1)
    rhs = (-block.bias[active] - J @ acc_free - c.row_kd[active] * (J @ xdot + block.ct[active])
           - c.row_ks[active] * block.C[active])
    lam = np.linalg.solve(J @ M_inv @ J.T, rhs)
    acc = (acc_free + M_inv @ J.T @ lam).reshape(n, 6)
    return acc[:, :3], acc[:, 3:]


@pytest.mark.parametrize("text,linear_solver,body_space", [
    (SCENE, "dense", True), (SCENE, "dense", False), (SCENE, "sparse", False), (TREE, "tree", False),
    (TREE, "dense", True), (TREE, "dense", False)],
    ids=["scene-dense-body-space", "scene-dense-slots", "scene-sparse", "tree-tree", "tree-dense-body-space",
         "tree-dense-slots"])
def test_accelerations_match_the_dense_equations(text, linear_solver, body_space, monkeypatch):
    """Both forms of the dense stage (in body space for few bodies, by slot pairs beyond) and the sparse and tree
    solvers give the accelerations of the equations written out with full matrices."""
    if not body_space:
        monkeypatch.setattr(dynamics_module, "BODY_SPACE_MAX_BODIES", 0)
    sim = _simulation(linear_solver, text)
    rng = np.random.default_rng(3)
    c = sim.plan.constraints
    for t in EPOCH_TIMES:
        epoch = c.epoch_at(t)
        for _ in range(2):
            x, q, v, w = _random_state(sim, rng)
            a, alpha = np.zeros_like(x), np.zeros_like(x)
            sim.dynamics.accelerations(t, x, q, v, w, a, alpha, epoch)
            a_ref, alpha_ref = _dense_reference(sim, t, x, q, v, w, epoch)
            scale = max(1.0, np.abs(a_ref).max(), np.abs(alpha_ref).max())
            np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(alpha, alpha_ref, rtol=0, atol=1e-9 * scale)
        assert epoch.solver == linear_solver
        assert (sim.dynamics._active_rows(epoch).body_space is not None) == body_space
        assert sim.dynamics.scratch.last_solve.method in ("cholesky", "lu", "tree")


# -- integrators --------------------------------------------------------------------------------------------


def _toy_accelerations(t, x, q, v, w, a, alpha, epoch):
    """A smooth, state- and time-dependent right-hand side."""
    a[...] = -x * np.sum(v * v, axis=1, keepdims=True) + np.sin(t)
    alpha[...] = np.cross(w, x) - 0.1 * w + q[:, 1:]


def _plain_rk4(accel, t, h, state):
    """Classic RK4 on separate arrays, one slope at a time."""
    x, q, v, w = (s.copy() for s in state)
    slopes = []
    stage = (x, q, v, w)
    for c in (0.0, 0.5, 0.5, 1.0):
        if slopes:
            dx, dq, dv, dw = slopes[-1]
            xs, qs = x + c * h * dx, quat_normalize(q + c * h * dq)
            stage = (xs, qs, v + c * h * dv, w + c * h * dw)
        a, alpha = np.zeros_like(x), np.zeros_like(x)
        accel(t + c * h, *stage, a, alpha, None)
        slopes.append((stage[2].copy(), quat_derivative_reference(stage[1], stage[3]), a, alpha))
    out = []
    for i, y in enumerate((x, q, v, w)):
        y = y + h * (slopes[0][i] + 2.0 * slopes[1][i] + 2.0 * slopes[2][i] + slopes[3][i]) / 6.0
        out.append(y)
    out[1] = quat_normalize(out[1])
    return out


def _plain_midpoint(accel, t, h, state):
    x, q, v, w = (s.copy() for s in state)
    a, alpha = np.zeros_like(x), np.zeros_like(x)
    accel(t, x, q, v, w, a, alpha, None)
    half = 0.5 * h
    stage = (x + half * v, quat_normalize(q + half * quat_derivative_reference(q, w)), v + half * a, w + half * alpha)
    a2, alpha2 = np.zeros_like(x), np.zeros_like(x)
    accel(t + half, *stage, a2, alpha2, None)
    return [x + h * stage[2], quat_normalize(q + h * quat_derivative_reference(stage[1], stage[3])), v + h * a2,
            w + h * alpha2]


@pytest.mark.parametrize("name,plain", [("rk4", _plain_rk4), ("midpoint", _plain_midpoint)])
def test_packed_integrators_match_plain_ones(name, plain):
    rng = np.random.default_rng(4)
    n = 5
    state = [rng.normal(size=(n, 3)), quat_normalize(rng.normal(size=(n, 4))), rng.normal(size=(n, 3)),
             rng.normal(size=(n, 3))]
    expected = plain(_toy_accelerations, 0.3, 0.01, state)
    stages = Stages(n)
    for _ in range(2):  # the buffers are reused: a second step from the same state gives the same answer
        y = [s.copy() for s in state]
        INTEGRATORS[name](_toy_accelerations, 0.3, 0.01, y, stages, None)
        for got, want in zip(y, expected):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


def test_positions_at_gives_the_rows_C():
    """The constraint error's evaluation of C alone (Simulation.constraint_errors) is the full rows' C."""
    sim = _simulation("dense")
    rng = np.random.default_rng(5)
    for t in EPOCH_TIMES:
        x, q, v, w = _random_state(sim, rng)
        full = sim.dynamics.rows_at(sim.dynamics.frame(x, q, v, w, t)).C.copy()
        sim.dynamics.rows_at(sim.dynamics.frame(*_random_state(sim, rng), t + 0.1))  # C of another state
        np.testing.assert_array_equal(sim.dynamics.positions_at(sim.dynamics.frame(x, q, v, w, t)).C, full)
