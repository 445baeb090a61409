"""The procedural sphere: rolling and bouncing on static planes without a contact solve (PHYSICS.md section 6).

The dissertation names a procedural algorithm for sphere-like objects; its text is lost, so it is designed here
from the same three steps, for spheres against static planes (a floor, a ramp), where every contact is one
sphere and one immovable plane and so has a closed form:

1. move unconstrained: the solver's substep moves every body by its forces (procedural.py, stage 1);
2. put the sphere back where the constraint "not inside the plane" allows, mass-weighted, in closed form:
   - an impact (the sphere reached the plane during this substep, approaching faster than REST_SPEED_STEPS
     substeps of gravity would make it): find the moment it touched, t_c = d0 / (-v_n) into the substep,
     reflect the normal velocity there, v_n+ = -e v_n, and apply the Coulomb-limited tangential impulse at the
     contact point (below); the sphere then moves with the new velocities for the rest of the substep;
   - a resting or rolling contact (the sphere was on the plane, or arrives slowly): move it out along the normal
     by its depth d (a normal impulse of m d / hs), and remove the contact point's tangential slip u over the
     substep as far as friction allows: the tangential impulse that stops the slip at the contact point
     r_c = -r n is P = -u / (1/m + r^2/I) (the generalized inverse mass of the contact point along the slip,
     w = 1/m + (r_c x t)^T I^-1 (r_c x t) = 1/m + r^2/I), kept within |P| <= mu (normal impulse). It moves the
     centre by hs P / m and turns the sphere by hs I^-1 (r_c x P): a sphere on a slope rolls, v = w r, with
     a = g sin(slope) / (1 + I / (m r^2)) (5/7 g sin for a solid ball) while tan(slope) <= mu (1 + m r^2 / I);
     beyond, it slides with a = g (sin - mu cos);
3. velocities from the positions (procedural.py, stage 3), except for a sphere in contact, whose velocities
   after the contact are known in closed form and set directly: after an impact the substep's average would
   blur the bounce, and rolling keeps v = w r exactly.
So bounce heights follow e^2 (up to the substep's O(hs) error in free flight) and no linear system is ever
formed. Planes are static bodies with a `plane` shape: normal R n through the body's position.
"""
from __future__ import annotations

import numpy as np

from .constraints import projections as pj

# an approach slower than the speed gravity gives in this many substeps is resting contact, not an impact
REST_SPEED_STEPS = 2.0


class ProceduralSpheres:
    """Spheres against static planes. sphere (k,) body index, radius (k,), inv_mass (k,), lever (k,) = r^2 m / I
    (5/2 for a solid ball); normal (p,3) unit and offset (p,) of plane n . x = offset; restitution and friction
    (k,p) per pair; gravity (3,) for the rest threshold. The spheres in contact in the last substep: touched (k,)
    and the velocities v_after, w_after (k,3) the contact leaves them."""

    def __init__(self, sphere, radius, inv_mass, inertia, normal, offset, restitution, friction, gravity):
        self.sphere = np.asarray(sphere, dtype=np.int64)
        self.radius = np.asarray(radius, dtype=float)
        self.inv_mass = np.asarray(inv_mass, dtype=float)
        self.inv_inertia = 1.0 / np.asarray(inertia, dtype=float)  # scalar moment of a sphere
        normal = np.asarray(normal, dtype=float).reshape(-1, 3)
        self.normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
        self.offset = np.asarray(offset, dtype=float).reshape(-1)
        k, p = len(self.sphere), len(self.offset)
        self.restitution = np.broadcast_to(np.asarray(restitution, dtype=float), (k, p))
        self.friction = np.broadcast_to(np.asarray(friction, dtype=float), (k, p))
        self.gravity = float(np.linalg.norm(gravity))
        self.touched = np.zeros(k, dtype=bool)
        self.v_after, self.w_after = np.zeros((k, 3)), np.zeros((k, 3))
        self.events: list = []  # (plane, sphere index, normal speed) of the impacts not yet taken

    @classmethod
    def from_plan(cls, plan):
        """The dynamic spheres and static planes of a plan that collide, or None when there are no such pairs.
        Pair materials: friction sqrt(mu_a mu_b), restitution max(e_a, e_b) (as Box2D)."""
        scene = plan.scene
        materials = {m.name: m for m in scene.materials}

        def material(body):
            m = materials.get(body.material)
            return (0.5, 0.5) if m is None else (m.friction, m.restitution)

        bodies = scene.bodies
        spheres = [i for i, b in enumerate(bodies) if b.shape.type == "sphere" and b.collide and plan.dynamic[i]]
        planes = [i for i, b in enumerate(bodies) if b.shape.type == "plane" and b.collide and not plan.dynamic[i]]
        if not spheres or not planes:
            return None
        R = [pj.rotation_matrix(plan.q0[i:i + 1])[0] for i in planes]
        normals = np.array([r @ np.asarray(scene.bodies[i].shape.normal or (0.0, 1.0, 0.0), float)
                            for r, i in zip(R, planes)])
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        offsets = np.einsum("pi,pi->p", normals, plan.x0[planes])
        mu = np.array([[np.sqrt(material(scene.bodies[s])[0] * material(scene.bodies[p])[0]) for p in planes]
                       for s in spheres])
        e = np.array([[max(material(scene.bodies[s])[1], material(scene.bodies[p])[1]) for p in planes]
                      for s in spheres])
        inertia = [plan.inertia_body[s][0, 0] for s in spheres]
        return cls(spheres, [scene.bodies[s].shape.radius for s in spheres], plan.inv_mass[spheres], inertia,
                   normals, offsets, e, mu, plan.gravity)

    # ------------------------------------------------------------ the hooks of ProceduralSolver

    def project(self, x, q, hs, before) -> None:
        """Stage 2 for the spheres: out of every plane, with the impact or the rolling friction (module doc)."""
        s, r = self.sphere, self.radius
        self.touched[:] = False
        for j, (n, offset) in enumerate(zip(self.normal, self.offset)):
            d1 = x[s] @ n - offset - r  # signed distance at the end of the substep
            hit = d1 < 0.0
            if not hit.any():
                continue
            i = np.flatnonzero(hit)
            b = s[i]
            x0 = before.x[b]
            d0 = x0 @ n - offset - r[i]
            v = (x[b] - x0) / hs  # what the substep moved with
            w = pj.turn_since(q[b], before.q[b]) / hs
            vn = v @ n
            impact = (d0 >= 0.0) & (-vn > REST_SPEED_STEPS * self.gravity * hs)
            self._contact(j, i, b, n, d0, d1[i], v, w, vn, impact, x, q, hs)

    def _contact(self, j, i, b, n, d0, d1, v, w, vn, impact, x, q, hs) -> None:
        r, e, mu = self.radius[i], self.restitution[i, j], self.friction[i, j]
        im, lever = self.inv_mass[i], self.radius[i] ** 2 * self.inv_inertia[i]
        # normal velocity change: to -e vn at an impact, to 0 (resting, rolling)
        dvn = np.where(impact, -(1.0 + e) * vn, -vn)
        # the slip of the contact point r_c = -r n: u = v + w x r_c, tangential part
        u = v + pj.cross(w, -r[:, None] * n)
        u -= (u @ n)[:, None] * n
        # the impulse per mass that stops it, P / m = -u / (1 + r^2 m / I), within mu dvn
        stick = -u / (1.0 + lever / im)[:, None]
        size = np.sqrt(pj.dot(stick, stick))
        limit = mu * dvn
        P = np.where((size > limit)[:, None], stick * (limit / np.maximum(size, 1e-300))[:, None], stick)
        dv = P + dvn[:, None] * n
        # dw = I^-1 (r_c x m P) = (r m / I) (P x n)
        dw = (lever / (im * r))[:, None] * pj.cross(P, np.broadcast_to(n, P.shape))
        # an impact at t_c = d0 / (-vn) into the substep: from there the new velocities; else the whole substep
        rest = np.where(impact, hs - d0 / np.where(impact, -vn, 1.0), hs)
        dx = dv * rest[:, None]
        # resting: end on the surface (the normal part of dv hs is exactly the depth -d1 when d0 = 0)
        dx += np.where(impact, 0.0, -d1 - dvn * hs)[:, None] * n
        x[b] += dx
        q[b] = pj.turn_by(q[b], dw * rest[:, None])
        self.touched[i] = True
        self.v_after[i], self.w_after[i] = v + dv, w + dw
        self.events.extend((j, int(k), float(-s)) for k, s in zip(i[impact], vn[impact]))

    def take_events(self) -> list:
        """The impacts since the last call, (plane, sphere index, normal speed m/s), for the sound stage."""
        events, self.events = self.events, []
        return events

    def velocities(self, x, q, v, w, hs, before) -> None:
        """Stage 3 for the spheres in contact: the closed-form velocities (after an impact, the substep's average
        would blur the bounce; rolling, they keep v = w r exactly)."""
        if self.touched.any():
            b = self.sphere[self.touched]
            v[b], w[b] = self.v_after[self.touched], self.w_after[self.touched]
