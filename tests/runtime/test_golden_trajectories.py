"""The compiled core against the previous implementation's trajectories (data/baumgarte), to round-off.

The golden trajectories of every example scene are scenes/<name>.golden/ (isaac golden, checked by the pytest
plugin as scenes/<name>.isaac::golden; record them again after an intended change with
`isaac golden --update scenes/*.isaac`, then review the diff).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.run import RunOptions, simulate

from .test_scenes import SCENES

# (scene, seconds compared): the chain is chaotic, so rounding differences grow; compare its first 2 s only
GOLDEN = [("pendulum", 10.0), ("transition", 5.0), ("windmill", 10.0), ("chain", 2.0), ("gears", 1.0),
          ("selfassembly", 4.0)]


# The previous implementation (numpy, one evaluation at a time, commit f58d6bf) ran the dissertation's formulation:
# Baumgarte on every row at f = 1 / (20 h), nothing projected. Its trajectories are kept in data/baumgarte; the
# compiled core run the same way (`stabilization baumgarte`, and no error control: `tolerance 0`) must give them
# again, to round-off.
BAUMGARTE = Path(__file__).parent / "data" / "baumgarte"


@pytest.mark.parametrize("name,seconds", GOLDEN)
def test_the_compiled_core_reproduces_the_previous_implementation(name, seconds):
    text = (SCENES / f"{name}.isaac").read_text()
    solver = re.search(r"solver dynamics \{([^}]*)\}", text)
    text = text.replace(solver.group(0), "solver dynamics {" + solver.group(1) + " stabilization baumgarte  tolerance 0 }")
    arrays = simulate(load_text(text, name=f"{name}.isaac", folder=SCENES).scene, RunOptions()).recorder.arrays()
    reference = np.load(BAUMGARTE / f"{name}.npz")
    keep = arrays["time"] <= min(seconds, 2.0) + 1e-9  # 2000 steps at 1 ms (the chain is chaotic beyond)
    count = int(np.count_nonzero(reference["time"] <= min(seconds, 2.0) + 1e-9))
    for key in ("position", "orientation", "linear_velocity", "angular_velocity"):
        got = arrays[key][keep][::10][:count]
        want = reference[key][:count]
        scale = max(1.0, np.abs(want).max())
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * scale, err_msg=f"{name} {key}")
