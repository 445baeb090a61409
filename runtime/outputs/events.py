"""A run's events (Simulation.events): the contact events of collide/events.py, in order, whichever contact path
wrote them, as events.json lists them. Apart from the collision stage, so that a run without contact imports none
of it."""
from __future__ import annotations

import bisect
from collections.abc import Sequence


class EventList(Sequence):
    """A run's events, in order: a read-only list of the event dicts that may be appended to. The
    exact path appends dicts; the capturing loop hands on blocks of rows (capture/events.py RowEvents: len(),
    dicts(), json_items()), which make their dicts only when read, once, and are written to events.json from their
    rows: a heap's 109,000 events cost 2 s as dicts, of a run of 6. (The dicts read are the events: not to be
    changed.)"""

    def __init__(self, events=()):
        self._chunks: list = []  # lists of dicts and RowEvents, in order
        self._ends: list = []  # the count of events up to the end of each chunk
        for event in events:
            self.append(event)

    def append(self, event: dict) -> None:
        if not self._chunks or not isinstance(self._chunks[-1], list):
            self._chunks.append([])
            self._ends.append(len(self))
        self._chunks[-1].append(event)
        self._ends[-1] += 1

    def add_rows(self, block) -> None:
        if len(block):
            self._chunks.append(block)
            self._ends.append(len(self) + len(block))

    def __len__(self) -> int:
        return self._ends[-1] if self._ends else 0

    def __getitem__(self, index):
        if isinstance(index, slice):
            first, end, stride = index.indices(len(self))
            if stride != 1:
                return list(self)[index]
            return self._between(first, end)
        count = len(self)
        if index < 0:
            index += count
        if not 0 <= index < count:
            raise IndexError("event index out of range")
        k = bisect.bisect_right(self._ends, index)
        return self._dicts(k)[index - (self._ends[k] - len(self._chunks[k]))]

    def _between(self, first: int, end: int) -> list:
        """The events first..end-1 as dicts, converting only the blocks they lie in."""
        out: list = []
        k = bisect.bisect_right(self._ends, first)
        while first < end and k < len(self._chunks):
            start = self._ends[k] - len(self._chunks[k])
            out += self._dicts(k)[first - start:min(end, self._ends[k]) - start]
            first, k = self._ends[k], k + 1
        return out

    def _dicts(self, k: int) -> list:
        chunk = self._chunks[k]
        return chunk if isinstance(chunk, list) else chunk.dicts()  # (a block makes its dicts once)

    def impacts_from(self, first: int) -> list:
        """(index, dict) of the events from index `first` on that are not pressing ("contact") events, in order;
        a block of rows makes the dicts of its impacts only."""
        out: list = []
        for k in range(bisect.bisect_right(self._ends, first), len(self._chunks)):
            chunk = self._chunks[k]
            start = self._ends[k] - len(chunk)
            if isinstance(chunk, list):
                found = ((i, event) for i, event in enumerate(chunk) if event.get("kind", "impact") != "contact")
            else:
                found = chunk.impacts()
            out += [(start + i, event) for i, event in found if start + i >= first]
        return out

    def __iter__(self):
        for k in range(len(self._chunks)):
            yield from self._dicts(k)

    def __eq__(self, other) -> bool:
        return isinstance(other, Sequence) and len(self) == len(other) and list(self) == list(other)

    __hash__ = None

    def __repr__(self) -> str:
        return f"EventList({len(self)} events)"

    def json_items(self, encode):
        """Each event's JSON text as encode(dict) writes it (sort_keys, the standard separators): the blocks of
        rows formatted from them. ValueError at a figure that is not finite, as encode raises."""
        for chunk in self._chunks:
            yield from (map(encode, chunk) if isinstance(chunk, list) else chunk.json_items())
