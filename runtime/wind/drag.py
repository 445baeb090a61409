"""Wind stage, drag: the aerodynamic force and torque on every body that feels the wind.

For body i in the relative wind u_rel = u(x_i, t) - v_i, n = u_rel / |u_rel| in the body frame:

    F   = 1/2 rho Cd A(n) |u_rel| u_rel                               at the centre of pressure r_cp
    tau = r_cp x F + R (-D w_b - 1/2 rho Cd K |w_b| w_b)               w_b: body-frame angular velocity

A(n), the area facing the relative wind, is exact for the convex primitives (the area of the shape's shadow):
    sphere    A = pi r^2
    box       A = A_x |n_x| + A_y |n_y| + A_z |n_z|        A_x = b c, A_y = a c, A_z = a b  (face areas)
    cylinder  A = pi r^2 |n_z| + 2 r L sqrt(1 - n_z^2)      (axis along body z)
    capsule   A = pi r^2 + 2 r L sqrt(1 - n_z^2)
A mesh is treated as the box with its mass and inertia; a body's `area` replaces A(n) by a constant.
A plate is a thin box (or a thin cylinder: a disc).

Centre of pressure: r_cp = -CP_SHIFT H n, H = diag(half extents). On a plate at angle of attack alpha this puts
it at a quarter chord from the leading edge when the wind grazes the plate (alpha -> 0) and at the centre when
the wind meets it square: x_cp / c = 1/2 - 1/4 cos(alpha), the classical linear fit. The moment r_cp x F turns
a flat body broadside to the wind. A sphere's centre of pressure is its centre.

Turning (strip theory on the faces of the body's box, half extents h): a face with normal e_k pushes air with
normal speed u_rel . e_k - w . (r x e_k); expanding 1/2 rho Cd |s| s over the face to second order in w gives
    D_j = rho Cd |u_rel| sum_k |n_k| J_kj,   J_kj = integral of r_l^2 over face k = 4/3 h_j h_l^3   (l != j, k)
the pitch damping of a plate in a wind (first order), and, for the second order, the drag of the faces swept
in still air (a strip of width W and half-length l: 1/4 rho Cd w^2 W l^4)
    K_j = h_j (h_k^4 + h_l^4).
Both vanish about an axis of revolution (all axes of a sphere; z of a cylinder or capsule); a round end face
counts pi/4 of its square.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# r_cp = -CP_SHIFT H n: a quarter chord ahead of the centre when the wind grazes a plate
CP_SHIFT = 0.5
# below this relative speed (m/s) a body has no well-defined wind direction (and no drag to speak of)
TINY_SPEED = 1e-12


@dataclass(frozen=True)
class Aero:
    """Aerodynamic constants of one body: A(n) = area0 + face . |n| + side sqrt(1 - n_z^2)."""

    area0: float
    face: tuple  # (3,)
    side: float
    half: tuple  # (3,) half extents H for the centre of pressure (0 for a sphere)
    sweep: tuple  # (3,3) J_kj, m^4: face k turning about axis j (the wind's pitch damping)
    spin: tuple  # (3,) K_j, m^5: faces swept in still air
    size: float  # m, cross dimension (aeolian tone f = St U / d)


def shape_aero(shape, mass: float | None, inertia, area: float | None = None) -> Aero:
    """The constants of a shape (ir.Shape); `area` (m2) overrides the projected area when given."""
    kind = shape.type
    if kind == "sphere":
        r = shape.radius
        zero = (0.0, 0.0, 0.0)
        aero = Aero(math.pi * r * r, zero, 0.0, zero, (zero, zero, zero), zero, 2 * r)
    elif kind in ("cylinder", "capsule"):
        r, length = shape.radius, shape.length
        h = (r, r, 0.5 * length + (r if kind == "capsule" else 0.0))
        end = math.pi * r * r
        sweep = [list(row) for row in _sweep(h)]
        for k in range(3):
            sweep[k][2] = 0.0  # no push about the axis of revolution
        if kind == "cylinder":
            sweep[2] = [math.pi / 4 * j for j in sweep[2]]  # the flat round ends
        else:
            sweep[2] = [0.0, 0.0, 0.0]  # hemispherical ends push no air as they turn
        aero = Aero(end if kind == "capsule" else 0.0, (0.0, 0.0, 0.0 if kind == "capsule" else end),
                    2 * r * length, h, tuple(tuple(row) for row in sweep), _spin(h, round_z=True), 2 * r)
    else:  # box, or a mesh as the box of the same mass and inertia
        h = tuple(0.5 * e for e in (shape.size if kind == "box" else _equivalent_box(shape, mass, inertia)))
        aero = Aero(0.0, (4 * h[1] * h[2], 4 * h[0] * h[2], 4 * h[0] * h[1]), 0.0, h, _sweep(h), _spin(h),
                    2 * min(h))
    if area is not None:
        aero = Aero(float(area), (0.0, 0.0, 0.0), 0.0, aero.half, aero.sweep, aero.spin, aero.size)
    return aero


def _sweep(h) -> tuple:
    # J_kj = 4/3 h_j h_l^3 for j != k, l the third axis; 0 for j == k
    return tuple(tuple(0.0 if j == k else 4.0 / 3.0 * h[j] * h[3 - j - k] ** 3 for j in range(3))
                 for k in range(3))


def _spin(h, round_z: bool = False) -> tuple:
    # K_j = h_j (h_k^4 + h_l^4)
    spin = [h[j] * (h[(j + 1) % 3] ** 4 + h[(j + 2) % 3] ** 4) for j in range(3)]
    if round_z:
        spin[2] = 0.0
    return tuple(spin)


def _equivalent_box(shape, mass, inertia) -> tuple:
    """Edges (a, b, c) of the uniform box with this mass and principal inertia: a^2 = 6 (Iy + Iz - Ix) / m."""
    if inertia is None or not mass:
        s = shape.scale
        return (s, s, s)
    moments = np.diag(np.asarray(inertia, float))
    total = moments.sum()
    return tuple(float(np.sqrt(max(6.0 * (total - 2 * moments[j]) / mass, 1e-12))) for j in range(3))


@dataclass
class DragBodies:
    """The k bodies that feel the wind, as arrays (the constants of `Aero`, stacked)."""

    body: np.ndarray  # (k,) indices into the plan's bodies
    mass: np.ndarray  # (k,) kg
    moments: np.ndarray  # (k,3) principal moments, kg m2 (for the procedural model)
    cd: np.ndarray  # (k,)
    area0: np.ndarray  # (k,)
    face: np.ndarray  # (k,3)
    side: np.ndarray  # (k,)
    half: np.ndarray  # (k,3)
    sweep: np.ndarray  # (k,3,3) J
    spin: np.ndarray  # (k,3) K
    size: np.ndarray  # (k,)

    @property
    def shaped(self) -> bool:
        """Whether A(n) depends on n for any of the bodies (else A = area0: a sphere, or a body's `area`)."""
        return bool(np.any(self.face) or np.any(self.side))

    @property
    def turning(self) -> bool:
        """Whether the wind can turn any of the bodies (else the torque is 0: r_cp = 0, D = 0, K = 0)."""
        return bool(np.any(self.half) or np.any(self.sweep) or np.any(self.spin))


def stack_bodies(indices, aeros, cds, mass, inertia_body) -> DragBodies:
    idx = np.asarray(indices, dtype=int)
    return DragBodies(
        body=idx, mass=np.asarray(mass, float)[idx], moments=np.einsum("kii->ki", np.asarray(inertia_body)[idx]),
        cd=np.asarray(cds, float), area0=np.array([a.area0 for a in aeros], float),
        face=np.array([a.face for a in aeros], float).reshape(-1, 3), side=np.array([a.side for a in aeros], float),
        half=np.array([a.half for a in aeros], float).reshape(-1, 3),
        sweep=np.array([a.sweep for a in aeros], float).reshape(-1, 3, 3),
        spin=np.array([a.spin for a in aeros], float).reshape(-1, 3), size=np.array([a.size for a in aeros], float))


@dataclass
class DragConstants:
    """What `drag` computes from the bodies and the air alone, computed once (plan): the same products, in the
    same order, as the formulas below write them, so the forces are the same to the last bit."""

    half_rho_cd: np.ndarray  # (k,) 1/2 rho Cd
    force_scale: np.ndarray  # (k,) 1/2 rho Cd area0: F = force_scale |u_rel| u_rel when A = area0
    rho_cd: np.ndarray  # (k,) rho Cd
    spin_drag: np.ndarray  # (k,3) 1/2 rho Cd K
    arm: np.ndarray  # (k,3) -CP_SHIFT H: r_cp = arm * n
    shaped: bool  # A(n) varies (else A = area0)
    turning: bool  # there is a torque (else it is 0)


def drag_constants(b: DragBodies, rho: float) -> DragConstants:
    half_rho_cd = 0.5 * rho * b.cd
    return DragConstants(half_rho_cd, half_rho_cd * b.area0, rho * b.cd, 0.5 * rho * b.cd[:, None] * b.spin,
                         -CP_SHIFT * b.half, b.shaped, b.turning)


def _norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ki,ki->k", a, a))


_NEXT, _PREV = np.array([1, 2, 0]), np.array([2, 0, 1])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b for (k,3) arrays (np.cross is several times slower on small arrays):
    (a x b)_i = a_{i+1} b_{i+2} - a_{i+2} b_{i+1}, all three components at once."""
    return a.take(_NEXT, axis=1) * b.take(_PREV, axis=1) - a.take(_PREV, axis=1) * b.take(_NEXT, axis=1)


def projected_area(b: DragBodies, n_body: np.ndarray) -> np.ndarray:
    """(k,) A(n) for unit body-frame directions n (k,3)."""
    # A = area0 + face . |n| + side sqrt(1 - n_z^2)
    lateral = np.sqrt(np.maximum(0.0, 1.0 - n_body[:, 2] ** 2))
    return b.area0 + np.einsum("kj,kj->k", b.face, np.abs(n_body)) + b.side * lateral


@dataclass
class DragResult:
    force: np.ndarray  # (k,3) N, world
    torque: np.ndarray  # (k,3) N m, world, about the centre of mass
    speed: np.ndarray  # (k,) |u_rel|, m/s
    area: np.ndarray  # (k,) m2 facing the relative wind
    damping: np.ndarray  # (k,3) D_j, N m s: the wind's damping of turns about each body axis


def drag(b: DragBodies, rho: float, u: np.ndarray, v: np.ndarray, w: np.ndarray, R: np.ndarray,
         constants: DragConstants | None = None) -> DragResult:
    """Drag on the k bodies: u (k,3) the air velocity at each; v, w (k,3) and R (k,3,3) the bodies' own (w and R
    unused, and may be None, when the wind cannot turn the bodies). constants: drag_constants(b, rho), when the
    caller keeps them."""
    c = constants if constants is not None else drag_constants(b, rho)
    rel = u - v
    speed = _norm(rel)
    if not (c.shaped or c.turning):
        # A = area0 (area0 + face . |n| + side sqrt(1 - n_z^2) with face = side = 0), and no torque
        force = (c.force_scale * speed)[:, None] * rel
        zero = np.zeros_like(force)
        return DragResult(force, zero, speed, b.area0.copy(), zero)
    n_body = np.einsum("kji,kj->ki", R, rel) / np.maximum(speed, TINY_SPEED)[:, None]
    area = projected_area(b, n_body)
    # F = 1/2 rho Cd A |u_rel| u_rel, at r_cp = -CP_SHIFT H n
    force = (c.half_rho_cd * area * speed)[:, None] * rel
    arm = np.einsum("kij,kj->ki", R, c.arm * n_body)
    # D_j = rho Cd |u_rel| sum_k |n_k| J_kj;  tau_b = -D w_b - 1/2 rho Cd K |w_b| w_b
    damping = (c.rho_cd * speed)[:, None] * np.einsum("kf,kfj->kj", np.abs(n_body), b.sweep)
    w_body = np.einsum("kji,kj->ki", R, w)
    turning = -damping * w_body - c.spin_drag * np.abs(w_body) * w_body
    torque = cross(arm, force) + np.einsum("kij,kj->ki", R, turning)
    return DragResult(force, torque, speed, area, damping)


def relaxation_factors(b: DragBodies, rho: float, result: DragResult, w_body: np.ndarray, h: float) -> tuple:
    """The procedural model's phi(kappa h) = (1 - exp(-kappa h)) / (kappa h) for force and torque, (k,) each.

    Drag linearized about the step's start, dv/dt = a - kappa (v - v0) with kappa = rho Cd A |u_rel| / m (the
    rate of 1/2 rho Cd A |u_rel| u_rel along u_rel), solved exactly over h: dv = h a phi(kappa h). So the step
    uses phi (F_other + F_drag): never past the velocity where the forces balance, however long the step, and
    the same balance (terminal velocity, the angle a disc hangs at) as the force model.
    Turning: kappa_w = (D_j + rho Cd K_j |w_j|) / I_j, the largest over the body axes."""
    kappa = rho * b.cd * result.area * result.speed / b.mass
    rate = result.damping + rho * b.cd[:, None] * b.spin * np.abs(w_body)
    kappa_w = np.max(rate / np.maximum(b.moments, 1e-300), axis=1)
    return _phi(kappa * h), _phi(kappa_w * h)


def _phi(z: np.ndarray) -> np.ndarray:
    """(1 - exp(-z)) / z, 1 at z = 0."""
    small = z < 1e-8
    safe = np.where(small, 1.0, z)
    return np.where(small, 1.0 - 0.5 * z, -np.expm1(-safe) / safe)


# ---- the slow, obvious twin ---------------------------------------------------------------------------------

def shadow_points(shape, samples: int = 720) -> np.ndarray:
    """Points whose convex hull is the shape (body frame): corners of a box, rims of a cylinder, a capsule's
    spheres sampled on great circles."""
    if shape.type == "box":
        h = 0.5 * np.asarray(shape.size, float)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    a = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    if shape.type == "cylinder":
        r, half = shape.radius, 0.5 * shape.length
        rim = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)], axis=1)
        return np.concatenate([rim + [0, 0, -half], rim + [0, 0, half]])
    if shape.type == "sphere":
        return _sphere_points(shape.radius, samples)
    if shape.type == "capsule":
        ball = _sphere_points(shape.radius, samples)
        return np.concatenate([ball + [0, 0, -0.5 * shape.length], ball + [0, 0, 0.5 * shape.length]])
    raise ValueError(f"no reference shadow for a {shape.type}")


def _sphere_points(r: float, samples: int) -> np.ndarray:
    golden = np.pi * (3.0 - np.sqrt(5.0))
    i = np.arange(samples * 8)
    z = 1.0 - 2.0 * (i + 0.5) / len(i)
    rho = np.sqrt(1.0 - z * z)
    return r * np.stack([rho * np.cos(golden * i), rho * np.sin(golden * i), z], axis=1)


def projected_area_reference(shape, n_body) -> float:
    """Area of the shape's shadow on the plane normal to n: the convex hull of its projected points."""
    from scipy.spatial import ConvexHull

    n = np.asarray(n_body, float) / np.linalg.norm(n_body)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    points = shadow_points(shape)
    return float(ConvexHull(np.stack([points @ e1, points @ e2], axis=1)).volume)  # 2-D "volume" is the area


def drag_reference(aero: Aero, cd: float, rho: float, u, v, w, R) -> tuple:
    """(force, torque) on one body, written out term by term (the twin of `drag`)."""
    u, v, w, R = (np.asarray(a, float) for a in (u, v, w, R))
    rel = u - v
    speed = np.linalg.norm(rel)
    n = R.T @ rel / max(speed, TINY_SPEED)
    area = aero.area0 + sum(aero.face[j] * abs(n[j]) for j in range(3)) + aero.side * math.sqrt(max(0.0, 1 - n[2] ** 2))
    force = 0.5 * rho * cd * area * speed * rel
    arm = R @ np.array([-CP_SHIFT * aero.half[j] * n[j] for j in range(3)])
    w_body = R.T @ w
    turning = np.zeros(3)
    for j in range(3):
        damping = rho * cd * speed * sum(abs(n[k]) * aero.sweep[k][j] for k in range(3))
        turning[j] = -damping * w_body[j] - 0.5 * rho * cd * aero.spin[j] * abs(w_body[j]) * w_body[j]
    return force, np.cross(arm, force) + R @ turning
