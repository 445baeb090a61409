"""runtime/checks.py: the settling windows after switch-ons, and the settled constraint error a run is held to."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime import checks
from isaac_runtime.plan import compile_plan

SCENE = """scene s {
  time 0 s .. 5 s
  body a sphere { radius 5 cm  mass 1 kg  at (-0.25, 0, 0) }
  body b sphere { radius 5 cm  mass 1 kg  at (0.25, 0, 0) }
  exclude a, b
  constraint join point(a @ (0.05, 0, 0), b @ (-0.05, 0, 0)) from 1 s { stabilize 2 Hz  damping 1 }
  constraint hold nail(a) + nail(b) until 1 s
}
"""


def test_a_window_after_every_switch_on_ten_decay_times_long():
    scene = load_text(SCENE, "s.isaac").scene
    windows = checks.settling_windows(scene, compile_plan(scene))
    # hold: from the start, at the default 10 Hz, critically damped: 10 / (2 pi 10) s; join: 10 / (2 pi 2) s
    assert windows == [pytest.approx((0.0, 10 / (2 * math.pi * 10))), pytest.approx((1.0, 1 + 10 / (2 * math.pi * 2)))]


def test_an_overdamped_row_decays_at_its_slow_root():
    scene = load_text(SCENE.replace("damping 1", "damping 2"), "s.isaac").scene
    (_, (start, end)) = checks.settling_windows(scene, compile_plan(scene))
    omega, zeta = 2 * math.pi * 2, 2.0
    assert end - start == pytest.approx(10 / (omega * (zeta - math.sqrt(zeta ** 2 - 1))))


def test_the_settled_error_skips_the_windows():
    time = np.linspace(0, 3, 31)
    error = np.where((time >= 1) & (time < 1.5), 0.4, 1e-9)
    assert checks.settled_error(time, error, [(1.0, 1.5)]) == (pytest.approx(1e-9), 0.0)
    assert checks.settled_error(time, error, []) == (0.4, pytest.approx(1.0))
    assert checks.settled_error(time, error, [(0.0, 3.1)]) == (None, None)  # too short a run to tell


def test_the_check_of_a_report():
    report = {"constraint_error_settled": 0.5, "constraint_error_settled_time": 2.0}
    assert checks.constraint_check(report, 0.1) == {"limit": 0.1, "value": 0.5, "time": 2.0, "ok": False,
                                                    "constraints": []}
    assert checks.constraint_check(report, None)["ok"] and checks.constraint_check(report, 1.0)["ok"]
