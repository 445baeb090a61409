"""benchmarks/linsolve.py: dense assembly against a loop-built J M^-1 J^T; the dense pattern, sparse and tree against
dense; singular systems stay finite and say so."""
import numpy as np
import pytest

from benchmarks.linsolve import (
    DensePattern,
    SolveInfo,
    SparsePattern,
    apply_inverse_mass,
    assemble_dense,
    choose_solver,
    max_rows_per_body,
    solve_dense,
    solve_sparse,
)
from benchmarks.linsolve_tree import TreeSolver


def skew(r):
    return np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])


class Scene:
    """Random bodies (masses, principal inertias, orientations) and groups of rows appended one by one."""

    def __init__(self, rng, n, static=()):
        self.rng, self.n = rng, n
        self.x = rng.normal(size=(n, 3))
        self.inv_mass = 1.0 / rng.uniform(0.2, 5.0, n)
        R = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
        inv_I = 1.0 / rng.uniform(0.05, 2.0, (n, 3))
        self.inv_inertia = np.einsum("nij,nj,nkj->nik", R, inv_I, R)
        self.dynamic = np.ones(n, bool)
        for b in static:
            self.inv_mass[b], self.inv_inertia[b], self.dynamic[b] = 0.0, 0.0, False
        self.J, self.rb, self.group = [], [], []

    def _add(self, J, rb):
        gid = len(set(self.group)) + 100  # group ids need not start at 0
        self.J.append(J)
        self.rb.append(rb)
        self.group += [gid] * len(J)

    def ball(self, a, b, p=None):
        """Ball joint between a and b (b may be -1) at world point p: J_a = [I, -[r_a]x], J_b = [-I, [r_b]x]."""
        p = self.rng.normal(size=3) if p is None else np.asarray(p, float)
        J = np.zeros((3, 2, 6))
        J[:, 0, :3], J[:, 0, 3:] = np.eye(3), -skew(p - self.x[a])
        if b >= 0:
            J[:, 1, :3], J[:, 1, 3:] = -np.eye(3), skew(p - self.x[b])
        self._add(J, np.tile([a, b], (3, 1)))

    def generic(self, pairs):
        """A group of len(pairs) rows with random Jacobian blocks; pairs = [(a, b), ...], -1 = world."""
        J = self.rng.normal(size=(len(pairs), 2, 6))
        rb = np.array(pairs)
        J[rb < 0] = 0.0
        self._add(J, rb)

    def arrays(self, shuffle=False):
        J, rb, g = np.concatenate(self.J), np.concatenate(self.rb), np.array(self.group)
        if shuffle:  # rows of a group need not be contiguous
            p = self.rng.permutation(len(J))
            J, rb, g = J[p], rb[p], g[p]
        return J, rb, g

    def dense(self, J, rb):
        return assemble_dense(J, rb, self.inv_mass, self.inv_inertia)


def chain(rng, n, to_world=False):
    s = Scene(rng, n, static=() if to_world else (0,))
    s.ball(1, -1) if to_world else s.ball(1, 0)
    for i in range(2, n):
        s.ball(i, i - 1)
    return s


def branched(rng, n):
    """Random recursive tree hanging from static body 0, mixed group sizes, one 3-body group."""
    s = Scene(rng, n, static=(0,))
    for i in range(1, n):
        p = int(rng.integers(0, i))
        kind = rng.integers(0, 3)
        if kind == 0:
            s.ball(i, p)
        else:
            s.generic([(i, p)] * (1 if kind == 1 else 2))
    return s


def floating(rng, n):
    """Free-floating tree (no ground) plus one static leaf; contains a group touching three bodies."""
    s = Scene(rng, n + 1, static=(n,))
    s.generic([(0, 1), (1, 2), (0, 2), (2, 1)])
    for i in range(3, n):
        s.ball(i, int(rng.integers(0, i)))
    s.ball(int(rng.integers(0, n)), n)
    return s


def loop_built_A(s, J, rb):
    m = len(J)
    Jf, Mi = np.zeros((m, 6 * s.n)), np.zeros((6 * s.n, 6 * s.n))
    for r in range(m):
        for slot in range(2):
            b = rb[r, slot]
            if b >= 0:
                Jf[r, 6 * b : 6 * b + 6] += J[r, slot]
    for b in range(s.n):
        Mi[6 * b : 6 * b + 3, 6 * b : 6 * b + 3] = s.inv_mass[b] * np.eye(3)
        Mi[6 * b + 3 : 6 * b + 6, 6 * b + 3 : 6 * b + 6] = s.inv_inertia[b]
    return Jf @ Mi @ Jf.T


def all_solves(s, J, rb, g, rhs):
    A = s.dense(J, rb)
    out = {"dense": solve_dense(A, rhs)}
    out["dense pattern"] = DensePattern(rb).solve(J, s.inv_mass, s.inv_inertia, rhs)
    pattern = SparsePattern.build(rb, s.n, s.dynamic)
    out["sparse"] = solve_sparse(pattern, J, s.inv_mass, s.inv_inertia, rhs)
    tree = TreeSolver.build(rb, g, s.n, s.dynamic)
    if tree is not None:
        out["tree"] = tree.solve(J, s.inv_mass, s.inv_inertia, rhs)
    return A, out


@pytest.mark.parametrize("make", [chain, branched, floating])
def test_dense_assembly_matches_loop(make):
    s = make(np.random.default_rng(1), 9)
    J, rb, g = s.arrays(shuffle=True)
    np.testing.assert_allclose(s.dense(J, rb), loop_built_A(s, J, rb), rtol=1e-12, atol=1e-12)
    out = np.empty((len(J), len(J)))
    assert assemble_dense(J, rb, s.inv_mass, s.inv_inertia, out=out) is out
    MJ = apply_inverse_mass(J, rb, s.inv_mass, s.inv_inertia, np.empty_like(J))
    assert np.all(MJ[rb < 0] == 0)
    # the once-per-epoch pattern: the same matrix from one product of all slots and a fixed mask
    pattern = DensePattern(rb)
    np.testing.assert_allclose(pattern.assemble(J, s.inv_mass, s.inv_inertia), out, rtol=1e-12, atol=1e-12)
    J2 = s.rng.normal(size=J.shape) * (rb >= 0)[..., None]  # reused with other Jacobians
    np.testing.assert_allclose(pattern.assemble(J2, s.inv_mass, s.inv_inertia), s.dense(J2, rb), rtol=1e-12,
                               atol=1e-12)


@pytest.mark.parametrize("make", [chain, branched, floating])
def test_sparse_assembly_matches_dense_and_is_refilled(make):
    s = make(np.random.default_rng(2), 9)
    J, rb, _ = s.arrays(shuffle=True)
    pattern = SparsePattern.build(rb, s.n, s.dynamic)
    for J_now in (J, s.rng.normal(size=J.shape) * (rb >= 0)[..., None]):
        A = pattern.assemble(J_now, apply_inverse_mass(J_now, rb, s.inv_mass, s.inv_inertia))
        np.testing.assert_allclose(A.toarray(), s.dense(J_now, rb), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("make", [chain, lambda rng, n: chain(rng, n, True), branched, floating])
def test_sparse_and_tree_match_dense(make, seed):
    rng = np.random.default_rng(seed)
    s = make(rng, int(rng.integers(5, 40)))
    J, rb, g = s.arrays(shuffle=seed % 2 == 1)
    rhs = rng.normal(size=len(J))
    A, out = all_solves(s, J, rb, g, rhs)
    assert set(out) == {"dense", "dense pattern", "sparse", "tree"}
    lam0, info0 = out["dense"]
    assert info0.method == "cholesky" and not info0.rank_deficient and info0.residual < 1e-10
    for name in ("dense pattern", "sparse", "tree"):
        lam, info = out[name]
        assert info.method == {"dense pattern": "cholesky", "sparse": "lu", "tree": "tree"}[name], info
        assert not info.rank_deficient and info.residual < 1e-10
        assert np.linalg.norm(lam - lam0) <= 1e-9 * np.linalg.norm(lam0), name


def test_tree_solver_is_reusable_and_handles_a_forest():
    rng = np.random.default_rng(7)
    s = Scene(rng, 12, static=(0,))
    for i in range(1, 6):
        s.ball(i, i - 1)
    for i in range(7, 12):  # second, free-floating component
        s.ball(i, i - 1)
    J, rb, g = s.arrays()
    tree = TreeSolver.build(rb, g, s.n, s.dynamic)
    A = s.dense(J, rb)
    for _ in range(2):
        rhs = rng.normal(size=len(J))
        lam, info = tree.solve(J, s.inv_mass, s.inv_inertia, rhs)
        assert info.method == "tree"
        np.testing.assert_allclose(A @ lam, rhs, atol=1e-9)


def closed_loop(rng):
    """Two bodies held together by three ball joints at non-collinear points: 9 rows, rank 6."""
    s = Scene(rng, 2)
    for _ in range(3):
        s.ball(0, 1)
    return s


def test_tree_build_refuses_loops():
    rng = np.random.default_rng(3)
    s = closed_loop(rng)
    assert TreeSolver.build(*s.arrays()[1:], s.n, s.dynamic) is None
    ring = Scene(rng, 4)  # four bodies in a ring: a loop, though full rank
    for i in range(4):
        ring.ball(i, (i + 1) % 4)
    assert TreeSolver.build(*ring.arrays()[1:], ring.n, ring.dynamic) is None
    bridge = chain(rng, 5)  # pinned to static body 0 and to the world: a loop through the ground
    bridge.ball(4, -1)
    assert TreeSolver.build(*bridge.arrays()[1:], bridge.n, bridge.dynamic) is None


def duplicated(rng):
    s = chain(rng, 6)
    J, rb, g = s.arrays()
    # the last row of the first joint again, inside its group (tree stays a tree, A turns singular)
    return s, np.concatenate([J, J[2:3]]), np.concatenate([rb, rb[2:3]]), np.concatenate([g, g[2:3]])


@pytest.mark.parametrize("case", ["duplicate", "loop", "zero_row"])
def test_singular_consistent_systems_stay_finite_and_say_so(case):
    rng = np.random.default_rng(11)
    if case == "duplicate":
        s, J, rb, g = duplicated(rng)
    elif case == "loop":
        s = closed_loop(rng)
        J, rb, g = s.arrays()
    else:
        s = chain(rng, 4)
        s.generic([(0, -1)])  # a row on the static body only: a zero row of A
        J, rb, g = s.arrays()
    A = s.dense(J, rb)
    rhs = A @ rng.normal(size=len(J))  # consistent
    _, out = all_solves(s, J, rb, g, rhs)
    assert ("tree" in out) == (case != "loop")
    for name, (lam, info) in out.items():
        assert isinstance(info, SolveInfo)
        assert np.all(np.isfinite(lam)), name
        assert info.rank_deficient, (name, info)
        assert info.method in ("pinv", "lu+shift", "tree->lu+shift"), (name, info)
        assert np.linalg.norm(A @ lam - rhs) <= 1e-8 * np.linalg.norm(rhs), (name, info)
        assert info.residual <= 1e-8
    lam_pinv, info = out["dense"]
    assert info.rank == np.linalg.matrix_rank(A)
    assert np.linalg.norm(lam_pinv) <= np.linalg.norm(np.linalg.lstsq(A, rhs, rcond=None)[0]) * (1 + 1e-8)


def test_inconsistent_singular_system_is_finite_least_squares():
    rng = np.random.default_rng(5)
    s, J, rb, g = duplicated(rng)
    A = s.dense(J, rb)
    rhs = rng.normal(size=len(J))  # duplicate rows asked for different values
    lam, info = solve_dense(A, rhs)
    assert np.all(np.isfinite(lam)) and info.rank_deficient and info.residual > 1e-3
    np.testing.assert_allclose(lam, np.linalg.pinv(A) @ rhs, atol=1e-8)
    lam_s, info_s = solve_sparse(SparsePattern.build(rb, s.n, s.dynamic), J, s.inv_mass, s.inv_inertia, rhs)
    assert np.all(np.isfinite(lam_s)) and info_s.rank_deficient and info_s.regularization > 0
    # the redundant direction carries no force: the accelerations agree with the least-squares solution
    MJ = apply_inverse_mass(J, rb, s.inv_mass, s.inv_inertia)
    np.testing.assert_allclose(A @ lam_s, A @ lam, atol=1e-6 * np.linalg.norm(rhs))
    assert MJ.shape == J.shape


def test_empty_and_choose_solver():
    lam, info = solve_dense(np.zeros((0, 0)), np.zeros(0))
    assert lam.shape == (0,) and not info.rank_deficient
    assert choose_solver(9, True) == "dense"
    assert choose_solver(3000, False, 3000) == "sparse"
    assert choose_solver(3000, True, 3000) == "tree"
    assert choose_solver(3000, True, 6) == "sparse"
    s = chain(np.random.default_rng(0), 5)  # body 0 static; bodies 1..3 carry two joints
    J, rb, g = s.arrays()
    assert max_rows_per_body(rb, s.dynamic) == 6
