"""Integrate stage: advance (x, q, v, w) by one step h with the accelerations of `Dynamics`.

    dx/dt = v      dq/dt = 0.5 (0, w) q      dv/dt = a      dw/dt = alpha

euler: semi-implicit (symplectic) Euler, velocities first. midpoint: explicit RK2. rk4: classic Runge-Kutta.
Quaternions are renormalized after every step. Stage buffers are allocated once (`Stages`).
"""
from __future__ import annotations

import numpy as np

from .rotation import quat_derivative, quat_integrate, quat_normalize

# classic RK4 tableau: stage times and the weights of the four slopes
RK4_C = (0.0, 0.5, 0.5, 1.0)
RK4_B = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)


class Stages:
    """Preallocated slopes and stage states for up to four stages."""

    def __init__(self, n: int, count: int = 4):
        self.dx = np.zeros((count, n, 3))
        self.dq = np.zeros((count, n, 4))
        self.dv = np.zeros((count, n, 3))
        self.dw = np.zeros((count, n, 3))
        self.x = np.zeros((n, 3))
        self.q = np.zeros((n, 4))
        self.v = np.zeros((n, 3))
        self.w = np.zeros((n, 3))


def _slope(accel, t, x, q, v, w, stages: Stages, k: int, epoch) -> None:
    stages.dx[k] = v
    stages.dq[k] = quat_derivative(q, w)
    accel(t, x, q, v, w, stages.dv[k], stages.dw[k], epoch)


def _stage_state(state, stages: Stages, k: int, scale: float) -> tuple:
    x, q, v, w = state
    np.multiply(stages.dx[k], scale, out=stages.x)
    stages.x += x
    np.multiply(stages.dq[k], scale, out=stages.q)
    stages.q += q
    quat_normalize(stages.q, out=stages.q)
    np.multiply(stages.dv[k], scale, out=stages.v)
    stages.v += v
    np.multiply(stages.dw[k], scale, out=stages.w)
    stages.w += w
    return stages.x, stages.q, stages.v, stages.w


def step_rk4(accel, t, h, state, stages: Stages, epoch) -> None:
    x, q, v, w = state
    _slope(accel, t, x, q, v, w, stages, 0, epoch)
    for k in (1, 2, 3):
        xs, qs, vs, ws = _stage_state(state, stages, k - 1, RK4_C[k] * h)
        _slope(accel, t + RK4_C[k] * h, xs, qs, vs, ws, stages, k, epoch)
    # y += h sum_k b_k k_k
    x += h * np.tensordot(RK4_B, stages.dx, axes=1)
    q += h * np.tensordot(RK4_B, stages.dq, axes=1)
    v += h * np.tensordot(RK4_B, stages.dv, axes=1)
    w += h * np.tensordot(RK4_B, stages.dw, axes=1)
    quat_normalize(q, out=q)


def step_midpoint(accel, t, h, state, stages: Stages, epoch) -> None:
    x, q, v, w = state
    _slope(accel, t, x, q, v, w, stages, 0, epoch)
    xs, qs, vs, ws = _stage_state(state, stages, 0, 0.5 * h)
    _slope(accel, t + 0.5 * h, xs, qs, vs, ws, stages, 1, epoch)
    x += h * stages.dx[1]
    q += h * stages.dq[1]
    v += h * stages.dv[1]
    w += h * stages.dw[1]
    quat_normalize(q, out=q)


def step_euler(accel, t, h, state, stages: Stages, epoch) -> None:
    """Semi-implicit Euler: v += h a(x, v); x += h v_new; q turned by w_new for h."""
    x, q, v, w = state
    accel(t, x, q, v, w, stages.dv[0], stages.dw[0], epoch)
    v += h * stages.dv[0]
    w += h * stages.dw[0]
    x += h * v
    q[:] = quat_integrate(q, w, h)


INTEGRATORS = {"rk4": step_rk4, "midpoint": step_midpoint, "euler": step_euler}
