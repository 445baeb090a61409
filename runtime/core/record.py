"""Frames recorded inside the kernels: the state, the energy and the largest constraint error at a frame."""
from __future__ import annotations

from collections import namedtuple

from .bodies import copy_state, energy, rotations
from .contact import record_contacts
from .jit import inlined, kernel
from .rows import evaluate_rows

# a constraint error beyond this (m or rad) is a blow-up: a joint this far apart is not a joint any more
RUNAWAY_CONSTRAINT_ERROR = 1.0

# y (F, n+1, 13) the states, energy (F,), error (F,) the largest |C| of the active position rows, worst (F,) its row;
# contact (F, K, 8): for every contact instance k active at the frame, its normal impulse since the last frame,
# its slip speed, the contact point (3) and normal (3) (core/contact.py `contact_state`); 0 elsewhere
Frames = namedtuple("Frames", "y energy error worst contact")


@inlined
def constraint_error(m, act, s, y, table, j):
    """(largest |C| over the active position rows, that row or -1) at state y (R current)."""
    if not len(act.rows):
        return 0.0, -1
    evaluate_rows(m, act, s, y, table, j)
    worst, row = 0.0, -1
    for i in range(len(act.rows)):
        r = act.rows[i]
        if m.constraints.velocity_only[r]:
            continue
        e = abs(s.C[r])
        if not e <= worst:  # (a NaN is worst of all)
            worst, row = e, r
    return worst, row


@inlined
def record(m, act, s, y, table, j, frames, f):
    copy_state(y, frames.y[f])
    rotations(y, s.R)
    error, row = constraint_error(m, act, s, y, table, j)
    frames.energy[f] = energy(m.bodies, s.R, y)
    frames.error[f] = error
    frames.worst[f] = row
    record_contacts(act, m.constraints, s.param, y, s.R, s.impulse, frames.contact, f)



