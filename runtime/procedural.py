"""The procedural solver plan (PHYSICS.md section 6), in its modern form: XPBD with substeps.

Lee, Baek, Kim, Hahn (2000): (1) move every body unconstrained, (2) translate and rotate the bodies so the
constraints hold again, mass-weighted, (3) set velocities from the change of position and orientation.
Mueller et al. (2020) run the three steps on every substep hs = h / substeps with compliance alpha / hs^2.
Two changes (docs/procedural.md): corrections go along the constraint normals of the start of the substep (as in
SHAKE), which keeps energy and periods instead of damping them; and stage 2 projects all rows at once
(procedural_direct.py, one Newton step of the projection) up to DIRECT_MAX_ROWS rows, Gauss-Seidel colour sweeps
(constraints/projections.py) beyond, where a direct solve stops paying.

Plan (built once): families, rows, colours, masses, substeps. State: x, q, v, w, owned by the caller, updated in
place. Scratch: the start-of-substep Frame and the multipliers, preallocated.
`project_reference` and `direct_reference` below are the fast paths' slow, obvious twins.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from .constraints import projections as pj
from .constraints.layout import WORLD
from .procedural_direct import DirectProjection
from .rotation import quat_conjugate, quat_multiply, quat_to_matrix, skew

# default substeps per step, when the caller gives none (scenes: `solver procedural { substeps N }`)
DEFAULT_SUBSTEPS = 20
# default projections per substep: Newton steps (direct) or sweeps (Gauss-Seidel); more substeps beat more of them
DEFAULT_ITERATIONS = 1
# the direct projection up to this many live rows, Gauss-Seidel above (docs/procedural.md, "Which projection":
# a 400-link chain, 1200 rows, costs 8 ms a step with it, sparse LU)
DIRECT_MAX_ROWS = 4000
METHODS = ("auto", "direct", "gauss-seidel")
# the direct projection takes further Newton steps, up to MAX_NEWTON_STEPS in all, while the last one is estimated
# to leave an error above NEWTON_TOLERANCE (m or rad): only large substeps need them
NEWTON_TOLERANCE = 1e-6
MAX_NEWTON_STEPS = 8
# corrections go along the start-of-substep gradients (SHAKE: no energy drift) while no body turns by more than
# this in a substep; beyond, along the current gradients (a closest-point projection: dissipative, stable)
SHAKE_MAX_TURN = 0.25  # rad


@dataclass
class ProceduralPlan:
    """What is decided once. families in sweep order; offsets[f] first global row of family f (rows: family
    after family, instance after instance, 3 per point instance); compliance[f] (k_f,) in m/N (rad/(N m) for
    angular rows) and row_compliance (rows,); keep[f] (k_f,3) bool rows kept (point families) or None;
    colours[f] index arrays; inv_mass (n,); inv_inertia_body (n,3,3) (0 for bodies that are not dynamic);
    inertia_body (n,3,3) its pseudo-inverse, for the gyroscopic term; spinning: whether any dynamic body has
    unequal principal moments (else there is no gyroscopic term); method: direct or gauss-seidel."""

    families: list
    offsets: list
    rows: int
    compliance: list
    row_compliance: np.ndarray
    keep: list
    colours: list
    inv_mass: np.ndarray
    inv_inertia_body: np.ndarray
    inertia_body: np.ndarray
    spinning: bool
    substeps: int
    iterations: int
    method: str


@dataclass
class ProceduralScratch:
    """Preallocated working memory. before: the Frame of the start of the substep (x_prev, q_prev: views of its
    first n rows); now: the Frame the direct projection evaluates rows on; lam_rows (rows,) the multipliers,
    accumulated over one substep, and lam[f] the view of family f ((k,3) or (k,))."""

    before: pj.Frame
    now: pj.Frame
    lam_rows: np.ndarray
    lam: list

    @property
    def x_prev(self) -> np.ndarray:
        return self.before.x[:-1]

    @property
    def q_prev(self) -> np.ndarray:
        return self.before.q[:-1]


class ProceduralSolver:
    """XPBD substep loop over a fixed set of constraint families (the procedural plan).

    Gauss-Seidel sweeps families in the order given, each colour after the other: the family swept last ends the
    substep satisfied to round-off (when its instances share no body), the others to Gauss-Seidel tolerance; put
    the rows whose exactness matters most last (gears). The direct projection treats all rows alike.

    target: None, or (rows,) the value each row is projected to instead of 0 (self-assembly curves, written by
    the caller between substeps through on_substep). contacts: None, or an object with project(x, q, hs, before)
    and velocities(x, q, v, w, hs, before), run after stage 2 and stage 3 (procedural_sphere.py).
    """

    def __init__(self, families: Sequence, compliance: Sequence | None, inv_mass, inv_inertia_body,
                 substeps: int = DEFAULT_SUBSTEPS, iterations: int = DEFAULT_ITERATIONS, keep: Sequence | None = None,
                 method: str = "auto", contacts=None):
        inv_mass = np.asarray(inv_mass, dtype=float).reshape(-1)
        inv_inertia_body = np.asarray(inv_inertia_body, dtype=float).reshape(-1, 3, 3)
        n = len(inv_mass)
        if inv_inertia_body.shape[0] != n:
            raise ValueError(f"inv_inertia_body: expected ({n},3,3), got {inv_inertia_body.shape}")
        if substeps < 1 or iterations < 1:
            raise ValueError(f"substeps and iterations must be >= 1, got {substeps}, {iterations}")
        if method not in METHODS:
            raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
        families = list(families)
        k = [len(pj.instance_bodies(f)[0]) for f in families]
        sizes = [kf * type(f).ROWS for kf, f in zip(k, families)]
        offsets = [int(o) for o in np.cumsum([0] + sizes[:-1])] if families else []
        compliance = [np.zeros(kf) for kf in k] if compliance is None else [
            np.broadcast_to(np.asarray(c, dtype=float), (kf,)).copy() for c, kf in zip(compliance, k)]
        row_compliance = np.concatenate([np.repeat(c, type(f).ROWS) for c, f in zip(compliance, families)]
                                        ) if families else np.zeros(0)
        keep = [None] * len(families) if keep is None else [
            None if kp is None else np.asarray(kp, dtype=bool).reshape(-1, 3) for kp in keep]
        dynamic = inv_mass > 0.0
        inv_inertia_body = np.where(dynamic[:, None, None], inv_inertia_body, 0.0)
        inertia = np.linalg.pinv(inv_inertia_body) if n else np.zeros((0, 3, 3))
        principal = np.linalg.eigvalsh(inertia[dynamic]) if dynamic.any() else np.zeros((0, 3))
        self.direct = None
        if method != "gauss-seidel":
            self.direct = DirectProjection(families, offsets, keep, inv_mass)
            if method == "auto" and self.direct.size > DIRECT_MAX_ROWS:
                self.direct = None
        self.plan = ProceduralPlan(
            families=families, offsets=offsets, rows=int(sum(sizes)), compliance=compliance,
            row_compliance=row_compliance, keep=keep,
            colours=[pj.colour_instances(*pj.instance_bodies(f), dynamic=dynamic) for f in families],
            inv_mass=np.where(dynamic, inv_mass, 0.0), inv_inertia_body=inv_inertia_body, inertia_body=inertia,
            spinning=bool(np.any(np.ptp(principal, axis=1) > 1e-12 * principal.max(initial=0.0))),
            substeps=int(substeps), iterations=int(iterations),
            method="gauss-seidel" if self.direct is None else "direct")
        lam_rows = np.zeros(self.plan.rows)
        lam = [lam_rows[o:o + size].reshape(pj.lam_shape(f)) for f, o, size in zip(families, offsets, sizes)]
        self.scratch = ProceduralScratch(pj.Frame.empty(inv_mass), pj.Frame.empty(inv_mass), lam_rows, lam)
        self.target = None
        self.contacts = contacts
        self._alpha = (None, None)  # (hs, row compliance / hs^2 of the direct system's rows)

    def family_rows(self, f: int) -> slice:
        """The global rows of family f (as in target and lam_rows)."""
        fam = self.plan.families[f]
        return slice(self.plan.offsets[f], self.plan.offsets[f] + len(pj.instance_bodies(fam)[0]) * fam.ROWS)

    # ------------------------------------------------------------ the step: a list of stages

    def step(self, x, q, v, w, h: float, force, torque, on_substep: Callable[[float], None] | None = None) -> None:
        """Advance the state (x (n,3), q (n,4), v (n,3), w (n,3), in place) by h under world force and torque
        (n,3), constant over the step. on_substep(tau), if given, runs after each substep's unconstrained move,
        tau = end of that substep relative to the step's start: the place to refresh moving nails' targets and
        the self-assembly targets."""
        hs = h / self.plan.substeps
        contacts = self.contacts
        for s in range(self.plan.substeps):
            self.integrate(x, q, v, w, hs, force, torque)
            # the unconstrained move turned each body by |w| hs
            self.scratch.before.use_directions = hs * hs * (w * w).sum(axis=1).max(initial=0.0) <= SHAKE_MAX_TURN ** 2
            if on_substep is not None:
                on_substep((s + 1) * hs)
            self.project(x, q, hs)
            if contacts is not None:
                contacts.project(x, q, hs, self.scratch.before)
            self.update_velocities(x, q, v, w, hs)
            if contacts is not None:
                contacts.velocities(x, q, v, w, hs, self.scratch.before)
        if not (np.isfinite(x).all() and np.isfinite(q).all()):
            bad = np.flatnonzero(~(np.isfinite(x).all(axis=1) & np.isfinite(q).all(axis=1)))
            raise FloatingPointError(f"procedural step (h={h}): non-finite pose of bodies {bad.tolist()}")

    def integrate(self, x, q, v, w, hs, force, torque) -> None:
        """Stage 1: the unconstrained move, after saving the start of the substep. Every body moves by its
        velocity; only the dynamic ones feel forces (inverse mass and inertia 0 for the others), so a kinematic
        body glides along its path within the step, to be set exactly on it after the step."""
        p, before = self.plan, self.scratch.before
        before.refresh(x, q, slice(None), p.inv_inertia_body)
        # v += hs F / m
        v += (hs * p.inv_mass)[:, None] * force
        if p.spinning or torque.any():
            # w += hs I^-1 (tau - w x I w), I = R I_b R^T, done in the body frame: w_b = R^T w,
            # dw = hs R I_b^-1 (R^T tau - w_b x I_b w_b)
            R = before.R[:-1]
            wb = (w[:, None, :] @ R)[:, 0]
            tau_b = (torque[:, None, :] @ R)[:, 0] - pj.cross(wb, pj.matvec(p.inertia_body, wb))
            w += hs * pj.matvec(R, pj.matvec(p.inv_inertia_body, tau_b))
        x += hs * v
        q[:] = pj.turn_by(q, hs * w)

    def project(self, x, q, hs) -> None:
        """Stage 2: iterations of the direct projection, or of the Gauss-Seidel sweep."""
        s = self.scratch
        if self.direct is not None:
            d = self.direct
            d.start(s.before)
            alpha = self._direct_alpha(hs)
            target = None if self.target is None else self.target.take(d.rows)
            # the scene's iterations, and more (up to MAX_NEWTON_STEPS) while a step leaves more than NEWTON_TOLERANCE
            for i in range(max(self.plan.iterations, MAX_NEWTON_STEPS)):
                left = d.project(x, q, s.now, alpha, target)
                if i + 1 >= self.plan.iterations and left <= NEWTON_TOLERANCE:
                    break
            s.lam_rows[d.rows] = d.lam
            return
        s.lam_rows.fill(0.0)
        for _ in range(self.plan.iterations):
            self.sweep(x, q, hs)

    def _direct_alpha(self, hs):
        if self._alpha[0] != hs:
            self._alpha = (hs, self.plan.row_compliance.take(self.direct.rows) / (hs * hs))
        return self._alpha[1]

    def sweep(self, x, q, hs) -> None:
        """One Gauss-Seidel sweep, families in plan order, colours in order, each colour vectorized."""
        p, s = self.plan, self.scratch
        for f, fam in enumerate(p.families):
            kernel = pj.PROJECTIONS[type(fam)]
            extra = {"before": s.before}
            if p.keep[f] is not None:
                extra["keep"] = p.keep[f]
            if self.target is not None:
                extra["target"] = self.target[self.family_rows(f)].reshape(pj.lam_shape(fam))
            for idx in p.colours[f]:
                kernel(fam, idx, x, q, p.inv_mass, p.inv_inertia_body, p.compliance[f], hs, s.lam[f], **extra)

    def update_velocities(self, x, q, v, w, hs) -> None:
        """Stage 3: v = (x - x_prev) / hs, w = turn_since(q, q_prev) / hs (the exact inverse of stage 1's turn_by, so
        a free spinner keeps its w; Mueller et al.'s 2 vec(q q_prev^-1) / hs slows it down)."""
        s = self.scratch
        np.subtract(x, s.x_prev, out=v)
        v /= hs
        w[:] = pj.turn_since(q, s.q_prev) / hs


# ---------------------------------------------------------------- the slow, obvious reference


def project_reference(families, colours, x, q, x_prev, q_prev, inv_mass, inv_inertia_body, compliance, h, lam,
                      keep=None) -> None:
    """One Gauss-Seidel sweep like ProceduralSolver.sweep (families in order, colours in order), but one instance
    at a time with 3-vectors and rotation matrices, sharing nothing with the vectorized kernels but layout.py
    and rotation.py. As there, corrections go along the gradient at (x_prev, q_prev) and use the inverse
    inertia of that pose."""
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
                else:  # C and gradient now, and the gradient at the start of the substep (the direction)
                    bodies, C, grad = _REF_ROWS[name](fam, i, now, before)
                    direction = _REF_ROWS[name](fam, i, before, before)[2]
                    _ref_row(now, before, bodies, C, grad, direction, alpha, lam[f], i)


def direct_reference(families, x, q, x_prev, q_prev, inv_mass, inv_inertia_body, row_compliance, h, lam_rows,
                     keep=None, target=None, before_frame=None) -> None:
    """One Newton step of the projection of all rows at once, like DirectProjection.project (without its trust
    region), built the obvious way: dense J and Jd (rows x 6n, rows numbered as in ProceduralSolver) from the
    one-instance functions below, W = diag(1/m, I^-1) of (x_prev, q_prev), K = J W Jd^T + alpha~,
    dx = W Jd^T dlam. Jd = J when before_frame.use_directions is False."""
    from .procedural_direct import REGULARIZATION

    keep = [None] * len(families) if keep is None else keep
    now = _RefPoses(x, q, inv_mass, inv_inertia_body)
    before = _RefPoses(x_prev, q_prev, inv_mass, inv_inertia_body)
    rows, offset = [], 0
    for f, fam in enumerate(families):
        name = type(fam).__name__
        for i in range(len(pj.instance_bodies(fam)[0])):
            if name in ("PointToPoint", "PointToNail"):
                rows += [(offset + 3 * i + c, *row) for c, row in enumerate(_ref_point_rows(fam, i, now, before))
                         if keep[f] is None or keep[f][i][c]]
            else:
                bodies, C, grad = _REF_ROWS[name](fam, i, now, before)
                rows.append((offset + i, bodies, C, grad, _REF_ROWS[name](fam, i, before, before)[2]))
        offset += len(pj.instance_bodies(fam)[0]) * fam.ROWS
    n = len(x)
    mobile = [b for b in range(n) if inv_mass[b] > 0.0]
    rows = [r for r in rows if any(b in mobile for b in r[1])]
    if not rows:
        return
    J, Jd, W = np.zeros((len(rows), 6 * n)), np.zeros((len(rows), 6 * n)), np.zeros((6 * n, 6 * n))
    for b in mobile:
        m, I = before.inverse_mass(b)
        W[6 * b:6 * b + 3, 6 * b:6 * b + 3], W[6 * b + 3:6 * b + 6, 6 * b + 3:6 * b + 6] = m * np.eye(3), I
    use_directions = getattr(before_frame, "use_directions", True) if before_frame is not None else True
    for r, (_, (a, b), _, (la, ga, lb, gb), (da, dga, db, dgb)) in enumerate(rows):
        for body, block, direction in ((a, (la, ga), (da, dga)), (b, (lb, gb), (db, dgb))):
            if body in mobile:
                J[r, 6 * body:6 * body + 6] = np.concatenate(block)
                Jd[r, 6 * body:6 * body + 6] = np.concatenate(direction if use_directions else block)
    index = [r[0] for r in rows]
    C = np.array([r[2] for r in rows]) - (0.0 if target is None else np.asarray(target)[index])
    alpha = np.asarray(row_compliance)[index] / (h * h)
    K = J @ W @ Jd.T
    K += np.diag(REGULARIZATION * np.diag(K) + alpha)
    dlam = np.linalg.solve(K, -C - alpha * lam_rows[index])
    lam_rows[index] += dlam
    move = W @ Jd.T @ dlam
    for b in mobile:
        now.move(b, move[6 * b:6 * b + 3], move[6 * b + 3:6 * b + 6])


def _ref_point_rows(fam, i, P, before):
    """The 3 rows of a point instance: (bodies, C_c, gradient now, gradient at the start of the substep)."""
    if type(fam).__name__ == "PointToNail":
        a, b, pa, pb, target = fam.body[i], WORLD, fam.point[i], np.zeros(3), fam.target[i]
    else:
        a, b, pa, pb, target = fam.body_a[i], fam.body_b[i], fam.point_a[i], fam.point_b[i], np.zeros(3)
    ra, rb = P.rot(a) @ pa, P.rot(b) @ pb
    da, db = before.rot(a) @ pa, before.rot(b) @ pb
    C = P.pos(a) + ra - P.pos(b) - rb - target
    out = []
    for c, e in enumerate(np.eye(3)):
        out.append(((a, b), C[c], (e, np.cross(ra, e), -e, -np.cross(rb, e)),
                    (e, np.cross(da, e), -e, -np.cross(db, e))))
    return out


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


def _ref_row(P, before, bodies, C, grad, direction, alpha, lam, i):
    (a, b), (la, ga, lb, gb), (da, dga, db, dgb) = bodies, grad, direction
    ma, Ia = before.inverse_mass(a)  # inverse inertia of the start of the substep, as in projections.py
    mb, Ib = before.inverse_mass(b)
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
    ma, Ia = before.inverse_mass(a)
    mb, Ib = before.inverse_mass(b)
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


def _ref_orientation(fam, i, P, before):
    a, b = fam.body_a[i], fam.body_b[i]
    T, N = P.rot(a) @ fam.axis_a[i], P.rot(b) @ fam.axis_b[i]
    n = np.cross(T, N)
    if np.linalg.norm(n) <= pj.PARALLEL_EPS:
        n = np.cross(T, np.eye(3)[np.argmin(np.abs(T))])
    n = n / np.linalg.norm(n)
    zero = np.zeros(3)
    return (a, b), np.arcsin(min(1.0, max(-1.0, T @ N))), (zero, n, zero, -n)


def _ref_point_on_plane(fam, i, P, before):
    a, b = fam.body_a[i], fam.body_b[i]
    xa, xb = P.pos(a), P.pos(b)
    p = xa + P.rot(a) @ fam.point_a[i]
    S, N = xb + P.rot(b) @ fam.plane_point[i], P.rot(b) @ fam.plane_normal[i]
    return (a, b), N @ (p - S), (N, np.cross(p - xa, N), -N, -np.cross(p - xb, N))


def _ref_element(fam, i, P, before):
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
    """The turn since the start of the substep in the Cayley map, 2 vec(dq) / dq_w, dq = q q_prev^-1 (0 for
    WORLD)."""
    dq = quat_multiply(P.quat(b), quat_conjugate(before.quat(b)))
    return 2.0 * dq[1:] / dq[0]


def _ref_turn_jacobian(theta):
    """d theta / d phi = I - [theta]x / 2 + theta theta^T / 4 (theta of q turned by a small world dphi)."""
    return np.eye(3) - 0.5 * skew(theta) + 0.25 * np.outer(theta, theta)


def _ref_gear_to_gear(fam, i, P, before):
    a, b = fam.body_a[i], fam.body_b[i]
    ta, tb = _ref_turn(P, before, a), _ref_turn(P, before, b)
    Aa, Ab = P.rot(a) @ fam.axis_a[i], P.rot(b) @ fam.axis_b[i]
    ra, rb = fam.radius_a[i], fam.radius_b[i]
    zero = np.zeros(3)
    # C = r_a theta_a . A_a + r_b theta_b . A_b; g = r (J^T A + A x theta), J = d theta / d phi
    ga = ra * (_ref_turn_jacobian(ta).T @ Aa + np.cross(Aa, ta))
    gb = rb * (_ref_turn_jacobian(tb).T @ Ab + np.cross(Ab, tb))
    return (a, b), ra * (ta @ Aa) + rb * (tb @ Ab), (zero, ga, zero, gb)


def _ref_gear_to_weight(fam, i, P, before):
    g, wt = fam.gear[i], fam.weight[i]
    theta = _ref_turn(P, before, g)
    d = fam.direction[i]
    u = np.cross(fam.arm[i], d)
    zero = np.zeros(3)
    C = theta @ u - (P.pos(wt) - before.pos(wt)) @ d
    return (g, wt), C, (zero, _ref_turn_jacobian(theta).T @ u, -d, zero)


_REF_ROWS = {
    "Orientation": _ref_orientation,
    "PointOnPlane": _ref_point_on_plane,
    "Element": _ref_element,
    "GearToGear": _ref_gear_to_gear,
    "GearToWeight": _ref_gear_to_weight,
}
