"""Compound bodies on the capturing contact path (runtime/capture/compound.py through loop.py): a body of two boxes
dropped flat comes to rest on its lowest part, on a floor or on a box, with its energy never rising; a scene's
report says it took the path; the clock (scenes/clock.isaac) takes it by the rule for jointed scenes and its ticks
are impact events that name the tooth and the pallet; a scene
whose pairs of parts a contact's key cannot name stays exact.

The answer of the drops: the body is a 10 cm cube (0.5 kg, centred at x = -5 cm) joined to a 10 x 6 x 10 cm box
(0.3 kg, centred at x = +5 cm, 2 cm up), so its centre of mass lies (0.5 * 0 + 0.3 * 0.02) / 0.8 = 7.5 mm above the
cube's centre, and lying flat on the cube's bottom face (the other box's bottom is 4 cm higher) it rests with its
centre 5 cm + 7.5 mm above what it lies on.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from isaac.api import Simulation
from isaac.cli import main

CLOCK = Path(__file__).resolve().parents[2] / "scenes" / "clock.isaac"
# the compound's centre of mass above its lowest face, m (module docstring)
ABOVE = 0.05 + 0.3 * 0.02 / 0.8
PAIR = """  body pair compound {
    material m
    part left box { size (0.1, 0.1, 0.1) m  at (-0.05, 0, 0) m }
    part right box { size (0.1, 0.06, 0.1) m  at (0.05, 0.02, 0) m }
    at (0, HEIGHT, 0) m
  }"""


def scene(bodies: str, height: float, end: float = 1.5) -> str:
    return (f"scene drop {{\n  time 0 s .. {end} s\n  frames 100 Hz\n  gravity (0, -9.81, 0) m/s2\n"
            f"  solver dynamics {{ integrator rk4  step 1 ms }}\n"
            f"  material m {{ density 500 kg/m3  friction 0.4  restitution 0.3 }}\n"
            f"  body floor plane {{ material m }}\n{bodies}\n{PAIR.replace('HEIGHT', str(height))}\n}}\n")


def test_a_compound_dropped_flat_on_a_floor_rests_on_its_lowest_part():
    sim = Simulation.from_text(scene("", 0.25))
    sim.switch_to_capture("test")  # (alone on a floor it never strikes a moving body: it would stay exact)
    energies = [sim.energy()]
    for k in range(30):
        sim.advance_to((k + 1) * 0.05)
        energies.append(sim.energy())
    pair = sim.body("pair")
    y = sim.state.y[pair]
    assert abs(y[1] - ABOVE) < 5e-4, y[1]
    assert np.linalg.norm(y[7:13]) < 1e-4  # at rest
    # lying flat: its body y axis stays up
    w, x, yq, z = y[3:7]
    assert 1 - 2 * (x * x + z * z) > 1 - 1e-6
    energies = np.array(energies)
    released = energies[0] - energies[-1]
    assert np.max(np.diff(energies)) <= 0.01 * released
    report = sim.contact_report()
    assert report["path"] == "capturing" and report["deepest"] < 1e-3 and report["steps_creating_energy"] == 0


def test_a_compound_dropped_on_a_box_changes_to_the_capturing_path_and_rests_on_it(tmp_path):
    path = tmp_path / "drop.isaac"
    base = "  body base box { size (0.3, 0.1, 0.3) m  material m  at (0, 0.05, 0) m }"
    path.write_text(scene(base, 0.3))
    out = tmp_path / "out"
    assert main(["-q", "run", str(path), "--out", str(out), "--no-viewer"]) == 0
    contact = json.loads((out / "report.json").read_text())["contact"]
    assert contact["path"] == "capturing", contact
    assert contact["why"].startswith("an impact between moving bodies `base` and `pair`")
    assert contact["deepest"] < 1e-3 and contact["steps_creating_energy"] == 0
    with np.load(out / "trajectory.npz") as data:
        bodies = list(data["bodies"])
        position, velocity = data["position"][-1], data["linear_velocity"][-1]
    assert abs(position[bodies.index("pair"), 1] - (0.1 + ABOVE)) < 5e-4
    assert abs(position[bodies.index("base"), 1] - 0.05) < 5e-4
    assert np.abs(velocity).max() < 1e-4
    events = json.loads((out / "events.json").read_text())
    assert any(e["kind"] == "impact" and e["bodies"] == ["base", "pair"] for e in events)


def test_the_clock_takes_the_capturing_path(tmp_path):
    out = tmp_path / "clock"
    assert main(["-q", "run", str(CLOCK), "--out", str(out), "--until", "1", "--no-viewer"]) == 0
    contact = json.loads((out / "report.json").read_text())["contact"]
    assert contact["path"] == "capturing", contact
    assert contact["why"] == "the contacts changed 20 times within 50 steps"
    assert contact["deepest"] < 1e-3 and contact["steps_too_deep"] == 0
    # a tick on this path: a tooth's tip landing on a locking face, an impact event naming both parts
    events = json.loads((out / "events.json").read_text())
    ticks = [e for e in events if e["kind"] == "impact" and e["time"] > contact["since"]]
    assert len(ticks) == 2, ticks  # (0.42 s and 0.89 s: one at each pallet)
    assert all(e["parts"][0].startswith("tip") and e["parts"][1].endswith("_lock") for e in ticks)
    assert all(0.05 < e["normal_speed"] < 0.1 for e in ticks)


def test_a_pair_with_more_pairs_of_parts_than_a_key_names_stays_exact():
    from isaac_runtime.capture import eligible

    def comb(name: str, x: float) -> str:
        teeth = "\n".join(f"    part t{k} box {{ size (0.01, 0.01, 0.01) m  at ({0.02 * k}, 0, 0) m }}"
                          for k in range(50))
        return f"  body {name} compound {{\n    material m\n{teeth}\n    at ({x}, 0.5, 0) m\n  }}"

    # 50 x 50 pairs of parts: more than the 2048 a contact's key can name (capture/kinds.py LOCAL_FEATURES)
    sim = Simulation.from_text(scene(comb("one", -1.0) + "\n" + comb("two", 1.0), 2.0).replace("body pair", "body p"))
    assert eligible(sim.plan) == "compound bodies with more pairs of parts than a contact key holds"
    sim = Simulation.from_text(scene(comb("one", -1.0), 2.0))
    assert eligible(sim.plan) is None
