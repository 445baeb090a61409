"""The scenes with a known answer (SCENES.md) and how far a trajectory is from it.

Each Case names a scene (and --set overrides), how long to run it, and a function from a trajectory
(common.py's dict, sampled every ~1 ms) to its errors. The same functions judge our runs and the peers', so a
ratio compares like with like. Errors, all >= 0:

    period_error     |T_measured / T_exact - 1|; T from the zero crossings of the body's x (both directions,
                     located on the cubic Hermite interpolant of x and dx/dt, as tests/runtime/test_scenes.py)
    joint_drift      m, the largest distance between two points a joint holds together (or a point and its nail)
    energy_drift     max |E(t) - E(0)| / (m g extent), as report.json's energy_drift_relative
    off_axis         rad/s, the windmill's largest angular velocity about x or y
    ratio_residual   rad*m/s, max |0.1 w_drive + 0.3 w_wheel|
    fall_error       m, max |y_weight(t) - (-0.5 - a t^2 / 2)|, a = g / 2.25
    curve_error      max |gap(t) - g0 (1 + w0 s) exp(-w0 s)| / g0 after the switch at 1 s
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ellipk

G = 9.81


@dataclass(frozen=True)
class Physics:
    """The bodies as our plan compiled them: what a peer model is built from, and what energy needs."""

    names: tuple
    mass: np.ndarray  # (B,)
    inertia: np.ndarray  # (B,3,3) body frame
    dynamic: np.ndarray  # (B,) bool
    x0: np.ndarray  # (B,3)
    energy_scale: float  # J


@dataclass(frozen=True)
class Case:
    name: str
    scene: str  # scenes/NAME.isaac
    until: float  # s simulated (the scene's own end may be later)
    metrics: tuple  # error names, the first the headline
    overrides: tuple = ()  # (("theta0", "10 deg"),)
    params: dict = field(default_factory=dict, hash=False, compare=False)

    def load(self):
        """The scene, with contacts off: none of these answers has one, and the peers run without contacts too
        (the gears touch at their rims, and would pay for collision detection in our runs alone)."""
        import dataclasses

        from .common import load

        scene = load(self.scene, dict(self.overrides))
        return dataclasses.replace(scene, bodies=tuple(dataclasses.replace(b, collide=False) for b in scene.bodies))

    def measure(self, trajectory: dict) -> dict:
        return MEASURES[self.scene](self, trajectory)


@functools.lru_cache(maxsize=None)
def physics(case: Case) -> Physics:
    from isaac_runtime.core.build import energy_scale

    from .common import plan_for

    plan = plan_for(case.load(), "dynamics")
    return Physics(tuple(plan.names), plan.mass.copy(), plan.inertia_body.copy(), plan.dynamic.copy(),
                   plan.x0.copy(), energy_scale(plan))


# -- exact answers ---------------------------------------------------------------------------------------------


def pendulum_period(theta0_deg: float, inertia: float = 1.0 + 0.4 * 0.05**2, m: float = 1.0, d: float = 1.0):
    """Physical pendulum from rest at theta0: T = 4 sqrt(I_p / (m g d)) K(sin^2(theta0 / 2))."""
    return 4.0 * math.sqrt(inertia / (m * G * d)) * float(ellipk(math.sin(math.radians(theta0_deg) / 2) ** 2))


WINDMILL_INERTIA = 3.0 * (2.0**2 + 0.2**2) / 12 + 3.0 * 0.5**2  # m (a^2 + b^2)/12 + m d^2 = 1.76
WINDMILL_PERIOD = pendulum_period(90.0, WINDMILL_INERTIA, 3.0, 0.5)
GEAR_ACCEL = G / 2.25  # m g / (m + I_d / r_d^2 + I_w / r_w^2)


def _pendulum_case(theta: float) -> Case:
    period = pendulum_period(theta)
    return Case(f"pendulum{theta:g}", "pendulum", round(1.3 * period, 2),
                ("period_error", "joint_drift", "energy_drift"), (("theta0", f"{theta:g} deg"),),
                {"theta0": theta, "period": period})


CASES = [
    _pendulum_case(10.0), _pendulum_case(90.0), _pendulum_case(150.0),
    Case("windmill", "windmill", round(1.3 * WINDMILL_PERIOD, 2), ("period_error", "joint_drift", "off_axis",
                                                                      "energy_drift"), params={"period": WINDMILL_PERIOD}),
    Case("chain", "chain", 2.0, ("energy_drift", "joint_drift")),
    Case("gears", "gears", 1.0, ("ratio_residual", "fall_error")),
    Case("selfassembly", "selfassembly", 2.5, ("curve_error",)),
]
BY_NAME = {c.name: c for c in CASES}


# -- measures --------------------------------------------------------------------------------------------------


def body_points(traj: dict, body: int, point) -> np.ndarray:
    """World trajectory (T,3) of a body-frame point."""
    from isaac_runtime.core.rotation import quat_rotate

    q = traj["orientation"][:, body]
    return traj["position"][:, body] + quat_rotate(q, np.broadcast_to(np.asarray(point, float), (len(q), 3)))


def crossings(time, value, rate) -> np.ndarray:
    """Times where value changes sign, on the cubic Hermite interpolant of (value, rate) between samples."""
    out = []
    for k in np.flatnonzero(np.signbit(value[:-1]) != np.signbit(value[1:])):
        t0, h = time[k], time[k + 1] - time[k]
        p0, p1, m0, m1 = value[k], value[k + 1], rate[k] * h, rate[k + 1] * h
        u = -p0 / (p1 - p0) if p1 != p0 else 0.5
        for _ in range(30):  # Newton on the Hermite cubic
            f = (2 * u**3 - 3 * u**2 + 1) * p0 + (u**3 - 2 * u**2 + u) * m0 + (-2 * u**3 + 3 * u**2) * p1 \
                + (u**3 - u**2) * m1
            df = (6 * u**2 - 6 * u) * p0 + (3 * u**2 - 4 * u + 1) * m0 + (-6 * u**2 + 6 * u) * p1 \
                + (3 * u**2 - 2 * u) * m1
            if df == 0:
                break
            u -= f / df
        out.append(t0 + min(max(u, 0.0), 1.0) * h)
    return np.array(out)


def period_error(traj: dict, body: int, exact: float) -> float:
    """A half period between consecutive crossings of x = 0; the first and last crossing span whole periods."""
    c = crossings(traj["time"], traj["position"][:, body, 0], traj["linear_velocity"][:, body, 0])
    if len(c) < 3:
        return math.nan
    measured = 2.0 * (c[-1] - c[0]) / (len(c) - 1)
    return abs(measured / exact - 1.0)


def energy(traj: dict, ph: Physics) -> np.ndarray:
    """(T,) kinetic + gravitational potential energy of the dynamic bodies (as Simulation.energy)."""
    from isaac_runtime.core.rotation import quat_to_matrix

    d = ph.dynamic
    v, w = traj["linear_velocity"][:, d], traj["angular_velocity"][:, d]
    R = quat_to_matrix(traj["orientation"][:, d])
    Iw = np.einsum("tnij,njk,tnlk->tnil", R, ph.inertia[d], R)
    kinetic = 0.5 * np.einsum("n,tni,tni->t", ph.mass[d], v, v) + 0.5 * np.einsum("tni,tnij,tnj->t", w, Iw, w)
    return kinetic + G * np.einsum("n,tn->t", ph.mass[d], traj["position"][:, d, 1])


def energy_drift(traj: dict, ph: Physics) -> float:
    e = energy(traj, ph)
    return float(np.max(np.abs(e - e[0])) / ph.energy_scale)


def _finite_max(values) -> float:
    values = np.asarray(values, float)
    return float(np.max(values)) if values.size and np.all(np.isfinite(values)) else math.nan


def measure_pendulum(case: Case, traj: dict) -> dict:
    theta = math.radians(case.params["theta0"])
    nailed = body_points(traj, 0, (-math.sin(theta), math.cos(theta), 0.0))
    return {"period_error": period_error(traj, 0, case.params["period"]),
            "joint_drift": _finite_max(np.linalg.norm(nailed - [0.0, 1.0, 0.0], axis=1)),
            "energy_drift": energy_drift(traj, physics(case))}


def measure_windmill(case: Case, traj: dict) -> dict:
    blade = physics(case).names.index("blade")
    pivot = body_points(traj, blade, (-0.5, 0.0, 0.0))
    return {"period_error": period_error(traj, blade, case.params["period"]),
            "joint_drift": _finite_max(np.linalg.norm(pivot, axis=1)),
            "off_axis": _finite_max(np.abs(traj["angular_velocity"][:, blade, :2])),
            "energy_drift": energy_drift(traj, physics(case))}


def chain_joint_drift(traj: dict, links: int, half: float = 0.1) -> float:
    gaps = [np.linalg.norm(body_points(traj, 0, (-half, 0, 0)), axis=1)]
    for i in range(links - 1):
        gaps.append(np.linalg.norm(body_points(traj, i, (half, 0, 0)) - body_points(traj, i + 1, (-half, 0, 0)), axis=1))
    return _finite_max(gaps)


def measure_chain(case: Case, traj: dict) -> dict:
    return {"energy_drift": energy_drift(traj, physics(case)),
            "joint_drift": chain_joint_drift(traj, len(physics(case).names))}


def measure_gears(case: Case, traj: dict) -> dict:
    names = physics(case).names
    drive, wheel, weight = names.index("drive"), names.index("wheel"), names.index("weight")
    w, t = traj["angular_velocity"], traj["time"]
    fall = traj["position"][:, weight, 1] - (-0.5 - 0.5 * GEAR_ACCEL * t**2)
    return {"ratio_residual": _finite_max(np.abs(0.1 * w[:, drive, 2] + 0.3 * w[:, wheel, 2])),
            "fall_error": _finite_max(np.abs(fall))}


def measure_selfassembly(case: Case, traj: dict) -> dict:
    t = traj["time"]
    gap = np.linalg.norm(body_points(traj, 1, (-0.05, 0, 0)) - body_points(traj, 0, (0.05, 0, 0)), axis=1)
    after = t >= 1.0 - 1e-12
    s = t[after] - 1.0
    g0, w0 = 0.4, 2 * math.pi * 2
    still = traj["position"][~after] - traj["position"][0]
    error = np.abs(gap[after] - g0 * (1 + w0 * s) * np.exp(-w0 * s)) / g0
    return {"curve_error": _finite_max(np.concatenate((error, np.abs(still).ravel() / g0)))}


MEASURES = {"pendulum": measure_pendulum, "windmill": measure_windmill, "chain": measure_chain,
            "gears": measure_gears, "selfassembly": measure_selfassembly}
