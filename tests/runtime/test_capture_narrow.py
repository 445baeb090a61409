"""runtime/capture/narrow.py: the compiled narrow phase against the Python one (runtime/collide/narrow.py, boxes.py)
on random poses, the manifolds of resting shapes by hand, feature stability, the capacity guard and the bounds."""
from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from isaac_runtime.capture.narrow import bounds, closed_form, pair_contacts
from isaac_runtime.collide import narrow as oracle
from isaac_runtime.collide.shapes import BOX, CAPSULE, CYLINDER, MESH, PLANE, SPHERE, ShapeTable, boxes_of
from isaac_runtime.core.model import Shapes
from isaac_runtime.core.rotation import quat_to_matrix

MARGIN = 0.005


@numba.njit(error_model="numpy", nogil=True, _nrt=False)
def _entry(shapes, a, b, y, R, margin, point, normal, depth, feature, first, capacity, work):
    return pair_contacts(shapes, a, b, y, R, margin, point, normal, depth, feature, first, capacity, work)


@numba.njit(error_model="numpy", nogil=True, _nrt=False)
def _bounds(shapes, i, y, R, box):
    bounds(shapes, i, y, R, box)


def shapes_of(table: ShapeTable) -> Shapes:
    """The model's Shapes of a table, padded with the world row (as core/build.py makes them)."""
    pad = lambda a: np.concatenate((np.asarray(a, float), np.zeros((1,) + np.shape(a)[1:])))
    return Shapes(np.concatenate((table.kind, [0])).astype(np.int64), pad(table.radius),
                  np.nan_to_num(pad(table.half), posinf=1e300), pad(table.half_length), pad(table.normal),
                  pad(table.centre))


def state_of(x, R):
    n = len(x)
    y = np.zeros((n + 1, 13))
    y[:n, 0:3] = x
    y[:, 3] = 1.0
    return y, np.concatenate((R, np.eye(3)[None]))


def compiled(table, a, b, x, R, margin=MARGIN, capacity=16, first=0):
    """(points, normals, depths, features) of the compiled test, plus the full count."""
    y, Rp = state_of(x, R)
    point, normal = np.full((capacity + 4, 3), np.nan), np.full((capacity + 4, 3), np.nan)
    depth, feature, work = np.full(capacity + 4, np.nan), np.full(capacity + 4, -7, np.int64), np.zeros((16, 4))
    count = _entry(shapes_of(table), a, b, y, Rp, margin, point, normal, depth, feature, first, capacity, work)
    assert np.isnan(depth[capacity:]).all() and np.isnan(point[capacity:]).all()  # nothing past capacity
    k = min(count, capacity - first)
    s = slice(first, first + k)
    return point[s], normal[s], depth[s], feature[s], count


def reference(table, a, b, x, R, margin=MARGIN):
    """The Python narrow phase, in the order (a, b) (normals flipped when its test is written for (b, a))."""
    test, swapped = oracle.closed_form(table.kind[a], table.kind[b])
    if not swapped:
        return test(table, a, b, x, R, margin)
    p, n, d, f = test(table, b, a, x, R, margin)
    return p, -n, d, f


def random_table(kinds, rng):
    n = len(kinds)
    t = ShapeTable(np.array(kinds), np.zeros(n), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)),
                   np.zeros(n), np.full(n, -1))
    for i, k in enumerate(kinds):
        t.radius[i], t.half_length[i] = rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.3)
        t.half[i] = rng.uniform(0.05, 0.3, 3)
        if k == SPHERE:
            t.half[i] = t.radius[i]
        elif k in (CAPSULE, CYLINDER):
            t.half[i] = (t.radius[i], t.radius[i], t.half_length[i] + (t.radius[i] if k == CAPSULE else 0))
        elif k == PLANE:
            t.normal[i], t.half[i] = rng.normal(size=3), np.inf
            t.normal[i] /= np.linalg.norm(t.normal[i])
    return t


def random_pose(rng, n=2):
    q = rng.normal(size=(n, 4))
    return rng.uniform(-0.2, 0.2, (n, 3)), quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))


def placed(table, x, R, target, find=reference, rounds=6):
    """Body 0 moved along the deepest normal that `find` (the reference, or the compiled phase) gives the pair
    until its signed distance is `target`."""
    for _ in range(rounds):
        n, d = find(table, 0, 1, x, R, np.inf)[1:3]
        k = int(np.argmax(d))
        x[0] += n[k] * (target + d[k])
    return x


PAIRS = [(SPHERE, SPHERE), (SPHERE, PLANE), (BOX, PLANE), (BOX, BOX), (SPHERE, BOX), (CAPSULE, PLANE),
         (SPHERE, CAPSULE), (CAPSULE, CAPSULE), (CAPSULE, BOX), (CYLINDER, PLANE), (SPHERE, CYLINDER)]
# capsule-box: both phases find the axis point nearest the box by 40 golden steps (0.618^40 = 4e-9 of the axis),
# the Python one in world coordinates, the compiled one in the box's frame
TOLERANCE = {(CAPSULE, BOX): 1e-8}


@pytest.mark.parametrize("kinds", PAIRS)
def test_agrees_with_the_python_narrow_phase(kinds):
    """200 random poses, 3 mm deep to 5 mm apart (the margin), each order of the pair: the deepest depth to 1e-9
    m, its normal to 1e-9, the same number of points (box-box: the same count from the clipping)."""
    rng = np.random.default_rng(sum(kinds))
    tol = TOLERANCE.get(kinds, 1e-9)
    worst_depth = worst_normal = 0.0
    seen = 0
    for trial in range(200):
        table = random_table(list(kinds), rng)
        x, R = random_pose(rng)
        x = placed(table, x, R, rng.uniform(-0.003, MARGIN))
        for a, b in ((0, 1), (1, 0)):
            p, n, d, f, count = compiled(table, a, b, x, R)
            rp, rn, rd, _ = reference(table, a, b, x, R)
            assert count == len(rd), (trial, a, b, d, rd)
            if count == 0:
                continue
            seen += 1
            k, rk = int(np.argmax(d)), int(np.argmax(rd))
            worst_depth = max(worst_depth, abs(d[k] - rd[rk]))
            worst_normal = max(worst_normal, 1.0 - n[k] @ rn[rk])
            assert d[k] == pytest.approx(rd[rk], abs=tol) and n[k] @ rn[rk] == pytest.approx(1.0, abs=tol)
            assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and len(set(f.tolist())) == count
            if kinds != (BOX, BOX):  # (the Python phase keeps the points of a box-box pair in another order)
                assert np.abs(d - rd).max() < tol and np.abs(p - rp).max() < 10 * tol
    assert seen > 300
    print(f"{kinds}: max |depth - oracle| {worst_depth:.1e} m, max 1 - n.n_oracle {worst_normal:.1e}")


@pytest.mark.parametrize("kinds", [(BOX, BOX), (BOX, PLANE), (CAPSULE, BOX), (CYLINDER, PLANE), (CAPSULE, CAPSULE)])
def test_features_are_stable_under_a_small_move(kinds):
    """A pose moved by 1e-7 m and turned by 1e-6 rad keeps its features (the same points, warm-started)."""
    rng = np.random.default_rng(3)
    same = total = 0
    for _ in range(200):
        table = random_table(list(kinds), rng)
        x, R = random_pose(rng)
        x = placed(table, x, R, rng.uniform(-0.003, 0.0))
        f0 = compiled(table, 0, 1, x, R)[3]
        turn = quat_to_matrix(np.array([1.0, *rng.normal(0.0, 0.5e-6, 3)]))
        R2 = R.copy()
        R2[0] = turn @ R[0]
        f1 = compiled(table, 0, 1, x + rng.normal(0.0, 1e-7, x.shape), R2)[3]
        total += 1
        same += sorted(f0.tolist()) == sorted(f1.tolist())
    print(f"{kinds}: {same}/{total} kept their features")
    assert same >= 0.97 * total


def test_capacity_is_never_exceeded():
    """A box 1 mm into a floor has four corners down: with room for two, two are written and 4 returned."""
    table, x, R = resting(BOX, (0.2, 0.1, 0.3), 0.1 - 1e-3)
    for first, capacity in ((0, 2), (3, 4), (5, 5)):
        _, _, d, _f, count = compiled(table, 1, 0, x, R, capacity=capacity, first=first)
        assert count == 4 and len(d) == max(0, min(4, capacity - first))


def resting(kind, size, height, rotation=None):
    """Body 1 of `kind` (box: half edges size; capsule, cylinder: radius, half length) at height on the floor
    y = 0 (body 0), turned by rotation."""
    table = random_table([PLANE, kind], np.random.default_rng(0))
    table.normal[0] = (0.0, 1.0, 0.0)
    if kind == BOX:
        table.half[1] = size
    else:
        table.radius[1], table.half_length[1] = size[0], size[1]
    x = np.array([[0.0, 0.0, 0.0], [0.0, height, 0.0]])
    R = np.stack((np.eye(3), np.eye(3) if rotation is None else rotation))
    return table, x, R


def test_sphere_on_a_plane():
    table = random_table([PLANE, SPHERE], np.random.default_rng(0))
    table.normal[0], table.radius[1] = (0.0, 1.0, 0.0), 0.1
    x, R = np.array([[0.0, 0.0, 0.0], [0.3, 0.099, -0.2]]), np.tile(np.eye(3), (2, 1, 1))
    p, n, d, _f, count = compiled(table, 1, 0, x, R)
    assert count == 1 and d[0] == pytest.approx(1e-3, abs=1e-15) and np.allclose(n[0], (0, 1, 0))
    assert np.allclose(p[0], (0.3, -0.0005, -0.2), atol=1e-15)
    p, n, d, _f, count = compiled(table, 0, 1, x, R)  # the other order: the normal from the sphere to the plane
    assert count == 1 and np.allclose(n[0], (0, -1, 0))


def boxes(half_a, half_b, xa, rotation=None):
    table = random_table([BOX, BOX], np.random.default_rng(0))
    table.half[0], table.half[1] = half_a, half_b
    return table, np.array([xa, (0.0, 0.0, 0.0)]), np.stack((np.eye(3) if rotation is None else rotation, np.eye(3)))


def test_box_resting_off_centre_touches_at_the_overlap_rectangle():
    table, x, R = boxes((0.2, 0.1, 0.2), (0.2, 0.1, 0.2), (0.1, 0.2 - 1e-4, 0.05))
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    assert count == 4 and np.allclose(d, 1e-4, atol=1e-12) and np.allclose(n, (0, 1, 0))
    corners = {(round(px, 9), round(pz, 9)) for px, _, pz in p}
    assert corners == {(-0.1, -0.15), (-0.1, 0.2), (0.2, -0.15), (0.2, 0.2)}
    assert np.allclose(p[:, 1], 0.1 - 0.5e-4)
    assert count == len(reference(table, 0, 1, x, R)[2])


def test_box_turned_45_degrees_on_a_box_keeps_four_of_eight():
    turn = quat_to_matrix(np.array([math.cos(math.pi / 8), 0.0, math.sin(math.pi / 8), 0.0]))
    table, x, R = boxes((0.2, 0.1, 0.2), (0.2, 0.1, 0.2), (0.0, 0.2 - 1e-4, 0.0), turn)
    p, n, d, f, count = compiled(table, 0, 1, x, R)
    assert count == 4 and np.allclose(d, 1e-4, atol=1e-12) and np.allclose(n, (0, 1, 0)) and len(set(f)) == 4
    # the octagon's vertices lie 0.2 m from the centre's axis on b's edges or a's: its four kept span it
    radius = np.hypot(p[:, 0], p[:, 2])
    assert np.all((radius > 0.2 - 1e-9) & (radius < 0.2 * math.sqrt(2) + 1e-9))
    area = 0.5 * abs(np.cross(p[2] - p[0], p[3] - p[1])[1])
    # the overlap is an octagon of 0.4^2 (2 sqrt 2 - 2) = 0.133 m^2: the four kept span most of it
    assert area > 0.08
    assert count == len(reference(table, 0, 1, x, R)[2])


def test_box_sliding_off_an_edge_touches_along_the_edge():
    """A box turned 10 degrees about z, its bottom face resting on b's top edge x = 0.2: two points, x = 0.2."""
    turn = quat_to_matrix(np.array([math.cos(math.radians(5)), 0.0, 0.0, -math.sin(math.radians(5))]))
    table, x, R = boxes((0.2, 0.1, 0.1), (0.2, 0.1, 0.3), (0.3, 0.0, 0.0), turn)
    up, edge, bottom = turn[:, 1], np.array([0.2, 0.1, 0.0]), turn @ np.array([0.0, -0.1, 0.0])
    # the edge 1e-4 above a's bottom face: (edge - x_a - bottom) . up = 1e-4, x_a = (0.3, h, 0)
    x[0, 1] = ((edge - bottom) @ up - 1e-4 - 0.3 * up[0]) / up[1]
    p, n, d, _f, count = compiled(table, 0, 1, x, R)
    rd = reference(table, 0, 1, x, R)[2]
    assert count == 2 == len(rd) and np.allclose(p[:, 0], 0.2, atol=1e-4) and np.allclose(d, rd.max(), atol=1e-12)
    assert np.allclose(n, turn[:, 1])


def test_resting_round_shapes():
    """A capsule lying on the floor: two points; a cylinder standing on a cap: four (>= 3); lying: two."""
    upright = quat_to_matrix(np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]))  # z -> -y
    cases = [(CAPSULE, (0.05, 0.2), np.eye(3), 0.05, 2), (CYLINDER, (0.1, 0.2), upright, 0.2, 4),
             (CYLINDER, (0.1, 0.2), np.eye(3), 0.1, 2)]
    for kind, size, rotation, height, expected in cases:
        table, x, R = resting(kind, size, height - 1e-5, rotation)
        p, n, d, _f, count = compiled(table, 1, 0, x, R, margin=1e-4)
        assert count == expected and np.allclose(d, 1e-5) and np.allclose(n, (0, 1, 0))
        assert np.allclose(p[:, 1], -0.5e-5, atol=1e-15)  # midway: half the depth under the floor


# the pairs the compiled phase handles beyond the Python one (which asks python-fcl for them)
BEYOND_PYTHON = {(CYLINDER, BOX), (BOX, CYLINDER), (CYLINDER, CYLINDER), (CYLINDER, CAPSULE), (CAPSULE, CYLINDER)}


def test_which_pairs_are_closed_forms():
    """The Python phase's closed forms (but mesh-plane), and cylinder against box, cylinder or capsule, which it
    leaves to fcl: every pair of sphere, box, capsule, cylinder and plane but plane-plane."""
    kinds = (SPHERE, BOX, CAPSULE, CYLINDER, PLANE, MESH)
    for ka in kinds:
        for kb in kinds:
            python = oracle.closed_form(ka, kb) is not None and MESH not in (ka, kb)
            assert closed_form(ka, kb) == (python or (ka, kb) in BEYOND_PYTHON), (ka, kb)
            if (ka, kb) in BEYOND_PYTHON:
                assert not python
            assert closed_form(ka, kb) == (MESH not in (ka, kb) and (ka, kb) != (PLANE, PLANE)), (ka, kb)
    table, x, R = resting(BOX, (0.1, 0.1, 0.1), 0.0)
    table.kind[1] = PLANE
    assert compiled(table, 0, 1, x, R)[4] == 0


def test_bounds_agree_with_the_broad_phase():
    rng = np.random.default_rng(5)
    table = random_table([SPHERE, BOX, CAPSULE, CYLINDER, PLANE], rng)
    x, R = random_pose(rng, 5)
    y, Rp = state_of(x, R)
    box = np.zeros((6, 6))
    for i in range(5):
        _bounds(shapes_of(table), i, y, Rp, box)
    lo, hi = boxes_of(table, np.arange(4), x[:4], R[:4], 0.0)
    assert np.allclose(box[:4, :3], lo, atol=1e-15) and np.allclose(box[:4, 3:], hi, atol=1e-15)
    assert np.all(box[4, :3] == -np.inf) and np.all(box[4, 3:] == np.inf)


def test_a_scene_through_the_public_api():
    """The Shapes the model builds from a scene, against the table the plan holds."""
    from isaac.api import Simulation

    sim = Simulation.from_text("""scene s {
      body floor plane { }
      body crate box { size (0.4, 0.2, 0.6)  mass 1 kg  at (0, 0.0995, 0)  orient (0, 30, 0) }
      body ball sphere { radius 0.1 m  mass 1 kg  at (0, 0.2995, 0) }
    }""")
    table, shapes = sim.plan.collisions.table, sim.compiled.model.shapes
    n = len(table.kind)
    x, R = np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1))
    x[1], x[2] = (0, 0.0995, 0), (0, 0.2995, 0)
    R[1] = quat_to_matrix(np.array([math.cos(math.radians(15)), 0.0, math.sin(math.radians(15)), 0.0]))
    y, Rp = state_of(x, R)
    for a, b in ((1, 0), (2, 1)):
        point, normal, depth = np.zeros((8, 3)), np.zeros((8, 3)), np.zeros(8)
        count = _entry(shapes, a, b, y, Rp, MARGIN, point, normal, depth, np.zeros(8, np.int64), 0, 8,
                       np.zeros((16, 4)))
        rd = reference(table, a, b, x, R)[2]
        assert count == len(rd) and np.allclose(np.sort(depth[:count]), np.sort(rd), atol=1e-12)


# rotations that turn the box's y (identity), z or x face down
FACE_DOWN = [np.eye(3), np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]), np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])]


def test_stacked_boxes_agree_and_keep_their_features():
    """300 boxes resting on boxes (random yaw up to 90 degrees, tilt up to 0.5 degree, off-centre, 1 mm deep to 1
    mm apart): the count and the deepest depth of the Python phase, four points when flat, the same features after
    a 1e-7 m, 1e-6 rad move (but where the deepest of more than four clipped points changes)."""
    rng = np.random.default_rng(9)
    counts, same, worst = {}, 0, 0.0
    for _ in range(300):
        table, x, R = boxes(rng.uniform(0.05, 0.3, 3), rng.uniform(0.05, 0.3, 3), (0.0, 0.0, 0.0))
        yaw, tilt = rng.uniform(0, math.pi / 2), rng.normal(0.0, math.radians(0.25), 2)
        R[0] = quat_to_matrix(np.array([1.0, tilt[0], 0.0, tilt[1]]) / math.hypot(1.0, *tilt)) @ quat_to_matrix(
            np.array([math.cos(yaw / 2), 0.0, math.sin(yaw / 2), 0.0]))
        R[0] = R[0] @ FACE_DOWN[rng.integers(3)]  # which of a's faces rests on b
        x[0] = (rng.uniform(-0.15, 0.15), 1.0, rng.uniform(-0.15, 0.15))
        x = placed(table, x, R, rng.uniform(-1e-3, 1e-3))
        _p, _n, d, f, count = compiled(table, 0, 1, x, R)
        _rp, _rn, rd, _ = reference(table, 0, 1, x, R)
        assert count == len(rd)
        counts[count] = counts.get(count, 0) + 1
        if count:
            worst = max(worst, abs(d.max() - rd.max()))
            assert d.max() == pytest.approx(rd.max(), abs=1e-9)
        R2 = R.copy()
        R2[0] = quat_to_matrix(np.array([1.0, *rng.normal(0.0, 0.5e-6, 3)])) @ R[0]
        f1 = compiled(table, 0, 1, x + rng.normal(0.0, 1e-7, x.shape), R2)[3]
        same += sorted(f.tolist()) == sorted(f1.tolist())
    print(f"stacked boxes: counts {counts}, max |depth - oracle| {worst:.1e} m, {same}/300 kept their features")
    assert counts.get(4, 0) > 150 and same >= 0.9 * 300


def test_a_box_resting_askew_on_a_box_touches_at_several_points_no_deeper_than_they_overlap():
    # two 10 x 8 x 12 cm boxes as a column of them dropped onto one another left them (one turned 53 degrees about
    # the vertical and tipped 1.2 degrees), 1 mm into each other: the crossed edges of the two faces separate the
    # boxes a little more than the faces do (1.50 mm against 1.55 at 1.5 mm deep), and their one point let such a
    # column rock onto corners that no contact held (it sank 13.6 mm into itself). Lying almost flat in the face,
    # they take the face's points, each no deeper than the boxes overlap (the separating-axis overlap, computed
    # independently)
    from tests.runtime.test_collide import box_overlap

    q = np.array([0.895963, 0.004179, -0.444007, -0.009566])
    turn = quat_to_matrix(q / np.linalg.norm(q))
    table, x, R = boxes((0.05, 0.04, 0.06), (0.05, 0.04, 0.06), (0.010574, 0.079544, 0.00619), turn)
    x = placed(table, x, R, -1e-3)
    overlap = box_overlap(table, x, R)
    assert overlap == pytest.approx(1e-3, abs=1e-9)
    for p, n, d, f, *_ in (compiled(table, 0, 1, x, R), reference(table, 0, 1, x, R)):
        assert len(d) == 4, d  # (the crossed edges' one point before)
        assert d.max() == pytest.approx(overlap, abs=1e-9)
        assert abs(n[0] @ (0.0, 1.0, 0.0)) > math.cos(math.radians(1.5))
