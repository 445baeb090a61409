"""runtime/capture/broad.py: the capturing step's broad phase against every pair of boxes, on random poses of
spheres, boxes and capsules (one of them big), both as a dense grid (a heap in its bin) and hashed (bodies spread
over more cells than there are buckets); both find the same pairs in the same order (the contact solve's order)."""
from __future__ import annotations

import numba
import numpy as np
import pytest
from isaac.api import Simulation
from isaac_runtime.capture.broad import find_pairs
from isaac_runtime.core.rotation import quat_to_matrix


@numba.njit(error_model="numpy", nogil=True, _nrt=False)
def _find(shapes, sw, dynamic, y, R, h, margin, parts, poses):
    find_pairs(shapes, sw, dynamic, y, R, h, margin, parts, poses)


def _scene(count: int) -> str:
    kinds = ["sphere { radius 4 cm", "box { size (6, 9, 5) cm", "capsule { radius 2 cm  length 7 cm"]
    lines = [f"  body b{k} {kinds[k % 3]}  material m  at ({0.3 * k}, 1, 0) m }}" for k in range(count)]
    lines.append("  body big box { size (60, 10, 40) cm  material m  at (0, 3, 0) m }")
    lines.append("  body shelf static box { size (20, 2, 20) cm  material m  at (0, -0.2, 0) m }")
    return ("scene s {\n  time 0 s .. 1 s\n  gravity (0, -9.81, 0) m/s2\n"
            "  solver dynamics { integrator rk4  step 1 ms }\n  material m { density 500 kg/m3 }\n"
            "  body floor plane { material m }\n  body wall plane { normal (-1, 0, 0)  at (0.5, 0, 0) m  material m }\n"
            + "\n".join(lines) + "\n}\n")


def _stage(count: int):
    sim = Simulation.from_text(_scene(count))
    sim.switch_to_capture("test")
    return sim, sim.collider


def _pose(sim, rng, spread: float):
    """A state of random positions within +-spread (y above -0.1 m), turns and velocities; R its rotations."""
    n = sim.plan.n
    y = sim.state.y.copy()
    dynamic = np.flatnonzero(sim.plan.dynamic[:n])
    y[dynamic, 0:3] = rng.uniform(-spread, spread, (len(dynamic), 3)) + [0, spread - 0.1, 0]
    q = rng.normal(size=(len(dynamic), 4))
    y[dynamic, 3:7] = q / np.linalg.norm(q, axis=1)[:, None]
    y[dynamic, 7:13] = rng.normal(0, 2, (len(dynamic), 6))
    R = np.array([quat_to_matrix(row[3:7]) for row in y])
    return y, np.ascontiguousarray(R)


def _pairs(sim, stage, sweep, y, R) -> list:
    model = sim.compiled.model
    _find(model.shapes, sweep, model.bodies.dynamic, y, R, 1e-3, model.margin, stage.parts, stage.poses)
    return [tuple(p) for p in sweep.pairs[:sweep.count[0]].tolist()], sweep


def _every_pair(sim, sweep, y, R) -> set:
    """The oracle: every pair of grown boxes that overlap, with a moving body; every body whose box reaches
    below a plane."""
    order, box, dynamic = sweep.order.tolist(), sweep.box, sim.compiled.model.bodies.dynamic
    found = set()
    for x, i in enumerate(order):
        for j in order[x + 1:]:
            if (dynamic[i] or dynamic[j]) and np.all(box[i, :3] <= box[j, 3:]) and np.all(box[j, :3] <= box[i, 3:]):
                found.add((min(i, j), max(i, j)))
    for p in sweep.planes.tolist():
        normal = R[p] @ sim.compiled.model.shapes.normal[p]
        for i in order:
            centre, half = 0.5 * (box[i, :3] + box[i, 3:]), 0.5 * (box[i, 3:] - box[i, :3])
            if dynamic[i] and normal @ (centre - y[p, :3]) - np.abs(normal) @ half <= 0.0:
                found.add((min(i, p), max(i, p)))
    return found


@pytest.mark.parametrize("spread, dense", [(0.2, {1}), (0.6, None), (40.0, {0})])
def test_the_grid_finds_every_pair_of_overlapping_boxes_once(spread, dense):
    sim, stage = _stage(40)
    rng = np.random.default_rng(7)
    big, modes = sim.body("big"), set()
    for _ in range(12):
        y, R = _pose(sim, rng, spread)
        pairs, sweep = _pairs(sim, stage, stage.sweep, y, R)
        modes.add(int(sweep.frame[0]))
        assert len(pairs) == len(set(pairs)) and set(pairs) == _every_pair(sim, sweep, y, R)
        assert sweep.cell[big, 3] == -1 and (spread > 1 or any(big in pair for pair in pairs))
    assert dense is None or modes == dense  # a heap: a dense grid; bodies 80 m apart: hashed


def test_a_dense_grid_and_a_hashed_one_find_the_pairs_in_the_same_order():
    sim, stage = _stage(60)
    rng = np.random.default_rng(11)
    buckets = len(stage.sweep.start) - 1
    # (as few buckets as there are bodies: the heap's cells no longer fit, and are hashed)
    few = stage.sweep._replace(start=np.zeros(65, np.int64), fill=np.zeros(64, np.int64))
    for _ in range(8):
        y, R = _pose(sim, rng, 0.3)
        dense, sweep = _pairs(sim, stage, stage.sweep, y, R)
        assert sweep.frame[0] == 1 and buckets > 64
        hashed, small = _pairs(sim, stage, few, y, R)
        assert small.frame[0] == 0
        assert dense == hashed and len(dense) > 20
