"""The capturing loop's events as it writes them: a block of rows (data.py Events) that becomes the dicts of
collide/events.py only when read, and is written to events.json from its rows."""
from __future__ import annotations

import json

import numpy as np

from .data import IMPACT

# one event's JSON as the standard library's encoder writes the dict, keys sorted
_ROW_JSON = ('{"bodies": [%s, %s], "impulse": %r, "kind": %s, "normal": [%r, %r, %r], "normal_speed": %r, '
             '"parts": [%s, %s], "point": [%r, %r, %r], "tangential_speed": %r, "time": %r}')


class RowEvents:
    """A block of events as the capturing loop writes them (rows above, copied), with the bodies' names, the same
    as JSON strings, and parts(a, b, feature) -> [name or None, name or None] (None: no body has parts)."""

    def __init__(self, rows: np.ndarray, names: list, quoted: list, parts=None):
        self.rows, self.names, self.quoted, self.parts = rows, names, quoted, parts
        self._dicts: list | None = None
        self._impacts: list | None = None  # (index in the block, dict) of its impacts, when asked for alone

    def __len__(self) -> int:
        return len(self.rows)

    def dicts(self) -> list:
        """The events as dicts (collide/events.py), made once (an impact's dict is the one `impacts` gave)."""
        if self._dicts is None:
            self._dicts = self._made(self.rows.tolist())
            for k, event in self._impacts or ():
                self._dicts[k] = event
        return self._dicts

    def impacts(self) -> list:
        """(index in the block, dict) of its impacts only, in order, made once: the dicts of its pressing rows are
        not made (a row of 20 dominoes presses on about 60 pairs at every frame, and clicks 54 times in 2 s)."""
        if self._impacts is None:
            if self._dicts is not None:
                self._impacts = [(k, event) for k, event in enumerate(self._dicts) if event["kind"] == "impact"]
            else:
                where = np.flatnonzero(self.rows[:, 1] == IMPACT)
                self._impacts = list(zip(where.tolist(), self._made(self.rows[where].tolist())))
        return self._impacts

    def _made(self, rows: list) -> list:
        names, parts, simple = self.names, self.parts, [None, None]
        out = []
        append = out.append
        # (the rows as Python floats at once: read value by value, numpy's scalars cost a heap's events 1 s)
        for t, kind, a, b, px, py, pz, nx, ny, nz, impulse, slip, approach, feature in rows:
            a, b = int(a), int(b)
            append({"time": t, "bodies": [names[a], names[b]], "point": [px, py, pz], "normal": [nx, ny, nz],
                    "impulse": impulse, "tangential_speed": slip, "normal_speed": approach,
                    "kind": "impact" if kind == IMPACT else "contact",
                    "parts": parts(a, b, int(feature)) if parts is not None else list(simple)})
        return out

    def json_items(self):
        """Each event's JSON as the standard library's encoder writes its dict (keys sorted); ValueError at a figure
        that is not finite."""
        if not np.isfinite(self.rows).all():
            raise ValueError("an event's figure is not finite")
        quoted = self.quoted
        kinds = ('"impact"', '"contact"')
        parts, null = self.parts, "null"
        for t, kind, a, b, px, py, pz, nx, ny, nz, impulse, slip, approach, feature in self.rows.tolist():
            a, b = int(a), int(b)
            if parts is None:
                pa = pb = null
            else:
                pa, pb = (json.dumps(name) for name in parts(a, b, int(feature)))
            yield _ROW_JSON % (quoted[a], quoted[b], impulse, kinds[kind != IMPACT], nx, ny, nz, approach, pa,
                               pb, px, py, pz, slip, t)
