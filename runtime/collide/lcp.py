"""The contact problem at velocity level, once the joint rows have been eliminated (response.py):

    u = u0 + W lam         W (r,r) symmetric positive semi-definite (the contacts' Delassus matrix)

Rows 0..k-1 are the contacts' normal rows, then two tangent rows per contact with friction (`tangent[c]` gives
the first of them, -1 for none). Find lam with

    normal row i:   lam_i >= 0,   u_i >= target_i,   lam_i (u_i - target_i) = 0       (no pull, no penetration)
    tangent rows:   |(lam_t1, lam_t2)| <= mu_c lam_c, and, when inside the cone, u_t1 = u_t2 = 0   (Coulomb)

Two methods, the cheap one first:
  * direct, on an active set: with a guessed set of pressing contacts, all sticking, the problem is the linear
    system W lam = target - u0 on their rows; solved in the minimum-norm sense (four corners of a box on a floor
    give W of rank 6 for 12 rows, and the minimum-norm solution shares the load symmetrically). A contact that
    pulls leaves the set, one that would approach joins it, and the system is solved again. Resting stacks
    end here, in one to three Cholesky solves.
  * projected Gauss-Seidel (sequential impulses, Erleben 2007; Catto 2005), started from the direct solution
    clipped into the feasible set: a normal row is solved alone and clamped at zero, a contact's two tangent
    rows alone and projected onto the friction disc of the current normal impulse. Sliding ends here.
"""
from __future__ import annotations

import numpy as np

# PGS stops when no row changes the velocities by more than this fraction of the largest velocity change asked
# for, max |target - u0| (a sliding block's friction is then right to 1e-8 of itself)
PGS_TOLERANCE = 1e-8
# PGS gives up after this many sweeps (the last iterate is used)
PGS_SWEEPS = 300
# PGS keeps its velocities in Python lists up to this many rows (numpy arrays beyond)
PGS_LISTS_UP_TO = 24
# passes of the active-set correction before PGS takes over
ACTIVE_SET_PASSES = 6
# diagonal shift of the direct solve, relative to the largest diagonal entry of W
REGULARIZATION = 1e-10


# numpy's own LAPACK (imported with numpy) serves these small systems: scipy.linalg would cost 0.1 s to import at
# a run's first impact, more than every impulse solve of a short scene together
def cholesky(A):
    """The lower Cholesky factor L of A (m,m), A = L L^T, or None when A is not positive definite."""
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return None


def cholesky_solve(factor, b):
    """A^-1 b (m,) or (m,k) from the factor L of `cholesky`: L z = b, then L^T x = z (m is a few contacts' rows:
    a general solve of the triangular factors costs what a triangular one would)."""
    return np.linalg.solve(factor.T, np.linalg.solve(factor, b))


def solve(W, u0, target, mu, tangent) -> np.ndarray:
    """lam (r,) for the problem above; W (r,r), u0 (r,), target (r,) (0 on tangent rows), mu (k,),
    tangent (k,) int (-1: frictionless contact)."""
    r = len(u0)
    if r == 0:
        return np.zeros(0)
    tol = PGS_TOLERANCE * float(np.max(np.abs(target - u0))) + 1e-15
    lam = _active_set(W, u0, target, mu, tangent, tol)
    if lam is not None:
        return lam
    lam = _direct(W, target - u0)
    lam = _project(np.zeros(r) if lam is None else lam, mu, tangent)
    lam = _pgs(W, u0, target, mu, tangent, lam, tol)
    polished = _polish(W, u0, target, mu, tangent, lam, tol)
    return lam if polished is None else polished


def _active_set(W, u0, target, mu, tangent, tol):
    """The direct solve on a guessed set of pressing contacts (all of them, every one sticking), the set then
    corrected: a contact that pulls leaves it, one that would approach comes back. None when that does not
    settle within ACTIVE_SET_PASSES or a contact must slide (friction at its limit: PGS's job)."""
    k, r = len(mu), len(u0)
    rows_of = [np.array([c] + ([tangent[c], tangent[c] + 1] if tangent[c] >= 0 else [])) for c in range(k)]
    pressing = np.ones(k, bool)
    seen = set()
    for _ in range(ACTIVE_SET_PASSES):
        key = pressing.tobytes()
        if key in seen or not pressing.any():
            return None
        seen.add(key)
        rows = np.concatenate([rows_of[c] for c in np.flatnonzero(pressing)])
        lam = np.zeros(r)
        part = _direct(W[np.ix_(rows, rows)], target[rows] - u0[rows])
        if part is None:
            return None
        lam[rows] = part
        if _feasible(W, u0, target, mu, tangent, lam, tol, pressing):
            return lam
        u = u0 + W @ lam
        pulling = pressing & (lam[:k] < 0)
        approaching = ~pressing & (u[:k] < target[:k] - tol)
        if not (pulling.any() or approaching.any()):
            return None  # only friction is violated
        pressing = (pressing & ~pulling) | approaching
    return None


def _polish(W, u0, target, mu, tangent, lam, tol):
    """PGS's answer made exact: keep its active set (pressing contacts; each sticking, or sliding with the
    friction impulse mu lam_n along PGS's direction d) and solve that linear system,

        lam = B z,   E (u0 + W B z) = E target      (E: the rows held at their target, B: the impulse pattern)

    in the least-squares sense. Returned only if it meets every condition, else None."""
    k = len(mu)
    pressing = lam[:k] > 0
    sliding = np.zeros(k, bool)
    columns, rows = [], []
    for c in np.flatnonzero(pressing):
        column = np.zeros(len(lam))
        column[c] = 1.0
        rows.append(c)
        j = tangent[c]
        if j >= 0:
            t = lam[j:j + 2]
            if np.hypot(*t) >= mu[c] * lam[c] * (1 - 1e-6) and np.hypot(*t) > 0:  # sliding
                column[j:j + 2] = mu[c] * t / np.hypot(*t)
                sliding[c] = True
            else:  # sticking: two more unknowns, two more rows held at zero slip
                for jj in (j, j + 1):
                    extra = np.zeros(len(lam))
                    extra[jj] = 1.0
                    columns.append(extra)
                    rows.append(jj)
        columns.append(column)
    if not columns:
        return None
    B = np.array(columns).T
    rows = np.array(rows)
    try:
        z = np.linalg.lstsq(W[rows] @ B, target[rows] - u0[rows], rcond=None)[0]
    except (np.linalg.LinAlgError, ValueError):
        return None
    polished = B @ z
    if not _feasible(W, u0, target, mu, tangent, polished, tol, pressing, sliding):
        return None
    u = u0 + W @ polished
    for c in np.flatnonzero(sliding):  # a sliding contact must not slide the other way
        j = tangent[c]
        if u[j:j + 2] @ polished[j:j + 2] > tol * np.hypot(*polished[j:j + 2]):
            return None
    return polished


def _direct(W, rhs):
    """Minimum-norm solution of W lam = rhs for W positive semi-definite: Cholesky of W + eps I (Tikhonov;
    tends to W^+ rhs as eps -> 0), refined once against W. LAPACK's eigh would give W^+ exactly but costs
    10x more, and on a loaded machine its threads make that 100x."""
    scale = float(np.max(np.diag(W), initial=0.0))
    if scale <= 0:
        return None
    factor = cholesky(W + REGULARIZATION * scale * np.eye(len(W)))
    if factor is None:
        return None
    lam = cholesky_solve(factor, rhs)
    return lam + cholesky_solve(factor, rhs - W @ lam)


def _feasible(W, u0, target, mu, tangent, lam, tol, pressing, sliding=None) -> bool:
    """Every condition of the module docstring, for lam pressing on the contacts `pressing` only, the contacts
    `sliding` (if given) at the edge of their friction disc, free to slip."""
    k = len(mu)
    u = u0 + W @ lam
    normal = lam[:k]
    sticking = pressing & (tangent >= 0) & (True if sliding is None else ~sliding)
    rows = np.concatenate([np.flatnonzero(pressing), tangent[sticking], tangent[sticking] + 1])
    if np.any(normal < 0) or np.any(np.abs(u[rows] - target[rows]) > tol):
        return False
    if np.any(u[:k][~pressing] < target[:k][~pressing] - tol):
        return False
    has = pressing & (tangent >= 0)
    if has.any():
        t1, t2 = lam[tangent[has]], lam[tangent[has] + 1]
        if np.any(np.hypot(t1, t2) > mu[has] * normal[has] * (1 + 1e-12)):
            return False
    return True


def _project(lam, mu, tangent):
    k = len(mu)
    lam = lam.copy()
    lam[:k] = np.maximum(lam[:k], 0.0)
    for c in np.flatnonzero(tangent >= 0):
        j = tangent[c]
        norm = np.hypot(lam[j], lam[j + 1])
        limit = mu[c] * lam[c]
        if norm > limit:
            lam[j:j + 2] *= limit / norm if norm > 0 else 0.0
    return lam


def _pgs(W, u0, target, mu, tangent, lam, tol):
    """Projected Gauss-Seidel sweeps from lam. u = u0 + W lam is kept up to date row by row: in Python lists
    for a few rows (a numpy call per update costs more than the update), else in numpy; the same sums in the
    same order either way (u_i + W_ji d, or u_i + (W_ji d1 + W_j+1,i d2)), so the same numbers."""
    k = len(mu)
    u = u0 + W @ lam
    diag = np.diag(W).copy()
    diag[diag <= 0] = np.inf  # a row no body can move: its impulse does nothing
    lists = len(u0) <= PGS_LISTS_UP_TO
    W_rows, u_l = (W.tolist(), u.tolist()) if lists else (W, u)
    shift = _shift_list if lists else _shift_array
    lam_l, target_l, diag_l = lam.tolist(), target.tolist(), diag.tolist()
    mu_l, tangent_l = mu.tolist(), tangent.tolist()
    for _ in range(PGS_SWEEPS):
        change = 0.0
        for c in range(k):
            # normal row: u_c = target_c if that takes a pushing impulse, else lam_c = 0
            old = lam_l[c]
            new = max(0.0, old + (target_l[c] - u_l[c]) / diag_l[c])
            if new != old:
                lam_l[c] = new
                shift(u_l, W_rows[c], new - old)
                change = max(change, abs(new - old) * diag_l[c])
            j = tangent_l[c]
            if j < 0:
                continue
            # tangent rows: stop the slip, then project onto the disc |lam_t| <= mu lam_n
            o1, o2 = lam_l[j], lam_l[j + 1]
            l1, l2 = o1 - u_l[j] / diag_l[j], o2 - u_l[j + 1] / diag_l[j + 1]
            norm, limit = (l1 * l1 + l2 * l2) ** 0.5, mu_l[c] * lam_l[c]
            if norm > limit:
                s = limit / norm
                l1, l2 = l1 * s, l2 * s
            if l1 != o1 or l2 != o2:
                lam_l[j], lam_l[j + 1] = l1, l2
                shift(u_l, W_rows[j], l1 - o1, W_rows[j + 1], l2 - o2)
                change = max(change, abs(l1 - o1) * diag_l[j], abs(l2 - o2) * diag_l[j + 1])
        if change < tol:
            break
    return np.array(lam_l)


def _shift_array(u, row, d, row2=None, d2=0.0) -> None:
    """u += row d (+ row2 d2), u and the rows numpy arrays."""
    if row2 is None:
        u += row * d
    else:
        u += row * d + row2 * d2


def _shift_list(u, row, d, row2=None, d2=0.0) -> None:
    """u += row d (+ row2 d2), u and the rows Python lists (the same operations as _shift_array)."""
    if row2 is None:
        u[:] = [a + b * d for a, b in zip(u, row)]
    else:
        u[:] = [a + (b * d + c * d2) for a, b, c in zip(u, row, row2)]
