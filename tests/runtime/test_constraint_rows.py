"""Constraint rows: the compiled kernels (runtime/core/rows.py) against the scalar reference, and against calculus.

Every check compares with an independently computed quantity: the scalar oracle (rows_reference.py, which
computes bias as Jdot v rather than d2C/dt2), finite differences of C along free motion, and known rotations.
"""
from __future__ import annotations

import numpy as np
import pytest

from isaac_runtime.constraints.layout import (
    WORLD,
    BodyFrame,
    Element,
    GearToGear,
    GearToWeight,
    Orientation,
    PointOnPlane,
    PointToNail,
    PointToPoint,
)
from isaac_runtime.constraints.plan import capture_element_references, row_count
from isaac_runtime.core.rotation import (
    quat_from_axis_angle,
    quat_integrate,
    quat_multiply,
    quat_normalize,
    quat_rotate,
    quat_to_matrix,
)

from .core_helpers import model_of, packed_state, rows_at
from .rows_reference import reference_rows

N_BODIES = 5  # bodies in every random scene
K = 6  # instances per family; the first two are referenced to the WORLD
T0 = 0.3  # time of evaluation (P(t) has nonzero sin and cos there)
NAIL_AMPLITUDE_FREQ = 3.0  # P(t) = P0 + A sin(3 t)


def _unit(rng, k):
    u = rng.normal(size=(k, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def _pairs(rng):
    """body_a (k,) and a distinct body_b (k,), with body_b WORLD for the first two instances."""
    a = rng.integers(0, N_BODIES, K)
    b = (a + rng.integers(1, N_BODIES, K)) % N_BODIES
    b[:2] = WORLD
    return a, b


def _random_poses(rng):
    return rng.normal(size=(N_BODIES, 3)), quat_normalize(rng.normal(size=(N_BODIES, 4)))


def _element(rng):
    a, b = _pairs(rng)
    fam = Element(a, b, _unit(rng, K), rotational=[True, False, True, False, True, False])
    capture_element_references(fam, *_random_poses(rng))  # references from another pose: C != 0 here
    return fam


def _point_to_point(rng):
    a, b = _pairs(rng)
    return PointToPoint(a, rng.normal(size=(K, 3)), b, rng.normal(size=(K, 3)))


def _point_to_nail(rng):
    body, p, P, dP, ddP = rng.integers(0, N_BODIES, K), *rng.normal(size=(4, K, 3))
    return PointToNail(body, p, P, dP, ddP)


def _orientation(rng):
    a, b = _pairs(rng)
    return Orientation(a, _unit(rng, K), b, _unit(rng, K))


def _point_on_plane(rng):
    a, b = _pairs(rng)
    return PointOnPlane(a, rng.normal(size=(K, 3)), b, rng.normal(size=(K, 3)), _unit(rng, K))


def _gear_to_gear(rng):
    a, b = _pairs(rng)
    return GearToGear(a, _unit(rng, K), rng.uniform(0.1, 2.0, K), b, _unit(rng, K), rng.uniform(0.1, 2.0, K))


def _gear_to_weight(rng):
    gear, weight = _pairs(rng)
    return GearToWeight(gear, rng.normal(size=(K, 3)), weight, _unit(rng, K))


BUILDERS = {
    "point_to_point": _point_to_point,
    "point_to_nail": _point_to_nail,
    "orientation": _orientation,
    "point_on_plane": _point_on_plane,
    "gear_to_gear": _gear_to_gear,
    "gear_to_weight": _gear_to_weight,
    "element": _element,
}
FAMILIES = sorted(BUILDERS)
POSITIONAL = [f for f in FAMILIES if not f.startswith("gear")]


def _frame(x, q, v, w, t=T0):
    return BodyFrame(x=x, q=q, v=v, w=w, R=quat_to_matrix(q), t=t)


def _scene(name, seed=0):
    """A family instance set and a random frame (poses and velocities) for it."""
    rng = np.random.default_rng([seed, FAMILIES.index(name)])
    fam = BUILDERS[name](rng)
    x, q = _random_poses(rng)
    return fam, _frame(x, q, rng.normal(size=(N_BODIES, 3)), rng.normal(size=(N_BODIES, 3))), rng


def _rows(fam, frame):
    """The compiled rows of the family's instances at the frame."""
    return rows_at(model_of([fam], len(frame.x)), packed_state(frame.x, frame.q, frame.v, frame.w), frame.t)


def _apply_J(out, v, w):
    """J xdot for every row, xdot = (v, w) per body, WORLD slots contributing nothing."""
    vw = np.concatenate((v, w), axis=1)
    vw = np.concatenate((vw, np.zeros((1, 6))))  # index -1 (WORLD) reads this zero row
    return np.einsum("rsk,rsk->r", out.J, vw[out.row_bodies])


def _assert_close(actual, expected, rel):
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    np.testing.assert_allclose(actual, expected, rtol=rel, atol=rel * scale)


@pytest.mark.parametrize("name", FAMILIES)
@pytest.mark.parametrize("seed", [0, 1])
def test_compiled_rows_match_the_reference(name, seed):
    fam, frame, _ = _scene(name, seed)
    out = _rows(fam, frame)
    assert len(out.C) == row_count(fam) == type(fam).ROWS * K
    ref = reference_rows(fam, frame)
    for key in ("C", "J", "ct", "bias"):
        np.testing.assert_allclose(getattr(out, key), ref[key], rtol=0, atol=1e-12, err_msg=key)
    np.testing.assert_array_equal(out.row_bodies, ref["row_bodies"])
    np.testing.assert_array_equal(out.velocity_only, ref["velocity_only"])
    assert (out.row_bodies == WORLD).any(), "the scene must exercise WORLD slots"
    assert np.all(out.J[out.row_bodies == WORLD] == 0.0)


def _gradient_error(name, J_hook=None):
    """max |(C(x + dv h) - C(x - dv h)) / 2h - J dxdot| over rows, relative to the scale of J dxdot."""
    fam, frame, rng = _scene(name, 2)
    dv, dw = rng.normal(size=(N_BODIES, 3)), rng.normal(size=(N_BODIES, 3))
    out = _rows(fam, frame)
    if J_hook:
        J_hook(out.J)
    h = 1e-5
    C_plus = _rows(fam, _frame(frame.x + h * dv, quat_integrate(frame.q, dw, h), frame.v, frame.w)).C
    C_minus = _rows(fam, _frame(frame.x - h * dv, quat_integrate(frame.q, dw, -h), frame.v, frame.w)).C
    J_dxdot = _apply_J(out, dv, dw)
    return np.max(np.abs((C_plus - C_minus) / (2 * h) - J_dxdot)) / max(1.0, np.max(np.abs(J_dxdot)))


@pytest.mark.parametrize("name", POSITIONAL)
def test_J_is_the_gradient_of_C(name):
    assert _gradient_error(name) < 1e-6


@pytest.mark.parametrize("name", POSITIONAL)
def test_gradient_check_detects_a_wrong_angular_block(name):
    def flip_angular(J):
        J[:, :, 3:] *= -1.0

    assert _gradient_error(name, flip_angular) > 1e-2


def _moving(name, t):
    """Rows along free motion x(t) = x0 + v t, q(t) = exp(w t) q0, nail P(t) = P0 + A sin(3t)."""
    fam, frame, rng = _scene(name, 3)
    if isinstance(fam, PointToNail):
        P0, A, f = fam.target.copy(), rng.normal(size=(K, 3)), NAIL_AMPLITUDE_FREQ
        fam.target, fam.target_velocity = P0 + A * np.sin(f * t), f * A * np.cos(f * t)
        fam.target_acceleration = -f * f * A * np.sin(f * t)
    x, q = frame.x + frame.v * t, quat_integrate(frame.q, frame.w, t)
    moved = _frame(x, q, frame.v, frame.w, t)
    out = _rows(fam, moved)
    return out, _apply_J(out, frame.v, frame.w) + out.ct


@pytest.mark.parametrize("name", FAMILIES)
def test_bias_is_the_time_derivative_of_J_v_plus_ct(name):
    out, _ = _moving(name, T0)
    h = 1e-5
    d_Cdot = (_moving(name, T0 + h)[1] - _moving(name, T0 - h)[1]) / (2 * h)
    _assert_close(out.bias, d_Cdot, 1e-6)
    if name in POSITIONAL:
        assert np.max(np.abs(out.bias)) > 1e-2, "free motion must give a nonzero bias to test"


@pytest.mark.parametrize("name", POSITIONAL)
def test_C_along_free_motion_has_derivatives_Jv_plus_ct_and_bias(name):
    out, C_dot = _moving(name, T0)
    h1, h2 = 1e-5, 1e-4
    C = {s: _moving(name, T0 + s)[0].C for s in (-h1, h1, -h2, h2)}
    _assert_close(C_dot, (C[h1] - C[-h1]) / (2 * h1), 1e-6)
    _assert_close(out.bias, (C[h2] - 2 * out.C + C[-h2]) / h2**2, 1e-5)


def test_velocity_rows_evaluate_their_definition():
    """J v of the gear rows equals Cv written straight from layout.py (axes turned by quat_rotate, not R)."""
    for name in ("gear_to_gear", "gear_to_weight"):
        fam, frame, _ = _scene(name, 4)
        w = np.concatenate((frame.w, np.zeros((1, 3))))  # index -1: the world does not turn
        v = np.concatenate((frame.v, np.zeros((1, 3))))
        q = np.concatenate((frame.q, [[1.0, 0.0, 0.0, 0.0]]))
        if name == "gear_to_gear":
            a, b = fam.body_a, fam.body_b
            # Cv = r_a (w_a . A_a) + r_b (w_b . A_b)
            expected = fam.radius_a * np.sum(w[a] * quat_rotate(q[a], fam.axis_a), axis=1) + fam.radius_b * np.sum(
                w[b] * quat_rotate(q[b], fam.axis_b), axis=1)
        else:
            # Cv = (w_gear x arm) . d - v_weight . d
            d = fam.direction
            expected = np.sum((np.cross(w[fam.gear], fam.arm) - v[fam.weight]) * d, axis=1)
        out = _rows(fam, frame)
        _assert_close(_apply_J(out, frame.v, frame.w) + out.ct, expected, 1e-12)


def test_velocity_rows_are_velocity_only():
    for name in ("gear_to_gear", "gear_to_weight"):
        out = _rows(*_scene(name)[:2])
        assert out.velocity_only.all() and np.all(out.C == 0.0)
    assert not _rows(*_scene("element")[:2]).velocity_only.any()


def _element_scene():
    """Translational and rotational element rows on every axis, against the world and against body 0."""
    rng = np.random.default_rng(11)
    x0, q0 = _random_poses(rng)
    axes = np.tile(np.eye(3), (4, 1))
    body_b = np.repeat([WORLD, 0, WORLD, 0], 3)
    rotational = np.repeat([False, False, True, True], 3)
    fam = Element(np.full(12, 2), body_b, axes, rotational)
    capture_element_references(fam, x0, q0)
    return fam, x0, q0


def test_element_C_is_zero_after_capture():
    fam, x0, q0 = _element_scene()
    out = _rows(fam, _frame(x0, q0, np.zeros_like(x0), np.zeros_like(x0)))
    np.testing.assert_allclose(out.C, 0.0, atol=1e-14)


def test_element_C_measures_the_motion_of_a_relative_to_b():
    fam, x0, q0 = _element_scene()
    zero = np.zeros_like(x0)
    # world form of every row's axis: as given for WORLD rows, R_b0 axis for rows on body 0
    W = np.where((fam.body_b == WORLD)[:, None], fam.axis, fam.axis @ quat_to_matrix(q0[0]).T)
    theta, delta = 0.01, 0.37
    for row in range(12):
        x, q = x0.copy(), q0.copy()
        if fam.rotational[row]:
            # rotate a by theta about W[row]: q_err = exp(theta R_b^T W[row]), so C_j = 2 sin(theta/2) W[row].W[j]
            q[2] = quat_multiply(quat_from_axis_angle(W[row], theta), q0[2])
            expected = np.where(fam.rotational, 2 * np.sin(theta / 2) * (W @ W[row]), 0.0)
        else:
            # translate a by delta along W[row]: C_j = delta W[row].W[j] on translational rows
            x[2] = x0[2] + delta * W[row]
            expected = np.where(fam.rotational, 0.0, delta * (W @ W[row]))
        C = _rows(fam, _frame(x, q, zero, zero)).C
        np.testing.assert_allclose(C, expected, atol=1e-12)
        assert abs(C[row] - (theta if fam.rotational[row] else delta)) < theta**3 / 20  # the small angle itself


def test_element_C_ignores_motion_of_a_and_b_together():
    fam, x0, q0 = _element_scene()
    zero = np.zeros_like(x0)
    spin = quat_from_axis_angle(np.array([0.3, -1.0, 0.5]), 0.8)
    x, q = x0.copy(), q0.copy()
    # rigidly rotate bodies 0 and 2 together about body 0's centre
    x[2] = x0[0] + quat_to_matrix(spin) @ (x0[2] - x0[0])
    q[0], q[2] = quat_multiply(spin, q0[0]), quat_multiply(spin, q0[2])
    C = _rows(fam, _frame(x, q, zero, zero)).C
    body_rows = fam.body_b == 0
    np.testing.assert_allclose(C[body_rows], 0.0, atol=1e-12)
    assert np.max(np.abs(C[~body_rows])) > 0.1  # the world-referenced rows do see it
