"""The position pass of the capturing step, compiled: interpenetration removed on pseudo-velocities (split
impulses), which move positions only and never add kinetic energy. A contact deeper than SLOP is pushed apart at
BETA (depth - SLOP) / h; a contact struck across its gap (a speculative contact: struck in the step that closes the
gap, still apart) is brought where its impact's time within the step puts it (`clear`). POSITION_SWEEPS sweeps of
Gauss-Seidel over the contacts (`separate`), the joints' rows among them (joints.py), after the velocity solve
(solve.py) and before the drift (loop.py); islands.py solves whole the islands they leave unsolved.
"""
from __future__ import annotations

import math

from ..core.jit import inlined, kernel
from .solve import MOVED, push, speed

# position sweeps per step
POSITION_SWEEPS = 6
# interpenetration left alone (m), and the fraction of the rest removed per step by the position pass
SLOP = 1e-4
BETA = 0.3


@kernel
def _struck_across_gap(ct, c):
    """Whether contact c was struck this step while still apart (`clear`)."""
    return ct.hit[c] > 0.0 and ct.depth[c] < 0.0 and ct.approach[c] > 0.0


@kernel
def deep(ct):
    """Whether the position pass has work: a contact deeper than SLOP, or one struck across a gap (`clear`)."""
    for c in range(ct.count[0]):
        if ct.depth[c] > SLOP or _struck_across_gap(ct, c):
            return True
    return False


@kernel
def clear(pseudo, ct, y, h, jointed):
    """The position pass starts from rest: pseudo-velocities and the contacts' push impulses 0; each contact's
    target for the pass in ct.bounce and the least impulse it may take in ct.base (both free after the solve;
    y: the velocities after it). A contact struck across a gap g = -depth (an impact this step, still apart at
    its start, approaching at |u|): the impact came when the gap closed, tau = g / |u| into the step, after which
    the pair parted at its normal speed after the solve u+, so it ends the step max(u+, 0) (h - tau) apart where
    the drift leaves it g + u+ h apart (u+ < 0: the solve let it close its gap again, pressed from behind): the
    target is the difference over h, -(g + u+ tau) / h when it parts, the bodies sharing it by their masses as the
    impulse does (u+ = -e u for two bodies: both displacements exact; a clay sphere lands once, where stopping at
    the gap landed it again 14 ms later), pulled at most that much. One deeper than SLOP: pushed apart at
    BETA (depth - SLOP) / h. Any other: not brought nearer than its gap and its speed after the solve allow (a
    pull or a push elsewhere does not drive it in; its target made when a body of its moves, `separate`). Each
    body some row will move is marked."""
    for b in range(len(pseudo)):
        for k in range(7, 13):
            pseudo[b, k] = 0.0
        pseudo[b, MOVED] = 1.0 if jointed else 0.0  # (the joints' rows move bodies too)
    for c in range(ct.count[0]):
        ct.push[c] = 0.0
        depth = ct.depth[c]
        if _struck_across_gap(ct, c):
            u, gap = speed(ct, c, 0, y), -depth
            # u~ = (max(u+, 0) (h - tau) - g) / h - u+, tau = g / |u|: the gap it ends with less the drift's, over h
            ct.bounce[c] = (max(u, 0.0) * (h - gap / ct.approach[c]) - gap) / h - u
            ct.base[c] = ct.mass[c, 0] * ct.bounce[c]
        elif depth > SLOP:
            ct.bounce[c], ct.base[c] = BETA * (depth - SLOP) / h, 0.0
        else:
            ct.bounce[c], ct.base[c] = math.nan, 0.0  # (its target when a body of its moves: `separate`)
        if not _still(ct, c):
            pseudo[ct.a[c], MOVED], pseudo[ct.b[c], MOVED] = 1.0, 1.0


@kernel
def _still(ct, c):
    """Whether contact c's row in the position pass only holds its bodies back (it moves nothing while they do
    not move: its target <= 0 or not yet known, its impulse >= 0)."""
    return ct.base[c] == 0.0 and not ct.bounce[c] > 0.0


@kernel
def separate(ct, pseudo, y, h):
    """One sweep of the position pass over the contacts (`separate_one` each)."""
    for c in range(ct.count[0]):
        separate_one(ct, c, pseudo, y, h)


@inlined
def separate_one(ct, c, pseudo, y, h):
    """Contact c's update of a sweep of the position pass: pseudo-velocities (pseudo (n+1,13), columns 7..12 as v,
    w in y) that move positions only (split impulses), its normal speed in them brought to its target (`clear`)
    with an impulse no less than its least. A contact that only holds its bodies back gets its target when one of
    them first moves: not brought nearer than its gap and its speed after the solve (y) allow."""
    a, b = ct.a[c], ct.b[c]
    if pseudo[a, MOVED] == 0.0 and pseudo[b, MOVED] == 0.0 and _still(ct, c):
        return  # (its update would be max(0, m_n target) = 0: most of a heap's rows, skipped)
    if math.isnan(ct.bounce[c]):
        # u~ >= -(gap / h + u+): the pass may close no more than what the drift at u+ leaves of its gap
        ct.bounce[c] = min(0.0, -(max(-ct.depth[c], 0.0) / h + speed(ct, c, 0, y)))
    lam = max(ct.base[c], ct.push[c] + ct.mass[c, 0] * (ct.bounce[c] - speed(ct, c, 0, pseudo)))
    if lam != ct.push[c]:
        push(ct, c, 0, pseudo, lam - ct.push[c])
        ct.push[c] = lam
        pseudo[a, MOVED], pseudo[b, MOVED] = 1.0, 1.0
