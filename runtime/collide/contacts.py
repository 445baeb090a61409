"""The contacts of a run that last: which points of which body pairs touch, how (sticking, sliding, without
friction), and the rows that hold them in the compiled step (core/contact.py states their equations).

A contact is found by the narrow phase (narrow.py: point, normal from b toward a, depth, feature) and kept from
one look to the next by its key (a, b, feature), so that a sticking point keeps its anchor (where it stuck) and
nothing creeps. It becomes rows of the constraint table, after the joints' (`write`):
  * a sphere's (or a capsule's end's) centre and radius, or a point of any other shape (a corner), on a face of
    b: b's plane through the touching point (a box's face: its centre, axes and half extents, so that the kernel
    sees the point leave the face), or the tangent plane of a curved b (valid near the point only: a short face);
  * two spheres: their centres and the sum of their radii;
  * rows: the normal one; with friction and sticking, two tangent rows (anchored for a point, rolling for a
    sphere); sliding: the normal row and the friction coefficient (a force in the solve), T1 along the slip.
The pair states the kernel watches between looks (core/model.py Pairs) are written too.
"""
from __future__ import annotations

import math

from dataclasses import dataclass

import numpy as np

from ..core import model as M
from ..core.rotation import quat_conjugate, quat_multiply
from .response import cross
from .shapes import BOX, CAPSULE, FCL_POINT, PLANE, SPHERE, VERTEX_OF_B, local_feature, part_of

# a contact whose points part faster than this after the impulses (m/s) is not kept: the bodies separate
SEPARATING_SPEED = 1e-6
# a point that let go comes back as a contact once it is this deep (m), or approaching
REJOIN_DEPTH = 1e-7
# a new contact slipping slower than this (m/s) sticks (the entry projection removes what is left)
STICK_SPEED = 1e-4
# a slip slower than this (m/s) has no direction of its own
STILL = 1e-12
# the relative regularization of a contact row's diagonal: redundant contacts (a box's four corners) share
# their load as the least-norm solution does, instead of one basic solution of many
SOFTNESS = 1e-9
# the tangent plane of a curved face is trusted this far from the touching point, relative to the body's size
CURVED_FACE = 0.05
# a face with no edge (a plane)
NO_EDGE = 1e300


@dataclass
class Contact:
    """One lasting contact (module docstring); vectors in the body frames."""

    a: int
    b: int
    family: int  # M.CONTACT or M.CONTACT_SPHERES
    point: np.ndarray  # (3,) a's point (a sphere's centre)
    radius: float  # a's radius at that point (0: a point); for two spheres, the sum of the radii
    origin: np.ndarray  # (3,) b's face (for two spheres: b's centre)
    normal: np.ndarray  # (3,)
    t1: np.ndarray
    t2: np.ndarray
    half: tuple  # (2,) along t1, t2
    anchor: np.ndarray  # (3,) in b's frame: where a sticking point stuck
    mu: float
    mode: str  # "stick" | "slide" | "free" (no friction)
    part_a: int = -1  # the parts of compound bodies a and b that touch (-1: the body's own shape)
    part_b: int = -1

    def rows(self) -> int:
        return 3 if self.mode == "stick" and self.family == M.CONTACT else 1


def _basis(n: np.ndarray, along: np.ndarray | None = None) -> tuple:
    """Unit t1, t2 perpendicular to n; t1 along `along` (projected) when it has a direction."""
    if along is not None:
        t = along - (along @ n) * n
        if np.linalg.norm(t) > 1e-12:
            t1 = t / np.linalg.norm(t)
            return t1, cross(n, t1)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = cross(n, helper)
    t1 /= np.linalg.norm(t1)
    return t1, cross(n, t1)


class ContactSet:
    """The lasting contacts of a simulation, written into its compiled model (module docstring)."""

    def __init__(self, simulation, cplan):
        self.sim, self.cp = simulation, cplan
        self.table = cplan.table
        self.contacts: dict = {}  # (a, b, feature) -> Contact
        self.lifted: set = set()  # keys of contacts that let go since they were last pressed
        self.instance_of: dict = {}  # key -> its instance in the constraint table (after `write`)
        self.version = 0  # counts the writes: the Active rows are rebuilt after each

    # -- what the collision stage found -----------------------------------------------------------------

    def update(self, found, x, q, v, w, bounced: float = math.inf, step: float = 0.0) -> None:
        """The contacts of a look at the state (x, q, v, w) after its impulses: `found` (response.Contacts with
        features, or None). Touching points that do not part are kept (a known one as it was, a new one as its
        slip says), and so are points inside the other body (deeper than REJOIN_DEPTH), the rest dropped; a
        point that lifted off lately (`lifted`) comes back only once it presses in again (deeper, or
        approaching); then the rows are written."""
        kept = {}
        if found is not None:
            R = _rotations(q)
            for i in range(len(found)):
                key = (int(found.a[i]), int(found.b[i]), int(found.feature[i]))
                u = _relative_velocity(found, i, x, v, w)
                n = found.normal[i]
                if local_feature(found.feature[i]) >= FCL_POINT:
                    continue  # fcl's point somewhere in an overlap (an edge across an edge): impulses only
                # a point that bounced (parting faster than `bounced`, the resting speed) and is out within one
                # step is let go however deep it is: an impact found at a step's end, not yet rewound
                out_in_a_step = n @ u > bounced and n @ u * step >= found.depth[i]
                deep = found.depth[i] > REJOIN_DEPTH and not out_in_a_step
                # a point inside the other body is held (its row puts it back on the surface), parting or not
                if n @ u > SEPARATING_SPEED and not deep:
                    continue
                if key in self.lifted and not deep and n @ u > -SEPARATING_SPEED:
                    continue
                self.lifted.discard(key)
                contact = self.contacts.get(key) or self._new(found, i, x, R, u - (n @ u) * n)
                kept[key] = contact
        self.contacts = kept
        self._one_mode_per_pair(x, q, v, w)
        self.write()

    def _one_mode_per_pair(self, x, q, v, w) -> None:
        """A pair's contacts stick or slide together (a body's patch does not stick at one corner and slide at
        another): where some slide, all do, each against its slip (or, where it has none, against the slip of
        one that slides)."""
        pairs = {}
        for contact in self.contacts.values():
            pairs.setdefault(frozenset((contact.a, contact.b)), []).append(contact)
        R = _rotations(q)
        for contacts in pairs.values():
            if {c.mode for c in contacts} != {"stick", "slide"}:
                continue
            leader = next(c for c in contacts if c.mode == "slide")
            along = _world(R, leader.b, leader.t1)  # the direction a's point slips in over b
            for c in contacts:
                if c.mode != "stick":
                    continue
                slip = self._slip(c, x, R, v, w)
                if np.linalg.norm(slip) <= STILL:
                    slip = along if c.a == leader.a else -along
                Rb = R[c.b] if c.b >= 0 else np.eye(3)
                c.t1, c.t2 = _basis(c.normal, Rb.T @ slip)
                c.mode = "slide"

    def _slip(self, contact, x, R, v, w) -> np.ndarray:
        """The tangential velocity of a's point over b at a contact (world)."""
        Rb = R[contact.b] if contact.b >= 0 else np.eye(3)
        normal = Rb @ contact.normal
        point = x[contact.a] + R[contact.a] @ contact.point - contact.radius * normal
        va = v[contact.a] + cross(w[contact.a], point - x[contact.a])
        vb = v[contact.b] + cross(w[contact.b], point - x[contact.b]) if contact.b >= 0 else np.zeros(3)
        u = va - vb
        return u - (u @ normal) * normal

    def remove(self, instance: int) -> None:
        """A contact that pulls lets go (and is not taken back while it merely touches)."""
        key = self._key(instance)
        self.contacts.pop(key, None)
        self.lifted.add(key)
        self.write()

    def to_sliding(self, instance: int, lam, q) -> None:
        """A sticking contact outside its cone slides, and so do the other sticking contacts of its pair (a
        body's contact patch slides as one): against the friction the patch could not supply (the slip starts
        opposite the sum of the tangential forces its rows needed: lam, the solve's multipliers by local row)."""
        contact = self.contacts.get(self._key(instance))
        if contact is None:
            return
        R = _rotations(q)
        patch = [(key, other) for key, other in self.contacts.items()
                 if other.mode == "stick" and {other.a, other.b} == {contact.a, contact.b}]
        # the tangential force on contact's a, summed over the patch (world)
        pull = np.zeros(3)
        for key, other in patch:
            row = self._local_row(key)
            sign = 1.0 if other.a == contact.a else -1.0
            pull += sign * _world(R, other.b, lam[row + 1] * other.t1 + lam[row + 2] * other.t2)
        for key, other in patch:
            sign = 1.0 if other.a == contact.a else -1.0
            Rb = R[other.b] if other.b >= 0 else np.eye(3)
            other.t1, other.t2 = _basis(other.normal, -sign * (Rb.T @ pull))
            other.mode = "slide"
        self.write()

    def to_sticking(self, instance: int, x, q) -> None:
        """A sliding contact whose slip turned back sticks where its point is now, and so do the other sliding
        contacts of its pair."""
        contact = self.contacts.get(self._key(instance))
        if contact is None:
            return
        R = _rotations(q)
        for other in self.contacts.values():
            if other.mode != "slide" or {other.a, other.b} != {contact.a, contact.b}:
                continue
            world = x[other.a] + R[other.a] @ other.point
            other.anchor = R[other.b].T @ (world - _position(x, other.b)) if other.b >= 0 else world
            other.t1, other.t2 = _basis(other.normal)
            other.mode = "stick"
        self.write()

    def slip_along_t1(self, instance: int, x, q, v, w) -> float:
        """A sliding contact's slip velocity along its t1 (the direction its slip began in) at the state
        (x, q, v, w): positive while it slides on, zero where it stops."""
        contact = self.contacts[self._key(instance)]
        R = _rotations(q)
        return float(self._slip(contact, x, R, v, w) @ _world(R, contact.b, contact.t1))

    def _local_row(self, key) -> int:
        """The local row (the solve's order) of a contact's normal row."""
        k = self.instance_of[key]
        c = self.sim.compiled
        return int(self.sim.rows_now.local[c.model.constraints.first_row[k]])

    def _key(self, instance: int):
        for key, k in self.instance_of.items():
            if k == instance:
                return key
        return None

    # -- a new contact --------------------------------------------------------------------------------------

    def _new(self, found, i, x, R, slip) -> Contact:
        a, b, n, depth = int(found.a[i]), int(found.b[i]), found.normal[i].copy(), float(found.depth[i])
        sa, sb = self._shape(a, part_of(found.feature[i], 0)), self._shape(b, part_of(found.feature[i], 1))
        ka, kb = sa.kind, sb.kind
        # a's point on b's face: a sphere, or the body whose vertex it is, takes a's part
        if (kb == SPHERE and ka != SPHERE) or VERTEX_OF_B <= local_feature(found.feature[i]) < FCL_POINT:
            a, b, n, slip = b, a, -n, -slip
            (ka, sa), (kb, sb) = (kb, sb), (ka, sa)
        p = found.point[i]
        on_a, on_b = p - 0.5 * depth * n, p + 0.5 * depth * n  # each surface's touching point
        Ra, Rb = R[a], (R[b] if b >= 0 else np.eye(3))
        to_b = lambda point: Rb.T @ (point - _position(x, b))  # noqa: E731
        mu = float(found.mu[i])
        if ka == SPHERE and kb == SPHERE:  # their centres in their bodies' frames
            return Contact(a, b, M.CONTACT_SPHERES, sa.offset.copy(), float(sa.radius + sb.radius),
                           sb.offset.copy(), Rb.T @ n, np.zeros(3), np.zeros(3), (NO_EDGE, NO_EDGE), np.zeros(3), mu,
                           "free", sa.part, sb.part)
        if ka in (SPHERE, CAPSULE):
            radius = float(sa.radius)
            point = Ra.T @ (on_a + radius * n - x[a])  # the centre of the sphere that touches
        else:
            radius, point = 0.0, Ra.T @ (on_a - x[a])
        normal = Rb.T @ n
        mode = "free" if mu <= 0.0 else ("stick" if np.linalg.norm(slip) <= STICK_SPEED else "slide")
        t1, t2 = _basis(normal, Rb.T @ slip if mode == "slide" else None)
        origin, half = to_b(on_b), self._curved(b, sb)
        if kb == BOX:
            own = sb.turn.T @ normal  # the normal in the box's own axes (a part's are turned in its body)
            axis = int(np.argmax(np.abs(own)))
            if abs(own[axis]) > 1.0 - 1e-9:
                origin, (t1, t2), half = self._box_face(sb, axis, own, mode, t1, t2)
        elif kb == PLANE:
            half = (NO_EDGE, NO_EDGE)
        anchor = to_b(x[a] + Ra @ point - radius * n) if radius == 0.0 else to_b(on_b)
        return Contact(a, b, M.CONTACT, point, radius, origin, normal, t1, t2, half, anchor, mu, mode, sa.part,
                       sb.part)

    def _box_face(self, box, axis, own, mode, t1, t2):
        """A box's face, in its body's frame: its centre, its two other axes (the tangents, unless the contact
        slides: t1 along the slip) and its half extents along the tangents; own: the normal in the box's axes."""
        half, turn = box.half, box.turn
        e = np.eye(3)
        others = [k for k in range(3) if k != axis]
        centre = box.offset + turn @ (np.sign(own[axis]) * half[axis] * e[axis])
        if mode == "slide":  # the tangents follow the slip; the face's bounds are checked along them (a disc)
            return centre, (t1, t2), (float(min(half[others])),) * 2
        return centre, (turn @ e[others[0]], turn @ e[others[1]]), (float(half[others[0]]), float(half[others[1]]))

    def _curved(self, b, shape) -> tuple:
        if b < 0:
            return (NO_EDGE, NO_EDGE)
        size = CURVED_FACE * float(np.min(shape.half))
        return (size, size)

    def _shape(self, body: int, part: int) -> "_Shape":
        """The shape of a contact's side: the body's own, or its part's (with where it sits in the body)."""
        elements = self.table.elements
        if body < 0:
            return _Shape(PLANE, 0.0, np.full(3, np.inf), np.zeros(3), np.eye(3), -1)
        if elements is None or part < 0:
            t = self.table
            return _Shape(int(t.kind[body]), float(t.radius[body]), t.half[body], np.zeros(3), np.eye(3), -1)
        e, t = elements.element(body, int(part)), elements.table
        return _Shape(int(t.kind[e]), float(t.radius[e]), t.half[e], elements.offset[e], elements.turn[e], int(part))

    # -- into the compiled model ------------------------------------------------------------------------------

    def write(self) -> None:
        """The contacts as instances and rows after the joints', and the pairs' states."""
        c = self.sim.compiled
        rows = sum(k.rows() for k in self.contacts.values())
        c.reserve_contacts(len(self.contacts), rows)
        cons, param = c.model.constraints, c.scratch.param
        k, r = c.joint_instances, c.joint_rows
        cons.family[k:], cons.rows[k:] = M.NAIL, 0  # the free slots: no rows
        cons.soft[r:], cons.velocity_only[r:], cons.settles[r:] = 0.0, False, True
        self.instance_of = {}
        for key, contact in self.contacts.items():
            self._write_one(cons, param, k, r, contact)
            self.instance_of[key] = k
            k, r = k + 1, r + contact.rows()
        self._pair_states()
        self.version += 1

    def _write_one(self, cons, param, k, r, contact: Contact) -> None:
        count = contact.rows()
        cons.family[k], cons.body[k] = contact.family, (contact.a, contact.b)
        cons.first_row[k], cons.rows[k] = r, count
        cons.row_instance[r:r + count], cons.row_component[r:r + count] = k, np.arange(count)
        cons.soft[r:r + count] = SOFTNESS
        cons.velocity_only[r:r + count] = [False] + [contact.radius > 0.0] * (count - 1)
        cons.ks[r:r + count], cons.kd[r:r + count], cons.compliance[r:r + count] = 0.0, 0.0, 0.0
        row = np.zeros(M.PARAMS)
        if contact.family == M.CONTACT_SPHERES:
            row[M.SPHERES_A:M.SPHERES_A + 3], row[M.SPHERES_B:M.SPHERES_B + 3] = contact.point, contact.origin
            row[M.SPHERES_REACH] = contact.radius
        else:
            row[M.CONTACT_POINT:M.CONTACT_POINT + 3] = contact.point
            row[M.CONTACT_ORIGIN:M.CONTACT_ORIGIN + 3] = contact.origin
            row[M.CONTACT_NORMAL:M.CONTACT_NORMAL + 3] = contact.normal
            row[M.CONTACT_T1:M.CONTACT_T1 + 3], row[M.CONTACT_T2:M.CONTACT_T2 + 3] = contact.t1, contact.t2
            row[M.CONTACT_ANCHOR:M.CONTACT_ANCHOR + 3] = contact.anchor
            row[M.CONTACT_RADIUS] = contact.radius
            row[M.CONTACT_HALF1], row[M.CONTACT_HALF2] = contact.half
            row[M.CONTACT_SLIDE_MU] = contact.mu if contact.mode == "slide" else 0.0
            row[M.CONTACT_MU] = contact.mu
        cons.param[k], param[k] = row, row

    def _pair_states(self) -> None:
        """Pairs with a contact: state 1 and their relative orientation now; the others apart (0), but for the
        ones excluded now (2, left as the collision stage set them); no pair keeps a clearance (the collision
        stage sets them anew after a look)."""
        pairs = self.sim.compiled.model.pairs
        pairs.clear[:] = 0.0
        touching = {(c.a, c.b) for c in self.contacts.values()} | {(c.b, c.a) for c in self.contacts.values()}
        y = self.sim.state.y
        for p in range(len(pairs.a)):
            if pairs.state[p] == 2:
                continue
            a, b = int(pairs.a[p]), int(pairs.b[p])
            pairs.state[p] = 1 if (a, b) in touching else 0
            if pairs.state[p] == 1:
                set_relative(pairs, p, y[:, 3:7])

    def active_rows(self) -> np.ndarray:
        """The global rows of the contacts (after `write`)."""
        c = self.sim.compiled
        r = c.joint_rows
        total = sum(k.rows() for k in self.contacts.values())
        return np.arange(r, r + total, dtype=np.int64)


@dataclass
class _Shape:
    """One side of a contact: kind, radius, half (3,), and where it sits in its body (offset (3,), turn (3,3))."""

    kind: int
    radius: float
    half: np.ndarray
    offset: np.ndarray
    turn: np.ndarray
    part: int


def set_relative(pairs, p: int, q) -> None:
    """Pair p's relative orientation now, conj(q_b) q_a (q (n,4)): what the compiled step measures its turn from
    (core/contact.py relative_cos_half)."""
    pairs.relative[p] = quat_multiply(quat_conjugate(q[pairs.b[p]]), q[pairs.a[p]])


def _world(R, b, vector):
    """A vector of b's frame in the world's (b < 0: the world)."""
    return R[b] @ vector if b >= 0 else np.asarray(vector, float)


def _position(x, b):
    return x[b] if b >= 0 else np.zeros(3)


def _rotations(q) -> np.ndarray:
    from ..core.rotation import quat_to_matrix

    return quat_to_matrix(q)


def _relative_velocity(found, i, x, v, w) -> np.ndarray:
    """Velocity of a's material point at the contact point minus b's."""
    p = found.point[i]
    a, b = int(found.a[i]), int(found.b[i])
    va = v[a] + cross(w[a], p - x[a])
    vb = v[b] + cross(w[b], p - x[b]) if b >= 0 else np.zeros(3)
    return va - vb
