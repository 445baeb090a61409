"""runtime/core/rotation.py: the fast kernels against their plain forms (np.cross, the per-entry matrix, the Hamilton
product, np.linalg.norm) on stacks of every shape the runtime uses, including one past CROSS_MATMUL_MAX."""
import numpy as np
import pytest

from isaac_runtime.core.rotation import (
    CROSS_MATMUL_MAX,
    cross,
    quat_derivative,
    quat_derivative_reference,
    quat_multiply,
    quat_normalize,
    quat_to_matrix,
    quat_to_matrix_reference,
    skew,
)

SHAPES = [(), (1,), (7,), (2, 5), (CROSS_MATMUL_MAX + 1,)]


def _vectors(shape, seed=0):
    rng = np.random.default_rng([seed, len(shape), *shape])
    return rng.normal(size=shape + (3,)), rng.normal(size=shape + (3,)), rng.normal(size=shape + (4,))


@pytest.mark.parametrize("shape", SHAPES)
def test_cross_is_np_cross_exactly(shape):
    a, b, _ = _vectors(shape)
    assert np.array_equal(cross(a, b), np.cross(a, b))
    # one vector against a stack, broadcast as np.cross does
    assert np.array_equal(cross(a.reshape(-1, 3)[0], b), np.cross(a.reshape(-1, 3)[0], b))
    assert np.array_equal(cross([1.0, 2.0, 3.0], b), np.cross([1.0, 2.0, 3.0], b))


@pytest.mark.parametrize("shape", SHAPES)
def test_skew_is_the_cross_product_matrix(shape):
    a, b, _ = _vectors(shape)
    S = skew(a)
    assert S.shape == shape + (3, 3)
    assert np.array_equal(S, -np.swapaxes(S, -1, -2))
    np.testing.assert_allclose(np.matmul(S, b[..., None])[..., 0], np.cross(a, b), rtol=0, atol=1e-14)


@pytest.mark.parametrize("shape", SHAPES)
def test_quat_to_matrix_is_the_per_entry_formula_exactly(shape):
    q = quat_normalize(_vectors(shape)[2])
    R = quat_to_matrix(q)
    assert np.array_equal(R, quat_to_matrix_reference(q))
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
    out = np.zeros(shape + (3, 3))
    assert quat_to_matrix(q, out=out) is out and np.array_equal(out, R)
    wide = np.zeros(shape + (3, 4))  # a non-contiguous out is written through a temporary
    quat_to_matrix(q, out=wide[..., :3])
    assert np.array_equal(wide[..., :3], R) and not wide[..., 3].any()


def _hamilton(p, q):
    """p q with scalar and vector parts: (ps qs - pv . qv, ps qv + qs pv + pv x qv)."""
    ps, pv, qs, qv = p[..., :1], p[..., 1:], q[..., :1], q[..., 1:]
    return np.concatenate((ps * qs - np.sum(pv * qv, axis=-1, keepdims=True), ps * qv + qs * pv + np.cross(pv, qv)),
                          axis=-1)


@pytest.mark.parametrize("shape", SHAPES)
def test_quat_multiply_is_the_hamilton_product(shape):
    _, _, p = _vectors(shape, 1)
    _, _, q = _vectors(shape, 2)
    np.testing.assert_allclose(quat_multiply(p, q), _hamilton(p, q), rtol=0, atol=1e-14)
    one = p.reshape(-1, 4)[0]  # one quaternion against a stack
    np.testing.assert_allclose(quat_multiply(one, q), _hamilton(np.broadcast_to(one, q.shape), q), rtol=0, atol=1e-14)


@pytest.mark.parametrize("shape", SHAPES)
def test_quat_derivative_is_half_of_0_w_times_q(shape):
    w, _, q = _vectors(shape)
    expected = quat_derivative_reference(q, w)
    np.testing.assert_allclose(quat_derivative(q, w), expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(expected, 0.5 * _hamilton(np.concatenate((np.zeros(shape + (1,)), w), -1), q),
                               rtol=0, atol=1e-14)
    out = np.zeros(shape + (5,))[..., 1:]  # a strided view, as the integrator's packed slopes
    quat_derivative(q, w, out=out)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("shape", SHAPES)
def test_quat_normalize_is_division_by_the_norm(shape):
    q = _vectors(shape)[2]
    # the squared norm is one vecdot, which may sum the four squares in another order than np.linalg.norm: the
    # results agree to the last bit or two
    np.testing.assert_allclose(quat_normalize(q), q / np.linalg.norm(q, axis=-1, keepdims=True), rtol=5e-16, atol=0)
    np.testing.assert_allclose(np.linalg.norm(quat_normalize(q), axis=-1), 1.0, rtol=0, atol=5e-16)
    copy = q.copy()
    assert quat_normalize(copy, out=copy) is copy and np.array_equal(copy, quat_normalize(q))
