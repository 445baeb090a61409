"""runtime/capture/cylinders.py: the compiled narrow phase of a cylinder against a box, a cylinder or a capsule,
against brute force (the signed distances of sampled points), on resting poses by hand, and its features' stability
under small moves."""
from __future__ import annotations

import math

import numpy as np
import pytest
from isaac_runtime.collide.shapes import BOX, CAPSULE, CYLINDER
from isaac_runtime.core.rotation import quat_to_matrix

from .test_capture_narrow import MARGIN, compiled, placed, random_pose, random_table


# ---- cylinder-box, against brute force ---------------------------------------------------------------------------

def sd_box(p, x, R, h):
    q = np.abs((p - x) @ R) - h
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)


def sd_cylinder(p, c, R, r, hl):
    local = (p - c) @ R
    q = np.stack((np.hypot(local[:, 0], local[:, 1]) - r, np.abs(local[:, 2]) - hl), axis=-1)
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)


def deepest_point(c, Rc, r, hl, x, Rb, h):
    """The deepest point of either surface inside the other, sampled (the cylinder's side 720 x 101, rims 5760,
    caps 29 rings; the box's faces 80 x 80, edges 2000): apart, the distance; overlapping, at most the depth."""
    turn = np.linspace(0.0, 2 * np.pi, 720, endpoint=False)
    ring = np.stack((np.cos(turn), np.sin(turn), 0 * turn), -1)
    fine = np.linspace(0.0, 2 * np.pi, 5760, endpoint=False)
    rim = np.stack((r * np.cos(fine), r * np.sin(fine), 0 * fine), -1)
    parts = [(r * ring[None] + np.linspace(-hl, hl, 101)[:, None, None] * np.array([0, 0, 1.0])).reshape(-1, 3)]
    for s in (-1, 1):
        parts += [rim + (0, 0, s * hl)] + [f * r * ring + (0, 0, s * hl) for f in np.linspace(0, 1, 30)[:-1]]
    on_cylinder = c + np.concatenate(parts) @ Rc.T
    g = np.linspace(-1.0, 1.0, 80)
    u, v = (w.ravel() for w in np.meshgrid(g, g))
    t = np.linspace(-1.0, 1.0, 2000)
    parts = []
    for k in range(3):
        for s in (-1.0, 1.0):
            parts.append(np.roll(np.stack((np.full_like(u, s), u, v), -1), k, axis=1))
            parts.append(np.roll(np.stack((t, np.full_like(t, s), np.full_like(t, 1.0)), -1), k, axis=1))
            parts.append(np.roll(np.stack((t, np.full_like(t, s), np.full_like(t, -1.0)), -1), k, axis=1))
    on_box = x + (np.concatenate(parts) * h) @ Rb.T
    return max((-sd_box(on_cylinder, x, Rb, h)).max(), (-sd_cylinder(on_box, c, Rc, r, hl)).max())


def largest_gap(c, Rc, r, hl, x, Rb, h, rng):
    """The depth as minus the largest separation of the two shapes' projections over every direction (their
    signed distance, apart or overlapping): 100k directions, the best 8 refined by a random search."""
    def gaps(N):
        w = np.abs(N @ Rc[:, 2])
        return np.abs(N @ (c - x)) - w * hl - r * np.sqrt(np.maximum(1 - w * w, 0)) - np.abs(N @ Rb) @ h

    i = np.arange(100000) + 0.5
    polar, azimuth = np.arccos(1 - 2 * i / len(i)), np.pi * (1 + 5 ** 0.5) * i
    N = np.stack((np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)), -1)
    g = gaps(N)
    best = g.max()
    for n in N[np.argsort(g)[-8:]]:
        f, step = gaps(n[None])[0], 0.02
        while step > 1e-9:
            trial = n + step * rng.normal(size=(64, 3))
            trial /= np.linalg.norm(trial, axis=1, keepdims=True)
            gt = gaps(trial)
            if gt.max() > f:
                n, f = trial[np.argmax(gt)], gt.max()
            else:
                step *= 0.5
        best = max(best, f)
    return -best


def test_cylinder_box_depth_agrees_with_brute_force():
    """150 random poses, 3 mm deep to 5 mm apart: the deepest point's depth within 1e-4 m of the largest gap over
    100k directions (refined), never shallower than the deepest sampled surface point (by 2e-5 m, the sampling),
    and equal to it (1e-4 m) when apart; the other order gives the same points, the normals reversed."""
    rng = np.random.default_rng(11)
    worst = worst_apart = 0.0
    for trial in range(150):
        table = random_table([CYLINDER, BOX], rng)
        x, R = random_pose(rng)
        placed(table, x, R, rng.uniform(-0.003, MARGIN), compiled, 8)
        p, n, d, f, count = compiled(table, 0, 1, x, R, margin=np.inf)
        shapes = (x[0], R[0], table.radius[0], table.half_length[0], x[1], R[1], table.half[1])
        exact, sampled = largest_gap(*shapes, rng), deepest_point(*shapes)
        worst = max(worst, abs(d.max() - exact))
        assert d.max() == pytest.approx(exact, abs=1e-4) and d.max() >= sampled - 2e-5, trial
        if sampled < 0.0:
            worst_apart = max(worst_apart, abs(d.max() - sampled))
            assert d.max() == pytest.approx(sampled, abs=1e-4)
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and len(set(f.tolist())) == count
        p2, n2, d2, _f2, count2 = compiled(table, 1, 0, x, R, margin=np.inf)
        assert count2 == count and np.array_equal(d2, d) and np.array_equal(n2, -n) and np.array_equal(p2, p)
    print(f"cylinder-box: max |depth - largest gap| {worst:.1e} m, apart: max |depth - sampled| {worst_apart:.1e} m")


def cylinder_on_box(half, radius, half_length, rotation, xc):
    table = random_table([CYLINDER, BOX], np.random.default_rng(0))
    table.radius[0], table.half_length[0], table.half[1] = radius, half_length, half
    return table, np.array([xc, (0.0, 0.0, 0.0)]), np.stack((rotation, np.eye(3)))


UPRIGHT = quat_to_matrix(np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]))  # z -> -y


def test_cylinder_resting_on_a_box():
    """On the box's top face y = 0.1, 1e-5 m deep: standing, four rim points; lying across a narrower box, the
    lowest line clipped to the face (two points, x = -/+0.1); tilted 10 degrees, its lowest rim point."""
    tilt = quat_to_matrix(np.array([math.cos(math.radians(5)), 0.0, 0.0, math.sin(math.radians(5))])) @ UPRIGHT
    lowest = 0.05 * math.sin(math.radians(10)) + 0.2 * math.cos(math.radians(10))  # below the centre, tilted
    cases = [(UPRIGHT, (0.0, 0.3, 0.0), 4, None), (np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),
             (0.0, 0.15, 0.0), 2, (-0.1, 0.1)), (tilt, (0.0, 0.1 + lowest, 0.0), 1, None)]
    for rotation, xc, expected, ends in cases:
        table, x, R = cylinder_on_box((0.1, 0.1, 0.3), 0.05, 0.2, rotation, np.array(xc) - (0, 1e-5, 0))
        for a, b, sign in ((0, 1, 1.0), (1, 0, -1.0)):
            p, n, d, _f, count = compiled(table, a, b, x, R, margin=1e-4)
            assert count == expected and np.allclose(d, 1e-5, atol=1e-12) and np.allclose(n, (0, sign, 0))
            assert np.allclose(p[:, 1], 0.1 - 0.5e-5, atol=1e-12)
            if ends:
                assert np.allclose(np.sort(p[:, 0]), ends, atol=1e-12)


def test_box_on_a_cylinder_and_pressing_into_it():
    """A small box flat on a standing cylinder's cap: its four bottom corners; a box corner, then an edge, 1 mm
    into the curved side: one point 1 mm deep, the normal along the radius."""
    table, x, R = cylinder_on_box((0.05, 0.05, 0.05), 0.2, 0.1, UPRIGHT, (0.0, 0.0, 0.0))
    x[1] = (0.03, 0.15 - 1e-4, 0.0)  # cap at y = 0.1, box bottom at y = 0.1 - 1e-4
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 4 and np.allclose(d, 1e-4, atol=1e-12) and np.allclose(n, (0, -1, 0))
    assert np.allclose(np.sort(p[:, 0]), (-0.02, -0.02, 0.08, 0.08), atol=1e-12)
    # the cylinder lying along z; a box turned 45 degrees about y and z has a corner straight below: at
    # -sqrt(3) 0.05 along y
    table, x, R = cylinder_on_box((0.05, 0.05, 0.05), 0.2, 0.3, np.eye(3), (0.0, 0.0, 0.0))
    corner_down = quat_to_matrix(np.array([math.cos(math.atan(math.sqrt(2)) / 2), 0.0, 0.0,
                                           math.sin(math.atan(math.sqrt(2)) / 2)])) @ quat_to_matrix(
        np.array([math.cos(math.pi / 8), 0.0, math.sin(math.pi / 8), 0.0]))
    edge_down = quat_to_matrix(np.array([math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0, 0.0]))
    for rotation, below in ((corner_down, math.sqrt(3) * 0.05), (edge_down, math.sqrt(2) * 0.05)):
        R[1] = rotation
        x[1] = (0.0, 0.2 + below - 1e-3, 0.0)
        p, n, d, _f, count = compiled(table, 0, 1, x, R)
        assert count == 1 and d[0] == pytest.approx(1e-3, abs=1e-9) and np.allclose(n[0], (0, -1, 0), atol=1e-6)
        assert np.allclose(p[0], (0.0, 0.2 - 0.5e-3, 0.0), atol=1e-6)


def keeps_its_features(table, x, R, rng) -> bool:
    """Body 0 moved along the deepest normal to a random depth up to 3 mm (x changed): whether its contacts keep
    their features after a 1e-7 m, 1e-6 rad move."""
    placed(table, x, R, rng.uniform(-0.003, 0.0), compiled, 8)
    f0 = compiled(table, 0, 1, x, R)[3]
    R2 = R.copy()
    R2[0] = quat_to_matrix(np.array([1.0, *rng.normal(0.0, 0.5e-6, 3)])) @ R[0]
    f1 = compiled(table, 0, 1, x + rng.normal(0.0, 1e-7, x.shape), R2)[3]
    return sorted(f0.tolist()) == sorted(f1.tolist())


def test_cylinder_box_features_are_stable():
    """Shallow random poses and cylinders resting on a face (tilted up to 0.5 degree): the same features after a
    1e-7 m, 1e-6 rad move."""
    rng = np.random.default_rng(13)
    same = 0
    for trial in range(200):
        table = random_table([CYLINDER, BOX], rng)
        x, R = random_pose(rng)
        if trial % 2:
            R[1] = np.eye(3)
            R[0] = quat_to_matrix(np.array([1.0, *rng.normal(0.0, math.radians(0.25), 3)])) @ (
                UPRIGHT if trial % 4 == 1 else np.eye(3))
            x[0] = (rng.uniform(-0.05, 0.05), 1.0, rng.uniform(-0.05, 0.05))
        same += keeps_its_features(table, x, R, rng)
    print(f"cylinder-box: {same}/200 kept their features")
    assert same >= 0.95 * 200


# ---- cylinder against cylinder or capsule, against brute force -------------------------------------------------

NAME = {CYLINDER: "cylinder", CAPSULE: "capsule"}

def round_gaps(N, c, u, r, hl, x, v, rb, hb, capsule):
    """The separation along each direction of N of a cylinder (c, u, r, hl) and a cylinder or capsule (x, v)."""
    w, wb = np.abs(N @ u), np.abs(N @ v)
    other = wb * hb + (rb if capsule else rb * np.sqrt(np.maximum(1 - wb * wb, 0)))
    return np.abs(N @ (c - x)) - w * hl - r * np.sqrt(np.maximum(1 - w * w, 0)) - other


def sd_capsule(p, c, u, r, hl):
    s = np.clip((p - c) @ u, -hl, hl)
    return np.linalg.norm(p - c - s[:, None] * u, axis=1) - r


def round_largest_gap(args, rng):
    """Minus the largest separation over 100k directions, the best 8 refined by a random search."""
    i = np.arange(100000) + 0.5
    polar, azimuth = np.arccos(1 - 2 * i / len(i)), np.pi * (1 + 5 ** 0.5) * i
    N = np.stack((np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)), -1)
    g = round_gaps(N, *args)
    best = g.max()
    for n in N[np.argsort(g)[-8:]]:
        f, step = round_gaps(n[None], *args)[0], 0.02
        while step > 1e-9:
            trial = n + step * rng.normal(size=(64, 3))
            trial /= np.linalg.norm(trial, axis=1, keepdims=True)
            gt = round_gaps(trial, *args)
            if gt.max() > f:
                n, f = trial[np.argmax(gt)], gt.max()
            else:
                step *= 0.5
        best = max(best, f)
    return -best


@pytest.mark.parametrize("other", [CYLINDER, CAPSULE])
def test_cylinder_against_a_round_shape_agrees_with_brute_force(other):
    """150 random poses, 3 mm deep to 5 mm apart: the deepest depth within 1e-4 m of the largest gap over 100k
    directions (refined), every point's depth at most that; the other order gives the same points, the normals
    reversed (two cylinders: the same points and depths); unit normals from b toward a, distinct features; at the
    margin at most 8 points, each between the surfaces."""
    rng = np.random.default_rng(17 + other)
    worst = 0.0
    counts = {}
    for trial in range(150):
        table = random_table([CYLINDER, other], rng)
        x, R = random_pose(rng)
        placed(table, x, R, rng.uniform(-0.003, MARGIN), compiled, 8)
        p, n, d, f, count = compiled(table, 0, 1, x, R, margin=np.inf)
        args = (x[0], R[0][:, 2], table.radius[0], table.half_length[0], x[1], R[1][:, 2], table.radius[1],
                table.half_length[1], other == CAPSULE)
        exact = round_largest_gap(args, rng)
        worst = max(worst, abs(d.max() - exact))
        assert d.max() == pytest.approx(exact, abs=1e-4), trial
        assert d.max() <= exact + 1e-6
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and len(set(f.tolist())) == count
        assert np.all(n @ (x[0] - x[1]) >= -1e-12)
        p2, n2, d2, _f2, count2 = compiled(table, 1, 0, x, R, margin=np.inf)
        if other == CAPSULE:  # the same test, its normals reversed
            assert count2 == count and np.array_equal(d2, d) and np.array_equal(n2, -n) and np.array_equal(p2, p)
        else:  # the test run with the roles swapped: the same depths and points in another order
            i, i2 = np.lexsort(p.T), np.lexsort(p2.T)
            assert count2 == count and np.allclose(d2[i2], d[i], atol=1e-9) and np.allclose(p2[i2], p[i], atol=1e-6)
            assert np.allclose(n2, -n[0], atol=1e-6)
        pk, _n, dk, _f, kept = compiled(table, 0, 1, x, R)
        counts[kept] = counts.get(kept, 0) + 1
        assert kept <= 8
        # each point between the two surfaces: within its depth (+ 2 mm: the points are placed along the pair's
        # normal, not each feature's own) of both
        sa = sd_cylinder(pk, x[0], R[0], table.radius[0], table.half_length[0])
        sb = (sd_capsule(pk, x[1], R[1][:, 2], table.radius[1], table.half_length[1]) if other == CAPSULE else
              sd_cylinder(pk, x[1], R[1], table.radius[1], table.half_length[1]))
        assert np.all(np.maximum(np.abs(sa), np.abs(sb)) <= np.abs(dk) + 2e-3), trial
    print(f"cylinder-{NAME[other]}: max |depth - largest gap| {worst:.1e} m, counts at the margin {counts}")


def round_table(kinds, sizes):
    table = random_table(list(kinds), np.random.default_rng(0))
    for i, (r, hl) in enumerate(sizes):
        table.radius[i], table.half_length[i] = r, hl
    return table


ALONG_X = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # body z along world x


def test_cylinders_side_by_side_standing_and_crossed():
    """Lying side by side (parallel, one on the other): two points at the ends of the overlap; standing on
    another's cap: the rim points (>= 3); crossed at right angles: one point; each 1e-4 m deep, normal up."""
    # a (r 0.05, hl 0.2) on b (r 0.1, hl 0.3), both along x, a shifted 0.15 along x: overlap x in [-0.05, 0.3]
    table = round_table((CYLINDER, CYLINDER), ((0.05, 0.2), (0.1, 0.3)))
    x, R = np.array([[0.15, 0.15 - 1e-4, 0.0], [0.0, 0.0, 0.0]]), np.stack((ALONG_X, ALONG_X))
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 2 and np.allclose(d, 1e-4, atol=1e-12) and np.allclose(n, (0, 1, 0))
    assert np.allclose(np.sort(p[:, 0]), (-0.05, 0.3), atol=1e-12) and np.allclose(p[:, 1], 0.1 - 0.5e-4)
    # standing: a (r 0.05, hl 0.1) upright on b's top cap (b upright too, r 0.2, hl 0.1), off centre
    table = round_table((CYLINDER, CYLINDER), ((0.05, 0.1), (0.2, 0.1)))
    x, R = np.array([[0.07, 0.2 - 1e-4, 0.03], [0.0, 0.0, 0.0]]), np.stack((UPRIGHT, UPRIGHT))
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count >= 3 and np.allclose(d, 1e-4, atol=1e-9) and np.allclose(n, (0, 1, 0), atol=1e-7)
    assert np.allclose(np.hypot(p[:, 0] - 0.07, p[:, 2] - 0.03), 0.05, atol=1e-7)
    # crossed: a along x on b along z
    table = round_table((CYLINDER, CYLINDER), ((0.05, 0.2), (0.1, 0.3)))
    x, R = np.array([[0.0, 0.15 - 1e-4, 0.0], [0.0, 0.0, 0.0]]), np.stack((ALONG_X, np.eye(3)))
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 1 and d[0] == pytest.approx(1e-4, abs=1e-9) and np.allclose(n[0], (0, 1, 0), atol=1e-6)
    assert np.allclose(p[0], (0.0, 0.1 - 0.5e-4, 0.0), atol=1e-6)
    _p2, n2, d2, _f, count2 = compiled(table, 1, 0, x, R)
    assert count2 == 1 and np.allclose(n2, -n) and np.allclose(d2, d)


def test_capsule_across_a_cylinder_and_pressing_into_its_cap():
    """A capsule lying across a lying cylinder: one point on top; along it: two; a capsule standing on a standing
    cylinder's cap, its end 1e-3 m in: one point, normal along the axis."""
    table = round_table((CAPSULE, CYLINDER), ((0.03, 0.2), (0.1, 0.3)))
    x, R = np.array([[0.0, 0.13 - 1e-4, 0.0], [0.0, 0.0, 0.0]]), np.stack((ALONG_X, np.eye(3)))
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 1 and d[0] == pytest.approx(1e-4, abs=1e-9) and np.allclose(n[0], (0, 1, 0), atol=1e-6)
    assert np.allclose(p[0], (0.0, 0.1 - 0.5e-4, 0.0), atol=1e-6)
    R[0] = np.eye(3)  # along it
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 2 and np.allclose(d, 1e-4, atol=1e-12) and np.allclose(n, (0, 1, 0))
    assert np.allclose(np.sort(p[:, 2]), (-0.2, 0.2), atol=1e-12)
    table = round_table((CAPSULE, CYLINDER), ((0.03, 0.1), (0.2, 0.1)))
    x, R = np.array([[0.05, 0.1 + 0.1 + 0.03 - 1e-3, -0.02], [0.0, 0.0, 0.0]]), np.stack((UPRIGHT, UPRIGHT))
    for a, b, s in ((0, 1, 1.0), (1, 0, -1.0)):
        p, n, d, _f, count = compiled(table, a, b, x, R)
        assert count == 1 and d[0] == pytest.approx(1e-3, abs=1e-12) and np.allclose(n[0], (0, s, 0), atol=1e-7)
        assert np.allclose(p[0], (0.05, 0.1 - 0.5e-3, -0.02), atol=1e-7)


@pytest.mark.parametrize("other", [CYLINDER, CAPSULE])
def test_cylinder_round_features_are_stable(other):
    """Shallow random poses and cylinders resting on the other (tilted up to 0.5 degree): the same features after
    a 1e-7 m, 1e-6 rad move."""
    rng = np.random.default_rng(19)
    same = 0
    for trial in range(200):
        table = random_table([CYLINDER, other], rng)
        x, R = random_pose(rng)
        if trial % 2:
            R[1] = UPRIGHT if trial % 4 == 1 else np.eye(3)
            R[0] = quat_to_matrix(np.array([1.0, *rng.normal(0.0, math.radians(0.25), 3)])) @ R[1]
            x[0] = (rng.uniform(-0.05, 0.05), 1.0, rng.uniform(-0.05, 0.05))
        same += keeps_its_features(table, x, R, rng)
    print(f"cylinder-{NAME[other]}: {same}/200 kept their features")
    assert same >= 0.9 * 200
