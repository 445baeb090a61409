"""The procedural solver plan (PHYSICS.md section 6), in its modern form: XPBD with substeps.

Lee, Baek, Kim, Hahn (2000): (1) move every body unconstrained, (2) translate and rotate the bodies so the
constraints hold again, mass-weighted, (3) set velocities from the change of position and orientation.
Mueller et al. (2020) run the three steps on every substep hs = h / substeps with compliance alpha / hs^2;
one projection sweep per substep (iterations = 1) is usually best, since substeps also shrink the errors the
sweep has to remove.

Plan (built once): families, colours, masses, substeps. State: x, q, v, w, owned by the caller, updated in
place. Scratch: x_prev, q_prev and the multipliers, preallocated. The projections themselves live in
constraints/projections.py; `project_reference` below is their slow, obvious twin (one instance at a time).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .constraints import projections as pj
from .constraints.layout import WORLD, PointToNail, PointToPoint
from .rotation import quat_conjugate, quat_integrate, quat_multiply, quat_to_matrix, skew

# default number of substeps per step: at h = 1/60 a 1 m pendulum keeps its period to ~2e-4, chains to 1e-4 m
DEFAULT_SUBSTEPS = 20
# default number of projection sweeps per substep (Mueller et al.: more substeps beat more iterations)
DEFAULT_ITERATIONS = 1


@dataclass
class ProceduralPlan:
    """What is decided once. families in sweep order; compliance[f] (k_f,) in m/N (rad/(N m) for angular rows);
    keep[f] (k_f,3) bool rows kept (point families) or None; colours[f] index arrays; inv_mass (n,);
    inv_inertia_body (n,3,3); inertia_body (n,3,3) (pseudo-inverse, for the gyroscopic term); moving (m,) indices
    of the bodies with inverse mass > 0."""

    families: list
    compliance: list
    keep: list
    colours: list
    inv_mass: np.ndarray
    inv_inertia_body: np.ndarray
    moving: slice | np.ndarray
    moving_inv_mass: np.ndarray
    moving_inertia_body: np.ndarray
    moving_inv_inertia_body: np.ndarray
    substeps: int
    iterations: int


@dataclass
class ProceduralScratch:
    """Preallocated working memory: before, the Frame of the start of the substep (x_prev, q_prev are views of
    its first n rows); lam[f] the XPBD multipliers of family f."""

    before: pj.Frame
    lam: list = field(default_factory=list)

    @property
    def x_prev(self) -> np.ndarray:
        return self.before.x[:-1]

    @property
    def q_prev(self) -> np.ndarray:
        return self.before.q[:-1]


class ProceduralSolver:
    """XPBD substep loop over a fixed set of constraint families (the procedural plan)."""

    def __init__(self, families: Sequence, compliance: Sequence | None, inv_mass, inv_inertia_body,
                 substeps: int = DEFAULT_SUBSTEPS, iterations: int = DEFAULT_ITERATIONS, keep: Sequence | None = None):
        inv_mass = np.asarray(inv_mass, dtype=float).reshape(-1)
        inv_inertia_body = np.asarray(inv_inertia_body, dtype=float).reshape(-1, 3, 3)
        n = len(inv_mass)
        if inv_inertia_body.shape[0] != n:
            raise ValueError(f"inv_inertia_body: expected ({n},3,3), got {inv_inertia_body.shape}")
        if substeps < 1 or iterations < 1:
            raise ValueError(f"substeps and iterations must be >= 1, got {substeps}, {iterations}")
        families = list(families)
        k = [len(pj.instance_bodies(f)[0]) for f in families]
        compliance = [np.zeros(kf) for kf in k] if compliance is None else [
            np.broadcast_to(np.asarray(c, dtype=float), (kf,)).copy() for c, kf in zip(compliance, k)]
        keep = [None] * len(families) if keep is None else list(keep)
        dynamic = inv_mass > 0.0
        moving = slice(None) if dynamic.all() else np.flatnonzero(dynamic)
        self.plan = ProceduralPlan(
            families=families,
            compliance=compliance,
            keep=keep,
            colours=[pj.colour_instances(*pj.instance_bodies(f), dynamic=dynamic) for f in families],
            inv_mass=inv_mass,
            inv_inertia_body=inv_inertia_body,
            moving=moving,
            moving_inv_mass=inv_mass[moving].copy(),
            moving_inertia_body=np.linalg.pinv(inv_inertia_body[moving]),
            moving_inv_inertia_body=inv_inertia_body[moving].copy(),
            substeps=int(substeps),
            iterations=int(iterations),
        )
        self.scratch = ProceduralScratch(pj.Frame.empty(n), [np.zeros(pj.lam_shape(f)) for f in families])
        # keyword arguments per family, bound once to the scratch buffers
        self._extra = [self._extra_arguments(f, kp) for f, kp in zip(families, keep)]

    def _extra_arguments(self, fam, keep) -> dict:
        extra = {"before": self.scratch.before}
        if isinstance(fam, (PointToPoint, PointToNail)) and keep is not None:
            extra["keep"] = np.asarray(keep, dtype=bool).reshape(-1, 3)
        return extra

    # ------------------------------------------------------------ the step: a list of stages

    def step(self, x, q, v, w, h: float, force, torque, on_substep: Callable[[float], None] | None = None) -> None:
        """Advance the state (x (n,3), q (n,4), v (n,3), w (n,3), in place) by h under world force and torque
        (n,3), constant over the step. on_substep(tau), if given, runs after each substep's unconstrained move,
        tau = end of that substep relative to the step's start: the place to refresh moving nails' targets."""
        hs = h / self.plan.substeps
        for s in range(self.plan.substeps):
            self.integrate(x, q, v, w, hs, force, torque)
            if on_substep is not None:
                on_substep((s + 1) * hs)
            for lam in self.scratch.lam:
                lam.fill(0.0)
            for _ in range(self.plan.iterations):
                self.sweep(x, q, hs)
            self.update_velocities(x, q, v, w, hs)
        if not (np.isfinite(x).all() and np.isfinite(q).all()):
            bad = np.flatnonzero(~(np.isfinite(x).all(axis=1) & np.isfinite(q).all(axis=1)))
            raise FloatingPointError(f"procedural step (h={h}): non-finite pose of bodies {bad.tolist()}")

    def integrate(self, x, q, v, w, hs, force, torque) -> None:
        """Stage 1: the unconstrained move of the moving bodies; saves x_prev, q_prev."""
        p, m = self.plan, self.plan.moving
        # v += hs F / m
        v[m] += hs * p.moving_inv_mass[:, None] * force[m]
        # w += hs I^-1 (tau - w x I w), I = R I_b R^T, done in the body frame: w_b = R^T w,
        # dw = hs R I_b^-1 (R^T tau - w_b x I_b w_b)
        R = pj.rotation_matrix(q[m])
        Rt = R.transpose(0, 2, 1)
        wb = pj.matvec(Rt, w[m])
        tau_b = pj.matvec(Rt, torque[m]) - pj.cross(wb, pj.matvec(p.moving_inertia_body, wb))
        w[m] += hs * pj.matvec(R, pj.matvec(p.moving_inv_inertia_body, tau_b))
        self.scratch.before.refresh(x, q, m, p.moving_inv_inertia_body)
        x[m] += hs * v[m]
        q[m] = quat_integrate(q[m], w[m], hs)

    def sweep(self, x, q, hs) -> None:
        """Stage 2: one Gauss-Seidel sweep, families in plan order, colours in order, each colour vectorized."""
        p, lam = self.plan, self.scratch.lam
        for f, fam in enumerate(p.families):
            kernel = pj.PROJECTIONS[type(fam)]
            for idx in p.colours[f]:
                kernel(fam, idx, x, q, p.inv_mass, p.inv_inertia_body, p.compliance[f], hs, lam[f], **self._extra[f])

    def update_velocities(self, x, q, v, w, hs) -> None:
        """Stage 3: v = (x - x_prev) / hs, w = 2 vec(q q_prev^-1) / hs with the scalar part made >= 0."""
        m, s = self.plan.moving, self.scratch
        v[m] = (x[m] - s.x_prev[m]) / hs
        _, turn = pj.turn_since(q[m], s.q_prev[m])
        w[m] = (2.0 / hs) * turn


# ---------------------------------------------------------------- the slow, obvious reference


def project_reference(families, colours, x, q, x_prev, q_prev, inv_mass, inv_inertia_body, compliance, h, lam,
                      keep=None) -> None:
    """One Gauss-Seidel sweep like ProceduralSolver.sweep (families in order, colours in order), but one instance
    at a time with 3-vectors and rotation matrices, sharing nothing with the vectorized kernels but layout.py
    and rotation.py. Corrections go along the gradient at (x_prev, q_prev) as in projections.py."""
    keep = [None] * len(families) if keep is None else keep
    now = _RefPoses(x, q, inv_mass, inv_inertia_body)
    before = _RefPoses(x_prev, q_prev, inv_mass, inv_inertia_body)
    for f, fam in enumerate(families):
        name = type(fam).__name__
        for idx in colours[f]:
            for i in idx.tolist():
                alpha = compliance[f][i] / (h * h)
                if name in ("PointToPoint", "PointToNail"):
                    _ref_point(fam, i, now, before, alpha, lam[f], None if keep[f] is None else keep[f][i])
                elif name in ("GearToGear", "GearToWeight"):
                    bodies, C, grad = _REF_ROWS[name](fam, i, now, before)
                    _ref_row(now, bodies, C, grad, grad, alpha, lam[f], i)
                else:
                    bodies, C, grad = _REF_ROWS[name](fam, i, now)
                    _ref_row(now, bodies, C, grad, _REF_ROWS[name](fam, i, before)[2], alpha, lam[f], i)


class _RefPoses:
    """Scalar access to one body at a time; WORLD is identity, bodies with inverse mass 0 never move."""

    def __init__(self, x, q, inv_mass, inv_inertia_body):
        self.x, self.q, self.inv_mass, self.inv_ib = x, q, inv_mass, inv_inertia_body

    def pos(self, b):
        return np.zeros(3) if b == WORLD else self.x[b].copy()

    def quat(self, b):
        return np.array([1.0, 0.0, 0.0, 0.0]) if b == WORLD else self.q[b].copy()

    def rot(self, b):
        return quat_to_matrix(self.quat(b))

    def inverse_mass(self, b):
        """(1/m, world I^-1), zero for WORLD and for bodies that do not move."""
        if b == WORLD or self.inv_mass[b] <= 0.0:
            return 0.0, np.zeros((3, 3))
        R = self.rot(b)
        return self.inv_mass[b], R @ self.inv_ib[b] @ R.T

    def move(self, b, dx, dphi):
        if b == WORLD or self.inv_mass[b] <= 0.0:
            return
        self.x[b] += dx
        # q += 0.5 (0, dphi) q, renormalized
        qn = self.q[b] + 0.5 * quat_multiply(np.concatenate(([0.0], dphi)), self.q[b])
        self.q[b] = qn / np.linalg.norm(qn)


def _ref_row(P, bodies, C, grad, direction, alpha, lam, i):
    (a, b), (la, ga, lb, gb), (da, dga, db, dgb) = bodies, grad, direction
    ma, Ia = P.inverse_mass(a)
    mb, Ib = P.inverse_mass(b)
    w = ma * (la @ la) + ga @ Ia @ ga + mb * (lb @ lb) + gb @ Ib @ gb
    wd = ma * (la @ da) + ga @ Ia @ dga + mb * (lb @ db) + gb @ Ib @ dgb
    if wd > pj.MIN_DIRECTION_ALIGNMENT * w:
        la, ga, lb, gb, w = da, dga, db, dgb, wd
    if w + alpha <= 0.0:
        return
    dlam = (-C - alpha * lam[i]) / (w + alpha)
    lam[i] += dlam
    P.move(a, ma * dlam * la, dlam * (Ia @ ga))
    P.move(b, mb * dlam * lb, dlam * (Ib @ gb))


def _ref_point(fam, i, P, before, alpha, lam, keep):
    if type(fam).__name__ == "PointToNail":
        a, b, pa, pb, target = fam.body[i], WORLD, fam.point[i], np.zeros(3), fam.target[i]
    else:
        a, b, pa, pb, target = fam.body_a[i], fam.body_b[i], fam.point_a[i], fam.point_b[i], np.zeros(3)
    ra, rb = P.rot(a) @ pa, P.rot(b) @ pb
    C = P.pos(a) + ra - P.pos(b) - rb - target
    da, db = before.rot(a) @ pa, before.rot(b) @ pb
    da = da if da @ ra >= pj.MIN_DIRECTION_ALIGNMENT * (ra @ ra) else ra
    db = db if db @ rb >= pj.MIN_DIRECTION_ALIGNMENT * (rb @ rb) else rb
    ma, Ia = P.inverse_mass(a)
    mb, Ib = P.inverse_mass(b)
    # K = sum_s I3 / m_s - [r_s]x I_s^-1 [d_s]x
    K = (ma + mb) * np.eye(3) - skew(ra) @ Ia @ skew(da) - skew(rb) @ Ib @ skew(db)
    rows = [r for r in range(3) if (keep is None or keep[r]) and K[r, r] > 0.0]
    dlam = np.zeros(3)
    if rows:
        sub = K[np.ix_(rows, rows)] + alpha * np.eye(len(rows))
        dlam[rows] = np.linalg.solve(sub, -C[rows] - alpha * lam[i][rows])
    lam[i] += dlam
    P.move(a, ma * dlam, Ia @ np.cross(da, dlam))
    P.move(b, -mb * dlam, -(Ib @ np.cross(db, dlam)))


def _ref_orientation(fam, i, P):
    a, b = fam.body_a[i], fam.body_b[i]
    T, N = P.rot(a) @ fam.axis_a[i], P.rot(b) @ fam.axis_b[i]
    n = np.cross(T, N)
    if np.linalg.norm(n) <= pj.PARALLEL_EPS:
        n = np.cross(T, np.eye(3)[np.argmin(np.abs(T))])
    n = n / np.linalg.norm(n)
    zero = np.zeros(3)
    return (a, b), np.arcsin(min(1.0, max(-1.0, T @ N))), (zero, n, zero, -n)


def _ref_point_on_plane(fam, i, P):
    a, b = fam.body_a[i], fam.body_b[i]
    xa, xb = P.pos(a), P.pos(b)
    p = xa + P.rot(a) @ fam.point_a[i]
    S, N = xb + P.rot(b) @ fam.plane_point[i], P.rot(b) @ fam.plane_normal[i]
    return (a, b), N @ (p - S), (N, np.cross(p - xa, N), -N, -np.cross(p - xb, N))


def _ref_element(fam, i, P):
    a, b = fam.body_a[i], fam.body_b[i]
    zero = np.zeros(3)
    if not fam.rotational[i]:
        e, d = P.rot(b) @ fam.axis[i], P.pos(a) - P.pos(b)
        return (a, b), e @ d - fam.offset[i], (e, zero, -e, -np.cross(d, e))
    err = quat_multiply(quat_multiply(quat_conjugate(P.quat(b)), P.quat(a)),
                        quat_conjugate(fam.reference_rotation[i]))
    err = -err if err[0] < 0.0 else err
    axis = fam.axis[i]
    g = P.rot(b) @ (err[0] * axis + np.cross(err[1:], axis))
    return (a, b), 2.0 * err[1:] @ axis, (zero, g, zero, -g)


def _ref_turn(P, before, b):
    """(s, v) of q q_prev^-1 with s >= 0 (no turn for WORLD)."""
    dq = quat_multiply(P.quat(b), quat_conjugate(before.quat(b)))
    dq = -dq if dq[0] < 0.0 else dq
    return dq[0], dq[1:]


def _ref_gear_to_gear(fam, i, P, before):
    a, b = fam.body_a[i], fam.body_b[i]
    (sa, va), (sb, vb) = _ref_turn(P, before, a), _ref_turn(P, before, b)
    Aa, Ab = P.rot(a) @ fam.axis_a[i], P.rot(b) @ fam.axis_b[i]
    ra, rb = fam.radius_a[i], fam.radius_b[i]
    zero = np.zeros(3)
    C = 2.0 * (ra * (va @ Aa) + rb * (vb @ Ab))
    return (a, b), C, (zero, ra * (sa * Aa + np.cross(Aa, va)), zero, rb * (sb * Ab + np.cross(Ab, vb)))


def _ref_gear_to_weight(fam, i, P, before):
    g, wt = fam.gear[i], fam.weight[i]
    s, v = _ref_turn(P, before, g)
    d = fam.direction[i]
    u = np.cross(fam.arm[i], d)
    zero = np.zeros(3)
    C = 2.0 * (v @ u) - (P.pos(wt) - before.pos(wt)) @ d
    return (g, wt), C, (zero, s * u + np.cross(v, u), -d, zero)


_REF_ROWS = {
    "Orientation": _ref_orientation,
    "PointOnPlane": _ref_point_on_plane,
    "Element": _ref_element,
    "GearToGear": _ref_gear_to_gear,
    "GearToWeight": _ref_gear_to_weight,
}
