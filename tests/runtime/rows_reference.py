"""Constraint rows, the slow obvious way: one instance at a time, one 3-vector at a time. Test oracle only.

Same meaning as rows.py (see layout.py for the conventions). To be an independent check rather than a copy,
bias is computed here as "Jdot v" (the time derivative of each Jacobian entry, dotted with the velocities)
instead of the second derivative of C that rows.py writes out.
"""
from __future__ import annotations

import numpy as np

from isaac_runtime.constraints.layout import (
    WORLD,
    BodyFrame,
    Element,
    GearToGear,
    GearToWeight,
    Orientation,
    PointOnPlane,
    PointToNail,
    PointToPoint,
)


def _body(frame: BodyFrame, i: int):
    """(x, q, R, v, w) of body i; the world is the identity pose at rest."""
    if i == WORLD:
        return np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.eye(3), np.zeros(3), np.zeros(3)
    return frame.x[i], frame.q[i], frame.R[i], frame.v[i], frame.w[i]


def _qmul(p, q):
    """Hamilton product of two quaternions (w, x, y, z), written with scalar and vector parts."""
    ps, pv, qs, qv = p[0], p[1:], q[0], q[1:]
    return np.concatenate(([ps * qs - pv @ qv], ps * qv + qs * pv + np.cross(pv, qv)))


def _qconj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


class _Rows:
    """Accumulates rows one at a time."""

    def __init__(self):
        self.C, self.row_bodies, self.J, self.ct, self.bias, self.velocity_only = [], [], [], [], [], []

    def add(self, i, j, C, lin_a, ang_a, lin_b, ang_b, ct, bias, velocity_only=False):
        block = np.zeros((2, 6))
        if i != WORLD:
            block[0] = np.concatenate((lin_a, ang_a))
        if j != WORLD:
            block[1] = np.concatenate((lin_b, ang_b))
        self.C.append(C)
        self.row_bodies.append((i, j))
        self.J.append(block)
        self.ct.append(ct)
        self.bias.append(bias)
        self.velocity_only.append(velocity_only)

    def arrays(self):
        return {
            "C": np.array(self.C, dtype=float),
            "row_bodies": np.array(self.row_bodies, dtype=np.int64).reshape(-1, 2),
            "J": np.array(self.J, dtype=float).reshape(-1, 2, 6),
            "ct": np.array(self.ct, dtype=float),
            "bias": np.array(self.bias, dtype=float),
            "velocity_only": np.array(self.velocity_only, dtype=bool),
        }


def _point_to_point(fam: PointToPoint, frame, rows: _Rows):
    for k in range(len(fam.body_a)):
        i, j = fam.body_a[k], fam.body_b[k]
        xa, _, Ra, va, wa = _body(frame, i)
        xb, _, Rb, vb, wb = _body(frame, j)
        ra, rb = Ra @ fam.point_a[k], Rb @ fam.point_b[k]
        for axis in np.eye(3):
            # row: axis . (x_a + r_a - x_b - r_b); d/dt = axis.v_a + (r_a x axis).w_a - ...
            # Jdot v: d/dt (r x axis) . w = ((w x r) x axis) . w
            C = axis @ (xa + ra - xb - rb)
            bias = np.cross(np.cross(wa, ra), axis) @ wa - np.cross(np.cross(wb, rb), axis) @ wb
            rows.add(i, j, C, axis, np.cross(ra, axis), -axis, -np.cross(rb, axis), 0.0, bias)


def _point_to_nail(fam: PointToNail, frame, rows: _Rows):
    for k in range(len(fam.body)):
        i = fam.body[k]
        x, _, R, v, w = _body(frame, i)
        r = R @ fam.point[k]
        for n, axis in enumerate(np.eye(3)):
            C = axis @ (x + r) - fam.target[k, n]
            ct = -fam.target_velocity[k, n]
            bias = np.cross(np.cross(w, r), axis) @ w - fam.target_acceleration[k, n]
            rows.add(i, WORLD, C, axis, np.cross(r, axis), None, None, ct, bias)


def _orientation(fam: Orientation, frame, rows: _Rows):
    for k in range(len(fam.body_a)):
        i, j = fam.body_a[k], fam.body_b[k]
        _, _, Ra, _, wa = _body(frame, i)
        _, _, Rb, _, wb = _body(frame, j)
        T, N = Ra @ fam.axis_a[k], Rb @ fam.axis_b[k]
        ang = np.cross(T, N)
        # Jdot v = d/dt (T x N) . (w_a - w_b)
        ang_dot = np.cross(np.cross(wa, T), N) + np.cross(T, np.cross(wb, N))
        rows.add(i, j, T @ N, np.zeros(3), ang, np.zeros(3), -ang, 0.0, ang_dot @ (wa - wb))


def _point_on_plane(fam: PointOnPlane, frame, rows: _Rows):
    for k in range(len(fam.body_a)):
        i, j = fam.body_a[k], fam.body_b[k]
        xa, _, Ra, va, wa = _body(frame, i)
        xb, _, Rb, vb, wb = _body(frame, j)
        ra = Ra @ fam.point_a[k]
        P, S, N = xa + ra, xb + Rb @ fam.plane_point[k], Rb @ fam.plane_normal[k]
        arm_b = P - xb  # b's material point under P
        # J_a = [N, r_a x N], J_b = [-N, -(P - x_b) x N]; differentiate every entry in time
        N_dot, P_dot = np.cross(wb, N), va + np.cross(wa, ra)
        bias = (
            N_dot @ va
            + (np.cross(np.cross(wa, ra), N) + np.cross(ra, N_dot)) @ wa
            - N_dot @ vb
            - (np.cross(P_dot - vb, N) + np.cross(arm_b, N_dot)) @ wb
        )
        rows.add(i, j, N @ (P - S), N, np.cross(ra, N), -N, -np.cross(arm_b, N), 0.0, bias)


def _gear_to_gear(fam: GearToGear, frame, rows: _Rows):
    for k in range(len(fam.body_a)):
        i, j = fam.body_a[k], fam.body_b[k]
        _, _, Ra, _, wa = _body(frame, i)
        _, _, Rb, _, wb = _body(frame, j)
        Aa, Ab = fam.radius_a[k] * (Ra @ fam.axis_a[k]), fam.radius_b[k] * (Rb @ fam.axis_b[k])
        bias = np.cross(wa, Aa) @ wa + np.cross(wb, Ab) @ wb
        rows.add(i, j, 0.0, np.zeros(3), Aa, np.zeros(3), Ab, 0.0, bias, velocity_only=True)


def _gear_to_weight(fam: GearToWeight, frame, rows: _Rows):
    for k in range(len(fam.gear)):
        d = fam.direction[k]
        ang = np.cross(fam.arm[k], d)
        rows.add(fam.gear[k], fam.weight[k], 0.0, np.zeros(3), ang, -d, np.zeros(3), 0.0, 0.0, velocity_only=True)


def _element(fam: Element, frame, rows: _Rows):
    for k in range(len(fam.body_a)):
        i, j = fam.body_a[k], fam.body_b[k]
        xa, qa, _, va, wa = _body(frame, i)
        xb, qb, Rb, vb, wb = _body(frame, j)
        axis = fam.axis[k]
        if fam.rotational[k]:
            qe = _qmul(_qmul(_qconj(qb), qa), _qconj(fam.reference_rotation[k]))
            s, u = qe[0], qe[1:]
            om = Rb.T @ (wa - wb)
            g = s * axis + np.cross(u, axis)
            G = Rb @ g
            # Jdot v = d/dt (R_b g) . (w_a - w_b), d/dt (R_b g) = w_b x R_b g + R_b g'
            g_dot = -0.5 * (om @ u) * axis + np.cross(0.5 * (s * om + np.cross(om, u)), axis)
            bias = (np.cross(wb, G) + Rb @ g_dot) @ (wa - wb)
            rows.add(i, j, 2.0 * (u @ axis), np.zeros(3), G, np.zeros(3), -G, 0.0, bias)
        else:
            e, dx = Rb @ axis, xa - xb
            e_dot = np.cross(wb, e)
            # J_a = [e, 0], J_b = [-e, e x dx]; Jdot v = e'.v_a - e'.v_b + (e' x dx + e x (v_a - v_b)).w_b
            bias = e_dot @ (va - vb) + (np.cross(e_dot, dx) + np.cross(e, va - vb)) @ wb
            rows.add(i, j, e @ dx - fam.offset[k], e, np.zeros(3), -e, np.cross(e, dx), 0.0, bias)


_REFERENCES = {
    PointToPoint: _point_to_point,
    PointToNail: _point_to_nail,
    Orientation: _orientation,
    PointOnPlane: _point_on_plane,
    GearToGear: _gear_to_gear,
    GearToWeight: _gear_to_weight,
    Element: _element,
}


def reference_rows(fam, frame: BodyFrame) -> dict:
    """Rows of every instance of fam: dict of C, row_bodies, J, ct, bias, velocity_only (as in RowBlock)."""
    rows = _Rows()
    _REFERENCES[type(fam)](fam, frame, rows)
    return rows.arrays()
