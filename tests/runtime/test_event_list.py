"""A run's events (runtime/outputs/events.py): the capturing loop's blocks of rows read as the dicts the exact
path appends, and written to events.json, from their rows, exactly as the dicts would be."""
from __future__ import annotations

import json
import math

import numpy as np

from isaac_runtime.capture.events import RowEvents
from isaac_runtime.outputs.events import EventList
from isaac_lang.load import load_text
from isaac_runtime.outputs import write_json
from isaac_runtime.run import RunOptions, simulate, write_outputs

from .test_capture import heap

NAMES = ["floor", "a", "b \"quoted\""]
QUOTED = [json.dumps(name) for name in NAMES]


def _rows(*rows) -> np.ndarray:
    """Rows [time, kind, a, b, point, normal, impulse, slip, approach, feature] (capture/data.py Events)."""
    return np.array(rows, float)


ROWS = _rows([0.1, 0, 1, 2, 1, 2, 3, 0, 1, 0, 0.5, 0.1, 2.0, 7],
             [0.2, 1, 0, 1, -0.0, 1e-300, 1 / 3, 0, -1, 0, 0.25, 0.0, 0.0, 3])


def test_an_event_list_reads_as_the_list_of_its_dicts_in_order():
    events = EventList([{"n": 0}])
    events.add_rows(RowEvents(ROWS.copy(), NAMES, QUOTED))
    events.append({"n": 3})
    events.add_rows(RowEvents(ROWS[:0].copy(), NAMES, QUOTED))  # (an empty block adds nothing)
    events.add_rows(RowEvents(ROWS[:1].copy(), NAMES, QUOTED))
    plain = list(events)
    assert len(events) == len(plain) == 5
    assert [e.get("n", e.get("kind")) for e in plain] == [0, "impact", "contact", 3, "impact"]
    assert events[1] == {"time": 0.1, "bodies": ["a", "b \"quoted\""], "point": [1.0, 2.0, 3.0],
                         "normal": [0.0, 1.0, 0.0], "impulse": 0.5, "tangential_speed": 0.1, "normal_speed": 2.0,
                         "kind": "impact", "parts": [None, None]}
    assert events[-1] == events[4] == plain[4] and events[-5] == {"n": 0}
    for first in range(6):
        for end in range(first, 7):
            assert events[first:end] == plain[first:end]
    assert events[::2] == plain[::2] and events == plain and events != plain[:4]


def test_the_impacts_from_an_index_are_the_events_that_are_not_contacts_and_stay_the_same_dicts():
    block = RowEvents(np.concatenate([ROWS, ROWS]), NAMES, QUOTED)
    events = EventList([{"n": 0}, {"n": 1, "kind": "contact"}])
    events.add_rows(block)
    events.append({"n": 6, "kind": "impact"})
    plain = [(k, e) for k, e in enumerate(list(EventList(list(events)))) if e.get("kind", "impact") != "contact"]
    for first in range(len(events) + 1):
        found = events.impacts_from(first)
        assert [(k, e) for k, e in found] == [(k, e) for k, e in plain if k >= first]
    # a block's impacts are the very dicts it reads as later, made once
    made = dict(events.impacts_from(0))
    assert made[2] is events[2] and made[4] is events[4] and block.impacts() is block.impacts()
    # and read the other way round
    other = RowEvents(ROWS.copy(), NAMES, QUOTED)
    assert other.dicts()[0] is other.impacts()[0][1] and len(other.impacts()) == 1


def test_a_block_of_rows_writes_the_json_its_dicts_would(tmp_path):
    def parts(a, b, feature):
        return [f"part{feature}", None]

    events = EventList()
    events.add_rows(RowEvents(ROWS.copy(), NAMES, QUOTED, parts))
    events.append({"time": 0.3, "kind": "impact"})
    events.add_rows(RowEvents(ROWS.copy(), NAMES, QUOTED))
    write_json(tmp_path / "rows.json", events)
    write_json(tmp_path / "dicts.json", list(events))
    assert (tmp_path / "rows.json").read_bytes() == (tmp_path / "dicts.json").read_bytes()
    assert json.loads((tmp_path / "rows.json").read_text())[0]["parts"] == ["part7", None]


def test_a_figure_that_is_not_finite_is_written_null(tmp_path):
    rows = ROWS.copy()
    rows[1, 10] = math.nan
    events = EventList()
    events.add_rows(RowEvents(rows, NAMES, QUOTED))
    write_json(tmp_path / "events.json", events)
    written = json.loads((tmp_path / "events.json").read_text())
    assert written[1]["impulse"] is None and written[0]["impulse"] == 0.5


def test_a_capturing_run_writes_the_events_it_reads(tmp_path):
    scene = load_text(heap(27, "sphere").replace("time 0 s .. 2.0 s", "time 0 s .. 0.6 s")).scene
    result = simulate(scene, RunOptions())
    assert result.simulation.contact_report()["path"] == "capturing"
    write_outputs(scene, result, tmp_path)
    written = json.loads((tmp_path / "events.json").read_text())
    assert len(written) > 1000 and written == json.loads(json.dumps(list(result.simulation.events)))
