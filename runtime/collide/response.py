"""Impulses (Hahn 1988; Moore & Wilhelms 1988), solved together with the active joint rows (docs/design/physics.md
section 5).

Rows. A contact c between bodies a and b, normal n (from b to a), arms r_a = p - x_a, r_b = p - x_b, has a
normal row and, with friction, two tangent rows, each direction d with Jacobian blocks

    J_a = [d, r_a x d],  J_b = [-d, -(r_b x d)]       u = J V = d . (v_a + w_a x r_a - v_b - w_b x r_b)

(u > 0: separating). Joint rows are the constraints' own rows (J, ct at the current pose) with the target
J V+ + ct = 0: an impulse never opens a joint.

Joints kept exact. With A = J M^-1 J^T over [joint rows j; contact rows c] and impulses lam:

    A_jj lam_j + A_jc lam_c = -(J_j V + ct) = r_j     (joints hold after the impulse)
    u_c+ = J_c V + A_cj lam_j + A_cc lam_c

Eliminating lam_j = A_jj^+ (r_j - A_jc lam_c) leaves the contact problem of lcp.py on the Schur complement
    W = A_cc - A_cj A_jj^+ A_jc,   u0 = J_c V + A_cj A_jj^+ r_j
(the contact rows as seen through the joints: a ball on a string is as heavy as the string lets it be).
Each island (bodies linked by contacts and joints) is solved on its own, dense.

Impacts propagate (Newton's cradle). Contacts approaching faster than the resting speed are impacts. They are
resolved in generations: the impacts of a generation are solved together, targets u+ >= -e u-, with the
contacts that are not approaching left out; what that generation sets in motion is the next generation's
impacts (ball 1 moves into ball 2 ...). A simultaneous solve of the whole row instead would let the four
touching balls leave together. A flat box landing on four corners is one generation, so it does not spin.
Then one resting pass over every contact with restitution 0 (targets u+ >= 0, or >= -gap/h for a contact
still apart by gap), which leaves no contact approaching.

Contacts that last are not impulses: they are rows of the step (runtime/core/contact.py, collide/contacts.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.solve import RANK_RTOL
from .mass_matrix import apply_inverse_mass, assemble_dense
from . import lcp

# contacts in an island are re-solved at most this many generations per impact (then restitution 0)
MAX_GENERATIONS = 64
# a generation of impacts may give the kinetic energy this fraction of itself (round-off) before it is taken again
# without restitution: Newton's law at several points at once is not bound to lose energy, and through joints
# that nearly lock the points' rows (a chain's link striking the link after next, its impulse 15 N s at 0.18 m/s)
# it gave a chain of 8 capsules 0.58 J, 7 % of what its fall makes available (found 2026-12-07)
ENERGY_RTOL = 1e-9


@dataclass
class Contacts:
    """k contact points. a, b (k,) body indices; point, normal (k,3) (normal from b toward a); depth (k,) m;
    pair (k,) index of the body pair in the step's pair list; mu, e (k,) friction and restitution; feature (k,)
    which corner, end or edge made the point (narrow.py), None when not known."""

    a: np.ndarray
    b: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    pair: np.ndarray
    mu: np.ndarray
    e: np.ndarray
    feature: np.ndarray | None = None

    def __len__(self):
        return len(self.a)

    def subset(self, mask) -> "Contacts | None":
        """The contacts where mask holds, or None if there are none."""
        return _take(self, np.flatnonzero(mask)) if np.any(mask) else None


@dataclass
class Outcome:
    """Per contact: impulse (k,) total normal impulse, N s; impact (k,) resolved as an impact; approach (k,)
    normal approach speed before (m/s, > 0 approaching); slip_before, slip_after (k,) tangential speeds, m/s."""

    impulse: np.ndarray
    impact: np.ndarray
    approach: np.ndarray
    slip_before: np.ndarray
    slip_after: np.ndarray


@dataclass
class Joints:
    """The active joint rows at this pose: J (m,2,6), rb (m,2) body indices (-1 world), ct (m,)."""

    J: np.ndarray
    rb: np.ndarray
    ct: np.ndarray

    @classmethod
    def none(cls):
        return cls(np.zeros((0, 2, 6)), np.zeros((0, 2), np.int64), np.zeros(0))


class Bodies:
    """What the solve reads and writes: velocities v, w (n,3) (the live state, changed in place), inverse mass
    (n,), world inverse inertia (n,3,3), dynamic (n,) bool."""

    def __init__(self, v, w, inv_mass, inv_inertia, dynamic):
        self.v, self.w, self.inv_mass, self.inv_inertia, self.dynamic = v, w, inv_mass, inv_inertia, dynamic

    def slot(self, body):
        """Body indices as solver slots: -1 for bodies that do not move (static, kinematic)."""
        body = np.asarray(body)
        return np.where((body >= 0) & self.dynamic[np.maximum(body, 0)], body, -1)


def cross(a, b):
    """a x b for stacks (..., 3), written out (numpy's cross moves axes around: slow on small stacks)."""
    out = np.empty(np.broadcast_shapes(np.shape(a), np.shape(b)))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


# ---- rows --------------------------------------------------------------------------------------------------

def tangent_basis(normal, slip):
    """Unit t1, t2 (k,3) perpendicular to the normals; t1 along the slip where there is one."""
    slip_speed = np.linalg.norm(slip, axis=1)
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    fallback = cross(normal, helper)
    fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
    moving = slip_speed > 1e-12
    t1 = np.where(moving[:, None], slip / np.where(moving, slip_speed, 1.0)[:, None], fallback)
    return t1, cross(normal, t1)


def contact_rows(c: Contacts, x, directions):
    """J (k,2,6) of rows along directions (k,3) at each contact."""
    ra, rb = c.point - x[c.a], c.point - x[c.b]
    J = np.empty((len(c), 2, 6))
    J[:, 0, :3], J[:, 0, 3:] = directions, cross(ra, directions)
    J[:, 1, :3], J[:, 1, 3:] = -directions, -cross(rb, directions)
    return J


def row_velocity(J, bodies_ab, v, w):
    """u = J V for rows (m,2,6) on bodies (m,2) (-1: world, at rest)."""
    u = np.zeros(len(J))
    for s in range(2):
        body = bodies_ab[:, s]
        inside = body >= 0
        safe = np.maximum(body, 0)
        part = np.einsum("ri,ri->r", J[:, s, :3], v[safe]) + np.einsum("ri,ri->r", J[:, s, 3:], w[safe])
        u += np.where(inside, part, 0.0)
    return u


def relative_velocity(c: Contacts, x, v, w):
    """Velocity of a's point relative to b's point at each contact, (k,3)."""
    ra, rb = c.point - x[c.a], c.point - x[c.b]
    return v[c.a] + cross(w[c.a], ra) - v[c.b] - cross(w[c.b], rb)


# ---- the solve -------------------------------------------------------------------------------------------------

class Response:
    """Impulses for one set of contacts at one pose (x fixed), written into bodies.v, bodies.w."""

    def __init__(self, contacts: Contacts, x, bodies: Bodies, joints: Joints):
        self.c, self.x, self.bodies, self.joints = contacts, x, bodies, joints
        k = len(contacts)
        vrel = relative_velocity(contacts, x, bodies.v, bodies.w)
        un = np.einsum("ki,ki->k", vrel, contacts.normal)
        slip = vrel - un[:, None] * contacts.normal
        t1, t2 = tangent_basis(contacts.normal, slip)
        f = np.flatnonzero(contacts.mu > 0)
        # rows: the k normal rows, then t1, t2 of every contact with friction
        directions = np.concatenate([contacts.normal, np.stack([t1[f], t2[f]], axis=1).reshape(-1, 3)])
        owner = np.concatenate([np.arange(k), np.repeat(f, 2)])
        self.J = contact_rows(_take(contacts, owner), x, directions)
        self.rows_ab = np.stack([contacts.a[owner], contacts.b[owner]], axis=1)
        self.tangent_of = np.full(k, -1, np.int64)
        self.tangent_of[f] = k + 2 * np.arange(len(f))
        self.outcome = Outcome(np.zeros(k), np.zeros(k, bool), -un, np.linalg.norm(slip, axis=1), np.zeros(k))
        self._islands = _islands(contacts, joints, bodies)
        self._delassus = {}  # island contacts -> (W, X_c) of the last solve over all of them (resting pass)

    def velocity(self):
        return row_velocity(self.J, self.rows_ab, self.bodies.v, self.bodies.w)

    def impacts(self, resting_speed: float) -> None:
        """Generations of impacts with restitution (module docstring). A generation whose impulses gave kinetic
        energy is taken again without restitution (`_kinetic`), unless something driven may have given it (`_driven`)."""
        c, b = self.c, self.bodies
        # (the kinetic energy is watched where nothing driven may give it: each body's inertia inverted once)
        inertia = None if self._driven() else _inertia(b)
        for _ in range(MAX_GENERATIONS):
            u = self.velocity()
            hit = u[: len(c)] < -resting_speed
            if not hit.any():
                return
            self.outcome.impact |= hit
            # an impact set off by another (ball 2 of the cradle) approached at its generation's speed
            np.maximum(self.outcome.approach, np.where(hit, -u[: len(c)], -np.inf), out=self.outcome.approach)
            if inertia is None:
                self._solve(hit, -c.e * u[: len(c)], friction=True)
                continue
            v, w, impulse, energy = b.v.copy(), b.w.copy(), self.outcome.impulse.copy(), _kinetic(b, inertia)
            self._solve(hit, -c.e * u[: len(c)], friction=True)
            if _kinetic(b, inertia) > energy * (1.0 + ENERGY_RTOL):
                b.v[:], b.w[:], self.outcome.impulse[:] = v, w, impulse
                self._solve(hit, np.zeros(len(c)), friction=True)

    def _driven(self) -> bool:
        """Whether the impulses may rightly give energy: a contact's body that they do not move moves (a kinematic
        path, a static body given a velocity: a wall moving at 1 m/s sends a ball off at 1.5 m/s, e = 0.5), or a
        joint row is driven (its ct)."""
        b, ends = self.bodies, np.concatenate([self.c.a, self.c.b])
        still = ends[(ends >= 0) & ~b.dynamic[np.maximum(ends, 0)]]
        return bool(np.any(b.v[still]) or np.any(b.w[still]) or np.any(self.joints.ct))

    def resting(self) -> None:
        """Every contact, restitution 0: none is left approaching."""
        self._solve(np.ones(len(self.c), bool), np.zeros(len(self.c)), friction=True)
        vrel = relative_velocity(self.c, self.x, self.bodies.v, self.bodies.w)
        un = np.einsum("ki,ki->k", vrel, self.c.normal)
        self.outcome.slip_after = np.linalg.norm(vrel - un[:, None] * self.c.normal, axis=1)

    def _solve(self, chosen, target_normal, friction: bool) -> None:
        for island_contacts, island_joints in self._islands:
            sel = island_contacts[chosen[island_contacts]]
            if not len(sel):
                continue
            rows = self._rows_of(sel, friction)
            target = np.zeros(len(rows))
            target[: len(sel)] = target_normal[sel]
            lam_c, lam_j = self._island_impulses(rows, island_joints, target, sel, friction)
            self._apply(rows, island_joints, lam_c, lam_j)
            self.outcome.impulse[sel] += lam_c[: len(sel)]

    def _rows_of(self, sel, friction):
        if not friction:
            return sel
        t = self.tangent_of[sel]
        t = t[t >= 0]
        return np.concatenate([sel, np.stack([t, t + 1], axis=1).reshape(-1)])

    def _island_impulses(self, rows, joint_rows, target, sel, friction):
        b = self.bodies
        Jc, rbc = self.J[rows], b.slot(self.rows_ab[rows])
        uc = row_velocity(self.J[rows], self.rows_ab[rows], b.v, b.w)
        tangent = np.full(len(sel), -1, np.int64)
        if friction:
            has = self.tangent_of[sel] >= 0
            tangent[has] = len(sel) + 2 * np.arange(int(has.sum()))
        mu = self.c.mu[sel]
        if not len(joint_rows):
            W = assemble_dense(Jc, rbc, b.inv_mass, b.inv_inertia)
            self._delassus[sel.tobytes()] = (W, None)
            return lcp.solve(W, uc, target, mu, tangent), np.zeros(0)
        j = self.joints
        Jj, rbj = j.J[joint_rows], b.slot(j.rb[joint_rows])
        r_j = -(row_velocity(Jj, rbj, b.v, b.w) + j.ct[joint_rows])
        W, u0, back, X_c = schur(Jj, rbj, Jc, rbc, b, r_j, uc)
        self._delassus[sel.tobytes()] = (W, X_c)
        lam_c = lcp.solve(W, u0, target, mu, tangent)
        return lam_c, back(lam_c)

    def _apply(self, rows, joint_rows, lam_c, lam_j) -> None:
        b = self.bodies
        apply_impulses(self.J[rows], b.slot(self.rows_ab[rows]), lam_c, b, b.v, b.w)
        if len(joint_rows):
            apply_impulses(self.joints.J[joint_rows], b.slot(self.joints.rb[joint_rows]), lam_j, b, b.v, b.w)


def _inertia(bodies: Bodies) -> tuple:
    """(the bodies impulses move, their world inertias: the inverses of their world inverse inertias)."""
    moving = bodies.dynamic & (bodies.inv_mass > 0)
    return moving, np.linalg.inv(bodies.inv_inertia[moving])


def _kinetic(bodies: Bodies, inertia: tuple) -> float:
    """1/2 m v^2 + 1/2 w . I w over the bodies impulses move (`_inertia`)."""
    moving, I = inertia
    v, w = bodies.v[moving], bodies.w[moving]
    spin = np.einsum("kij,kj,ki->", I, w, w)
    return 0.5 * (float((np.einsum("ki,ki->k", v, v) / bodies.inv_mass[moving]).sum()) + float(spin))


def schur(Jj, rbj, Jc, rbc, bodies: Bodies, r_j, uc):
    """W, u0 of the contact rows with the joint rows eliminated, and back(lam_c) -> lam_j (module docstring)."""
    m = len(Jj)
    A = assemble_dense(np.concatenate([Jj, Jc]), np.concatenate([rbj, rbc]), bodies.inv_mass,
                                bodies.inv_inertia)
    Ajj, Ajc, Acc = A[:m, :m], A[:m, m:], A[m:, m:]
    # X = A_jj^+ [r_j, A_jc]: Cholesky, or the pseudo-inverse for redundant joints
    X = _joint_solve(Ajj, np.column_stack([r_j, Ajc]))
    x_r, X_c = X[:, 0], X[:, 1:]
    W = Acc - Ajc.T @ X_c
    W = 0.5 * (W + W.T)
    u0 = uc + Ajc.T @ x_r
    return W, u0, lambda lam_c: x_r - X_c @ lam_c, X_c


def _joint_solve(A, B):
    scale = float(np.max(np.diag(A), initial=0.0))
    if scale > 0:
        factor = lcp.cholesky(A)
        if factor is not None and float(np.min(np.diag(factor))) ** 2 > RANK_RTOL * scale:
            return lcp.cholesky_solve(factor, B)
    w, V = np.linalg.eigh(A)
    keep = w > RANK_RTOL * max(scale, 1e-300)
    return V[:, keep] @ ((V[:, keep].T @ B) / w[keep, None])


def apply_impulses(J, slots, lam, bodies: Bodies, v, w) -> None:
    """v, w += M^-1 J^T lam, per body (slots -1 skipped)."""
    MJ = apply_inverse_mass(J, slots, bodies.inv_mass, bodies.inv_inertia)
    for s in range(2):
        inside = slots[:, s] >= 0
        if not inside.any():
            continue
        body = slots[inside, s]
        change = MJ[inside, s, :] * lam[inside, None]
        np.add.at(v, body, change[:, :3])
        np.add.at(w, body, change[:, 3:])


def _take(c: Contacts, index) -> Contacts:
    return Contacts(c.a[index], c.b[index], c.point[index], c.normal[index], c.depth[index], c.pair[index],
                    c.mu[index], c.e[index], None if c.feature is None else c.feature[index])


def _islands(c: Contacts, joints: Joints, bodies: Bodies) -> list:
    """[(contact indices, joint row indices)] per island: dynamic bodies linked by contacts or joint rows
    (connected components). Static, kinematic and world slots link nothing: they do not move."""
    sa, sb = bodies.slot(c.a), bodies.slot(c.b)
    rb = bodies.slot(joints.rb).reshape(-1, 2)
    ends = np.concatenate([np.stack([sa, sb], axis=1), rb])
    # a slot that does not move is replaced by the row's other body: the edge becomes a self-loop
    ends = np.where(ends < 0, ends[:, ::-1], ends)
    ends = ends[ends[:, 0] >= 0]
    label = _components(ends, len(bodies.dynamic))
    contact_label = label[np.maximum(sa, sb)]
    joint_body = np.max(rb, axis=1)
    joint_label = np.where(joint_body >= 0, label[np.maximum(joint_body, 0)], -1)
    return [(np.flatnonzero(contact_label == root), np.flatnonzero(joint_label == root))
            for root in dict.fromkeys(contact_label.tolist())]


def _components(edges, n) -> np.ndarray:
    """Connected-component label (n,) of every body; scipy for many edges, a union-find for a few."""
    if len(edges) > 256:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        return connected_components(graph, directed=False)[1]
    parent = {}

    def find(i):
        while parent.setdefault(i, i) != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in edges.tolist():
        parent[find(i)] = find(j)
    label = np.arange(n)
    for i in list(parent):
        label[i] = find(i)
    return label
