"""Steps at rest: a scene that has come to rest pays nothing for standing still.

A tower of boxes on a floor, a box held on a slope by static friction, a ball that has stopped bouncing: the
contact rows and the projection hold them still to round-off (speeds of 1e-14 m/s and below), and every further
step computes the same state again. The step loops (dynamics/integrate.py, procedural/loop.py) stop integrating
once, for `rest_after` steps in a row,

    every body             |v|, |w| <= REST_SPEED   and   |v(t + h) - v(t)|, |w(t + h) - w(t)| <= REST_ACCELERATION h
    every active row       held (none still assembling along its curve)
    the inputs             the time table's rows of the step equal the one at its start (kinematic paths, loads,
                           moving constraint parameters: all constant), and no body feels a wind (its gusts are
                           functions of time computed inside the kernel)

and from then on each step leaves the state as it is, for as long as the inputs stay constant. The rest of a step
goes on as usual: the contacts' impulses (lambda h), the traced motion, the frames and their checks. A step whose
inputs change ends the rest: it is integrated, and rest must be found again. A call of the loop goes on with the
count of the call before (`still_at_start`, `resumes`: a live run calls once a frame) only when it starts
from the state that call ended with and with the same active rows; whatever changed the state or the rows in
between (an impulse of the collision stage, a contact made or lost, a constraint switching, a drag) starts the
count afresh.

The state at rest is an equilibrium to these bounds: over a time T a body left where it stands would have moved at
most REST_SPEED T + REST_ACCELERATION T^2 / 2 (1e-8 m over 10 s). An unstable equilibrium (a pencil on its tip,
exactly upright) stays standing, as it would in exact arithmetic; one perturbed by less than the bounds does too.
"""
from __future__ import annotations

from .data import COUNTER_RESTING, COUNTER_STILL
from .jit import inlined
from .timetable import TIME

# m/s and rad/s: the speed of a body at rest, at most
REST_SPEED = 1e-9
# m/s^2 and rad/s^2: the change of its velocities over a step at rest, at most, per second of the step
REST_ACCELERATION = 1e-9
# steps in a row that find every body at rest before the loops stop integrating (0 in `rest_after`: never)
REST_STEPS = 10


@inlined
def rests(s, table, j, rows, rest_after, still):
    """Whether the step from grid row j (`rows` rows of the time table) is one at rest: `rest_after` steps in a
    row, `still`, have found the scene at rest, and its inputs are still constant. Counted."""
    if 0 < rest_after <= still and inputs_still(table, j, rows):
        s.counters[COUNTER_RESTING] += 1
        return True
    return False


@inlined
def still_after(m, act, s, y, table, j, rows, h, still):
    """The count of steps in a row at rest after an integrated step of h from grid row j (from s.start to y):
    one more when it left the scene at rest with constant inputs, else 0."""
    return still + 1 if standing_still(m, act, y, s.start, h) and inputs_still(table, j, rows) else 0


@inlined
def standing_still(m, act, y, start, h):
    """Whether the step of h from `start` to `y` left every body at rest (module docstring), with every active row
    held and no wind. (The bodies first: a moving scene fails at its first moving body.)"""
    change = REST_ACCELERATION * h
    for b in range(len(y) - 1):  # (every body: a static one declared with a velocity drifts with it)
        for c in range(7, 13):
            if not (abs(y[b, c]) <= REST_SPEED and abs(y[b, c] - start[b, c]) <= change):
                return False
    if len(m.wind.body):
        return False
    for i in range(len(act.rows)):
        if not act.held[i]:
            return False
    return True


@inlined
def inputs_still(table, j, rows):
    """Whether the time table's rows j + 1 .. j + rows equal row j, but for the time itself."""
    for k in range(j + 1, j + rows + 1):
        for c in range(table.shape[1]):
            if c != TIME and table[k, c] != table[j, c]:
                return False
    return True


@inlined
def resumes(s, y, carry):
    """Whether a call goes on where the last one ended: `carry` (the same active rows) and y is the state that
    call ended with."""
    if not carry:
        return False
    for b in range(len(y)):
        for c in range(13):
            if y[b, c] != s.rested[b, c]:
                return False
    return True


@inlined
def still_at_start(s, y, carry):
    """The steps in a row at rest to go on from: the last call's count if it `resumes`, else 0."""
    return s.counters[COUNTER_STILL] if resumes(s, y, carry) else 0


@inlined
def still_at_end(s, y, still):
    """Keep the count and the state a call ends with, for the next (`still_at_start`); returns nothing."""
    s.counters[COUNTER_STILL] = still
    for b in range(len(y)):
        for c in range(13):
            s.rested[b, c] = y[b, c]
