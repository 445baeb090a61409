"""Frames recorded inside the kernels: the state, the energy and the largest constraint error at a frame; and the
checks after each step that every plan's step loop makes (`after_step`), with the status codes they end a call
with."""
from __future__ import annotations

from collections import namedtuple

from .bodies import copy_state, energy, rotations, runaway_body
from .contact import look_after_step, record_contacts
from .jit import inlined
from .rows import evaluate_rows

# a constraint error beyond this (m or rad) is a blow-up: a joint this far apart is not a joint any more
RUNAWAY_CONSTRAINT_ERROR = 1.0
# status codes of a step loop's call (status[0]): done; a blow-up (a speed beyond core/bodies.RUNAWAY_SPEED, or a
# constraint error beyond RUNAWAY_CONSTRAINT_ERROR); the collision stage must look (core/contact.py)
DONE, RUNAWAY_BODY, RUNAWAY_ROW, CONTACT = 0, 1, 2, 3

# y (F, n+1, 13) the states, energy (F,), error (F,) the largest |C| of the active position rows, worst (F,) its row;
# contact (F, K, 8): for every contact instance k active at the frame, its normal impulse since the last frame,
# its slip speed, the contact point (3) and normal (3) (core/contact.py `contact_state`); 0 elsewhere;
# traced (k,) the bodies whose state rows (x, q, v, w) every step of the call leaves in trace (S, k, 13): what a stage
# reading the motion step by step needs (Simulation.tracers, the audio stage: where a contact point lies in a body
# at the step of its event); k = 0 or S = 0 traces nothing
Frames = namedtuple("Frames", "y energy error worst contact traced trace")


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


@inlined
def trace_step(y, frames, step):
    """frames.trace[step] <- the state row of each traced body after step `step` (counted from 0) of the call."""
    if step >= frames.trace.shape[0]:
        return
    for i in range(len(frames.traced)):
        b = frames.traced[i]
        for c in range(13):
            frames.trace[step, i, c] = y[b, c]


@inlined
def after_step(m, act, s, y, table, j, step, frame_step, frames, f, status):
    """After step `step` (counted from 0) of a call, ending at grid row j: the traced bodies' motion, a body that
    ran away, a change of contact the collision stage must see (before its frame is recorded), then the frames due
    now, each checked for a constraint error that ran away. Returns (the steps taken when the call must end there,
    else -1; the next frame); status (4,) <- (code, step, body or row or contact, detail) when it ends."""
    trace_step(y, frames, step)
    body = runaway_body(m.bodies, y)
    if body >= 0:
        status[0], status[1], status[2] = RUNAWAY_BODY, step + 1, body
        return step + 1, f
    if len(m.pairs.a):
        code, which = look_after_step(m, act, s, y)
        if code != 0:
            status[0], status[1], status[2], status[3] = CONTACT, step + 1, which, code
            return step + 1, f
    while f < len(frame_step) and frame_step[f] == step + 1:
        record(m, act, s, y, table, j, frames, f)
        if not frames.error[f] <= RUNAWAY_CONSTRAINT_ERROR:
            status[0], status[1], status[2] = RUNAWAY_ROW, step + 1, frames.worst[f]
            return step + 1, f
        f += 1
    return -1, f
