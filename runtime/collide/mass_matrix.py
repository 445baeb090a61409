"""J M^-1 J^T of a set of impulse rows, dense: the matrix the collision stage's simultaneous impulses solve
(collide/response.py). Each row touches at most two bodies (slots 0 and 1), -1 for the world."""

from __future__ import annotations

import numpy as np


def apply_inverse_mass(J, row_bodies, inv_mass, inv_inertia_world, out=None) -> np.ndarray:
    """M^-1 J^T per slot: out (m,2,6) = [inv_mass_b * J_lin, invI_b @ J_ang] with b = row_bodies; 0 for world.

    J (m,2,6), row_bodies (m,2) int, inv_mass (n,), inv_inertia_world (n,3,3).
    """
    if out is None:
        out = np.empty(J.shape)
    valid = row_bodies >= 0
    b = np.where(valid, row_bodies, 0)
    # (M^-1 J^T)_lin = J_lin / m_b
    np.multiply(np.take(inv_mass, b)[..., None], J[..., :3], out=out[..., :3])
    # (M^-1 J^T)_ang = I_b^-1 J_ang  (world frame)
    out[..., 3:] = np.matmul(np.take(inv_inertia_world, b, axis=0), J[..., 3:, None])[..., 0]
    np.copyto(out, 0.0, where=~valid[..., None])
    return out


def assemble_dense(J, row_bodies, inv_mass, inv_inertia_world, out=None) -> np.ndarray:
    """A (m,m) = J M^-1 J^T, vectorized over rows: four slot pairings, each a masked (m,6)x(6,m) product.

    A[r,c] = sum_{s,t in {0,1}} [body(r,s) == body(c,t) != world] J[r,s] . (M^-1 J^T)[c,t]
    """
    m = J.shape[0]
    A = np.zeros((m, m)) if out is None else out
    A[...] = 0.0
    MJ = apply_inverse_mass(J, row_bodies, inv_mass, inv_inertia_world)
    for s in (0, 1):
        for t in (0, 1):
            same = np.equal.outer(row_bodies[:, s], row_bodies[:, t])
            same &= (row_bodies[:, s] >= 0)[:, None]
            A += (J[:, s] @ MJ[:, t].T) * same
    return A
