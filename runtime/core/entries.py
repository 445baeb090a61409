"""The entry points the Python side calls outside the step loops (cached machine code, kernels inlined): the
energy and constraint error of a state, rows evaluated at a state."""
from __future__ import annotations

from .bodies import energy, rotations
from .contact import record_contacts
from .jit import entry
from .record import constraint_error
from .rows import apply_drivers, write_rows


@entry
def state_energy(bodies, R, y):
    """Kinetic plus potential energy of the dynamic bodies at state y (R scratch)."""
    rotations(y, R)
    return energy(bodies, R, y)


@entry
def state_constraint_error(m, act, s, y, table):
    """(largest |C| of the active position rows, its row or -1) at state y, time table row 0."""
    rotations(y, s.R)
    return constraint_error(m, act, s, y, table, 0)


@entry
def row_errors(m, instances, s, y, table):
    """C, J, ct, bias of the instances at state y (time table row 0)."""
    rotations(y, s.R)
    apply_drivers(m.constraints, s.param, table, 0)
    write_rows(instances, m.constraints, s.param, y, s.R, s.C, s.J, s.ct, s.bias)


@entry
def frame_contacts(act, cons, param, y, R, impulse, out):
    """out (1, K, 8) <- the active contacts at state y (core/contact.py record_contacts), their impulse
    accumulators back to 0."""
    rotations(y, R)
    record_contacts(act, cons, param, y, R, impulse, out, 0)
