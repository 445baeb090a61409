"""Integrate stage: advance (x, q, v, w) by one step h with the accelerations of `Dynamics`.

    dx/dt = v      dq/dt = 0.5 (0, w) q      dv/dt = a      dw/dt = alpha

euler: semi-implicit (symplectic) Euler, velocities first. midpoint: explicit RK2. rk4: classic Runge-Kutta.
Quaternions are renormalized after every step. Stage buffers are allocated once (`Stages`), each body's state
packed in one row [x(3) q(4) v(3) w(3)] so that a stage state y0 + c k is two numpy calls, not eight.

The state handed to a step is the tuple (x, q, v, w), or the packed (n, 13) array they are views of (the
simulation's `State.y`): then loading it and advancing it are one numpy call each, not four.
"""
from __future__ import annotations

import numpy as np

from .rotation import quat_derivative, quat_integrate, quat_normalize

# classic RK4 tableau: stage times and the weights of the four slopes
RK4_C = (0.0, 0.5, 0.5, 1.0)
RK4_B = np.array((1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0))

# columns of a packed body row
X, Q, V, W = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13)
PACKED = 13


class Stages:
    """Preallocated slopes and stage states for up to four stages, packed per body.

    k (count, n, 13) slopes, y0 (n, 13) the state at the start of the step, y (n, 13) a stage state,
    increment (n, 13) the step's; the named arrays are views into them, made once: dx, dq, dv, dw (count, n, 3
    or 4), slope[s] the tuple (dx[s], dq[s], dv[s], dw[s]), k_stage[s] = k[s], k_rows (count, 13 n), x, q, v, w
    (n, 3 or 4).
    """

    def __init__(self, n: int, count: int = 4):
        self.k = np.zeros((count, n, PACKED))
        self.y0 = np.zeros((n, PACKED))
        self.y = np.zeros((n, PACKED))
        self.increment = np.zeros((n, PACKED))
        self.dx, self.dq, self.dv, self.dw = self.k[:, :, X], self.k[:, :, Q], self.k[:, :, V], self.k[:, :, W]
        self.slope = [(self.dx[s], self.dq[s], self.dv[s], self.dw[s]) for s in range(count)]
        self.k_stage = list(self.k)  # (n, 13) slope of each stage
        self.k_rows = self.k.reshape(count, -1)
        self.x, self.q, self.v, self.w = self.y[:, X], self.y[:, Q], self.y[:, V], self.y[:, W]

    def load(self, state) -> None:
        """y0 <- the state (x, q, v, w), or the packed state."""
        y0 = self.y0
        if isinstance(state, np.ndarray):
            y0[...] = state
        else:
            y0[:, X], y0[:, Q], y0[:, V], y0[:, W] = state


def _unpack(state) -> tuple:
    """(x, q, v, w) of a state given as that tuple or packed (views of the packed array)."""
    if isinstance(state, np.ndarray):
        return state[:, X], state[:, Q], state[:, V], state[:, W]
    return state


def _slope(accel, t, x, q, v, w, stages: Stages, k: int, epoch) -> None:
    dx, dq, dv, dw = stages.slope[k]
    dx[...] = v
    quat_derivative(q, w, out=dq)
    accel(t, x, q, v, w, dv, dw, epoch)


def _stage_state(stages: Stages, k: int, scale: float) -> tuple:
    """y = y0 + scale k_k, its quaternions renormalized; returns the views (x, q, v, w) of y."""
    np.multiply(stages.k_stage[k], scale, out=stages.y)
    stages.y += stages.y0
    quat_normalize(stages.q, out=stages.q)
    return stages.x, stages.q, stages.v, stages.w


def _advance(state, increment) -> None:
    """(x, q, v, w) += the packed increment (n, 13); quaternions renormalized."""
    if isinstance(state, np.ndarray):
        state += increment
        q = state[:, Q]
    else:
        x, q, v, w = state
        x += increment[:, X]
        q += increment[:, Q]
        v += increment[:, V]
        w += increment[:, W]
    quat_normalize(q, out=q)


def step_rk4(accel, t, h, state, stages: Stages, epoch) -> None:
    x, q, v, w = _unpack(state)
    _slope(accel, t, x, q, v, w, stages, 0, epoch)
    # after the first slope: it may have moved kinematic bodies to their pose at t
    stages.load(state)
    for k in (1, 2, 3):
        xs, qs, vs, ws = _stage_state(stages, k - 1, RK4_C[k] * h)
        _slope(accel, t + RK4_C[k] * h, xs, qs, vs, ws, stages, k, epoch)
    # y += h sum_k b_k k_k  (ndarray.dot: the same BLAS product as matmul, without the gufunc machinery)
    increment = stages.increment
    RK4_B.dot(stages.k_rows[:4], out=increment.reshape(-1))
    increment *= h
    _advance(state, increment)


def step_midpoint(accel, t, h, state, stages: Stages, epoch) -> None:
    x, q, v, w = _unpack(state)
    _slope(accel, t, x, q, v, w, stages, 0, epoch)
    # after the first slope: it may have moved kinematic bodies to their pose at t
    stages.load(state)
    xs, qs, vs, ws = _stage_state(stages, 0, 0.5 * h)
    _slope(accel, t + 0.5 * h, xs, qs, vs, ws, stages, 1, epoch)
    _advance(state, h * stages.k[1])


def step_euler(accel, t, h, state, stages: Stages, epoch) -> None:
    """Semi-implicit Euler: v += h a(x, v); x += h v_new; q turned by w_new for h."""
    x, q, v, w = _unpack(state)
    accel(t, x, q, v, w, stages.dv[0], stages.dw[0], epoch)
    v += h * stages.dv[0]
    w += h * stages.dw[0]
    x += h * v
    q[:] = quat_integrate(q, w, h)


INTEGRATORS = {"rk4": step_rk4, "midpoint": step_midpoint, "euler": step_euler}
