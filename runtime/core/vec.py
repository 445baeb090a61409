"""Small vector and quaternion arithmetic for the kernels: 3-vectors and quaternions (w, x, y, z) as tuples of
floats (they live in registers: no allocation in a hot loop); matrices are read in place from their stack by
index (R, b) rather than through a view R[b]: a view kept in a variable costs numba a reference count, which
in a hot loop is most of the time."""
from __future__ import annotations

import math

from .jit import kernel


@kernel
def load3(a, i):
    """(a[i], a[i+1], a[i+2]) of a 1-D array."""
    return (a[i], a[i + 1], a[i + 2])


@kernel
def store3(a, i, v):
    a[i], a[i + 1], a[i + 2] = v[0], v[1], v[2]


@kernel
def add3(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel
def sub3(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel
def scale3(s, a):
    return (s * a[0], s * a[1], s * a[2])


@kernel
def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel
def cross3(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel
def norm3(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@kernel
def centripetal(w, r):
    """w x (w x r) = w (w . r) - r (w . w): the acceleration of a body-fixed vector r spinning at w."""
    wr, ww = dot3(w, r), dot3(w, w)
    return (w[0] * wr - r[0] * ww, w[1] * wr - r[1] * ww, w[2] * wr - r[2] * ww)


@kernel
def rotate(R, b, v):
    """R[b] v for a stack of (3,3) matrices R (n,3,3)."""
    return (R[b, 0, 0] * v[0] + R[b, 0, 1] * v[1] + R[b, 0, 2] * v[2],
            R[b, 1, 0] * v[0] + R[b, 1, 1] * v[1] + R[b, 1, 2] * v[2],
            R[b, 2, 0] * v[0] + R[b, 2, 1] * v[1] + R[b, 2, 2] * v[2])


@kernel
def rotate_t(R, b, v):
    """R[b]^T v for a stack of (3,3) matrices R (n,3,3)."""
    return (R[b, 0, 0] * v[0] + R[b, 1, 0] * v[1] + R[b, 2, 0] * v[2],
            R[b, 0, 1] * v[0] + R[b, 1, 1] * v[1] + R[b, 2, 1] * v[2],
            R[b, 0, 2] * v[0] + R[b, 1, 2] * v[1] + R[b, 2, 2] * v[2])


@kernel
def row3(a, k, i):
    """(a[k, i], a[k, i+1], a[k, i+2]) of a 2-D array."""
    return (a[k, i], a[k, i + 1], a[k, i + 2])


@kernel
def quat_to_matrix(w, x, y, z, R, b):
    """R[b] (3,3) <- the rotation of the unit quaternion (w, x, y, z): R = I + 2 w [v]x + 2 [v]x^2."""
    R[b, 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[b, 0, 1] = 2.0 * (x * y - w * z)
    R[b, 0, 2] = 2.0 * (x * z + w * y)
    R[b, 1, 0] = 2.0 * (x * y + w * z)
    R[b, 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[b, 1, 2] = 2.0 * (y * z - w * x)
    R[b, 2, 0] = 2.0 * (x * z - w * y)
    R[b, 2, 1] = 2.0 * (y * z + w * x)
    R[b, 2, 2] = 1.0 - 2.0 * (x * x + y * y)


@kernel
def quat_mul(p, q):
    """Hamilton product p * q of quaternions (w, x, y, z) given as tuples."""
    return (p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
            p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
            p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
            p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0])


@kernel
def quat_conj(q):
    return (q[0], -q[1], -q[2], -q[3])


@kernel
def similarity(R, b, A, out):
    """out[b] (3,3) <- R[b] A[b] R[b]^T (a body-frame tensor in the world frame); R, A, out (n,3,3)."""
    for i in range(3):
        for j in range(3):
            total = 0.0
            for k in range(3):
                for l in range(3):
                    total += R[b, i, k] * A[b, k, l] * R[b, j, l]
            out[b, i, j] = total
