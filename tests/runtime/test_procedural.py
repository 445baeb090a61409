"""The procedural (XPBD) solver: exact answers (pendulum period, gear ratio, rope acceleration), constraints held,
with both projections (direct: all rows at once; Gauss-Seidel: colour sweeps), each against its slow reference;
compliance, targets (self-assembly curves), redundant rows. Scenes: test_procedural_scenes.py; the sphere:
test_procedural_sphere.py."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ellipk

from isaac_runtime.constraints import projections as pj
from isaac_runtime.constraints.layout import (
    WORLD,
    Element,
    GearToGear,
    GearToWeight,
    Orientation,
    PointOnPlane,
    PointToNail,
    PointToPoint,
)
from isaac_runtime.procedural import ProceduralSolver, direct_reference, project_reference
from isaac_runtime.procedural_plan import Curve
from isaac_runtime.rotation import quat_from_axis_angle, quat_rotate, quat_to_matrix

G = 9.81
EX, EY, EZ = np.eye(3)
METHODS = ("direct", "gauss-seidel")


def sphere_inertia(m, r):
    return 0.4 * m * r * r * np.eye(3)


def box_inertia(m, a, b, c):
    return m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def cylinder_z_inertia(m, r, t=0.02):
    side = m * (3 * r * r + t * t) / 12.0
    return np.diag([side, side, 0.5 * m * r * r])


class Bodies:
    """State (x, q, v, w) and masses of n bodies, all at rest and unrotated unless set."""

    def __init__(self, masses, inertias, x):
        self.m = np.asarray(masses, dtype=float)
        self.inertia = np.asarray(inertias, dtype=float)
        n = len(self.m)
        self.x = np.asarray(x, dtype=float).reshape(n, 3).copy()
        self.q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        self.v = np.zeros((n, 3))
        self.w = np.zeros((n, 3))
        self.inv_mass = np.where(self.m > 0, 1.0 / np.where(self.m > 0, self.m, 1.0), 0.0)
        self.inv_inertia = np.array([np.linalg.inv(I) if mi > 0 else np.zeros((3, 3))
                                     for I, mi in zip(self.inertia, self.m)])
        self.gravity = np.zeros((n, 3))
        self.gravity[:, 1] = -G * self.m
        self.torque = np.zeros((n, 3))

    def solver(self, families, compliance=None, **kw):
        return ProceduralSolver(families, compliance, self.inv_mass, self.inv_inertia, **kw)

    def run(self, solver, h, steps, each=None):
        for k in range(steps):
            solver.step(self.x, self.q, self.v, self.w, h, self.gravity, self.torque)
            if each is not None:
                each(k)

    def energy(self):
        R = quat_to_matrix(self.q)
        I = R @ self.inertia @ np.swapaxes(R, 1, 2)
        kinetic = 0.5 * (self.m * (self.v * self.v).sum(1)).sum() + 0.5 * np.einsum("ki,kij,kj->", self.w, I, self.w)
        return kinetic + G * (self.m * self.x[:, 1]).sum()

    def point(self, body, p):
        return self.x[body] + quat_rotate(self.q[body], np.asarray(p, dtype=float))


# ---------------------------------------------------------------- exact answers


@pytest.mark.parametrize("method", METHODS)
def test_pendulum_period_matches_elliptic_integral(method):
    """Sphere r = 0.05 m, 1 kg, on a 1 m arm, released at 60 degrees: T = 4 sqrt(I_p / (m g L)) K(sin^2 30deg).

    Measured at h = 1/60, 10 substeps: period error 3e-6 relative (plain XPBD, gradients at the current pose,
    gives -7e-3 and a period that shrinks every swing); nail gap < 1e-9 m. One row block: both methods agree."""
    b = Bodies([1.0], [sphere_inertia(1.0, 0.05)], [[0.866025, 0.5, 0.0]])
    nail = PointToNail(body=[0], point=[[-0.866025, 0.5, 0.0]], target=[[0.0, 1.0, 0.0]])
    solver = b.solver([nail], substeps=10, method=method)
    h, t, xs, gaps = 1.0 / 60.0, [0.0], [b.x[0, 0]], []

    def record(k):
        t.append((k + 1) * h)
        xs.append(b.x[0, 0])
        gaps.append(np.linalg.norm(b.point(0, nail.point[0]) - nail.target[0]))

    b.run(solver, h, 330, record)
    t, xs = np.array(t), np.array(xs)
    down = np.flatnonzero((xs[:-1] > 0.0) & (xs[1:] <= 0.0))  # the bob passes the bottom moving -x
    crossings = t[down] + h * xs[down] / (xs[down] - xs[down + 1])
    period = np.diff(crossings)
    exact = 4.0 * np.sqrt(1.001 / (1.0 * G * 1.0)) * ellipk(np.sin(np.radians(30.0)) ** 2)
    assert len(period) >= 2
    assert np.abs(period / exact - 1.0).max() < 2e-5
    assert max(gaps) < 1e-6


def _chain(n=10):
    """Boxes 0.2 x 0.02 x 0.02 m, 0.5 kg, along +x; link 0's (-0.1, 0, 0) nailed at the origin."""
    b = Bodies([0.5] * n, [box_inertia(0.5, 0.2, 0.02, 0.02)] * n, [[0.2 * i + 0.1, 0.0, 0.0] for i in range(n)])
    nail = PointToNail(body=[0], point=[[-0.1, 0.0, 0.0]], target=[[0.0, 0.0, 0.0]])
    joints = PointToPoint(body_a=np.arange(n - 1), point_a=np.tile([0.1, 0.0, 0.0], (n - 1, 1)),
                          body_b=np.arange(1, n), point_b=np.tile([-0.1, 0.0, 0.0], (n - 1, 1)))
    return b, nail, joints


def _max_gap(b, nail, joints):
    a = b.point(joints.body_a, joints.point_a)
    c = b.point(joints.body_b, joints.point_b)
    return max(np.linalg.norm(a - c, axis=1).max(), np.linalg.norm(b.point(0, nail.point[0])))


def _run_chain(h, substeps, seconds, **kw):
    b, nail, joints = _chain()
    solver = b.solver([nail, joints], substeps=substeps, **kw)
    start = b.energy()
    worst = {"gap": 0.0, "energy": 0.0}

    def record(k):
        worst["gap"] = max(worst["gap"], _max_gap(b, nail, joints))
        worst["energy"] = max(worst["energy"], abs(b.energy() - start))

    b.run(solver, h, int(round(seconds / h)), record)
    assert np.isfinite(b.x).all() and np.isfinite(b.q).all()
    return worst["gap"], worst["energy"] / (5.0 * G * 2.0)  # energy error relative to m_total g L_total


@pytest.mark.parametrize("h, substeps, gap_limit, energy_limit", [
    (0.01, 20, 1e-5, 2e-3),  # the scene's default under --solver procedural; measured 7.6e-7 m, 7.7e-4
    (1.0 / 30.0, 20, 1e-4, 3e-3),  # measured 3.7e-5 m, 1.3e-3
    (0.01, 1, 1e-4, 0.5),  # one substep: joints still closed (Newton steps), energy lost (measured 1.8e-6 m, 0.22)
])
def test_chain_holds_together(h, substeps, gap_limit, energy_limit):
    """A 10-link chain falls from horizontal for 3 s; the whip at its free end (links at 50 rad/s, the chain taut)
    is the hard part, where Gauss-Seidel leaves 1.4 mm at 0.01 s x 20 substeps. The direct projection closes the
    joints to the Newton tolerance. Energy: SHAKE's direction keeps it (no drift, an O(hs^2) wobble) while the
    bodies turn by less than 0.25 rad a substep; coarser, the closest-point projection loses some, never gains."""
    gap, energy = _run_chain(h, substeps, 3.0)
    assert gap < gap_limit
    assert energy < energy_limit


@pytest.mark.slow
def test_chain_gauss_seidel_is_stretchier():
    """The same chain with colour sweeps: finite, joints open by a fraction of a millimetre even at 30 substeps
    (why `auto` takes the direct projection)."""
    gap, energy = _run_chain(1.0 / 60.0, 30, 5.0, method="gauss-seidel")
    assert 1e-5 < gap < 2e-3  # measured 5.6e-4 m


@pytest.mark.parametrize("method", METHODS)
def test_gears_keep_ratio_and_weight_falls_at_exact_rate(method):
    """Drive (r = 0.1, 0.5 kg) and wheel (r = 0.3, 2 kg) nailed at their centres, turning about z; 1 kg on a rope
    over the drive. 0.1 w_drive + 0.3 w_wheel = 0 and a = g m / (m + I_d / r_d^2 + I_w / r_w^2) = g / 2.25."""
    b = Bodies([0.5, 2.0, 1.0], [cylinder_z_inertia(0.5, 0.1), cylinder_z_inertia(2.0, 0.3), sphere_inertia(1.0, 0.05)],
               [[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [-0.1, -0.5, 0.0]])
    nails = PointToNail(body=[0, 1], point=np.zeros((2, 3)), target=[[0.0, 0.0, 0.0], [0.4, 0.0, 0.0]])
    axes = Orientation(body_a=[0, 0, 1, 1], axis_a=[EZ] * 4, body_b=[WORLD] * 4, axis_b=[EX, EY, EX, EY])
    rope = GearToWeight(gear=[0], arm=[[-0.1, 0.0, 0.0]], weight=[2], direction=[[0.0, -1.0, 0.0]])
    gears = GearToGear(body_a=[0], axis_a=[EZ], radius_a=[0.1], body_b=[1], axis_b=[EZ], radius_b=[0.3])
    solver = b.solver([nails, axes, rope, gears], method=method)
    ratio = []
    b.run(solver, 1.0 / 60.0, 60, lambda k: ratio.append((0.1 * b.w[0, 2] + 0.3 * b.w[1, 2]) / (0.1 * b.w[0, 2])))
    assert np.abs(ratio).max() < 1e-6
    fall = 2.0 * (-0.5 - b.x[2, 1]) / 1.0**2
    assert fall == pytest.approx(G / 2.25, rel=0.02)
    assert b.w[0, 2] > 0.0 > b.w[1, 2]


# ---------------------------------------------------------------- each family holds


@pytest.mark.parametrize("method", METHODS)
def test_orientation_keeps_spin_axis(method):
    """A free spinning box with two orientation rows (body z perpendicular to world x and to world y)."""
    b = Bodies([1.0], [box_inertia(1.0, 0.3, 0.2, 0.1)], [[0.0, 0.0, 0.0]])
    b.w[0] = [2.0, -1.0, 6.0]
    axes = Orientation(body_a=[0, 0], axis_a=[EZ, EZ], body_b=[WORLD, WORLD], axis_b=[EX, EY])
    solver = b.solver([axes], method=method)
    b.gravity[:] = 0.0
    worst, spin = [], []

    def record(k):
        worst.append(np.abs(quat_rotate(b.q[0], EZ)[:2]).max())
        spin.append(b.w[0].copy())

    b.run(solver, 1.0 / 60.0, 60, record)
    spin = np.array(spin)
    assert max(worst) < 1e-9
    # the first substep removes the x, y spin (a constraint impulse); from then on it spins steadily about z
    assert np.abs(spin[:, :2]).max() < 1e-9
    assert np.ptp(spin[1:, 2]) < 1e-9 and spin[-1, 2] == pytest.approx(6.0, rel=0.01)


@pytest.mark.parametrize("method", METHODS)
def test_block_slides_on_plane(method):
    """A block's bottom point held on a 30-degree plane slides down it at g sin 30 and never leaves it."""
    n = np.array([-0.5, np.sqrt(0.75), 0.0])  # plane through the origin, normal tilted 30 degrees
    b = Bodies([1.0], [box_inertia(1.0, 0.2, 0.1, 0.2)], [0.05 * n])
    b.q[0] = quat_from_axis_angle(EZ, np.radians(30.0))
    plane = PointOnPlane(body_a=[0], point_a=[[0.0, -0.05, 0.0]], body_b=[WORLD], plane_point=[[0.0, 0.0, 0.0]],
                         plane_normal=[n])
    solver = b.solver([plane], method=method)
    off = []
    b.run(solver, 1.0 / 60.0, 60, lambda k: off.append(abs(n @ b.point(0, plane.point_a[0]))))
    assert max(off) < 1e-9
    downhill = np.array([-np.sqrt(0.75), -0.5, 0.0])
    assert downhill @ (b.x[0] - 0.05 * n) == pytest.approx(0.5 * G * 0.5 * 1.0**2, rel=1e-3)


@pytest.mark.parametrize("method", METHODS)
def test_elements_fix_z_and_tilt(method):
    """Element rows: translation along world z fixed at its start, rotation about world x and y fixed."""
    b = Bodies([1.0], [box_inertia(1.0, 0.3, 0.2, 0.1)], [[0.0, 0.0, 0.25]])
    b.v[0] = [1.0, 2.0, 3.0]
    b.w[0] = [1.0, -2.0, 3.0]
    elements = Element(body_a=[0, 0, 0], body_b=[WORLD] * 3, axis=[EZ, EX, EY], rotational=[False, True, True],
                       offset=[0.25, 0.0, 0.0])
    solver = b.solver([elements], method=method)
    drift, spin = [], []

    def record(k):
        tilt = 2.0 * np.abs(b.q[0, 1:3] * np.sign(b.q[0, 0])).max()
        drift.append(max(abs(b.x[0, 2] - 0.25), tilt))
        spin.append(b.w[0, 2])

    b.run(solver, 1.0 / 60.0, 60, record)
    assert max(drift) < 1e-9
    assert np.ptp(spin[1:]) < 1e-9 and b.v[0, 2] == 0.0


@pytest.mark.parametrize("method", METHODS)
def test_subtracted_row_is_left_free(method):
    """A nail with its y row subtracted holds x and z; the body falls along y exactly as a free body."""
    b = Bodies([1.0], [sphere_inertia(1.0, 0.1)], [[0.0, 0.0, 0.0]])
    free = Bodies([1.0], [sphere_inertia(1.0, 0.1)], [[0.0, 0.0, 0.0]])
    nail = PointToNail(body=[0], point=[[0.1, 0.0, 0.0]], target=[[0.1, 0.0, 0.0]])
    b.run(b.solver([nail], keep=[[[True, False, True]]], method=method), 1.0 / 60.0, 30)
    free.run(free.solver([]), 1.0 / 60.0, 30)
    assert b.x[0, 1] == pytest.approx(free.x[0, 1], abs=1e-12) and b.x[0, 1] < -1.0
    assert np.abs(b.x[0, [0, 2]]).max() < 1e-12


# ---------------------------------------------------------------- colouring and the reference


def test_colouring():
    chain = pj.colour_instances(np.arange(9), np.arange(1, 10))
    assert len(chain) == 2
    rng = np.random.default_rng(3)
    a, b = rng.integers(-1, 8, 40), rng.integers(-1, 8, 40)
    dynamic = np.ones(8, dtype=bool)
    dynamic[5] = False
    colours = pj.colour_instances(a, b, dynamic)
    assert sorted(np.concatenate(colours).tolist()) == list(range(40))
    for idx in colours:
        used = [bd for i in idx for bd in {a[i], b[i]} if bd != WORLD and dynamic[bd]]
        assert len(used) == len(set(used))


def _mixed_system(rng):
    """Six bodies (body 3 static), every family, WORLD slots, compliance on some rows, one subtracted row."""
    m = [1.0, 0.7, 1.3, 0.0, 0.5, 2.0]
    inertias = [box_inertia(1.0, 0.3, 0.2, 0.1), box_inertia(0.7, 0.2, 0.2, 0.05), sphere_inertia(1.3, 0.1),
                np.eye(3), cylinder_z_inertia(0.5, 0.1), box_inertia(2.0, 0.4, 0.1, 0.3)]
    b = Bodies(m, inertias, rng.normal(scale=0.5, size=(6, 3)))
    b.q = rng.normal(size=(6, 4))
    b.q /= np.linalg.norm(b.q, axis=1, keepdims=True)
    b.v = rng.normal(size=(6, 3))
    b.w = rng.normal(scale=3.0, size=(6, 3))
    unit = lambda v: np.asarray(v, float) / np.linalg.norm(v, axis=-1, keepdims=True)  # noqa: E731
    p = lambda k: rng.normal(scale=0.2, size=(k, 3))  # noqa: E731
    families = [
        PointToPoint(body_a=[0, 1, 2, 4], point_a=p(4), body_b=[1, 2, WORLD, 3], point_b=p(4)),
        PointToNail(body=[5, 0], point=p(2), target=p(2)),
        Orientation(body_a=[0, 1, 4], axis_a=unit(p(3)), body_b=[WORLD, 2, 3], axis_b=unit(p(3))),
        PointOnPlane(body_a=[5, 2], point_a=p(2), body_b=[WORLD, 1], plane_point=p(2), plane_normal=unit(p(2))),
        Element(body_a=[0, 1, 5, 4], body_b=[WORLD, 0, WORLD, 2], axis=unit(p(4)),
                rotational=[False, True, True, False], offset=[0.1, 0.0, 0.0, -0.2],
                reference_rotation=unit(rng.normal(size=(4, 4)))),
        GearToGear(body_a=[4, 0], axis_a=[EZ, EX], radius_a=[0.1, 0.2], body_b=[5, 1], axis_b=[EZ, EY],
                   radius_b=[0.3, 0.1]),
        GearToWeight(gear=[4, 1], arm=p(2), weight=[2, 0], direction=unit(p(2))),
    ]
    compliance = [np.where(rng.random(len(pj.instance_bodies(f)[0])) < 0.3, 1e-4, 0.0) for f in families]
    keep = [np.array([[True, True, True], [True, False, True], [True, True, True], [False, True, True]]),
            None, None, None, None, None, None]
    return b, families, compliance, keep


def test_colour_sweep_equals_reference():
    rng = np.random.default_rng(7)
    b, families, compliance, keep = _mixed_system(rng)
    solver = ProceduralSolver(families, compliance, b.inv_mass, b.inv_inertia, substeps=1, iterations=1, keep=keep)
    hs = 1.0 / 240.0
    solver.integrate(b.x, b.q, b.v, b.w, hs, b.gravity, b.torque)  # sets the start of the substep and moves
    x, q = b.x.copy(), b.q.copy()
    for _ in range(2):
        solver.sweep(x, q, hs)
    xr, qr = b.x.copy(), b.q.copy()
    lam = [np.zeros_like(l) for l in solver.scratch.lam]
    for _ in range(2):
        project_reference(families, solver.plan.colours, xr, qr, solver.scratch.x_prev, solver.scratch.q_prev,
                          b.inv_mass, b.inv_inertia, compliance, hs, lam, keep)
    assert np.abs(x - b.x).max() > 1e-3  # the sweep did something
    np.testing.assert_allclose(x, xr, rtol=0, atol=1e-11)
    np.testing.assert_allclose(q, qr, rtol=0, atol=1e-11)
    for mine, theirs in zip(solver.scratch.lam, lam):
        np.testing.assert_allclose(mine, theirs, rtol=1e-9, atol=1e-13)
    assert np.array_equal(x[3], b.x[3]) and np.array_equal(q[3], b.q[3])  # the static body never moves


def test_direct_projection_equals_reference(monkeypatch):
    """One Newton step of the direct projection (every family, WORLD slots, a static body, compliance, a
    subtracted row) against the dense J W Jd^T built row by row, with and without SHAKE's directions."""
    import isaac_runtime.procedural_direct as pd

    monkeypatch.setattr(pd, "MAX_TURN", np.inf)  # the reference has no trust region
    for use_directions in (True, False):
        rng = np.random.default_rng(11)
        b, families, compliance, keep = _mixed_system(rng)
        solver = ProceduralSolver(families, compliance, b.inv_mass, b.inv_inertia, substeps=1, keep=keep,
                                  method="direct")
        hs = 1.0 / 240.0
        solver.integrate(b.x, b.q, b.v, b.w, hs, b.gravity, b.torque)
        s, d = solver.scratch, solver.direct
        s.before.use_directions = use_directions
        x, q = b.x.copy(), b.q.copy()
        d.start(s.before)
        d.project(x, q, s.now, solver.plan.row_compliance.take(d.rows) / hs**2, None)
        xr, qr, lam = b.x.copy(), b.q.copy(), np.zeros(solver.plan.rows)
        direct_reference(families, xr, qr, s.x_prev, s.q_prev, b.inv_mass, b.inv_inertia, solver.plan.row_compliance,
                         hs, lam, keep, before_frame=s.before)
        assert np.abs(x - b.x).max() > 1e-3  # the projection did something
        np.testing.assert_allclose(x, xr, rtol=0, atol=1e-10)
        np.testing.assert_allclose(q, qr, rtol=0, atol=1e-10)
        np.testing.assert_allclose(d.lam, lam[d.rows], rtol=1e-8, atol=1e-12)
        assert np.array_equal(x[3], b.x[3]) and np.array_equal(q[3], b.q[3])  # the static body never moves


def test_newton_steps_close_a_large_violation():
    """Bodies moved far off their joints: the direct projection's further Newton steps (up to 8) close them in
    one substep, as far as the trust region allows."""
    b, nail, joints = _chain(4)
    b.x[1:] += [[0.0, 0.05, 0.02], [0.03, -0.04, 0.0], [-0.02, 0.0, 0.05]]
    solver = b.solver([nail, joints], substeps=1)
    b.gravity[:] = 0.0
    solver.step(b.x, b.q, b.v, b.w, 1.0 / 60.0, b.gravity, b.torque)
    assert _max_gap(b, nail, joints) < 1e-6


@pytest.mark.parametrize("method", METHODS)
def test_redundant_rows_stay_finite(method):
    """Three orientation rows for two degrees of freedom, one of them twice (J M^-1 J^T singular): the body
    still spins about z only, with no NaN."""
    b = Bodies([1.0], [box_inertia(1.0, 0.3, 0.2, 0.1)], [[0.0, 0.0, 0.0]])
    b.w[0] = [0.0, 0.0, 5.0]
    b.gravity[:] = 0.0
    axes = Orientation(body_a=[0, 0, 0], axis_a=[EZ, EZ, EZ], body_b=[WORLD] * 3, axis_b=[EX, EY, EX])
    nail = PointToNail(body=[0], point=[[0.0, 0.0, 0.0]], target=[[0.0, 0.0, 0.0]])
    b.run(b.solver([nail, axes], method=method), 1.0 / 60.0, 120)
    assert np.isfinite(b.x).all() and np.isfinite(b.q).all()
    assert np.abs(quat_rotate(b.q[0], EZ)[:2]).max() < 1e-9
    assert b.w[0, 2] == pytest.approx(5.0, rel=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_compliance_is_softness(method):
    """A 1 kg ball hanging from a nail of compliance alpha = 1e-4 m/N oscillates about the static stretch
    alpha m g = 9.81e-4 m, whatever the substep (XPBD: alpha / hs^2 in the projection)."""
    b = Bodies([1.0], [sphere_inertia(1.0, 0.05)], [[0.0, -0.05, 0.0]])
    nail = PointToNail(body=[0], point=[[0.0, 0.05, 0.0]], target=[[0.0, 0.0, 0.0]])
    solver = b.solver([nail], compliance=[np.array([1e-4])], substeps=20, method=method)
    stretch = []
    b.run(solver, 1.0 / 60.0, 180, lambda k: stretch.append(-b.point(0, nail.point[0])[1]))
    # the spring rings at sqrt(1 / (alpha m)) = 100 rad/s (no damping): average it over the last 2 s
    assert np.mean(stretch[60:]) == pytest.approx(1e-4 * G, rel=0.02)


@pytest.mark.parametrize("method", METHODS)
def test_rows_are_projected_to_their_targets(method):
    """solver.target (the self-assembly curves' values): a nail's x row held 0.1 m off, a plane row 0.05 m."""
    b = Bodies([1.0], [sphere_inertia(1.0, 0.05)], [[0.0, 0.0, 0.0]])
    b.gravity[:] = 0.0
    nail = PointToNail(body=[0], point=[[0.0, 0.0, 0.0]], target=[[0.0, 0.0, 0.0]])
    solver = b.solver([nail], method=method)
    solver.target = np.array([0.1, -0.02, 0.0])
    b.run(solver, 1.0 / 60.0, 3)
    np.testing.assert_allclose(b.x[0], [0.1, -0.02, 0.0], atol=1e-12)


@pytest.mark.parametrize("ks, kd", [((2 * np.pi * 2) ** 2, 2 * 2 * np.pi * 2), (100.0, 4.0), (100.0, 50.0)])
def test_assembly_curve_solves_the_baumgarte_equation(ks, kd):
    """Curve: C'' + kd C' + ks C = 0 with C(0) = C0, C'(0) = D0, critically, under- and over-damped."""
    from scipy.integrate import solve_ivp

    C0, D0 = np.array([0.4, -0.3]), np.array([0.0, 2.0])
    s = np.linspace(0.0, 2.0, 41)
    curve = Curve(C0, D0, np.full(2, ks), np.full(2, kd))
    for i in range(2):
        exact = solve_ivp(lambda t, y: [y[1], -kd * y[1] - ks * y[0]], (0, 2), [C0[i], D0[i]], t_eval=s,
                          rtol=1e-11, atol=1e-13).y[0]
        np.testing.assert_allclose([curve(np.full(2, si))[i] for si in s], exact, atol=1e-8)
    assert np.all(curve.span > 0)


def test_auto_takes_the_direct_projection_up_to_its_limit(monkeypatch):
    import isaac_runtime.procedural as procedural

    b, nail, joints = _chain()
    assert b.solver([nail, joints]).plan.method == "direct"
    monkeypatch.setattr(procedural, "DIRECT_MAX_ROWS", 20)
    assert b.solver([nail, joints]).plan.method == "gauss-seidel"
