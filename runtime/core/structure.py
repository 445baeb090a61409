"""The structure of J M^-1 J^T for one set of active rows, found once per epoch (the symbolic half of the solve).

A = J M^-1 J^T couples two rows when they share a dynamic body. It is factored A = L L^T by a left-looking sparse
Cholesky (solve.py) whose pattern is decided here:

- order: the constraint instances are eliminated by greedy minimum degree on the graph "two instances share a
  dynamic body" (the rows of an instance stay together). On a tree of bodies this eliminates from the leaves
  inward, and a leaf's neighbours (the joints at its parent body) already form a clique: no fill at all, so
  chains and trees factor in time linear in the number of links (a chain's A is block tridiagonal, a banded
  matrix); on anything else minimum degree keeps the fill small; a dense system is simply a full pattern.
- pattern: L's columns by symbolic elimination: the pattern of column j is A's below the diagonal plus the
  patterns of its children in the elimination tree, minus themselves (Liu, "The role of elimination trees in
  sparse factorization", 1990).
- couplings: every pair of row slots on one dynamic body, (i, s_i) and (j, s_j) with i >= j in the order, and
  where its product J_i,s_i M^-1 J_j,s_j^T lands in L's value array: A is assembled by one pass over them.

Active (a named tuple of arrays, the kernels' view of an epoch):
    instances (k,)        the constraint instances with an active row, evaluated every time
    rows (m,)             the active rows (global row numbers) in elimination order
    held (m,)             the row is kept on its manifold by projection (else it is still assembling, and its
                          Baumgarte terms act): written by the kernels
    local (M,)            the position in `rows` of every global row (-1: not active)
    Lp (m+1,), Li (nnz,)  L in compressed columns, each column's rows ascending, the diagonal first
    Rp (m+1,), Rk, Rpos   L by rows below the diagonal: for row j, the columns k < j with L[j,k] != 0 and where
                          L[j,k] is in the value array
    cp_i, cp_j (c,)       the couplings: local rows (for masks), cp_ri, cp_si, cp_rj, cp_sj their global rows
                          and slots, cp_dest their place in L's value array
    refine (1,)           how many refinement corrections a kept factorization may take and still cost less than
                          a fresh one (solve.py solve_again), at most solve.REFINE_STEPS; -1: never keep one
"""
from __future__ import annotations

import heapq
from collections import defaultdict, namedtuple

import numpy as np

from .solve import REFINE_STEPS

Active = namedtuple("Active", "instances rows held local Lp Li Rp Rk Rpos cp_i cp_j cp_ri cp_si cp_rj cp_sj cp_dest "
                               "refine")


def _ints(values) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values, dtype=np.int64).reshape(-1))


# structures already built, by what they are built from (a contact set that comes back, as an escapement's does at
# every tick, is not analysed again); a few, since a long chain's structure is large
_BUILT: dict = {}
BUILT_KEPT = 32


def build_active(cons, active_rows: np.ndarray, dynamic: np.ndarray, held=None, dense: bool = False) -> Active:
    """The Active structure of the global rows `active_rows` of the model's constraints `cons`; dynamic (n+1,)
    marks the bodies with a mass (the world row is not). held: (len(active_rows),) initial flags, in the order of
    active_rows (default: none held). dense: L's pattern full (every row coupled to every other).

    The structure depends only on the rows, their instances, those instances' bodies and which bodies are
    dynamic: one built before from the same is reused (its arrays are read-only to the kernels), with fresh held
    flags (the one array the kernels write)."""
    active_rows = np.asarray(active_rows, dtype=np.int64)
    instances = cons.row_instance[active_rows]
    key = (dense, len(cons.row_instance), active_rows.tobytes(), instances.tobytes(), cons.body[instances].tobytes(),
           np.asarray(dynamic, np.bool_).tobytes())
    act = _BUILT.get(key)
    if act is None:
        act = _build(cons, active_rows, dynamic, dense)
        if len(_BUILT) >= BUILT_KEPT:
            _BUILT.clear()
        _BUILT[key] = act
    flags = np.zeros(len(act.rows), dtype=np.bool_)
    if held is not None:
        flags[act.local[active_rows]] = np.asarray(held, bool)
    return act._replace(held=flags)


def _build(cons, active_rows: np.ndarray, dynamic: np.ndarray, dense: bool) -> Active:
    """build_active's structure, analysed (its held flags all False)."""
    instances = list(dict.fromkeys(cons.row_instance[active_rows].tolist()))
    order = minimum_degree(instances, cons.body, dynamic)
    rows_of = defaultdict(list)
    for r in active_rows.tolist():
        rows_of[int(cons.row_instance[r])].append(r)
    rows = [r for k in order for r in rows_of[k]]
    m = len(rows)
    slots = _dynamic_slots(rows, cons, dynamic)
    Lp, Li = _pattern(m, slots, dense)
    Rp, Rk, Rpos = _by_rows(m, Lp, Li)
    ci, cj, si, sj, dest = _couplings(slots, Lp, Li)
    global_rows = np.asarray(rows, np.int64)
    flags = np.zeros(m, dtype=np.bool_)
    local = np.full(len(cons.row_instance), -1, np.int64)
    local[global_rows] = np.arange(m)
    return Active(_ints(sorted(set(instances))), _ints(rows), flags, local, Lp, Li, Rp, Rk, Rpos, ci, cj,
                  _ints(global_rows[ci]), si, _ints(global_rows[cj]), sj, dest,
                  _ints([affordable_corrections(Lp, len(dest))]))


def affordable_corrections(Lp: np.ndarray, couplings: int) -> int:
    """How many corrections of iterative refinement cost less than a fresh factorization, counted in
    multiply-adds: a fresh one assembles (6 a coupling) and factors (a column's update touches each column k
    reaching it, about sum_k len_k^2); a try substitutes (2 nnz, forward and back) and multiplies matrix-free
    (about 30 a row), then each correction does both again. At most solve.REFINE_STEPS; -1: not even the try."""
    lengths = np.diff(Lp)
    fresh = 6 * couplings + int(np.sum(lengths * lengths))
    one = 4 * int(Lp[-1]) + 30 * len(lengths)
    return int(min(REFINE_STEPS, fresh // max(one, 1) - 1))


def minimum_degree(instances: list, body: np.ndarray, dynamic: np.ndarray) -> list:
    """The instances in greedy minimum-degree elimination order (ties: first listed first)."""
    on_body = defaultdict(list)
    for k in instances:
        for b in set(body[k].tolist()):
            if b >= 0 and dynamic[b]:
                on_body[b].append(k)
    neighbours = {k: set() for k in instances}
    for members in on_body.values():
        for k in members:
            neighbours[k].update(members)
    for k in instances:
        neighbours[k].discard(k)
    rank = {k: i for i, k in enumerate(instances)}
    heap = [(len(neighbours[k]), rank[k], k) for k in instances]
    heapq.heapify(heap)
    done, order = set(), []
    while heap:
        degree, _, k = heapq.heappop(heap)
        if k in done or degree != len(neighbours[k]):
            continue  # eliminated, or a stale degree
        done.add(k)
        order.append(k)
        # eliminating k joins its neighbours into a clique
        around = neighbours.pop(k)
        for u in around:
            neighbours[u].discard(k)
            neighbours[u] |= around - {u}
            heapq.heappush(heap, (len(neighbours[u]), rank[u], u))
    return order


def _dynamic_slots(rows: list, cons, dynamic) -> dict:
    """body -> [(local row, slot)] of every row slot on a dynamic body."""
    slots = defaultdict(list)
    for i, r in enumerate(rows):
        k = int(cons.row_instance[r])
        for s in range(2):
            b = int(cons.body[k, s])
            if b >= 0 and dynamic[b]:
                slots[b].append((i, s))
    return slots


def _pattern(m: int, slots: dict, dense: bool = False) -> tuple:
    """Lp, Li of L (each column: the diagonal, then its rows ascending) by symbolic elimination (or full)."""
    below = [set(range(j + 1, m)) if dense else set() for j in range(m)]
    for members in slots.values():
        rows = sorted({i for i, _ in members})
        for a, i in enumerate(rows):
            for j in rows[:a]:
                below[j].add(i)
    for j in range(m):
        if below[j]:
            parent = min(below[j])
            below[parent] |= below[j] - {parent}
    Lp = np.zeros(m + 1, dtype=np.int64)
    Li = []
    for j in range(m):
        Li.append(j)
        Li.extend(sorted(below[j]))
        Lp[j + 1] = len(Li)
    return Lp, _ints(Li)


def _by_rows(m: int, Lp: np.ndarray, Li: np.ndarray) -> tuple:
    """For each row j, the columns k < j with L[j,k] in the pattern and the position of that entry."""
    entries = [[] for _ in range(m)]
    for k in range(m):
        for p in range(Lp[k] + 1, Lp[k + 1]):
            entries[int(Li[p])].append((k, p))
    Rp = np.zeros(m + 1, dtype=np.int64)
    Rk, Rpos = [], []
    for j in range(m):
        for k, p in sorted(entries[j]):
            Rk.append(k)
            Rpos.append(p)
        Rp[j + 1] = len(Rk)
    return Rp, _ints(Rk), _ints(Rpos)


def _couplings(slots: dict, Lp: np.ndarray, Li: np.ndarray) -> tuple:
    """cp_i, cp_j, cp_si, cp_sj, cp_dest: every pair of row slots on one dynamic body with i >= j."""
    ci, cj, csi, csj, dest = [], [], [], [], []
    for members in slots.values():
        for i, si in members:
            for j, sj in members:
                if i < j:
                    continue
                column = Li[Lp[j]:Lp[j + 1]]
                ci.append(i)
                cj.append(j)
                csi.append(si)
                csj.append(sj)
                dest.append(int(Lp[j] + np.searchsorted(column, i)))
    return _ints(ci), _ints(cj), _ints(csi), _ints(csj), _ints(dest)


def empty_active() -> Active:
    z = np.zeros(0, np.int64)
    return Active(z, z, np.zeros(0, np.bool_), z, np.zeros(1, np.int64), z, np.zeros(1, np.int64), z, z, z, z, z, z,
                  z, z, z, _ints([-1]))
