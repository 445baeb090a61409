"""Reference solvers of the multiplier system (J M^-1 J^T) lambda = rhs, for tests and benchmarks: the engine
solves it compiled (runtime/core/solve.py, docs/design/physics.md section 2); these are the dense, sparse and tree
solvers it is measured against (benchmarks/bench_linsolve.py).

Rows come in the RowBlock layout (constraints/layout.py): J (m,2,6) blocks [linear(3), angular(3)] per slot,
row_bodies (m,2) body indices (-1 = world). Bodies with zero inverse mass/inertia (static, kinematic) contribute
nothing. Three solvers, all returning (lam (m,), SolveInfo):

* dense   `assemble_dense` + `solve_dense`: A (m,m) built by pairwise comparison of slot bodies, Cholesky;
          O(m^2) memory, O(m^3) time. `DensePattern` does the comparisons once per active row set (the
          runtime's path for many bodies; `assemble_dense` is its reference); `solve_dense` calls LAPACK posv
          (potrf + potrs) directly.
* sparse  `SparsePattern.build` once per active row set, then `solve_sparse`: A as CSC filled by one
          bincount per step, scipy SuperLU. Near O(m) for chains and bounded-degree trees.
* tree    `TreeSolver` (Baraff 1996, "Linear-time dynamics using Lagrange multipliers"), O(nodes), below.

Singular systems (duplicate rows, closed loops, over-constrained mechanisms) never give NaN: dense falls back to
a minimum-norm pseudo-inverse (eigh), sparse shifts the diagonal by SPARSE_REG_RTOL * max(diag A) and refines,
tree falls back to sparse. SolveInfo says which path ran, the relative residual and whether A was rank-deficient.

Tree algorithm. Nodes are the dynamic bodies touched by a row (6 unknowns: acceleration) and the constraint
groups (k unknowns: -lambda); an edge joins a group to each dynamic body it touches. Instead of J M^-1 J^T
(dense wherever a body carries many joints) factor the always-sparse KKT matrix

    H = [[M, J^T], [J, 0]],   H [a; -lambda] = [0; rhs]     (M a = J^T lambda, J a = rhs)

whose block graph is that tree. With nodes ordered children before parents, H = L D L^T has no fill-in:
L is unit lower triangular with one off-diagonal block L_pn per node n (p its parent), D block diagonal,

    D_n  = H_nn - sum_{c child of n} L_nc D_c L_nc^T      (H_nn = M_i for a body, 0 for a group)
    L_pn = H_pn D_n^-1

A body pivot is M_i plus a positive semi-definite term; a group pivot is -J_g (child compliance) J_g^T, negative
definite when the group's rows are independent on its child bodies. Solve: forward z_n = b_n - sum L_nc z_c
(children first), diagonal and backward x_n = D_n^-1 z_n - L_pn^T x_p (root first). Every node does a fixed
number of (6x6, 6xk, kxk) products, so factor + solve cost O(nodes) whatever the degrees; the loops are Python,
the blocks numpy. Measured (benchmarks/bench_linsolve.py): t(1000 bodies)/t(100) = 10.5 on chains, but SuperLU
is ~5x faster on chains and bounded-degree trees; the tree wins where a body carries many rows (choose_solver).

A leaf group (pinned to the world or a static body) would have D = 0, so each component is rooted at its one
grounded group. The world is therefore a node of the graph: a component grounded twice (a chain pinned at both
ends) is a closed loop through the ground, and `TreeSolver.build` returns None for it as for any other loop.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isaac_runtime.core.solve import RANK_RTOL  # noqa: F401 (one definition: the compiled solve's)
from isaac_runtime.collide.mass_matrix import apply_inverse_mass, assemble_dense  # noqa: F401 (the dense path)

# A Cholesky/LU pivot or eigenvalue below RANK_RTOL * max(diag A) counts as zero (rank-deficient system).
# Relative residual ||A lam - rhs|| / ||rhs|| above which a fast path is distrusted and the fallback runs.
RESIDUAL_RTOL = 1e-8
# Diagonal shift of the sparse fallback, relative to max(diag A): A + eps I is non-singular.
SPARSE_REG_RTOL = 1e-11
# Iterative refinement steps against the unshifted A after the shifted solve (iterated Tikhonov).
SPARSE_REFINE_STEPS = 4
# Up to this many rows dense wins (bench_linsolve.py, ball-jointed chains: dense/sparse 0.23/0.25 ms at 108 rows,
# 0.24/0.23 ms at 114, 0.39/0.26 ms at 144; 343 ms vs 3.4 ms at 3000 rows).
DENSE_MAX_ROWS = 110
# From this many rows on one body the tree beats sparse: J M^-1 J^T holds a dense block of that size (stars:
# sparse/tree 0.33/0.37 ms at 60 rows, 0.44/0.43 at 72, 1.07/0.66 at 120; 2400 ms vs 17 ms at 3000 rows).
TREE_HUB_ROWS = 72



def lapack():
    """scipy's LAPACK wrappers, imported on first use: importing scipy.linalg takes about 0.1 s (with the numpy
    modules scipy's array API layer pulls in), which a run that never solves here (no impact, no Python-side
    solve) should not pay at its start."""
    import scipy.linalg.lapack

    return scipy.linalg.lapack


@dataclass
class SolveInfo:
    """How a solve went. method: "cholesky" | "pinv" | "lu" | "lu+shift" | "tree" | "tree->lu" | ...;
    residual: ||A lam - rhs|| / ||rhs|| (absolute if rhs = 0); rank: numerical rank when known (None for the
    fast paths, which only know "full"); regularization: absolute diagonal shift added (0 if none);
    note: why a fallback ran."""

    method: str
    residual: float
    rank_deficient: bool
    rank: int | None = None
    regularization: float = 0.0
    note: str = ""


def dynamic_slots(rb: np.ndarray, dynamic_mask) -> np.ndarray:
    """(m,2) bool: the slot names a dynamic body (not the world, not a static or kinematic body)."""
    dmask = np.asarray(dynamic_mask, dtype=bool)
    if len(dmask) == 0:
        return np.zeros(rb.shape, dtype=bool)
    return (rb >= 0) & dmask[np.clip(rb, 0, len(dmask) - 1)]


def relative_residual(r: np.ndarray, rhs: np.ndarray) -> float:
    # ||x|| = sqrt(x . x), as np.linalg.norm computes it for a vector (ndarray.dot: no dispatch)
    nb = math.sqrt(rhs.dot(rhs))
    nr = math.sqrt(r.dot(r))
    return nr / nb if nb > 0 else nr


# ---------------------------------------------------------------------------------------------------------
# M^-1 J^T and the dense path
# ---------------------------------------------------------------------------------------------------------


class DensePattern:
    """Which slot pairs of J M^-1 J^T share a body, for one active row set: `assemble_dense` without the
    per-step comparisons, as one (2m x 6) (6 x 2m) product of all slots and a fixed mask.

    row_bodies (m,2) the slots it was built from; safe (2m,) their bodies, slot 2r+s for row r, with WORLD read
    as body 0 (masked out below); same (2m,2m) 1.0 where slots 2r+s and 2c+t name the same body, not the world.
    """

    def __init__(self, row_bodies):
        rb = np.asarray(row_bodies, dtype=np.int64).reshape(-1, 2)
        self.m = len(rb)
        self.row_bodies = rb
        slots = rb.reshape(-1)
        self.safe = np.where(slots >= 0, slots, 0)
        self.same = ((slots[:, None] == slots[None, :]) & (slots >= 0)[:, None]).astype(float)

    def assemble(self, J, inv_mass, inv_inertia_world) -> np.ndarray:
        """A (m,m) = J M^-1 J^T from J (m,2,6), inv_mass (n,), inv_inertia_world (n,3,3)."""
        b, J = self.safe, J.reshape(2 * self.m, 6)  # one row per slot
        MJ = np.empty(J.shape)
        # (M^-1 J^T)_lin = J_lin / m_b,  (M^-1 J^T)_ang = I_b^-1 J_ang  (world frame)
        np.multiply(inv_mass.take(b)[:, None], J[:, :3], out=MJ[:, :3])
        MJ[:, 3:] = np.matmul(inv_inertia_world.take(b, axis=0), J[:, 3:, None])[:, :, 0]
        # P[2r+s, 2c+t] = J[r,s] . (M^-1 J^T)[c,t] where both slots name the same body, else 0
        # (ndarray.dot: the same BLAS product as matmul for 2-D operands, without the gufunc machinery)
        P = J.dot(MJ.T)
        P *= self.same
        # A[r,c] = sum over the four slot pairings (s,t) of P[2r+s, 2c+t]: columns first, then rows
        P = P[:, 0::2] + P[:, 1::2]
        return P[0::2] + P[1::2]

    def solve(self, J, inv_mass, inv_inertia_world, rhs) -> tuple[np.ndarray, "SolveInfo"]:
        """lam with (J M^-1 J^T) lam = rhs by `solve_dense`."""
        return solve_dense(self.assemble(J, inv_mass, inv_inertia_world), rhs)


def _pinv_solve(A, rhs):
    """Minimum-norm least-squares lam = A^+ rhs by symmetric eigendecomposition; returns (lam, rank)."""
    w, V = np.linalg.eigh(A)
    cutoff = RANK_RTOL * max(float(np.max(np.abs(w), initial=0.0)), float(np.max(np.diag(A), initial=0.0)))
    keep = w > cutoff
    # lam = V diag(1/w, kept) V^T rhs
    coef = np.zeros_like(w)
    coef[keep] = (V[:, keep].T @ rhs) / w[keep]
    return V @ coef, int(np.count_nonzero(keep))


def solve_dense(A, rhs) -> tuple[np.ndarray, SolveInfo]:
    """Solve A lam = rhs, A (m,m) symmetric positive semi-definite. Cholesky; pseudo-inverse if A is singular
    (a pivot below RANK_RTOL * max diag), Cholesky fails, or the residual exceeds RESIDUAL_RTOL."""
    A, rhs = np.asarray(A, dtype=float), np.asarray(rhs, dtype=float)
    m = len(rhs)
    if m == 0:
        return np.zeros(0), SolveInfo("cholesky", 0.0, False, 0)
    # the diagonals as Python floats: max/min of a list cost less than numpy reductions on a few entries
    scale = max(A.diagonal().tolist())
    if not scale > 0:
        return _dense_fallback(A, rhs, "A is zero")
    # LAPACK posv (potrf, then potrs with the factor) directly: what scipy's cho_factor / cho_solve call,
    # without their per-call checks
    c, lam, info = lapack().dposv(A, rhs, lower=1)
    if info != 0:
        return _dense_fallback(A, rhs, "cholesky failed (not positive definite)")
    min_pivot = min(c.diagonal().tolist()) ** 2
    if not min_pivot > RANK_RTOL * scale:
        return _dense_fallback(A, rhs, f"cholesky pivot {min_pivot / scale:.1e} of max diagonal")
    res = relative_residual(A.dot(lam) - rhs, rhs)
    # a non-finite lam gives a non-finite residual
    res = res if math.isfinite(res) else math.inf
    if res <= RESIDUAL_RTOL:
        return lam, SolveInfo("cholesky", res, False)
    return _dense_fallback(A, rhs, f"cholesky residual {res:.1e}")


def _dense_fallback(A, rhs, note):
    try:
        lam, rank = _pinv_solve(A, rhs)
    except np.linalg.LinAlgError:
        lam, rank = np.zeros(len(rhs)), 0
        note += "; eigh failed, lam = 0"
    if not np.all(np.isfinite(lam)):
        lam, note = np.zeros(len(rhs)), note + "; non-finite, lam = 0"
    res = relative_residual(A @ lam - rhs, rhs)
    return lam, SolveInfo("pinv", res, rank < len(rhs), rank, 0.0, note)


# ---------------------------------------------------------------------------------------------------------
# Sparse path
# ---------------------------------------------------------------------------------------------------------


@dataclass
class SparsePattern:
    """CSC structure of A = J M^-1 J^T for one active row set, and where each product lands in its data.

    A[r,c] += J[pr,ps] . (M^-1 J^T)[qr,qs] for every pair of (row, slot) touching the same dynamic body;
    the pair lands in data[p_dest]. indices, indptr: CSC arrays; diag (m,) data index of A[i,i].
    p_slot, q_slot: the same pairs as flat slot indices 2 row + slot (one gather each per assembly).
    """

    m: int
    row_bodies: np.ndarray  # (m,2) the slots the pattern was built from
    indices: np.ndarray
    indptr: np.ndarray
    diag: np.ndarray
    pr: np.ndarray
    ps: np.ndarray
    qr: np.ndarray
    qs: np.ndarray
    p_dest: np.ndarray

    def __post_init__(self):
        self.p_slot, self.q_slot = 2 * self.pr + self.ps, 2 * self.qr + self.qs
        self._matrix = None  # the CSC matrix `assemble` refills

    @classmethod
    def build(cls, row_bodies, n_bodies, dynamic_mask) -> "SparsePattern":
        rb = np.asarray(row_bodies, dtype=np.int64).reshape(-1, 2)
        m = len(rb)
        rows, slots = np.nonzero(dynamic_slots(rb, dynamic_mask))
        body = rb[rows, slots]
        order = np.argsort(body, kind="stable")
        rows, slots, body = rows[order], slots[order], body[order]
        starts = np.flatnonzero(np.r_[True, body[1:] != body[:-1]]) if len(body) else np.zeros(0, np.int64)
        ends = np.r_[starts[1:], len(body)].astype(np.int64)
        pi, qi = [], []
        for a, e in zip(starts, ends):  # all (row, slot) pairs sharing body `body[a]`
            idx = np.arange(a, e)
            pi.append(np.repeat(idx, e - a))
            qi.append(np.tile(idx, e - a))
        pi = np.concatenate(pi) if pi else np.zeros(0, np.int64)
        qi = np.concatenate(qi) if qi else np.zeros(0, np.int64)
        pr, ps, qr, qs = rows[pi], slots[pi], rows[qi], slots[qi]
        # CSC order: key = column * m + row; the diagonal is always stored (zero rows, regularization).
        diag_keys = np.arange(m, dtype=np.int64) * (m + 1)
        keys, inverse = np.unique(np.r_[qr * m + pr, diag_keys], return_inverse=True)
        p_dest = inverse[: len(pr)]
        indptr = np.r_[0, np.cumsum(np.bincount(keys // max(m, 1), minlength=m))].astype(np.int64)
        rows_of_keys = (keys % max(m, 1)).astype(np.int64)
        return cls(m, rb, rows_of_keys, indptr, inverse[len(pr):], pr, ps, qr, qs, p_dest)

    def assemble(self, J, MJ) -> "scipy.sparse.csc_matrix":
        """A = J M^-1 J^T as CSC from J (m,2,6) and MJ = apply_inverse_mass(...) (m,2,6).

        The structure never changes, so the matrix object is built once and its data refilled: the result is
        valid until the next call.
        """
        J_slot, MJ_slot = np.reshape(J, (-1, 6)), np.reshape(MJ, (-1, 6))
        vals = np.einsum("pk,pk->p", np.take(J_slot, self.p_slot, axis=0), np.take(MJ_slot, self.q_slot, axis=0))
        data = np.bincount(self.p_dest, weights=vals, minlength=len(self.indices))
        if self._matrix is None:
            self._matrix = _sparse().csc_matrix((data, self.indices, self.indptr), shape=(self.m, self.m))
        else:
            self._matrix.data[:] = data
        return self._matrix


def _sparse():
    """scipy.sparse (with its linalg), imported on first use: a plan whose epochs all solve dense or by the tree
    never needs it (17 ms of imports)."""
    import scipy.sparse
    import scipy.sparse.linalg  # noqa: F401  (binds scipy.sparse.linalg)

    return scipy.sparse


def _splu(A):
    # A is symmetric: minimum degree on A^T + A, diagonal pivots (SuperLU's symmetric mode).
    return _sparse().linalg.splu(
        A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True)
    )


def solve_sparse(pattern: SparsePattern, J, inv_mass, inv_inertia_world, rhs) -> tuple[np.ndarray, SolveInfo]:
    """Assemble A on `pattern` and solve A lam = rhs with SuperLU. On a pivot below RANK_RTOL * max(diag A),
    a failed factorization or a residual above RESIDUAL_RTOL: factor A + eps I (eps = SPARSE_REG_RTOL *
    max diag), refine against A, report eps."""
    rhs = np.asarray(rhs, dtype=float)
    if pattern.m == 0:
        return np.zeros(0), SolveInfo("lu", 0.0, False, 0)
    MJ = apply_inverse_mass(J, pattern.row_bodies, inv_mass, inv_inertia_world)
    A = pattern.assemble(J, MJ)
    return _solve_sparse_matrix(pattern, A, rhs)


def _solve_sparse_matrix(pattern, A, rhs):
    d = A.data[pattern.diag]
    scale = float(np.max(d))
    note = "A is zero"
    if scale > 0:
        try:
            lu = _splu(A)
            piv = np.abs(lu.U.diagonal())
            if float(np.min(piv)) > RANK_RTOL * scale:
                lam = lu.solve(rhs)
                res = relative_residual(A @ lam - rhs, rhs) if np.all(np.isfinite(lam)) else np.inf
                if res <= RESIDUAL_RTOL:
                    return lam, SolveInfo("lu", res, False)
                note = f"lu residual {res:.1e}"
            else:
                note = f"lu pivot {float(np.min(piv)) / scale:.1e} of max diagonal"
        except RuntimeError:
            note = "lu failed (exactly singular)"
    return _sparse_shifted(pattern, A, rhs, scale, note)


def _sparse_shifted(pattern, A, rhs, scale, note):
    m = pattern.m
    if scale <= 0:
        return np.zeros(m), SolveInfo("lu+shift", relative_residual(-rhs, rhs), True, 0, 0.0, note)
    eps = SPARSE_REG_RTOL * scale
    As = A.copy()
    As.data[pattern.diag] += eps
    lu = _splu(As)
    rank = int(np.count_nonzero(np.abs(lu.U.diagonal()) > RANK_RTOL * scale))
    # iterated Tikhonov: lam_{k+1} = lam_k + (A + eps I)^-1 (rhs - A lam_k), lam_0 = 0
    lam = np.zeros(m)
    r = rhs.copy()
    res = relative_residual(r, rhs)
    for _ in range(1 + SPARSE_REFINE_STEPS):
        step = lu.solve(r)
        r_new = rhs - A @ (lam + step)
        res_new = relative_residual(r_new, rhs)
        if not (np.all(np.isfinite(step)) and res_new < 0.5 * res):
            break
        lam += step
        r, res = r_new, res_new
    return lam, SolveInfo("lu+shift", res, rank < m, rank, eps, note)


# ---------------------------------------------------------------------------------------------------------
# Tree path (Baraff 1996)
# ---------------------------------------------------------------------------------------------------------


def max_rows_per_body(row_bodies, dynamic_mask) -> int:
    """The largest number of rows touching one dynamic body: the size of the densest block of J M^-1 J^T."""
    rb = np.asarray(row_bodies, dtype=np.int64).reshape(-1, 2)
    dyn = dynamic_slots(rb, dynamic_mask)
    # count a row once even if both slots name the same body
    dyn[:, 1] &= rb[:, 1] != rb[:, 0]
    return int(np.max(np.bincount(rb[dyn], minlength=1)))


def choose_solver(m_rows: int, tree_available: bool, hub_rows: int = 0) -> str:
    """Pick the solver for m_rows active rows, measured with benchmarks/bench_linsolve.py (numbers above
    DENSE_MAX_ROWS and TREE_HUB_ROWS):

    * m_rows <= DENSE_MAX_ROWS: "dense" (one BLAS call beats any per-row bookkeeping);
    * tree available and hub_rows (max_rows_per_body) >= TREE_HUB_ROWS: "tree" (its cost is linear whatever
      the degree, while SuperLU meets a dense hub_rows x hub_rows block);
    * otherwise "sparse": on chains and bounded-degree trees SuperLU (compiled) beats the Python-looped
      linear-time tree about 5x at every size measured (3000 rows: 3.4 ms vs 17 ms), both scaling linearly.
    """
    if m_rows <= DENSE_MAX_ROWS:
        return "dense"
    if tree_available and hub_rows >= TREE_HUB_ROWS:
        return "tree"
    return "sparse"
