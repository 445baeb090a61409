"""The data and the scratch of a run: the mutable state the kernels advance, and their preallocated buffers.

    y        (n+1, 13)  the state, one row per body [x(3) q(4: w,x,y,z) v(3) w(3: world angular velocity)], the
                        last row the world (at rest, identity pose; never advanced)
    Scratch  buffers of one evaluation and of the integrators (a named tuple of arrays, below)

Columns of a packed row: X, Q, V, W.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

X, Q, V, W = slice(0, 3), slice(3, 7), slice(7, 10), slice(10, 13)
PACKED = 13
STAGES = 5  # slopes kept by the integrators: RK4's four, and the slope at the end of a step (dynamics/integrate.py)

Scratch = namedtuple("Scratch", "R inv_inertia force torque acc param C J ct bias MJ Jd rhs lam dlam diag work dropped "
                                "include Lx target correction delta k y0 ys start R0 friction impulse air block "
                                "rested lam_step counters")
# the buffers of one small block (an instance's rows, at most 3) of the procedural projection
Block = namedtuple("Block", "K rhs x J D dx")
# counters: [0] evaluations whose solve dropped a dependent row, [1] projections done, [2] 1 + the first sliding
# contact whose slip a stage of the step found turned back (0: none; core/contact.py); the factorization kept for
# the next evaluations (core/solve.py `solve_again`): [3] 1 while Lx holds the factor of the active rows' whole
# J M^-1 J^T (0: it does not, or it was never made), [4] how many rows that factorization dropped, [5] evaluations
# still to factor afresh before the kept factor is tried again, [6] the length of the last such wait, [7]
# evaluations that the kept factor served; [8] steps taken at rest, the state left as it was (core/rest.py), [9]
# the steps in a row at rest when the last call ended, in the state `rested` (the state it ended with); the error
# control of RK4 (dynamics/integrate.py): [10] steps taken again in substeps, [11] the substeps they took, [12] steps
# whose estimated error stayed above the tolerance (time-varying inputs, or the most substeps not enough); [13] 1
# when the last call ended with RK4's slope at its end state in k[END] (a call that goes on from there keeps it)
COUNTER_RANK, COUNTER_PROJECTIONS, COUNTER_TURNED_BACK = 0, 1, 2
COUNTER_KEPT, COUNTER_KEPT_DROPPED, COUNTER_WAIT, COUNTER_BACKOFF, COUNTER_REUSED = 3, 4, 5, 6, 7
COUNTER_RESTING, COUNTER_STILL = 8, 9
COUNTER_REFINED, COUNTER_SUBSTEPS, COUNTER_OVER, COUNTER_SLOPE = 10, 11, 12, 13
COUNTERS = 14
# the counts of a whole run, kept when the buffers grow (core/build.py reserve_contacts)
CUMULATIVE_COUNTERS = (COUNTER_RANK, COUNTER_PROJECTIONS, COUNTER_REUSED, COUNTER_RESTING, COUNTER_REFINED,
                       COUNTER_SUBSTEPS, COUNTER_OVER)


def initial_state(plan) -> np.ndarray:
    """y (n+1, 13) at the plan's start."""
    n = plan.n
    y = np.zeros((n + 1, PACKED))
    y[:n, X], y[:n, Q], y[:n, V], y[:n, W] = plan.x0, plan.q0, plan.v0, plan.w0
    y[n, 3] = 1.0  # the world: identity orientation
    return y


def allocate_scratch(n: int, param: np.ndarray, rows: int, fill: int = 1) -> Scratch:
    """Buffers for n bodies (n+1 rows with the world), the constraint parameters `param` (copied: drivers write
    into the copy), `rows` constraint rows and `fill` entries of L."""
    b = n + 1
    m = max(rows, 1)
    return Scratch(
        R=np.tile(np.eye(3), (b, 1, 1)), inv_inertia=np.zeros((b, 3, 3)), force=np.zeros((b, 3)),
        torque=np.zeros((b, 3)), acc=np.zeros((b, 6)), param=np.array(param, dtype=np.float64, copy=True),
        C=np.zeros(m), J=np.zeros((m, 2, 6)), ct=np.zeros(m), bias=np.zeros(m), MJ=np.zeros((m, 2, 6)),
        Jd=np.zeros((m, 2, 6)),
        rhs=np.zeros(m), lam=np.zeros(m), dlam=np.zeros(m), diag=np.zeros(m), work=np.zeros(m), dropped=np.zeros(m, np.bool_),
        include=np.ones(m, np.bool_), Lx=np.zeros(max(fill, 1)), target=np.zeros(m), correction=np.zeros(m),
        delta=np.zeros((b, 6)),
        k=np.zeros((STAGES, b, PACKED)), y0=np.zeros((b, PACKED)), ys=np.zeros((b, PACKED)),
        start=np.zeros((b, PACKED)), R0=np.tile(np.eye(3), (b, 1, 1)), friction=np.zeros((b, 6)),
        impulse=np.zeros(max(len(param), 1)), air=np.zeros((b, 4)),
        block=Block(np.zeros((3, 3)), np.zeros(3), np.zeros(3), np.zeros((3, 2, 6)), np.zeros((3, 2, 6)),
                    np.zeros(6)),
        rested=np.zeros((b, PACKED)), lam_step=np.zeros(m), counters=np.zeros(COUNTERS, np.int64))
