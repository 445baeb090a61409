"""The factorization kept across evaluations (core/solve.py solve_again): where J M^-1 J^T barely changes (boxes
at rest on each other) it serves later evaluations by iterative refinement, and the motion is the one that
factoring afresh every time gives; where it changes (a swinging chain) the evaluations factor afresh."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import isaac_runtime.core.structure as structure
from isaac_runtime.core.data import COUNTER_REUSED
from isaac_runtime.dynamics import DynamicsStepper
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def _run(name: str, until: float, keep: bool, monkeypatch, overrides=None):
    structure._BUILT.clear()  # (structures are cached by their rows: the one built without keeping must not serve)
    monkeypatch.setattr(DynamicsStepper, "rest_after", 0)  # (every step evaluated: none left at rest, core/rest.py)
    if not keep:
        monkeypatch.setattr(structure, "affordable_corrections", lambda Lp, couplings: -1)
    sim = Simulation.from_file(SCENES / f"{name}.isaac", overrides or {}, until=until)
    sim.advance_to(until)
    monkeypatch.undo()
    structure._BUILT.clear()
    return sim


@pytest.mark.parametrize("name, until", [("stack", 1.0), ("slide", 1.5)])
def test_a_kept_factor_gives_the_motion_of_fresh_ones(name, until, monkeypatch):
    kept = _run(name, until, True, monkeypatch)
    fresh = _run(name, until, False, monkeypatch)
    assert fresh.compiled.scratch.counters[COUNTER_REUSED] == 0
    assert kept.compiled.scratch.counters[COUNTER_REUSED] > 0.5 * 4 * kept.state.steps  # most evaluations
    scale = max(1.0, float(np.max(np.abs(fresh.state.x))))
    assert np.max(np.abs(kept.state.x - fresh.state.x)) <= 1e-12 * scale
    assert np.max(np.abs(kept.state.v - fresh.state.v)) <= 1e-11
    assert [e["kind"] for e in kept.events] == [e["kind"] for e in fresh.events]


def test_a_tower_at_rest_keeps_one_factor_and_stays_put(monkeypatch):
    sim = _run("tower", 1.0, True, monkeypatch)
    start = Simulation.from_file(SCENES / "tower.isaac", until=1.0)
    # every evaluation after the first served by a kept factor; no box has moved (tests/runtime: 1e-15 m)
    assert sim.compiled.scratch.counters[COUNTER_REUSED] >= 4 * sim.state.steps - 2
    assert np.max(np.abs(sim.state.x - start.state.x)) <= 1e-12


def test_a_swinging_chain_factors_afresh(monkeypatch):
    # its J M^-1 J^T moves by about 1e-2 between stages: a try fails at once, and the tries back off
    sim = _run("chain", 0.5, True, monkeypatch)
    assert sim.compiled.scratch.counters[COUNTER_REUSED] <= 0.01 * 4 * sim.state.steps


def test_what_a_kept_factor_may_cost():
    # a pendulum's 3 rows: factoring is as cheap as one substitution, never keep; a tower's 120: two corrections
    Lp_small = np.array([0, 3, 5, 6])
    assert structure.affordable_corrections(Lp_small, 6) == -1
    blocks = 40  # a block tridiagonal matrix of 3x3 blocks with a wide coupling, as a stack's contacts make
    lengths = np.full(3 * blocks, 14)
    Lp_big = np.concatenate(([0], np.cumsum(lengths)))
    assert structure.affordable_corrections(Lp_big, 3000) == 2
