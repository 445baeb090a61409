"""Golden trajectories of the example scenes, compared with tolerances (pytest-regressions), not bytes.

Regenerate after an intended change with: python -m pytest tests/runtime/test_golden_trajectories.py --force-regen
"""
from __future__ import annotations

import pytest

from .test_scenes import run

# (scene, seconds compared): the chain is chaotic, so rounding differences grow; compare its first 2 s only
GOLDEN = [("pendulum", 10.0), ("transition", 5.0), ("windmill", 10.0), ("chain", 2.0), ("gears", 1.0),
          ("selfassembly", 4.0)]


@pytest.mark.parametrize("name,seconds", GOLDEN)
def test_golden_trajectory(name, seconds, ndarrays_regression):
    arrays = run(name).recorder.arrays()
    keep = arrays["time"] <= seconds + 1e-9
    every = slice(None, None, 10)  # 10 Hz is enough to see any change
    ndarrays_regression.check(
        {key: arrays[key][keep][every] for key in ("time", "position", "orientation", "linear_velocity",
                                                    "angular_velocity")},
        default_tolerance={"atol": 1e-8, "rtol": 1e-7},
    )
