"""Eli Terry's clock (scenes/clock.isaac) against its answer: `isaac run` writes trajectory.npz, events.json and
audio.wav, and every check below reads them. The run is cut to RUN_SECONDS: the scene's 30 s take 50 to 90 s
on a loaded two-core machine. The clock is in its steady beat from the second swing on (its amplitude drifts by
0.7 % over the whole 30 s), so the second half of the cut run stands for the second half of the whole.

The answer (the scene's header): the pendulum is a compound pendulum with the small-swing period
T0 = 2 pi sqrt(I_pivot / (m g l)), longer by (1 + A^2 / 16) at amplitude A; a deadbeat escapement lets the wheel
of N teeth go one tooth per period, in two steps of half a pitch, so its mean speed is (2 pi / N) / T; the
gear constraints hold their ratios, the rope carries the weight down by r_rope x (the drum's angle), and the
retainer's two point-on-plane constraints keep the weight on its vertical line.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import soundfile

from isaac.cli import main

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "clock.isaac"
RUN_SECONDS = 12.0
TEETH = 30
PITCH = 2 * math.pi / TEETH
G = 9.81
# the train (scene: gear(drum, 4 cm, middle, 5 mm), gear(middle, 4 cm, escape, 5 mm), rope on 1.5 cm)
DRUM_WHEEL, MIDDLE_PINION, MIDDLE_WHEEL, ESCAPE_PINION, ROPE_ARM = 0.04, 0.005, 0.04, 0.005, 0.015
WEIGHT_LINE = (0.06, -0.018)  # the retainer's line: x = 6 cm, z = -1.8 cm
# the escape wheel is at rest when it turns slower than this (its drops reach 1.5 rad/s, its creep 0.01)
AT_REST = 0.05  # rad/s


@pytest.fixture(scope="module")
def clock(tmp_path_factory):
    """The run's outputs: (arrays of trajectory.npz, events, ir, out folder)."""
    out = tmp_path_factory.mktemp("clock") / "out"
    assert main(["-q", "run", str(SCENE), "--out", str(out), "--until", str(RUN_SECONDS), "--no-viewer"]) == 0
    with np.load(out / "trajectory.npz", allow_pickle=False) as data:
        arrays = {name: data[name] for name in data.files}
    events = json.loads((out / "events.json").read_text())
    ir = json.loads((out / "ir.json").read_text())
    return arrays, events, ir, out


def index(arrays, name: str) -> int:
    return list(arrays["bodies"]).index(name)


def turn_about_z(arrays, name: str) -> np.ndarray:
    """(T,) a body's angle about world z (rad), unwrapped: its bodies turn about z only (their axles)."""
    q = arrays["orientation"][:, index(arrays, name)]
    return np.unwrap(2.0 * np.arctan2(q[:, 3], q[:, 0]))


def late(arrays) -> np.ndarray:
    """The frames of the run's second half."""
    return arrays["time"] >= 0.5 * arrays["time"][-1]


def swings(arrays) -> tuple:
    """(times, angles) of the pendulum's turning points (rad), each refined on the parabola through its frame and
    the two beside it."""
    phi, t = turn_about_z(arrays, "pendulum"), arrays["time"]
    k = np.flatnonzero(np.sign(np.diff(phi[1:])) != np.sign(np.diff(phi[:-1]))) + 1
    a, b, c = phi[k - 1], phi[k], phi[k + 1]
    shift = 0.5 * (a - c) / (a - 2 * b + c)
    return t[k] + shift * (t[1] - t[0]), b - 0.25 * (a - c) * shift


def upward_crossings(arrays) -> np.ndarray:
    """Times the pendulum passes its vertical turning counterclockwise (linear between frames)."""
    phi, t = turn_about_z(arrays, "pendulum"), arrays["time"]
    k = np.flatnonzero((phi[:-1] < 0) & (phi[1:] >= 0))
    return t[k] - phi[k] * (t[k + 1] - t[k]) / (phi[k + 1] - phi[k])


def small_swing_period(ir) -> float:
    """T0 = 2 pi sqrt(I_pivot / (m g l)) of the pendulum from its mass properties in the IR (the parts' sum):
    I_pivot = I_zz + m l^2 about the axle (parallel axis), l the centre's distance from the axle in the plane."""
    body = next(b for b in ir["bodies"] if b["name"] == "pendulum")
    axle = next(c for c in ir["constraints"] if c["name"] == "pendulum_axle")
    pivot = np.asarray(next(t for t in axle["terms"] if t["family"] == "nail")["params"]["target"], float)
    lever = float(np.linalg.norm((np.asarray(body["position"]) - pivot)[:2]))
    inertia = body["inertia"][2][2] + body["mass"] * lever**2
    return 2 * math.pi * math.sqrt(inertia / (body["mass"] * G * lever))


def test_the_clock_has_its_named_bodies(clock):
    arrays, _, ir, _ = clock
    assert {"pendulum", "escape", "weight"} <= set(arrays["bodies"])
    assert arrays["time"][-1] == pytest.approx(RUN_SECONDS)
    escape = next(b for b in ir["bodies"] if b["name"] == "escape")
    assert sum(part["name"].startswith("tooth") for part in escape["shape"]["parts"]) == TEETH


def test_late_swings_are_steady_and_wide(clock):
    arrays = clock[0]
    times, angles = swings(arrays)
    amplitude = np.degrees(np.abs(angles[times >= 0.5 * RUN_SECONDS]))
    assert len(amplitude) >= 8
    assert amplitude.min() > 2.0  # degrees: wide enough to unlock the pallets (the check asks over 1 degree)
    assert amplitude.max() / amplitude.min() - 1 < 0.02  # steady within 2 % (the check asks 5 %)


def test_the_period_is_the_compound_pendulums(clock):
    arrays, _, ir, _ = clock
    crossings = upward_crossings(arrays)
    crossings = crossings[crossings >= 0.5 * RUN_SECONDS]
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    times, angles = swings(arrays)
    amplitude = float(np.mean(np.abs(angles[times >= 0.5 * RUN_SECONDS])))
    expected = small_swing_period(ir) * (1 + amplitude**2 / 16)
    # the escapement's impulse and drops move the beat by a little: within 1 %
    assert period == pytest.approx(expected, rel=0.01)


def test_the_escape_wheel_goes_one_tooth_per_period(clock):
    arrays = clock[0]
    crossings = upward_crossings(arrays)
    crossings = crossings[crossings >= 0.5 * RUN_SECONDS]
    wheel = np.interp(crossings, arrays["time"], turn_about_z(arrays, "escape"))
    # clockwise (negative about z), exactly one pitch between beats of the same phase (the wheel is then locked)
    steps = -np.diff(wheel) / PITCH
    assert np.max(np.abs(steps - 1.0)) < 0.02
    # the mean speed is the answer's (2 pi / N) / T
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    speed = -(wheel[-1] - wheel[0]) / (crossings[-1] - crossings[0])
    assert speed == pytest.approx(PITCH / period, rel=0.005)


def test_the_escape_wheel_rests_and_advances_twice_a_period(clock):
    arrays = clock[0]
    window = late(arrays)
    spin = np.abs(arrays["angular_velocity"][window, index(arrays, "escape"), 2])
    assert np.mean(spin < AT_REST) > 0.3
    moving = spin >= AT_REST
    advances = int(np.sum(moving[1:] & ~moving[:-1]))
    periods = (arrays["time"][window][-1] - arrays["time"][window][0]) / np.mean(np.diff(upward_crossings(arrays)))
    # a drop on each pallet: two advances a period (one more or less at the window's ends)
    assert abs(advances - 2 * periods) <= 1.5


def test_the_gear_ratios_hold_and_the_weight_descends_with_the_rope(clock):
    arrays = clock[0]
    w = arrays["angular_velocity"][:, :, 2]
    drum, middle, escape = (index(arrays, name) for name in ("drum", "middle", "escape"))
    scale = np.max(np.abs(w[:, escape])) * ESCAPE_PINION
    # gear: ra wa + rb wb = 0
    assert np.max(np.abs(DRUM_WHEEL * w[:, drum] + MIDDLE_PINION * w[:, middle])) < 1e-6 * scale
    assert np.max(np.abs(MIDDLE_WHEEL * w[:, middle] + ESCAPE_PINION * w[:, escape])) < 1e-6 * scale
    # rope from the drum's right side: the weight's speed is the rim's, v_y = w_drum r_rope (clockwise: down)
    weight = index(arrays, "weight")
    v = arrays["linear_velocity"][:, weight, 1]
    assert np.max(np.abs(v - ROPE_ARM * w[:, drum])) < 1e-6 * scale
    # over the run, by the escape wheel's turn through the train (64 : 1)
    drop = arrays["position"][0, weight, 1] - arrays["position"][-1, weight, 1]
    turned = turn_about_z(arrays, "escape")
    ratio = (DRUM_WHEEL / MIDDLE_PINION) * (MIDDLE_WHEEL / ESCAPE_PINION)
    assert drop > 0
    assert drop == pytest.approx(-ROPE_ARM * (turned[-1] - turned[0]) / ratio, rel=1e-4)


def test_the_retainer_keeps_the_weight_on_its_line(clock):
    arrays = clock[0]
    weight = arrays["position"][:, index(arrays, "weight")]
    assert np.max(np.abs(weight[:, 0] - WEIGHT_LINE[0])) < 1e-9
    assert np.max(np.abs(weight[:, 2] - WEIGHT_LINE[1])) < 1e-9


def test_every_tick_is_an_impact_event(clock):
    arrays, events, _, _ = clock
    ticks = [e for e in events if e["kind"] == "impact" and set(e["bodies"]) == {"pendulum", "escape"}
             and e["time"] >= 0.5 * RUN_SECONDS]
    crossings = upward_crossings(arrays)
    periods = 0.5 * RUN_SECONDS / np.mean(np.diff(crossings))
    # a tooth drops onto a pallet twice a period
    assert abs(len(ticks) - 2 * periods) <= 1.5
    # from the first swing on, two in every period: none missed, none heard twice (a landing taken in two steps
    # of the capturing path is one tick; a landing whose step before took a little of its impulse is one too)
    every = sorted(e["time"] for e in events if e["kind"] == "impact" and set(e["bodies"]) == {"pendulum", "escape"})
    counts = [sum(1 for t in every if a <= t < b) for a, b in zip(crossings[:-1], crossings[1:])]
    assert counts == [2] * len(counts), list(zip(np.round(crossings, 3), counts))


def test_the_ticks_are_heard(clock):
    arrays, events, _, out = clock
    sound, rate = soundfile.read(out / "audio.wav")
    assert len(sound) == pytest.approx(RUN_SECONDS * rate, abs=rate * 0.05)
    tick = next(e["time"] for e in events if e["kind"] == "impact" and e["time"] > 1.0)
    loud = np.abs(sound[int(tick * rate): int((tick + 0.02) * rate)]).max()
    quiet = np.abs(sound[int((tick - 0.1) * rate): int((tick - 0.01) * rate)]).max()
    assert loud > 10 * quiet and loud > 1e-3
