"""When the exact path hands a run over to the capturing one (runtime/capture): the collision stage's decisions,
each with the reason it gives (`wants_capture`, printed by `isaac run -v` and kept in report.json's contact.why).

    _hands_over       an impact between two moving bodies (things falling on things change the contact set at
                      nearly every step), or a pair only the capturing path tests in closed form
    _heavy_on_light   a run that starts with a moving body touching another MASS_RATIO times lighter or heavier
"""
from __future__ import annotations

import numpy as np

from ..core.build import MASS_RATIO
from .narrow import needs_fcl
from .response import contact_rows, row_velocity


class HandOver:
    """Collider's hand-over decisions (a mixin: they read its plan, state, may_capture, strikers, kinds and
    resting_speed, and set wants_capture)."""

    def _hands_over(self, contacts, t: float) -> bool:
        """Whether two moving bodies strike each other here, in a scene that may take the capturing path: then the
        impact is left to it (Simulation.switch_to_capture), from this instant on."""
        if not self.may_capture:
            return False
        s, plan = self.sim.state, self.plan
        names = plan.names
        for a, b in zip(contacts.a.tolist(), contacts.b.tolist()):
            if self._one_point_only(a, b):
                a, b = sorted((a, b))
                self.wants_capture = (f"`{names[a]}` touches `{names[b]}` at t = {t:.6g} s, a pair whose contact only "
                                      "the capturing path tests in closed form")
                return True
        u = row_velocity(contact_rows(contacts, s.x, contacts.normal), np.stack([contacts.a, contacts.b], 1), s.v, s.w)
        both = plan.dynamic[contacts.a] & plan.dynamic[contacts.b]
        moving = (both | self.strikers[contacts.a] | self.strikers[contacts.b]) & (u < -self.resting_speed)
        if not moving.any():
            return False
        k = int(np.argmax(moving))
        a, b = sorted((int(contacts.a[k]), int(contacts.b[k])))
        what = "moving bodies" if both[k] else "a jointed body and another"
        self.wants_capture = f"an impact between {what} `{names[a]}` and `{names[b]}` at t = {t:.6g} s"
        return True

    def _heavy_on_light(self, contacts, t: float) -> bool:
        """Whether the run starts with a moving body touching another MASS_RATIO times lighter or heavier
        (contacts: those that touch): then it is left to the capturing path, which solves their island whole
        (capture/islands.py). The exact path's contact solve failed on a heavy body sliding on a light one: an 8 kg
        block sliding on a 0.18 kg board blew up at 0.05 s in the procedural plan, and on a 0.6 kg board sank
        1.3 mm into the floor and dragged the board 33 mm; in the dynamics plan at 4 ms it began to turn about the
        vertical, 0.004 rad/s at 0.04 s and 0.24 rad/s at 0.06 s (found 2026-12-07). (A body that lands on another
        is an impact between moving bodies: `_hands_over`.)"""
        if not self.may_capture or contacts is None:
            return False
        inv, dynamic, names = self.plan.inv_mass, self.plan.dynamic, self.plan.names
        for a, b in zip(contacts.a.tolist(), contacts.b.tolist()):
            if dynamic[a] and dynamic[b] and max(inv[a], inv[b]) >= MASS_RATIO * min(inv[a], inv[b]):
                light, heavy = (a, b) if inv[a] > inv[b] else (b, a)
                self.wants_capture = (f"`{names[heavy]}` touches `{names[light]}` at t = {t:.6g} s, "
                                      f"{inv[light] / inv[heavy]:.3g} times as heavy")
                return True
        return False

    def _one_point_only(self, a: int, b: int) -> bool:
        """Whether bodies a and b (or a pair of their parts) have no closed form here, only python-fcl's one point
        of deepest contact: a cylinder against a box, a capsule or a cylinder. The capturing path tests them in
        closed form, with a point on each side of a cylinder lying on a box; on one point it rolled off by
        itself after 0.8 s and sank to its axis, 28 mm deep, found 2026-12-07. (A scene with a mesh never gets
        here: it may not capture.)"""
        return any(needs_fcl(ka, kb) for ka in self.kinds[a] for kb in self.kinds[b])
