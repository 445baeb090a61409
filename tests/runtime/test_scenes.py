"""Each example scene against its exact answer (stated in its header comment), with its own default settings."""
from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipk

from isaac_lang.load import load_scene
from isaac_runtime.core.rotation import quat_rotate, quat_to_matrix
from isaac_runtime.run import RunOptions, simulate

SCENES = Path(__file__).resolve().parents[2] / "scenes"
G = 9.81


@functools.lru_cache(maxsize=None)
def run(name: str, solver: str | None = None):
    result = simulate(load_scene(SCENES / f"{name}.isaac").scene, RunOptions(solver=solver))
    assert result.error is None, result.error
    return result


def body_points(arrays, body: int, point) -> np.ndarray:
    """World trajectory (T,3) of a body-frame point."""
    q = arrays["orientation"][:, body]
    return arrays["position"][:, body] + quat_rotate(q, np.broadcast_to(np.asarray(point, float), (len(q), 3)))


def crossing_times(time, value, rate) -> np.ndarray:
    """Times where value crosses zero upward, located on the cubic Hermite interpolant of (value, rate)."""
    out = []
    for k in np.flatnonzero((value[:-1] < 0) & (value[1:] >= 0)):
        t0, h = time[k], time[k + 1] - time[k]
        p0, p1, m0, m1 = value[k], value[k + 1], rate[k] * h, rate[k + 1] * h
        u = -p0 / (p1 - p0)
        for _ in range(30):  # Newton on the Hermite cubic
            h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
            f = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
            df = (6 * u**2 - 6 * u) * p0 + (3 * u**2 - 4 * u + 1) * m0 + (-6 * u**2 + 6 * u) * p1 + (3 * u**2 - 2 * u) * m1
            u -= f / df
        out.append(t0 + u * h)
    return np.array(out)


def measured_period(arrays, body: int) -> float:
    t = arrays["time"]
    x, vx = arrays["position"][:, body, 0], arrays["linear_velocity"][:, body, 0]
    crossings = crossing_times(t, x, vx)
    assert len(crossings) >= 3
    return (crossings[-1] - crossings[0]) / (len(crossings) - 1)


def test_pendulum_period_matches_elliptic_integral():
    arrays = run("pendulum").recorder.arrays()
    theta0 = math.radians(60)
    inertia, length = 1.0 + 0.4 * 0.05**2, 1.0
    exact = 4 * math.sqrt(inertia / (G * length)) * ellipk(math.sin(theta0 / 2) ** 2)
    assert abs(measured_period(arrays, 0) / exact - 1) < 1e-6


def test_pendulum_nail_holds():
    arrays = run("pendulum").recorder.arrays()
    nailed = body_points(arrays, 0, (-math.sin(math.radians(60)), math.cos(math.radians(60)), 0))
    assert np.max(np.linalg.norm(nailed - [0, 1, 0], axis=1)) < 1e-6


def test_transition_axes_follow_the_switching_constraints():
    arrays = run("transition").recorder.arrays()
    t = arrays["time"]
    R = quat_to_matrix(arrays["orientation"][:, 0])
    at = lambda s: int(np.argmin(np.abs(t - s)))
    angle = lambda a, b: math.acos(min(1.0, abs(float(np.dot(a, b)))))
    for s in (1.0, 2.0, 2.4):
        assert angle(R[at(s)][:, 2], [0, 0, 1]) < 1e-6  # body z along world z
    assert angle(R[at(4.9)][:, 1], [0, 1, 0]) < 1e-6  # body y along world y
    assert np.max(np.abs(arrays["position"][:, 0])) < 1e-6  # the centre stays at the origin


def test_windmill_period_and_single_axis():
    arrays = run("windmill").recorder.arrays()
    m, a, b, d = 3.0, 2.0, 0.2, 0.5
    inertia = m * (a * a + b * b) / 12 + m * d * d
    exact = 4 * math.sqrt(inertia / (m * G * d)) * ellipk(0.5)
    blade = 1
    assert abs(measured_period(arrays, blade) / exact - 1) < 1e-6
    assert np.max(np.abs(arrays["angular_velocity"][:, blade, :2])) < 1e-6


def test_chain_conserves_energy_and_joints():
    result = run("chain")
    arrays = result.recorder.arrays()
    assert result.report["energy_drift_relative"] < 1e-4
    gaps = [np.linalg.norm(body_points(arrays, i, (0.1, 0, 0)) - body_points(arrays, i + 1, (-0.1, 0, 0)), axis=1)
            for i in range(9)]
    assert np.max(gaps) < 1e-6
    assert np.max(np.linalg.norm(body_points(arrays, 0, (-0.1, 0, 0)), axis=1)) < 1e-6


def test_gears_ratio_and_falling_weight():
    arrays = run("gears").recorder.arrays()
    names = list(arrays["bodies"])
    drive, wheel, weight = names.index("drive"), names.index("wheel"), names.index("weight")
    w = arrays["angular_velocity"]
    assert np.max(np.abs(0.1 * w[:, drive, 2] + 0.3 * w[:, wheel, 2])) < 1e-9
    inertia_d, inertia_w = 0.5 * 0.5 * 0.1**2, 0.5 * 2.0 * 0.3**2
    accel = G / (1.0 + inertia_d / 0.1**2 + inertia_w / 0.3**2)
    assert accel == pytest.approx(G / 2.25)
    t = arrays["time"]
    assert np.max(np.abs(arrays["position"][:, weight, 1] - (-0.5 - 0.5 * accel * t**2))) < 1e-6
    speed = np.linalg.norm(arrays["linear_velocity"][:, weight], axis=1)
    assert np.max(np.abs(speed - 0.1 * np.abs(w[:, drive, 2]))) < 1e-9


def assembly_errors(arrays) -> tuple:
    """(largest move before the joint switches on at 1 s, largest distance of the gap from the critically damped
    curve g0 (1 + w0 s) exp(-w0 s) after it), for the selfassembly scene; g0 = 0.4 m, w0 = 2 pi 2 Hz."""
    t = arrays["time"]
    gap = np.linalg.norm(body_points(arrays, 1, (-0.05, 0, 0)) - body_points(arrays, 0, (0.05, 0, 0)), axis=1)
    before = t < 1.0
    s = t[~before] - 1.0
    g0, w0 = 0.4, 2 * math.pi * 2
    moved = np.max(np.abs(arrays["position"][before] - arrays["position"][0]))
    return moved, np.max(np.abs(gap[~before] - g0 * (1 + w0 * s) * np.exp(-w0 * s)))


def test_selfassembly_follows_the_critically_damped_curve():
    moved, curve_error = assembly_errors(run("selfassembly").recorder.arrays())
    assert moved == 0.0
    assert curve_error < 1e-4 * 0.4
