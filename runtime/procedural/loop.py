"""The procedural plan's step loop, compiled: forces once per step (the wind's drag relaxed over the step,
wind/drag.py), then `substeps` substeps of move, project, put back (substep.py, project.py) and the sliding
contacts' friction as impulses (core/contact.py friction_impulses); kinematic bodies and moving constraint parameters at every
substep's end; frames recorded, blow-ups caught and changes of contact handed back as in the dynamics plan
(dynamics/integrate.py). The time table has `substeps` rows per step (row S i + s at the start of substep s).

Contacts are rows like any other here: the projection holds a resting or sticking contact (its multiplier
lambda, a position-level impulse, is the force times hs^2), so after a step s.lam holds the last substep's
lambda / hs^2, the forces that core/contact.py's tests read.
"""
from __future__ import annotations

import math

from ..core.bodies import copy_state, place_kinematic, rotations
from ..core.contact import add_impulses, friction_impulses, stopped_slips
from ..core.data import COUNTER_TURNED_BACK
from ..core.forces import step_forces
from ..core.jit import entry, kernel
from ..core.record import DONE, after_step, record
from ..core.rest import rests, still_after, still_at_end, still_at_start
from ..core.rows import apply_drivers
from ..core.timetable import TIME
from .project import direct, keep_rows, start_directions, sweep
from .substep import SHAKE_MAX_TURN, predict, put_back


@kernel
def _fastest_turn(m, y, hs):
    """The largest |w| hs of a dynamic body."""
    largest = 0.0
    for b in range(len(y) - 1):
        if m.bodies.dynamic[b]:
            largest = max(largest, hs * math.sqrt(y[b, 10] ** 2 + y[b, 11] ** 2 + y[b, 12] ** 2))
    return largest


@kernel
def procedural_step(m, act, sw, curves, s, y, table, j, h, substeps, iterations, all_at_once):
    """One step of h from grid row j: forces, then the substeps."""
    step_forces(m, s, y, table, j, h)
    hs = h / substeps
    for sub in range(substeps):
        row = j + sub
        start_directions(m, act, s, y, table, row)
        shake = _fastest_turn(m, y, hs) <= SHAKE_MAX_TURN
        copy_state(y, s.y0)
        predict(m, s, y, hs)
        place_kinematic(m.kinematic, table, row + 1, y)
        rotations(y, s.R)
        if len(act.rows):
            apply_drivers(m.constraints, s.param, table, row + 1)
            t = table[row + 1, TIME]
            if all_at_once:
                direct(m, act, curves, s, y, t, hs, iterations, shake)
            else:
                sweep(m, act, sw, curves, s, y, t, hs, shake, iterations)
        put_back(m, s, y, hs)
        if len(act.rows) and len(m.pairs.a):
            # the sliding contacts' friction; the rows' share of it (a box's friction would tip it about the corners
            # that hold it: they take the torque, as the dynamics plan's rows take its friction forces), only where
            # all rows are projected at once (its factor serves); then the slips it stopped, and the normal
            # impulse of the substep: lambda / hs
            applied = friction_impulses(act, m.constraints, s.param, m.bodies, s.inv_inertia, y, s.R, s.lam,
                                        act.local, hs, s.friction)
            if applied and all_at_once:
                keep_rows(m, act, s, y, hs)
            stopped_slips(act, m.constraints, s.param, y, s.R, s.counters)
            add_impulses(act, m.constraints, s.lam, act.local, 1.0 / hs, s.impulse)
    # forces = lambda / hs^2 (module docstring)
    for i in range(len(act.rows)):
        s.lam[i] /= hs * hs


@entry
def run(m, act, sw, curves, s, y, table, h, steps, substeps, iterations, all_at_once, frame_step, frames, status,
        rest_after, carry):
    """Advance y by `steps` steps of h (as dynamics/integrate.run, with the procedural step; at rest as there)."""
    status[0], status[1], status[2], status[3] = DONE, 0, -1, 0
    f = 0
    while f < len(frame_step) and frame_step[f] == 0:
        record(m, act, s, y, table, 0, frames, f)
        f += 1
    still = still_at_start(s, y, carry)  # steps in a row, inputs constant, every body at rest
    done = steps
    for step in range(steps):
        copy_state(y, s.start)
        s.counters[COUNTER_TURNED_BACK] = 0
        j = substeps * step
        if rests(s, table, j, substeps, rest_after, still):
            if len(act.rows) and len(m.pairs.a):
                # the contacts' impulses of the step's substeps, as its forces (s.lam) gave them: lambda h
                add_impulses(act, m.constraints, s.lam, act.local, h, s.impulse)
        else:
            procedural_step(m, act, sw, curves, s, y, table, j, h, substeps, iterations, all_at_once)
            still = still_after(m, act, s, y, table, j, substeps, h, still)
        taken, f = after_step(m, act, s, y, table, j + substeps, step, frame_step, frames, f, status)
        if taken >= 0:
            done = taken
            break
    still_at_end(s, y, still)
    return done
