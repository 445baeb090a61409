"""Baraff's linear-time solver for tree-structured constraint graphs (Baraff 1996), split from linsolve.py.

The KKT system [[M, -J^T], [-J, 0]] is factored block by block from the leaves to the root; see TreeSolver.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from benchmarks.linsolve import (RANK_RTOL, RESIDUAL_RTOL, SolveInfo, SparsePattern, dynamic_slots, relative_residual,
                       apply_inverse_mass, lapack, solve_sparse)


class TreeSolver:
    """Linear-time block LDL^T of the KKT matrix on a forest of bodies and constraint groups (module docstring).

    Built once per active row set; holds the elimination order and per-node views into persistent buffers so
    that `solve` does a fixed number of small numpy products per node.
    """

    @classmethod
    def build(cls, row_bodies, row_group, n_bodies, dynamic_mask) -> "TreeSolver | None":
        rb = np.asarray(row_bodies, dtype=np.int64).reshape(-1, 2)
        dmask = np.asarray(dynamic_mask, dtype=bool)
        dyn = dynamic_slots(rb, dmask)
        _, gidx = np.unique(np.asarray(row_group).reshape(-1), return_inverse=True)
        ng = int(gidx.max()) + 1 if len(gidx) else 0
        # a row with fewer than two distinct dynamic bodies acts against the world: its group is grounded
        internal = dyn.all(axis=1) & (rb[:, 0] != rb[:, 1])
        grounded = np.bincount(gidx[~internal], minlength=ng) > 0
        rows, slots = np.nonzero(dyn)
        ebody, egroup = rb[rows, slots], gidx[rows]
        edge_keys, rs_edge = np.unique(egroup * max(n_bodies, 1) + ebody, return_inverse=True)
        edge_group, edge_body = edge_keys // max(n_bodies, 1), edge_keys % max(n_bodies, 1)
        bodies = np.unique(edge_body)  # node bodies: dynamic and touched by a row
        graph = _Forest(len(bodies), ng, np.searchsorted(bodies, edge_body), edge_group, grounded)
        if not graph.ok:
            return None
        self = cls()
        self._setup(rb, gidx, ng, n_bodies, dmask, bodies, graph, rows, slots, rs_edge, edge_group)
        return self

    def _setup(self, rb, gidx, ng, n_bodies, dmask, bodies, graph, rows, slots, rs_edge, edge_group):
        m, nb = len(rb), len(bodies)
        self.row_bodies, self.n_bodies, self.dynamic_mask = rb, n_bodies, dmask
        self.bodies = bodies
        k = np.bincount(gidx, minlength=ng)
        kmax = int(k.max()) if ng else 1
        order = np.argsort(gidx, kind="stable")
        local = np.empty(m, np.int64)
        local[order] = np.arange(m) - np.r_[0, np.cumsum(k)][gidx[order]]
        # persistent buffers; every per-node array below is a view into them
        self.edge_J = np.zeros((len(edge_group), kmax, 6))  # (E,kmax,6) J_gb, rows of g in local order
        self.rs = (rows, slots, rs_edge, local[rows])
        self.Pb = np.zeros((nb, 6, 6))  # body pivots D_n
        self.Pg = np.zeros((ng, kmax, kmax))  # group pivots D_n, padded to kmax
        self.Pg_pad = np.arange(kmax)[None, :] >= k[:, None]  # (ng,kmax) padding rows/cols
        size = np.full(len(graph.kind), 6, dtype=np.int64)  # unknowns per node: 6 per body, k per group
        size[graph.kind == 1] = k[graph.index[graph.kind == 1]]
        offset = np.r_[0, np.cumsum(size)]
        self.z, self.x = np.zeros(offset[-1]), np.zeros(offset[-1])
        self.row_flat = offset[graph.position_of_group][gidx] + local  # where row r's multiplier sits
        self.P, self.zv, self.xv, self.links = [], [], [], []
        for n, (kind, i) in enumerate(zip(graph.kind, graph.index)):
            self.P.append(self.Pb[i] if kind == 0 else self.Pg[i, : k[i], : k[i]])
            self.zv.append(self.z[offset[n] : offset[n + 1]])
            self.xv.append(self.x[offset[n] : offset[n + 1]])
            p = graph.parent[n]
            if p >= 0:  # H_pn: rows of the parent, columns of n
                e = graph.parent_edge[n]
                Jgb = self.edge_J[e, : k[edge_group[e]]]
                H = Jgb if kind == 0 else Jgb.T
                self.links.append((n, p, H, H.T))
        self.n_nodes = len(graph.kind)
        self._fallback = None

    def solve(self, J, inv_mass, inv_inertia_world, rhs) -> tuple[np.ndarray, SolveInfo]:
        """lam with (J M^-1 J^T) lam = rhs, O(nodes). Falls back to the sparse solver (method "tree->lu" or
        "tree->lu+shift") on a singular pivot, a non-invertible body mass, or a residual above RESIDUAL_RTOL."""
        rhs = np.asarray(rhs, dtype=float)
        rows, slots, rs_edge, rs_local = self.rs
        self.edge_J.fill(0.0)
        np.add.at(self.edge_J, (rs_edge, rs_local), J[rows, slots])
        try:
            with np.errstate(all="ignore"):
                self._body_masses(inv_mass, inv_inertia_world)
                Dinv, L = self._factor()
                lam = self._substitute(Dinv, L, rhs)
            bad = self._bad_pivot()
        except np.linalg.LinAlgError:
            bad = "singular pivot"
        if not bad:
            res = self._residual(J, inv_mass, inv_inertia_world, lam, rhs)
            if res <= RESIDUAL_RTOL:
                return lam, SolveInfo("tree", res, False)
            bad = f"tree residual {res:.1e}"
        return self._solve_fallback(J, inv_mass, inv_inertia_world, rhs, bad)

    def _body_masses(self, inv_mass, inv_inertia_world):
        b = self.bodies
        if np.any(inv_mass[b] <= 0):
            raise np.linalg.LinAlgError("zero inverse mass on a tree body")
        # M_i = diag(m_i I3, I_world,i) with m_i = 1 / inv_mass_i, I_world,i = (inv_inertia_world_i)^-1
        self.Pb.fill(0.0)
        self.Pb[:, :3, :3] = np.eye(3) / inv_mass[b][:, None, None]
        self.Pb[:, 3:, 3:] = np.linalg.inv(inv_inertia_world[b])
        self.Pg.fill(0.0)

    def _factor(self):
        # LAPACK getrf + getri directly: a third of np.linalg.inv's per-call overhead on 3x3 and 6x6 blocks
        P, getrf, getri = self.P, lapack().dgetrf, lapack().dgetri
        Dinv, L = [None] * self.n_nodes, [None] * self.n_nodes
        links = iter(self.links)
        nxt = next(links, None)
        for n in range(self.n_nodes):  # children before parents
            # D_n^-1 (D_n already holds H_nn - sum_c L_nc D_c L_nc^T from its children)
            lu, piv, info = getrf(P[n])
            Dinv[n], info2 = getri(lu, piv)
            if info or info2:
                raise np.linalg.LinAlgError("singular pivot")
            if nxt is not None and nxt[0] == n:
                _, p, H, HT = nxt
                # L_pn = H_pn D_n^-1
                L[n] = H @ Dinv[n]
                # D_p -= L_pn D_n L_pn^T = L_pn H_np
                P[p] -= L[n] @ HT
                nxt = next(links, None)
        return Dinv, L

    def _substitute(self, Dinv, L, rhs):
        z, zv, xv = self.z, self.zv, self.xv
        # b = [0 for bodies; rhs for groups]
        z.fill(0.0)
        z[self.row_flat] = rhs
        # forward, children first: z_p -= L_pn z_n
        for n, p, _, _ in self.links:
            zv[p] -= L[n] @ zv[n]
        # diagonal: x_n = D_n^-1 z_n
        for n in range(self.n_nodes):
            np.matmul(Dinv[n], zv[n], out=xv[n])
        # backward, root first: x_n -= L_pn^T x_p
        for n, p, _, _ in reversed(self.links):
            xv[n] -= L[n].T @ xv[p]
        # the group unknowns are -lambda
        return -self.x[self.row_flat]

    def _bad_pivot(self):
        # every group pivot -D_g must be positive definite: eigenvalues of all blocks at once
        if not len(self.Pg):
            return ""
        kmax = self.Pg.shape[1]
        S = -self.Pg
        if not np.all(np.isfinite(S)):
            return "non-finite pivot"
        # padding rows/cols become (largest diagonal of the block) * I: no effect on its conditioning
        dmax = np.max(np.abs(np.diagonal(S, axis1=1, axis2=2)), axis=1)
        S[:, np.arange(kmax), np.arange(kmax)] += self.Pg_pad * np.where(dmax > 0, dmax, 1.0)[:, None]
        w = np.linalg.eigvalsh(S)
        if np.any(w[:, 0] <= RANK_RTOL * np.abs(w[:, -1])):
            return "singular group pivot"
        return ""

    def _residual(self, J, inv_mass, inv_inertia_world, lam, rhs):
        if not np.all(np.isfinite(lam)):
            return np.inf
        rb = self.row_bodies
        MJ = apply_inverse_mass(J, rb, inv_mass, inv_inertia_world)
        # a = M^-1 J^T lam per body, then J a
        f = np.zeros((max(self.n_bodies, 1), 6))
        valid = rb >= 0
        np.add.at(f, rb[valid], (MJ * lam[:, None, None])[valid])
        Ja = np.einsum("rsk,rsk->r", J, np.where(valid[..., None], f[np.maximum(rb, 0)], 0.0))
        return relative_residual(Ja - rhs, rhs)

    def _solve_fallback(self, J, inv_mass, inv_inertia_world, rhs, why):
        if self._fallback is None:
            self._fallback = SparsePattern.build(self.row_bodies, self.n_bodies, self.dynamic_mask)
        lam, info = solve_sparse(self._fallback, J, inv_mass, inv_inertia_world, rhs)
        info.method = "tree->" + info.method
        info.note = why + ("; " + info.note if info.note else "")
        return lam, info


class _Forest:
    """Nodes: bodies 0..nb-1, groups nb..nb+ng-1, and the world. Finds whether the graph is a forest and, if
    so, an elimination order (children before parents), each component rooted at its grounded group."""

    def __init__(self, nb, ng, edge_body, edge_group, grounded):
        world = nb + ng
        adj = [[] for _ in range(world + 1)]
        edges = [(b, nb + g, e) for e, (b, g) in enumerate(zip(edge_body, edge_group))]
        edges += [(world, nb + g, -1) for g in np.flatnonzero(grounded)]
        parent_uf = list(range(world + 1))

        def find(a):
            while parent_uf[a] != a:
                parent_uf[a] = parent_uf[parent_uf[a]]
                a = parent_uf[a]
            return a

        self.ok = True
        for a, c, e in edges:
            ra, rc = find(a), find(c)
            if ra == rc:  # a second path between two nodes: a closed loop
                self.ok = False
                return
            parent_uf[ra] = rc
            adj[a].append((c, e))
            adj[c].append((a, e))
        # breadth first from the world (so grounded groups are roots), then from every unreached node
        seen = [False] * (world + 1)
        bfs, par, pedge = [], {}, {}
        for root in [world] + list(range(world)):
            if seen[root]:
                continue
            seen[root] = True
            par[root], pedge[root] = -1, -1
            queue = deque([root])
            while queue:
                a = queue.popleft()
                bfs.append(a)
                for c, e in adj[a]:
                    if not seen[c]:
                        seen[c] = True
                        par[c], pedge[c] = (a if a != world else -1), e
                        queue.append(c)
        elim = [a for a in reversed(bfs) if a != world]
        pos = {a: i for i, a in enumerate(elim)}
        self.kind = np.array([0 if a < nb else 1 for a in elim], dtype=np.int64)
        self.index = np.array([a if a < nb else a - nb for a in elim], dtype=np.int64)
        self.parent = np.array([pos[par[a]] if par[a] >= 0 else -1 for a in elim], dtype=np.int64)
        self.parent_edge = np.array([pedge[a] for a in elim], dtype=np.int64)
        self.position_of_group = np.array([pos[nb + g] for g in range(ng)], dtype=np.int64)
        # the flat layout of the unknowns follows the elimination order
