"""The entry point the Python side calls outside the step loops (cached machine code, kernels inlined): the energy
and constraint error of a state, rows evaluated at a state, the contacts of a frame.

They are one compiled entry, `measure`, that does what `what` asks: every entry point a run calls is loaded from
numba's cache when the process first calls it (about 18 ms for one that evaluates rows) and compiled on a machine's
first run (every entry again compiles every row family it inlines), so four of them cost four times what one does.
The functions below are the Python side's names for its four uses.
"""
from __future__ import annotations

import numpy as np

from .bodies import energy, rotations
from .contact import record_contacts
from .jit import entry
from .record import constraint_error
from .rows import apply_drivers, write_rows
from .structure import empty_active

# what `measure` does
ENERGY, CONSTRAINT_ERROR, ROWS, CONTACTS = 0, 1, 2, 3

_NO_ROWS = empty_active()
_NO_INSTANCES = np.zeros(0, np.int64)
_NO_CONTACTS = np.zeros((1, 1, 8))
_NO_TABLE = np.zeros((1, 1))  # (energy and contacts read no time function)


@entry
def measure(m, act, instances, s, y, table, what, out):
    """At state y, time table row 0 (R of s current afterwards), by `what`:
        ENERGY            (kinetic plus potential energy of the dynamic bodies, -1)
        CONSTRAINT_ERROR  (largest |C| of the active position rows of act, its row or -1)
        ROWS              C, J, ct, bias of `instances` into s; (0, -1)
        CONTACTS          out (1, K, 8) <- act's active contacts (core/contact.py record_contacts), their impulse
                          accumulators back to 0; (0, -1)"""
    rotations(y, s.R)
    if what == ENERGY:
        return energy(m.bodies, s.R, y), -1
    if what == CONSTRAINT_ERROR:
        return constraint_error(m, act, s, y, table, 0)
    if what == ROWS:
        apply_drivers(m.constraints, s.param, table, 0)
        write_rows(instances, m.constraints, s.param, y, s.R, s.C, s.J, s.ct, s.bias)
    elif what == CONTACTS:
        record_contacts(act, m.constraints, s.param, y, s.R, s.impulse, out, 0)
    return 0.0, -1


def state_energy(m, s, y) -> float:
    """Kinetic plus potential energy of the dynamic bodies at state y."""
    return measure(m, _NO_ROWS, _NO_INSTANCES, s, y, _NO_TABLE, ENERGY, _NO_CONTACTS)[0]


def state_constraint_error(m, act, s, y, table) -> tuple:
    """(largest |C| of the active position rows, its row or -1) at state y, time table row 0."""
    return measure(m, act, _NO_INSTANCES, s, y, table, CONSTRAINT_ERROR, _NO_CONTACTS)


def row_errors(m, instances, s, y, table) -> None:
    """C, J, ct, bias of the instances at state y (time table row 0), into s."""
    measure(m, _NO_ROWS, np.ascontiguousarray(instances, dtype=np.int64), s, y, table, ROWS, _NO_CONTACTS)


def frame_contacts(m, act, s, y, out) -> None:
    """out (1, K, 8) <- the active contacts at state y, their impulse accumulators back to 0."""
    measure(m, act, _NO_INSTANCES, s, y, _NO_TABLE, CONTACTS, out)
