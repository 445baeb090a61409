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

The rule that keeps sustained contact from flooding the list: an impact (approach faster than the resting
speed) is an event at once; a pair that stays in contact with a non-zero impulse gives one "contact" event per
output frame, at the frame's time, with the frame's total impulse and its latest sliding speed. A scraping
block at 100 frames/s is therefore a 100 Hz signal of sliding speed and normal impulse.
"""
from __future__ import annotations

import numpy as np

# a pair pressing with less than this normal impulse over a frame is merely touching: no contact event, N s
MIN_CONTACT_IMPULSE = 1e-9


class EventLog:
    def __init__(self, names: list, events: list, frame_times: np.ndarray):
        self.names, self.events, self.frames = names, events, np.asarray(frame_times, float)
        self.next_frame = 1  # frame 0 is the start: contacts are first reported at the end of the first frame
        self.held: dict = {}  # (i, j) -> the frame's accumulated contact

    def record(self, contacts, outcome, impact_time) -> None:
        """contacts: response.Contacts, outcome: response.Outcome at one pose; impact_time(pair index) -> s."""
        for pair in np.unique(contacts.pair):
            mine = np.flatnonzero(contacts.pair == pair)
            a, b = int(contacts.a[mine[0]]), int(contacts.b[mine[0]])
            impulse = outcome.impulse[mine]
            total = float(impulse.sum())
            weights = impulse if total > 0 else np.ones(len(mine))
            point = weights @ contacts.point[mine] / weights.sum()
            normal = weights @ contacts.normal[mine]
            normal /= max(np.linalg.norm(normal), 1e-300)
            if a > b:  # declaration order; the normal keeps pointing toward bodies[0]
                a, b, normal = b, a, -normal
            if outcome.impact[mine].any():
                self.events.append(self._event(impact_time(int(pair)), a, b, point, normal, total,
                                               float(outcome.slip_before[mine].max()),
                                               float(outcome.approach[mine].max()), "impact"))
            elif total > MIN_CONTACT_IMPULSE:
                held = self.held.get((a, b))
                if held is None:
                    held = self.held[(a, b)] = {"impulse": 0.0}
                held["impulse"] += total
                held.update(point=point, normal=normal, slip=float(outcome.slip_after[mine].max()),
                            approach=float(outcome.approach[mine].max()))

    def flush(self, t: float) -> None:
        """At a frame time: one contact event per pair held during the frame."""
        if self.next_frame >= len(self.frames) or t < self.frames[self.next_frame] - 1e-12:
            return
        while self.next_frame < len(self.frames) and self.frames[self.next_frame] <= t + 1e-12:
            self.next_frame += 1
        for (a, b), held in self.held.items():
            self.events.append(self._event(t, a, b, held["point"], held["normal"], held["impulse"], held["slip"],
                                           held["approach"], "contact"))
        self.held.clear()

    def _event(self, time, a, b, point, normal, impulse, slip, approach, kind) -> dict:
        return {"time": float(time), "bodies": [self.names[a], self.names[b]],
                "point": [float(v) for v in point], "normal": [float(v) for v in normal],
                "impulse": float(impulse), "tangential_speed": float(slip), "normal_speed": float(approach),
                "kind": kind}
