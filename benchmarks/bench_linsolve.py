"""Benchmark of the multiplier solvers (benchmarks/linsolve.py): per-solve wall time, assembly included.

    python benchmarks/bench_linsolve.py

Scenes: chains of N ball-jointed unit boxes (3-row groups) hanging from the world, a branched tree (random
recursive tree of boxes hanging from the world) and a star (one hub box carrying N boxes). Prints a table in ms,
the ratio t(1000)/t(100) on chains (10 for linear cost) and the dense/sparse crossover used by choose_solver.
"""
import sys
import time

import numpy as np

from benchmarks.linsolve_tree import TreeSolver
from benchmarks.linsolve import SparsePattern, assemble_dense, solve_dense, solve_sparse

DENSE_MAX = 3000  # rows; beyond this dense assembly + Cholesky is not sane to time


def boxes(rng, n):
    """n unit boxes of mass 1..2 at random orientations: inv_mass (n,), inv_inertia_world (n,3,3)."""
    mass = rng.uniform(1.0, 2.0, n)
    R = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    inv_I = np.repeat((6.0 / mass)[:, None], 3, axis=1)  # unit cube: I = m/6
    return 1.0 / mass, np.einsum("nij,nj,nkj->nik", R, inv_I, R)


def ball_rows(x, pairs, anchors):
    """Ball-joint rows for (a, b) pairs at world anchors: J_a = [I, -[r_a]x], J_b = [-I, [r_b]x]."""
    k = len(pairs)
    J, rb = np.zeros((k, 3, 2, 6)), np.repeat(np.asarray(pairs)[:, None, :], 3, axis=1)
    eye = np.eye(3)
    for slot, sign in ((0, 1.0), (1, -1.0)):
        b = rb[:, 0, slot]
        r = anchors - np.where(b[:, None] >= 0, x[np.maximum(b, 0)], 0.0)
        sk = np.zeros((k, 3, 3))
        sk[:, 0, 1], sk[:, 0, 2], sk[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
        sk -= sk.transpose(0, 2, 1)
        J[:, :, slot, :3] = sign * eye
        J[:, :, slot, 3:] = -sign * sk
        J[b < 0, :, slot] = 0.0
    return J.reshape(-1, 2, 6), rb.reshape(-1, 2), np.repeat(np.arange(k), 3)


def scene(kind, n, rng):
    if kind == "chain":
        parent = np.arange(n) - 1
    elif kind == "tree":
        parent = np.r_[-1, [rng.integers(0, i) for i in range(1, n)]]
    else:  # star
        parent = np.r_[-1, np.zeros(n - 1, dtype=np.int64)]
    x = np.zeros((n, 3))
    for i in range(1, n):
        x[i] = x[parent[i]] + rng.normal(size=3)
    anchors = np.r_[[x[0] + [0, 0, 0.5]], 0.5 * (x[1:] + x[parent[1:]])]
    J, rb, g = ball_rows(x, np.c_[np.arange(n), parent], anchors)
    inv_mass, inv_inertia = boxes(rng, n)
    return J, rb, g, inv_mass, inv_inertia


def per_call(f, min_time=0.2):
    f()
    best, total, reps = np.inf, 0.0, 0
    while total < min_time or reps < 3:
        t = time.perf_counter()
        f()
        dt = time.perf_counter() - t
        best, total, reps = min(best, dt), total + dt, reps + 1
    return best


def measure(kind, n, rng, methods=("dense", "sparse", "tree")):
    J, rb, g, inv_mass, inv_I = scene(kind, n, rng)
    m, dyn = len(J), np.ones(n, bool)
    rhs = rng.normal(size=m)
    out = {"rows": m}
    if "dense" in methods and m <= DENSE_MAX:
        out["dense"] = per_call(lambda: solve_dense(assemble_dense(J, rb, inv_mass, inv_I), rhs))
    if "sparse" in methods:
        pattern = SparsePattern.build(rb, n, dyn)
        out["sparse"] = per_call(lambda: solve_sparse(pattern, J, inv_mass, inv_I, rhs))
        out["sparse build"] = per_call(lambda: SparsePattern.build(rb, n, dyn), 0.05)
    if "tree" in methods:
        tree = TreeSolver.build(rb, g, n, dyn)
        assert tree is not None and tree.solve(J, inv_mass, inv_I, rhs)[1].method == "tree"
        out["tree"] = per_call(lambda: tree.solve(J, inv_mass, inv_I, rhs))
        out["tree build"] = per_call(lambda: TreeSolver.build(rb, g, n, dyn), 0.05)
    return out


def main():
    rng = np.random.default_rng(0)
    cols = ("dense", "sparse", "tree", "sparse build", "tree build")
    print(f"{'scene':<8}{'bodies':>7}{'rows':>7}" + "".join(f"{c + ' ms':>16}" for c in cols))
    results = {}
    for kind, sizes in (("chain", (10, 100, 1000)), ("tree", (100, 1000)), ("star", (100, 1000))):
        for n in sizes:
            r = results[kind, n] = measure(kind, n, rng)
            cells = "".join(f"{1e3 * r[c]:16.3f}" if c in r else f"{'-':>16}" for c in cols)
            print(f"{kind:<8}{n:>7}{r['rows']:>7}{cells}")
            sys.stdout.flush()
    print("\nchain t(1000)/t(100):  " + "  ".join(
        f"{c} {results['chain', 1000][c] / results['chain', 100][c]:.1f}" for c in ("dense", "sparse", "tree")))
    print("\ndense vs sparse vs tree on short chains (ms):")
    print(f"  -> sparse first beats dense at {sweep('chain', (8, 16, 24, 32, 34, 36, 38, 40, 44, 48), rng)} rows")
    print("sparse vs tree on stars (rows at the hub = all rows; ms):")
    print(f"  -> tree first beats sparse at {sweep('star', (10, 15, 20, 22, 24, 26, 28, 30, 40), rng)} rows")


def sweep(kind, sizes, rng):
    first = {"chain": ("sparse", "dense"), "star": ("tree", "sparse")}[kind]
    found = None
    for n in sizes:
        r = measure(kind, n, rng)
        print(f"  {n:3d} bodies {r['rows']:4d} rows  " + "  ".join(
            f"{c} {1e3 * r[c]:.3f}" for c in ("dense", "sparse", "tree")))
        if found is None and r[first[0]] < r[first[1]]:
            found = r["rows"]
    return found

if __name__ == "__main__":
    main()
