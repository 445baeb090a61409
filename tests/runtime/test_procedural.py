"""The procedural plan (runtime/procedural): exact answers (pendulum period, gear ratio, rope acceleration), each
constraint family held, both projections (all rows at once, Gauss-Seidel), compliance, redundant rows, the
self-assembly curve, and the free rigid body's invariants (a tumbling box keeps its energy and angular momentum).
Scenes with collisions, wind and kinematic bodies: test_procedural_scenes.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ellipk

from isaac_runtime.procedural.project import curve
from isaac_runtime.core.rotation import quat_rotate, quat_to_matrix
from isaac.api import Simulation

G = 9.81
METHODS = ("direct", "gauss_seidel")


def simulation(body: str, method: str = "direct", substeps: int = 10, step: str = "(1/60) s", iterations: int = 1,
               gravity: str = "(0, -9.81, 0)", end: str = "5 s", extra: str = "") -> Simulation:
    text = f"""scene t {{
  time 0 s .. {end}
  frames 60 Hz
  gravity {gravity} m/s2
  solver procedural {{ step {step}  substeps {substeps}  iterations {iterations}  projection {method}  {extra} }}
{body}
}}"""
    return Simulation.from_text(text)


def frames(sim: Simulation, until: float, every: float = 1.0 / 60.0):
    """t (k,), and the state (x, q, v, w) copied at each time."""
    out = []
    t = 0.0
    while t < until - 1e-9:
        t = min(until, t + every)
        sim.advance_to(t)
        s = sim.state
        out.append((s.t, s.x.copy(), s.q.copy(), s.v.copy(), s.w.copy()))
    return out


def point(x, q, body, p):
    return x[body] + quat_rotate(q[body], np.asarray(p, dtype=float))


# ---------------------------------------------------------------- exact answers

PENDULUM = """
  body bob sphere { radius 5 cm  mass 1 kg  at (0.866025403784, 0.5, 0) }
  constraint hang nail(bob @ (-0.866025403784, 0.5, 0), (0, 1, 0))
"""


@pytest.mark.parametrize("method", METHODS)
def test_pendulum_period_matches_elliptic_integral(method):
    """Sphere r = 0.05 m, 1 kg, on a 1 m arm, released at 60 degrees: T = 4 sqrt(I_p / (m g L)) K(sin^2 30deg).
    At h = 1/60 with 10 substeps: the corrections go along the start-of-substep gradients (SHAKE), so the period
    is kept (measured 3e-6 relative; plain XPBD loses 7e-3) and the nail holds."""
    sim = simulation(PENDULUM, method)
    states = frames(sim, 5.5)
    t = np.array([s[0] for s in states])
    xs = np.array([s[1][0, 0] for s in states])
    gaps = [np.linalg.norm(point(s[1], s[2], 0, (-0.866025403784, 0.5, 0)) - [0, 1, 0]) for s in states]
    down = np.flatnonzero((xs[:-1] > 0.0) & (xs[1:] <= 0.0))  # the bob passes the bottom moving -x
    crossings = t[down] + (t[1] - t[0]) * xs[down] / (xs[down] - xs[down + 1])
    period = np.diff(crossings)
    exact = 4.0 * np.sqrt(1.001 / (1.0 * G * 1.0)) * ellipk(np.sin(np.radians(30.0)) ** 2)
    assert len(period) >= 2
    assert np.abs(period / exact - 1.0).max() < 2e-5
    assert max(gaps) < 1e-9


CHAIN = """
  for i in 0 .. 10 {
    body link{i} box { size (0.2, 2 cm, 2 cm)  mass 0.5 kg  at (0.2 * i + 0.1, 0, 0)  collide off }
  }
  constraint anchor nail(link0 @ (-0.1, 0, 0), (0, 0, 0))
  for i in 0 .. 9 {
    constraint joint{i} point(link{i} @ (0.1, 0, 0), link{i+1} @ (-0.1, 0, 0))
  }
"""


def _chain_run(method, substeps, step, iterations=1, seconds=3.0):
    sim = simulation(CHAIN, method, substeps, step, iterations)
    start = sim.energy()
    gap = energy = 0.0
    for _ in frames(sim, seconds):
        gap = max(gap, sim.constraint_errors()[0])
        energy = max(energy, abs(sim.energy() - start))
    assert np.isfinite(sim.state.x).all()
    return gap, energy / (5.0 * G * 2.0)  # relative to m_total g L_total


@pytest.mark.parametrize("method, substeps, step, gap_limit, energy_limit", [
    ("direct", 20, "10 ms", 1e-5, 2e-3),
    ("direct", 20, "(1/30) s", 1e-4, 3e-3),
    ("direct", 1, "10 ms", 1e-4, 0.5),  # one substep: joints closed (Newton iterations), energy lost
    ("gauss_seidel", 20, "10 ms", 5e-3, 3e-2),  # sweeps leave the whip's stretch open by a fraction of a mm
])
def test_chain_holds_together(method, substeps, step, gap_limit, energy_limit):
    """A 10-link chain falls from horizontal for 3 s; the whip at its free end (links at 50 rad/s, the chain taut)
    is the hard part."""
    gap, energy = _chain_run(method, substeps, step)
    assert gap < gap_limit
    assert energy < energy_limit


GEARS = """
  kind axle(gear) = nail(gear @ (0, 0, 0)) + orient(gear.z, x) + orient(gear.z, y)
  body drive cylinder { radius 0.1 m  length 2 cm  mass 0.5 kg  at (0, 0, 0) }
  body wheel cylinder { radius 0.3 m  length 2 cm  mass 2 kg  at (0.4, 0, 0) }
  body weight sphere { radius 3 cm  mass 1 kg  at (-0.1, -0.5, 0)  collide off }
  constraint drive_axle axle(drive)
  constraint wheel_axle axle(wheel)
  constraint mesh gear(drive.z, 0.1 m, wheel.z, 0.3 m)
  constraint rope rope(drive, (-0.1, 0, 0) m, weight, -y)
"""


@pytest.mark.parametrize("method, iterations, lag", [("direct", 1, 1e-4), ("gauss_seidel", 4, 3e-3)])
def test_gears_keep_ratio_and_weight_falls_at_exact_rate(method, iterations, lag):
    """0.1 w_drive + 0.3 w_wheel = 0 at every frame, and a = g m / (m + I_d / r_d^2 + I_w / r_w^2) = g / 2.25; the
    positions of a substep's symplectic Euler lead the exact ones by a hs t / 2 (3.6 mm at hs = 1/600 s, t = 1 s)."""
    sim = simulation(GEARS, method, iterations=iterations)
    ratio = [0.1 * s[4][0, 2] + 0.3 * s[4][1, 2] for s in frames(sim, 1.0)]
    assert np.abs(ratio).max() < 1e-9 * abs(0.1 * sim.state.w[0, 2])
    a, hs = G / 2.25, 1.0 / 600.0
    # (Gauss-Seidel: the rope and the gear, projected one after the other, leave the weight 1.8 mm further)
    assert sim.state.x[2, 1] == pytest.approx(-0.5 - 0.5 * a - 0.5 * a * hs, abs=lag)
    assert sim.state.w[0, 2] > 0.0 > sim.state.w[1, 2]


# ---------------------------------------------------------------- each family holds


@pytest.mark.parametrize("method", METHODS)
def test_orientation_keeps_spin_axis(method):
    """A spinning box with two orientation rows (body z perpendicular to world x and to world y): the x, y spin
    it starts with is removed as the rows assemble, then it spins steadily about z."""
    sim = simulation("""
  body b box { size (0.3, 0.2, 0.1) m  mass 1 kg  spin (2, -1, 6) }
  constraint axes orient(b.z, x) + orient(b.z, y) { stabilize 10 Hz }""", method, gravity="(0, 0, 0)")
    states = frames(sim, 3.0)
    late = [s for s in states if s[0] >= 2.0]
    assert max(np.abs(quat_rotate(s[2][0], [0, 0, 1])[:2]).max() for s in late) < 1e-9
    spin = np.array([s[4][0] for s in late])
    assert np.abs(spin[:, :2]).max() < 1e-9 and np.ptp(spin[:, 2]) < 1e-9


@pytest.mark.parametrize("method", METHODS)
def test_block_slides_on_plane(method):
    """A block's bottom point held on a 30-degree plane slides down it at g sin 30 and never leaves it."""
    sim = simulation("""
  body b box { size (0.2, 0.1, 0.2) m  mass 1 kg  at (-0.025, 0.0433012701892, 0)  orient (0, 0, 30 deg)  collide off }
  constraint on plane(b @ (0, -0.05, 0), (0, 0, 0), (-0.5, 0.866025403784, 0))""", method, end="1 s")
    n = np.array([-0.5, math.sqrt(0.75), 0.0])
    states = frames(sim, 1.0)
    assert max(abs(n @ point(s[1], s[2], 0, (0, -0.05, 0))) for s in states) < 1e-9
    downhill = np.array([-math.sqrt(0.75), -0.5, 0.0])
    # s = a t^2 / 2 with a = g sin 30, and the substeps' lead a hs t / 2 (hs = 1/600 s)
    a = 0.5 * G
    assert downhill @ (sim.state.x[0] - 0.05 * n) == pytest.approx(0.5 * a + 0.5 * a / 600.0, rel=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_subtracted_row_is_left_free(method):
    """A nail with its y row subtracted holds x and z; the body falls along y exactly as a free body."""
    held = simulation("""
  body b sphere { radius 0.1 m  mass 1 kg }
  constraint slide nail(b @ (0.1, 0, 0)) - ty""", method, end="0.5 s")
    free = simulation("  body b sphere { radius 0.1 m  mass 1 kg }", method, end="0.5 s")
    held.advance_to(0.5)
    free.advance_to(0.5)
    assert held.state.x[0, 1] == pytest.approx(free.state.x[0, 1], abs=1e-12) and held.state.x[0, 1] < -1.0
    assert np.abs(held.state.x[0, [0, 2]]).max() < 1e-12


@pytest.mark.parametrize("method", METHODS)
def test_redundant_rows_stay_finite(method):
    """Three orientation rows for two degrees of freedom: finite, held, and said (rank-deficient)."""
    sim = simulation("""
  body b box { size (0.3, 0.2, 0.1) m  mass 1 kg  spin (0, 0, 3) }
  constraint axes orient(b.z, x) + orient(b.z, y) + orient(b.z, x)""", method, gravity="(0, 0, 0)", end="1 s")
    sim.advance_to(1.0)
    assert np.isfinite(sim.state.q).all() and sim.constraint_errors()[0] < 1e-9
    if method == "direct":
        assert sim.rank_deficient()


def test_compliance_is_softness():
    """A 1 kg bob on a nail with compliance c (m/N) hangs c m g below it, as a spring of stiffness 1/c would."""
    sim = simulation("""
  body bob sphere { radius 5 cm  mass 1 kg }
  constraint hang nail(bob @ (0, 0, 0)) { compliance 1e-4 }""", "direct", end="4 s", extra="")
    sim.plan.scene.solver  # (the scene's compliance is per constraint)
    for _ in frames(sim, 4.0):
        pass
    assert sim.state.x[0, 1] == pytest.approx(-1e-4 * G, rel=2e-3)


# ---------------------------------------------------------------- self-assembly and the free rigid body


@pytest.mark.parametrize("ks, kd", [((2 * np.pi * 2) ** 2, 2 * 2 * np.pi * 2), (100.0, 4.0), (100.0, 50.0)])
def test_assembly_curve_solves_the_baumgarte_equation(ks, kd):
    """curve(C0, D0, ks, kd, s) meets C'' + kd C' + ks C = 0, C(0) = C0, C'(0) = D0 (critically, under- and
    over-damped), checked by finite differences."""
    C0, D0, h = 0.4, -0.3, 1e-4
    for s in (0.0, 0.1, 0.5, 1.3):
        c = [curve(C0, D0, ks, kd, s + k * h)[0] for k in (-1, 0, 1)] if s > 0 else None
        if c is None:
            assert curve(C0, D0, ks, kd, 0.0)[0] == pytest.approx(C0)
            slope = (curve(C0, D0, ks, kd, h)[0] - curve(C0, D0, ks, kd, 0.0)[0]) / h
            assert slope == pytest.approx(D0, abs=1e-2)
            continue
        second, first = (c[2] - 2 * c[1] + c[0]) / h**2, (c[2] - c[0]) / (2 * h)
        assert abs(second + kd * first + ks * c[1]) < 1e-5 * max(ks, 1.0)


TUMBLER = """
  body box box { size (0.3, 0.2, 0.1) m  mass 1 kg  spin (0.05, 6, 0.05) }
"""


def _invariants(sim):
    s, plan = sim.state, sim.plan
    R = quat_to_matrix(s.q[0])
    I = R @ plan.inertia_body[0] @ R.T
    return 0.5 * s.w[0] @ I @ s.w[0], I @ s.w[0]


@pytest.mark.parametrize("substeps", [1, 4])
def test_a_tumbling_box_keeps_energy_and_angular_momentum(substeps):
    """A box spun near its intermediate axis flips over and over (Dzhanibekov); at 10 ms steps its energy and
    world angular momentum are those it started with, to round-off: the move is the implicit midpoint rule on
    Euler's equations with the Cayley map, which keeps both (an explicit gyroscopic update gained 2.4e-3 of the
    energy per flip)."""
    sim = simulation(TUMBLER, "direct", substeps=substeps, step="10 ms", gravity="(0, 0, 0)", end="20 s")
    E0, L0 = _invariants(sim)
    # a flip: the body's y axis (the intermediate one, spun about) turns over against the angular momentum
    side = lambda: np.sign(quat_rotate(sim.state.q[0], [0, 1, 0]) @ L0)  # noqa: E731
    flips, last = 0, side()
    worst_E = worst_L = 0.0
    for k in range(1, 2001):
        sim.advance_to(0.01 * k)
        E, L = _invariants(sim)
        worst_E, worst_L = max(worst_E, abs(E / E0 - 1)), max(worst_L, np.linalg.norm(L - L0) / np.linalg.norm(L0))
        now = side()
        flips += now != last
        last = now
    assert flips >= 4  # it does tumble
    # round-off alone: measured 2.8e-12 and 1.4e-12 over 8000 substeps (the issue asks 1e-4 per flip)
    assert worst_E < 1e-9 and worst_L < 1e-10


@pytest.mark.parametrize("method", ("auto", "direct"))
def test_auto_holds_a_large_tree_with_every_row_at_once(method):
    # 63 spheres, 189 rows, at the plan's defaults (a step a frame, 20 substeps): sweeps (`gauss_seidel`) blow up at
    # 0.46 s, and trees of 127 to 1023 spheres at 0.25 to 0.3 s; `auto` took them beyond 64 rows. All rows at once
    # hold every joint
    from benchmarks.scaling import tree_text

    solver, text = "solver dynamics { integrator rk4  step 1 ms }", tree_text(63)
    assert solver in text
    procedural = f"solver procedural {{ step 10 ms  substeps 20  projection {method} }}"
    sim = Simulation.from_text(text.replace(solver, procedural))
    e0 = sim.energy()
    sim.advance_to(1.0)
    assert sim.constraint_errors()[0] < 1e-8
    assert abs(sim.energy() - e0) < 0.05 * 63 * 0.1 * G * 1.0  # of m g (the tree's depth, 1 m)
