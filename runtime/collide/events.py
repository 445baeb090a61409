"""Contact events: what the audio graph hears and what events.json lists.

One event per body pair, a dict:

    time              s: an impact's time of impact (located inside the step); a contact's frame time
    bodies            [name, name], in declaration order
    point             [x, y, z] world: the impulse-weighted mean of the pair's contact points
    normal            [x, y, z] unit, from bodies[1] toward bodies[0]: bodies[0] received impulse * normal
    impulse           N s, the normal impulse (an impact: of that impact; a contact: summed over the frame)
    tangential_speed  m/s, relative sliding speed at the contact (an impact: before it; a contact: after the
                      frame's last step, i.e. the speed it is sliding at)
    normal_speed      m/s, approach speed before the response (> 0: approaching)
    kind              "impact" | "contact"
    parts             [name or None, name or None]: the part of each body struck (a compound body's, the one
                      that took the most impulse; None for a body of one shape)

The rule that keeps sustained contact from flooding the list: an impact (approach faster than the resting
speed) is an event at once; a pair that stays in contact with a non-zero impulse gives one "contact" event per
output frame, at the frame's time, with the frame's total impulse (its contact rows' normal force over the
frame, recorded by the compiled step) and its sliding speed at the frame. A scraping block at 100 frames/s is
therefore a 100 Hz signal of sliding speed and normal impulse.
"""
from __future__ import annotations

import numpy as np

# a pair pressing with less than this normal impulse over a frame is merely touching: no contact event, N s
MIN_CONTACT_IMPULSE = 1e-9


class EventLog:
    def __init__(self, names: list, events: list, frame_times: np.ndarray, elements=None):
        self.names, self.events, self.frames = names, events, np.asarray(frame_times, float)
        self.elements = elements  # shapes.Elements of the compound bodies' parts, or None

    def record(self, contacts, outcome, impact_time) -> None:
        """The impacts among contacts (response.Contacts) with their outcome (response.Outcome) at one pose;
        impact_time(pair index) -> s."""
        for pair in np.unique(contacts.pair):
            mine = np.flatnonzero(contacts.pair == pair)
            if not outcome.impact[mine].any():
                continue
            a, b = int(contacts.a[mine[0]]), int(contacts.b[mine[0]])
            if a > b:  # declaration order; the normal keeps pointing toward bodies[0]
                a, b = b, a
            # a compound pair's contacts may name its bodies in either order: each normal turned toward a
            sign = np.where(contacts.a[mine] == a, 1.0, -1.0)
            impulse = outcome.impulse[mine]
            total = float(impulse.sum())
            weights = impulse if total > 0 else np.ones(len(mine))
            point = weights @ contacts.point[mine] / weights.sum()
            normal = (weights * sign) @ contacts.normal[mine]
            normal /= max(np.linalg.norm(normal), 1e-300)
            parts = self._parts(contacts, mine[int(np.argmax(weights))], a, b)
            self.events.append(self._event(impact_time(int(pair)), a, b, point, normal, total,
                                           float(outcome.slip_before[mine].max()),
                                           float(outcome.approach[mine].max()), "impact", parts))

    def _parts(self, contacts, k: int, a: int, b: int) -> list:
        """[part of a, part of b] (names or None) of contact k."""
        if self.elements is None or contacts.feature is None:
            return [None, None]
        from .shapes import part_of

        names = {int(contacts.a[k]): self.elements.part_name(int(contacts.a[k]), int(part_of(contacts.feature[k], 0))),
                 int(contacts.b[k]): self.elements.part_name(int(contacts.b[k]), int(part_of(contacts.feature[k], 1)))}
        return [names.get(a), names.get(b)]

    def frame(self, t: float, table: np.ndarray, bodies: dict) -> None:
        """One "contact" event per pair pressing during the frame that ends at t: table (K, 8) per contact
        instance (impulse over the frame, slip speed, point, normal: core/contact.py record_contacts), bodies
        {instance: (a, b)} or {instance: (a, b, part of a, part of b)} (part numbers, -1: none)."""
        pairs: dict = {}
        for k, ends in bodies.items():
            a, b = ends[:2]
            impulse = float(table[k, 0])
            if impulse <= 0.0:
                continue
            held = pairs.setdefault((min(a, b), max(a, b)), {"impulse": 0.0, "point": np.zeros(3),
                                                           "normal": np.zeros(3), "slip": 0.0, "most": 0.0,
                                                           "parts": [None, None]})
            sign = 1.0 if a < b else -1.0  # the normal keeps pointing toward bodies[0]
            if len(ends) == 4 and self.elements is not None and impulse > held["most"]:
                names = [self.elements.part_name(a, ends[2]), self.elements.part_name(b, ends[3])]
                held["most"], held["parts"] = impulse, names if a < b else names[::-1]
            held["impulse"] += impulse
            held["point"] = held["point"] + impulse * table[k, 2:5]
            held["normal"] = held["normal"] + sign * impulse * table[k, 5:8]
            held["slip"] = max(held["slip"], float(table[k, 1]))
        for (a, b), held in pairs.items():
            if held["impulse"] <= MIN_CONTACT_IMPULSE:
                continue
            normal = held["normal"] / max(np.linalg.norm(held["normal"]), 1e-300)
            self.events.append(self._event(t, a, b, held["point"] / held["impulse"], normal, held["impulse"],
                                           held["slip"], 0.0, "contact", held["parts"]))

    def _event(self, time, a, b, point, normal, impulse, slip, approach, kind, parts=(None, None)) -> dict:
        # (unpacked, not comprehended: a heap's capturing loop hands on 78,000 events, and two comprehensions
        # an event were a third of their cost)
        (px, py, pz), (nx, ny, nz) = point, normal
        return {"time": float(time), "bodies": [self.names[a], self.names[b]],
                "point": [float(px), float(py), float(pz)], "normal": [float(nx), float(ny), float(nz)],
                "impulse": float(impulse), "tangential_speed": float(slip), "normal_speed": float(approach),
                "kind": kind, "parts": list(parts)}
