"""The joints on the capturing path: each active constraint row (core/rows.py: C, J, ct at the step's start) is a
bilateral row of the same Gauss-Seidel sweep as the contacts, so an impact on a jointed body moves what it is
joined to, and a contact holds what hangs from a joint:

    u_r = J_r V + ct_r          the row's velocity (J_r: its two bodies' 6-vectors, ct: a moving anchor's rate)
    u_r+ = 0
    lam_r' = lam_r + m_r (0 - u_r),   m_r = 1 / (sum over its bodies of |J_lin|^2 / m + J_ang . I^-1 J_ang)

warm-started from the row's impulse of the last step. What is left of a position row's error C is closed by the
position pass (position.py `separate`) with the contacts' depths: pseudo-velocities J_r V~ = -BETA C_r / h, which
move positions only, so closing a joint never gives it speed (energy). Data: lam, mass, target (M,) by global row,
target the position pass's.
"""
from __future__ import annotations

from ..core.jit import kernel
from ..core.vec import dot3, rotate

# the fraction of a row's position error closed per step
BETA = 0.2


@kernel
def _lin(J, r, slot):
    return (J[r, slot, 0], J[r, slot, 1], J[r, slot, 2])


@kernel
def _ang(J, r, slot):
    return (J[r, slot, 3], J[r, slot, 4], J[r, slot, 5])


@kernel
def _apply(m, invI, y, J, r, k, p):
    """V += M^-1 J_r^T p on the row's bodies."""
    for slot in range(2):
        b = m.constraints.body[k, slot]
        if b < 0 or not m.bodies.dynamic[b]:
            continue
        turn = rotate(invI, b, _ang(J, r, slot))
        for c in range(3):
            y[b, 7 + c] += p * m.bodies.inv_mass[b] * J[r, slot, c]
            y[b, 10 + c] += p * turn[c]


@kernel
def _velocity(m, y, J, ct, r, k, moving):
    u = ct[r] if moving else 0.0
    for slot in range(2):
        b = m.constraints.body[k, slot]
        if b < 0:
            continue
        for c in range(6):
            u += J[r, slot, c] * y[b, 7 + c]
    return u


@kernel
def prepare_joints(m, act, s, invI, jt, h):
    """Masses and targets of the active rows (s.C, s.J, s.ct evaluated at the step's start)."""
    cons = m.constraints
    for i in range(len(act.rows)):
        r = act.rows[i]
        k = cons.row_instance[r]
        w = 0.0
        for slot in range(2):
            b = cons.body[k, slot]
            if b >= 0 and m.bodies.dynamic[b]:
                lin, ang = _lin(s.J, r, slot), _ang(s.J, r, slot)
                w += m.bodies.inv_mass[b] * dot3(lin, lin) + dot3(ang, rotate(invI, b, ang))
        jt.mass[r] = 1.0 / w if w > 0.0 else 0.0
        jt.target[r] = 0.0 if cons.velocity_only[r] else -BETA * s.C[r] / h  # (the position pass's)


@kernel
def warm_start_joints(m, act, s, invI, jt, y):
    """The active rows' impulses of the last step applied (warm start), after the impacts, as the contacts' are
    (solve.py `warm_start`): with the joints' warm start in them and not the contacts', the links of a chain
    resting on a floor were pulled into it by their joints' last impulses, and bounced (a chain of 12 capsules
    landing with e = 0.5 blew up)."""
    for i in range(len(act.rows)):
        r = act.rows[i]
        _apply(m, invI, y, s.J, r, m.constraints.row_instance[r], jt.lam[r])


@kernel
def sweep_joints(m, act, s, invI, jt, y):
    """One Gauss-Seidel sweep over the active rows: u_r+ = 0."""
    for i in range(len(act.rows)):
        r = act.rows[i]
        k = m.constraints.row_instance[r]
        p = -jt.mass[r] * _velocity(m, y, s.J, s.ct, r, k, True)
        _apply(m, invI, y, s.J, r, k, p)
        jt.lam[r] += p


@kernel
def close_joints(m, act, s, invI, jt, pseudo):
    """One sweep of the position pass over the active rows: J_r V~ = -BETA C_r / h (pseudo (n+1,13), as y)."""
    for i in range(len(act.rows)):
        r = act.rows[i]
        k = m.constraints.row_instance[r]
        _apply(m, invI, pseudo, s.J, r, k, jt.mass[r] * (jt.target[r] - _velocity(m, pseudo, s.J, s.ct, r, k, False)))
