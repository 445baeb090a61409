"""runtime/collide: the plan (exclusion, no stage when nothing can touch), the broad phase, the closed-form narrow
phase against python-fcl and brute force, the contact LCP, impulses (the textbook formula, joints respected),
meshes (OBJ/STL, fcl only when needed)."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_scene, load_text
from isaac_runtime.collide import lcp
from isaac_runtime.collide.meshes import load_shape, read_mesh
from isaac_runtime.collide.narrow import closed_form, needs_fcl
from isaac_runtime.collide.shapes import segment
from isaac_runtime.collide.pairs import BroadPhase
from isaac_runtime.collide.response import Bodies, Contacts, Joints, Response
from isaac_runtime.collide.shapes import BOX, CAPSULE, CYLINDER, PLANE, SPHERE, ShapeTable, bounding_boxes
from isaac_runtime.plan import compile_plan
from isaac_runtime.core.rotation import quat_to_matrix
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"
ASSETS = SCENES / "assets"


def plan_of(text: str):
    return compile_plan(load_text(text).scene)


# ---- the plan ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["pendulum", "windmill", "chain", "transition"])
def test_scenes_where_nothing_can_touch_have_no_collision_stage(name):
    plan = compile_plan(load_scene(SCENES / f"{name}.isaac").scene)
    assert plan.collisions is None and plan.stages()["collisions"] is False
    assert "off collisions" in plan.describe()


def test_exclusion_reasons_are_counted_once():
    plan = plan_of("""scene ex {
      body floor plane { }
      body wall static box { size (1, 1, 1)  at (3, 0, 0) }
      body a sphere { radius 0.1 m  mass 1 kg  at (0, 1, 0) }
      body b sphere { radius 0.1 m  mass 1 kg  at (0, 2, 0) }
      body c sphere { radius 0.1 m  mass 1 kg  at (0, 3, 0) }
      body ghost sphere { radius 0.1 m  mass 1 kg  at (0, 4, 0)  collide off }
      constraint link point(a @ (0, 0.5, 0), b @ (0, -0.5, 0))
      exclude b, c
    }""")
    c = plan.collisions
    # 5 collidable bodies: 10 pairs; floor-wall neither dynamic, a-b joined, b-c excluded
    assert c.pairs == 10 - 1 - 1 - 1
    assert c.reasons == {"joined by a constraint": 1, "by `exclude`": 1, "neither dynamic": 1}
    assert "7 pairs can touch" in c.describe() and len(c.fcl_bodies) == 0


def test_a_joined_pair_alone_gives_no_stage():
    plan = plan_of("""scene j {
      body a box { size (1, 1, 1)  mass 1 kg }
      body b box { size (1, 1, 1)  mass 1 kg  at (1, 0, 0) }
      constraint hinge point(a @ (0.5, 0, 0), b @ (-0.5, 0, 0))
    }""")
    assert plan.collisions is None


def test_a_pair_joined_later_collides_until_the_joint_is_on():
    # a meets b at 0.3 s (centres 0.2 m apart); from 1 s a joint pulls their centres to 0.1 m, through each
    # other, which only an exclusion that starts with the joint allows
    plan = plan_of("""scene w {
      time 0 s .. 3 s
      gravity (0, 0, 0) m/s2
      body a sphere { radius 0.1 m  mass 1 kg  at (0, 0.5, 0)  velocity (0, -1, 0) m/s }
      body b sphere { radius 0.1 m  mass 1 kg  at (0, 0, 0) }
      constraint tie point(a @ (0, -0.05, 0) m, b @ (0, 0.05, 0) m) from 1 s { stabilize 2 Hz  damping 1 }
    }""")
    assert plan.collisions is not None and plan.collisions.pairs == 1
    sim = Simulation(plan)
    sim.advance_to(3.0)
    impacts = [e for e in sim.events if e["kind"] == "impact"]
    assert len(impacts) == 1 and abs(impacts[0]["time"] - 0.3) < 1e-6
    assert abs(np.linalg.norm(sim.state.x[0] - sim.state.x[1]) - 0.1) < 1e-6


def test_pendulum_run_imports_neither_collide_nor_fcl(tmp_path):
    code = ("import sys; from isaac.cli import main; rc = main(['run', sys.argv[1], '--out', sys.argv[2], "
            "'--until', '0.05']); assert 'fcl' not in sys.modules and 'isaac_runtime.collide' not in sys.modules; "
            "sys.exit(rc)")
    done = subprocess.run([sys.executable, "-c", code, str(SCENES / "pendulum.isaac"), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_contact_scenes_never_import_scipy_linalg(tmp_path):
    # scipy.linalg costs 0.1 s to import: the impulse solves use numpy's own LAPACK, so neither a box that slides
    # from rest nor a ball that bounces (an impact, and its solve) imports it
    code = ("import sys; from isaac.cli import main; rc = main(['run', sys.argv[1], '--out', sys.argv[2], "
            "'--until', sys.argv[3]]); print('scipy.linalg' in sys.modules); sys.exit(rc)")
    seen = {}
    for scene, until in (("slide", "1.5"), ("bounce", "1.0")):
        done = subprocess.run([sys.executable, "-c", code, str(SCENES / f"{scene}.isaac"), str(tmp_path / scene),
                               until], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        seen[scene] = done.stdout.strip().splitlines()[-1]
    assert seen == {"slide": "False", "bounce": "False"}


def test_isaac_plan_says_a_scene_whose_pairs_are_all_excluded_has_no_collision_stage():
    # the windmill's two boxes collide, but its blade is joined to its tower: the stage is off, fcl never loaded
    code = ("import sys; from isaac.cli import main; rc = main(['plan', sys.argv[1]]); "
            "assert 'fcl' not in sys.modules; sys.exit(rc)")
    done = subprocess.run([sys.executable, "-c", code, str(SCENES / "windmill.isaac")], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    assert "off collisions" in done.stdout and "collisions:" not in done.stdout


def test_fcl_is_imported_only_for_pairs_without_a_closed_form():
    code = """
import sys
from isaac_lang.load import load_text
from isaac_runtime.plan import compile_plan
from isaac.api import Simulation
mesh = 'body rock mesh { file "%s"  mass 1 kg  inertia (1e-3, 1e-3, 1e-3) kg*m2  at (0, 0.2, 0) }'
on_plane = 'scene a { body floor plane { } ' + mesh + ' }'
Simulation(compile_plan(load_text(on_plane).scene)).advance_to(0.01)
assert 'fcl' not in sys.modules, 'a mesh on a plane is a closed form'
on_box = 'scene b { body floor static box { size (1, 0.1, 1)  at (0, -0.05, 0) } ' + mesh + ' }'
Simulation(compile_plan(load_text(on_box).scene)).advance_to(0.01)
assert 'fcl' in sys.modules
""" % (ASSETS / "icosahedron.obj").as_posix()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_which_pairs_need_fcl():
    assert not any(needs_fcl(a, b) for a in (SPHERE, BOX, CAPSULE, CYLINDER) for b in (SPHERE, PLANE))
    assert not needs_fcl(BOX, BOX) and not needs_fcl(CAPSULE, BOX) and not needs_fcl(CAPSULE, CAPSULE)
    assert needs_fcl(CYLINDER, BOX) and needs_fcl(CYLINDER, CYLINDER) and needs_fcl(CYLINDER, CAPSULE)


# ---- broad phase ---------------------------------------------------------------------------------------------

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
            t.normal[i], t.half[i] = (0.0, 1.0, 0.0), np.inf
        t.thin[i] = np.min(t.half[i])
    return t


def random_poses(n, rng, spread):
    x = rng.uniform(-spread, spread, (n, 3))
    q = rng.normal(size=(n, 4))
    return x, quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))


@pytest.mark.parametrize("n,spread", [(20, 0.5), (400, 3.0)])  # every pair directly; the grid
def test_broad_phase_finds_exactly_the_overlapping_boxes(n, spread):
    rng = np.random.default_rng(3)
    kinds = rng.choice([SPHERE, BOX, CAPSULE, CYLINDER], n)
    kinds[:2] = PLANE
    table = random_table(kinds, rng)
    x, R = random_poses(n, rng, spread)
    x[:2] = 0.0
    R[:2] = np.eye(3)
    dynamic = rng.random(n) < 0.7
    dynamic[:2] = False
    excluded = np.array(sorted({int(a) * n + int(b) for a, b in np.sort(rng.integers(2, n, (50, 2)), axis=1)
                                if a != b}), np.int64)
    broad = BroadPhase(table, np.arange(n), dynamic, excluded, 1e-4)
    found = {tuple(p) for p in broad.pairs((x, R)).tolist()}
    lo, hi = bounding_boxes(table, np.arange(2, n), x, R, 1e-4)
    expected = set()
    for i in range(2, n):
        for j in range(i + 1, n):
            if np.all(lo[i - 2] <= hi[j - 2]) and np.all(lo[j - 2] <= hi[i - 2]):
                expected.add((i, j))
        for plane in (0, 1):
            if lo[i - 2][1] <= 1e-4:
                expected.add((plane, i))
    expected = {p for p in expected if (dynamic[p[0]] or dynamic[p[1]]) and p[0] * n + p[1] not in set(excluded)}
    assert found == expected and len(found) > n // 4


def random_bodies(n: int, planes: int, rng) -> tuple:
    """(kinds, table) of n random finite bodies, the first `planes` of them planes."""
    kinds = rng.choice([SPHERE, BOX, CAPSULE, CYLINDER], n)
    kinds[:planes] = PLANE
    return kinds, random_table(kinds, rng)


@pytest.mark.parametrize("planes", [0, 1])
def test_broad_phase_early_out_never_hides_a_pair(planes):
    """anything_near (cubes about the dynamic bodies, kept boxes of the still ones) says False only when the
    full broad phase finds no pair, over random scenes of dynamic, still and kinematic bodies moving a
    random step; and it does say False for most sparse scenes."""
    rng = np.random.default_rng(11)
    quiet = 0
    for trial in range(300):
        n = 8
        kinds, table = random_bodies(n, planes, rng)
        table.centre[kinds == BOX] = rng.normal(size=(int(np.sum(kinds == BOX)), 3)) * 0.05  # off-centre boxes
        dynamic = rng.random(n) < 0.4
        dynamic[:planes] = False
        still = ~dynamic & (rng.random(n) < 0.7)
        still[:planes] = True
        spread = rng.choice([0.8, 2.0, 4.0])
        x0, R0 = random_poses(n, rng, spread)
        x1, R1 = x0 + rng.normal(size=(n, 3)) * 0.1 * ~still[:, None], R0.copy()
        R1[~still] = random_poses(n, rng, 1.0)[1][~still]
        x0[:planes], x1[:planes] = (0.0, -spread, 0.0), (0.0, -spread, 0.0)
        R0[:planes] = R1[:planes] = np.eye(3)
        broad = BroadPhase(table, np.arange(n), dynamic, np.zeros(0, np.int64), 1e-4, still=still)
        near = broad.anything_near(x1, lambda index: (R1[index], R0[index]), x0)
        found = broad.pairs((x1, R1), (x0, R0))
        assert near or not len(found), (trial, found)
        quiet += not near
    assert quiet > 30


@pytest.mark.parametrize("planes", [0, 1])
def test_broad_phase_room_never_hides_a_pair(planes):
    """Once the early-out finds nothing near, it measures how far the dynamic bodies may move before it could
    find something (the room) and then only checks that they stay inside it. Over random scenes of dynamic and
    still bodies (and a tilted floor) moved by random steps of about the room's size, on both sides of it, or all
    toward one another to the edge of the room: every time the room says nothing is near, the full test
    (`_cubes_near`) and the full broad phase (`pairs`) say so too; and the room does say so for most moves."""
    rng = np.random.default_rng(5)
    trusted = 0
    for trial in range(200):
        n = 7
        kinds, table = random_bodies(n, planes, rng)
        dynamic = rng.random(n) < 0.5
        dynamic[:planes] = False
        dynamic[planes] = True
        still = ~dynamic
        spread = rng.choice([1.5, 3.0, 6.0])
        x0, R0 = random_poses(n, rng, spread)
        x0[:planes] = (0.0, -spread - 0.5, 0.0)
        R0[:planes] = quat_to_matrix(np.array([0.99, 0.1, 0.0, 0.05]) / np.linalg.norm([0.99, 0.1, 0.0, 0.05]))
        broad = BroadPhase(table, np.arange(n), dynamic, np.zeros(0, np.int64), 1e-4, still=still)
        assert broad.roomy
        x, R = x0.copy(), R0.copy()
        for step in range(20):
            room = broad.room if np.isfinite(broad.room) and broad.room > 0 else 0.05
            x_before, R_before = x.copy(), R.copy()
            if step % 2:  # anywhere about the room's size
                x[dynamic] += rng.uniform(-1.3, 1.3, (int(dynamic.sum()), 3)) * room * rng.choice([0.3, 1.0])
            else:  # the dynamic bodies all toward one another, as far as the room lets them
                x[dynamic] += 0.999 * room * np.sign(x[dynamic].mean(axis=0) - x[dynamic])
            R[dynamic] = random_poses(n, rng, 1.0)[1][dynamic]
            rotations = lambda index, R=R, R_before=R_before: (R[index], R_before[index])
            if broad._within_room(x, x_before):
                trusted += 1
                assert not broad._cubes_near(x, rotations, x_before), (trial, step)
                assert not len(broad.pairs((x, R), (x_before, R_before))), (trial, step)
            near = broad.anything_near(x, rotations, x_before)
            assert near or not len(broad.pairs((x, R), (x_before, R_before))), (trial, step)
    assert trusted > 400


def test_broad_phase_room_is_off_when_something_else_moves():
    """A kinematic body (or a plane that is not still) changes its box without the dynamic bodies moving: then
    there is no room, and every step runs the full test."""
    rng = np.random.default_rng(2)
    table = random_table(np.array([SPHERE, BOX, BOX]), rng)
    dynamic = np.array([True, False, False])
    broad = BroadPhase(table, np.arange(3), dynamic, np.zeros(0, np.int64), 1e-4,
                       still=np.array([False, True, False]))
    assert not broad.roomy


# ---- narrow phase --------------------------------------------------------------------------------------------

def contact(kind_a, kind_b, table, x, R, margin=np.inf):
    test, swapped = closed_form(kind_a, kind_b)
    a, b = (1, 0) if swapped else (0, 1)
    return a, b, test(table, a, b, x, R, margin)


def fcl_reference(table, a, b, x, R):
    import fcl

    from isaac_runtime.collide.meshes import primitive_geometry

    oa = fcl.CollisionObject(primitive_geometry(table, a), fcl.Transform(R[a], x[a]))
    ob = fcl.CollisionObject(primitive_geometry(table, b), fcl.Transform(R[b], x[b]))
    result = fcl.CollisionResult()
    if fcl.collide(oa, ob, fcl.CollisionRequest(num_max_contacts=1, enable_contact=True), result):
        c = result.contacts[0]
        return -c.penetration_depth, -np.asarray(c.normal)
    return fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult()), None


def box_overlap(table, x, R):
    """Penetration depth of two boxes, independently: the smallest overlap of their corners' projections on the
    15 axes (face normals, edge crosses), which is exact for boxes (separating axis theorem)."""
    from isaac_runtime.collide.shapes import CORNER_SIGNS

    corners = [x[i] + (CORNER_SIGNS * table.half[i]) @ R[i].T for i in (0, 1)]
    axes = [R[0][:, i] for i in range(3)] + [R[1][:, j] for j in range(3)]
    axes += [np.cross(R[0][:, i], R[1][:, j]) for i in range(3) for j in range(3)]
    best = np.inf
    for axis in axes:
        if np.linalg.norm(axis) > 1e-6:
            pa, pb = (c @ (axis / np.linalg.norm(axis)) for c in corners)
            best = min(best, min(pa.max(), pb.max()) - max(pa.min(), pb.min()))
    return best


@pytest.mark.parametrize("kinds", [(SPHERE, SPHERE), (SPHERE, BOX), (SPHERE, CAPSULE), (SPHERE, CYLINDER),
                                   (BOX, BOX)])
def test_closed_forms_agree_with_fcl(kinds):
    """Signed distance and normal of random pairs against fcl's GJK/EPA, which is exact for spheres against
    these shapes. For two boxes EPA is only approximate (up to 1e-4 m off at 2 cm depth, its normal not
    matching its depth): the reference is the exact separating-axis overlap, fcl a loose check. Poses are
    random, pushed together until they overlap by at most 2 cm (what a simulation meets)."""
    rng = np.random.default_rng(7)
    touching = 0
    for _ in range(150):
        table = random_table(list(kinds), rng)
        x, R = random_poses(2, rng, 0.2)
        distance, normal = fcl_reference(table, 0, 1, x, R)
        while distance < -0.02:
            x[0] += 0.01 * (x[0] - x[1]) / np.linalg.norm(x[0] - x[1])
            distance, normal = fcl_reference(table, 0, 1, x, R)
        a, b, (points, normals, depths, _) = contact(*kinds, table, x, R)
        distance, normal = fcl_reference(table, a, b, x, R)
        if kinds == (BOX, BOX):
            if normal is None:  # apart: the separating-axis gap is a lower bound of the distance
                assert -depths.max() <= distance + 1e-9
                continue
            touching += 1
            assert depths.max() == pytest.approx(box_overlap(table, x, R), abs=1e-9)
            assert -depths.max() == pytest.approx(distance, abs=2e-4)
            continue
        assert -depths.max() == pytest.approx(distance, abs=1e-9)
        if normal is not None:
            touching += 1
            assert normals[np.argmax(depths)] @ normal == pytest.approx(1.0, abs=1e-9)
    assert touching > 30


def test_capsule_tests_agree_with_brute_force():
    """fcl's EPA only approximates round shapes; the closed forms are exact: r_a + r_b - |segment distance|,
    and r - min over the axis of the distance to the box."""
    rng = np.random.default_rng(11)
    u = np.linspace(0.0, 1.0, 2001)
    for _ in range(15):
        table = random_table([CAPSULE, CAPSULE, BOX], rng)
        x, R = random_poses(3, rng, 0.2)
        s0, s1 = segment(table, 0, x, R)
        t0, t1 = segment(table, 1, x, R)
        axis = s0 + u[:, None] * (s1 - s0)
        other = t0 + u[::2, None] * (t1 - t0)
        gap = np.min(np.linalg.norm(axis[::2, None] - other[None], axis=2))
        _, _, (_, _, depths, _) = contact(CAPSULE, CAPSULE, table, x, R)
        assert depths.max() == pytest.approx(table.radius[0] + table.radius[1] - gap, abs=2e-4)
        # signed distance of the axis points to the box, written out: outside |max(q, 0)|, inside max(q) < 0
        q = np.abs((axis - x[2]) @ R[2]) - table.half[2]
        box_distance = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        test, _ = closed_form(CAPSULE, BOX)
        depths = test(table, 0, 2, x, R, np.inf)[2]
        assert depths.max() == pytest.approx(table.radius[0] - box_distance.min(), abs=2e-5)


def test_resting_shapes_get_a_full_manifold():
    """1e-5 m into a floor: a box on a face and a cylinder on a cap touch at four points, a cylinder or a
    capsule lying on its side at two, a box on an edge at two."""
    rng = np.random.default_rng(0)
    table = random_table([PLANE, BOX, CYLINDER, CAPSULE], rng)
    table.half[1] = (0.2, 0.1, 0.3)
    table.radius[2], table.half_length[2] = 0.1, 0.2
    table.radius[3], table.half_length[3] = 0.05, 0.2
    upright = quat_to_matrix(np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]))  # z -> -y
    edge = quat_to_matrix(np.array([math.cos(math.pi / 8), 0.0, 0.0, math.sin(math.pi / 8)]))  # 45 deg about z
    cases = [(1, np.eye(3), 0.1, 4), (1, edge, 0.1 * math.sqrt(2) * math.cos(math.radians(45 - math.degrees(
        math.atan2(0.1, 0.2)))), 2), (2, upright, 0.2, 4), (2, np.eye(3), 0.1, 2), (3, np.eye(3), 0.05, 2)]
    for body, rotation, height, count in cases:
        x = np.zeros((4, 3))
        R = np.tile(np.eye(3), (4, 1, 1))
        R[body] = rotation
        x[body, 1] = height - 1e-5
        if body == 1 and count == 2:  # box on an edge: lift it so that its lowest corners are 1e-5 deep
            corners = (np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
                       * table.half[1]) @ rotation.T
            x[body, 1] = -corners[:, 1].min() - 1e-5
        test, swapped = closed_form(table.kind[body], PLANE)
        assert not swapped
        points, normals, depths, _ = test(table, body, 0, x, R, 1e-4)
        assert len(depths) == count, (body, count, depths)
        assert np.allclose(depths, 1e-5) and np.allclose(normals, [0, 1, 0])


# ---- the contact problem -------------------------------------------------------------------------------------

def test_lcp_solution_satisfies_signorini_and_coulomb():
    """Contact problems of random bodies pressed onto a floor and onto each other, at random points, with
    random velocities and friction: the answer meets every condition of lcp.py."""
    from isaac_runtime.collide.mass_matrix import assemble_dense
    from isaac_runtime.collide.response import contact_rows, row_velocity, tangent_basis

    rng = np.random.default_rng(5)
    for trial in range(60):
        n = int(rng.integers(1, 4))
        x = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(0.2, 0.5, n), rng.uniform(-1, 1, n)])
        x = np.vstack([x, [[0.0, 0.0, 0.0]]])  # the floor: body n, static
        inv_mass = np.append(rng.uniform(0.2, 2.0, n), 0.0)
        moments = rng.uniform(0.01, 0.2, (n, 3))
        inv_inertia = np.concatenate([np.array([np.diag(1 / m) for m in moments]), np.zeros((1, 3, 3))])
        a, b, normal, point = [], [], [], []
        for body in range(n):
            for _ in range(int(rng.integers(1, 5))):  # on the floor
                a.append(body), b.append(n), normal.append([0.0, 1.0, 0.0])
                point.append(x[body] + [rng.uniform(-0.2, 0.2), -x[body, 1], rng.uniform(-0.2, 0.2)])
            if body + 1 < n:  # against the next body
                d = x[body] - x[body + 1]
                a.append(body), b.append(body + 1), normal.append(d / np.linalg.norm(d))
                point.append(0.5 * (x[body] + x[body + 1]))
        a, b, normal, point = np.array(a), np.array(b), np.array(normal), np.array(point)
        t1, t2 = tangent_basis(normal, rng.normal(size=normal.shape))
        k = len(a)
        f = rng.random(k) < 0.7
        directions = np.concatenate([normal, np.stack([t1[f], t2[f]], axis=1).reshape(-1, 3)])
        owner = np.concatenate([np.arange(k), np.repeat(np.flatnonzero(f), 2)])
        sub = Contacts(a[owner], b[owner], point[owner], normal[owner], *(np.zeros(len(owner)) for _ in range(4)))
        J = contact_rows(sub, x, directions)
        slots = np.stack([a[owner], np.where(b[owner] == n, -1, b[owner])], axis=1)
        W = assemble_dense(J, slots, inv_mass, inv_inertia)
        v, w = rng.normal(size=(n + 1, 3)), rng.normal(size=(n + 1, 3))
        v[n] = w[n] = 0.0
        u0 = row_velocity(J, slots, v, w)
        tangent = np.full(k, -1)
        tangent[f] = k + 2 * np.arange(f.sum())
        target = np.zeros(len(u0))
        target[:k] = np.maximum(0.0, -0.5 * u0[:k])  # restitution 0.5 on the approaching ones
        mu = rng.uniform(0.0, 1.0, k)
        lam = lcp.solve(W, u0, target, mu, tangent)
        u = u0 + W @ lam
        scale = 1.0 + np.abs(u0).max()
        assert np.all(lam[:k] >= 0.0)
        assert np.all(u[:k] >= target[:k] - 1e-6 * scale)
        assert np.all(np.abs(lam[:k] * (u[:k] - target[:k])) <= 1e-6 * scale * (1 + np.abs(lam).max()))
        for c in np.flatnonzero(f):
            j = tangent[c]
            assert np.hypot(lam[j], lam[j + 1]) <= mu[c] * lam[c] * (1 + 1e-9) + 1e-12
            if np.hypot(lam[j], lam[j + 1]) < mu[c] * lam[c] * (1 - 1e-6):  # inside the cone: sticking
                assert np.hypot(u[j], u[j + 1]) <= 1e-6 * scale


def test_pgs_sweeps_agree_in_lists_and_in_arrays(monkeypatch):
    """Projected Gauss-Seidel keeps its velocities in Python lists for a few rows and in numpy arrays beyond:
    the same operations in the same order, so the same numbers to the last bit."""
    rng = np.random.default_rng(8)
    for trial in range(100):
        k = int(rng.integers(1, 6))
        tangent = np.full(k, -1)
        r = k
        for c in np.flatnonzero(rng.random(k) < 0.7):
            tangent[c], r = r, r + 2
        A = rng.normal(size=(r, r + 2))
        W, u0 = A @ A.T, rng.normal(size=r)
        target = np.zeros(r)
        target[:k] = rng.uniform(0, 1, k) * (rng.random(k) < 0.5)
        mu = rng.uniform(0.1, 1.0, k)
        start = lcp._project(np.abs(rng.normal(size=r)), mu, tangent)
        monkeypatch.setattr(lcp, "PGS_LISTS_UP_TO", 0)
        arrays = lcp._pgs(W, u0, target, mu, tangent, start, 1e-10)
        monkeypatch.setattr(lcp, "PGS_LISTS_UP_TO", r)
        lists = lcp._pgs(W, u0, target, mu, tangent, start, 1e-10)
        assert np.array_equal(arrays, lists), trial


def test_single_impact_matches_the_textbook_impulse():
    """The textbook impulse (docs/design/physics.md section 5):
    j = -(1 + e) vrel / (1/ma + 1/mb + n.((Ia^-1 (ra x n)) x ra) + n.((Ib^-1 (rb x n)) x rb))."""
    rng = np.random.default_rng(2)
    n = np.array([0.0, 1.0, 0.0])
    x = np.array([[0.1, 0.5, 0.0], [-0.2, -0.4, 0.1]])
    point = np.array([0.0, 0.0, 0.0])
    inv_mass = np.array([1 / 2.0, 1 / 3.0])
    Ia = rng.normal(size=(3, 3))
    Ib = rng.normal(size=(3, 3))
    inv_inertia = np.array([np.linalg.inv(Ia @ Ia.T + np.eye(3)), np.linalg.inv(Ib @ Ib.T + np.eye(3))])
    v = np.array([[0.0, -2.0, 0.0], [0.0, 1.0, 0.0]])
    w = rng.normal(size=(2, 3))
    e = 0.7
    ra, rb = point - x[0], point - x[1]
    vrel = n @ (v[0] + np.cross(w[0], ra) - v[1] - np.cross(w[1], rb))
    denominator = (inv_mass.sum() + n @ np.cross(inv_inertia[0] @ np.cross(ra, n), ra)
                   + n @ np.cross(inv_inertia[1] @ np.cross(rb, n), rb))
    j = -(1 + e) * vrel / denominator
    contacts = Contacts(np.array([0]), np.array([1]), point[None], n[None], np.zeros(1), np.zeros(1, int),
                        np.zeros(1), np.array([e]))
    response = Response(contacts, x, Bodies(v, w, inv_mass, inv_inertia, np.ones(2, bool)), Joints.none())
    response.impacts(resting_speed=1e-3)
    assert response.outcome.impulse[0] == pytest.approx(j, rel=1e-12)
    vrel_after = n @ (v[0] + np.cross(w[0], ra) - v[1] - np.cross(w[1], rb))
    assert vrel_after == pytest.approx(-e * vrel, rel=1e-12)


def test_an_impact_does_not_open_a_joint():
    """A ball hits a nailed box off-centre. Right after the step of the impact the nail's rows still have
    J v + ct = 0 (an impulse that ignored the nail would leave ~1 m/s there)."""
    sim = Simulation.from_text("""scene hit {
      gravity (0, 0, 0) m/s2
      material m { friction 0.4  restitution 0.8 }
      body bob box { size (0.1, 0.1, 0.1)  mass 1 kg  material m }
      body ball sphere { radius 0.05 m  mass 0.5 kg  at (-0.2, 0.03, 0.02)  velocity (3, 0.5, 0)  material m }
      constraint hang nail(bob @ (0, 0.5, 0.1), (0, 0.5, 0.1))
    }""")
    while not sim.events:
        sim.step()
        assert sim.state.t < 0.1
    impact, = sim.events
    assert impact["kind"] == "impact" and impact["impulse"] > 0.5
    s = sim.state
    active = sim.plan.constraints.epoch_at(s.t).active
    J, ct = sim.joint_rows(active, s.t)
    V = np.concatenate([s.v[0], s.w[0]])
    assert np.abs(J[:, 0] @ V + ct).max() < 1e-9
    assert np.linalg.norm(s.w[0]) > 1.0  # the box does turn about its nail
    sim.advance_to(0.2)
    assert sim.constraint_errors()[0] < 1e-6


# ---- meshes --------------------------------------------------------------------------------------------------

def test_obj_and_stl_give_the_same_mesh(tmp_path):
    vertices, faces = read_mesh(ASSETS / "cube.obj")
    assert vertices.shape == (8, 3) and faces.shape == (12, 3)  # six quads fanned into triangles
    corners = vertices[faces]
    ascii_ = ["solid cube"] + ["facet normal 0 0 0\nouter loop\n" + "".join(
        f"vertex {p[0]} {p[1]} {p[2]}\n" for p in tri) + "endloop\nendfacet" for tri in corners] + ["endsolid cube"]
    (tmp_path / "cube_ascii.stl").write_text("\n".join(ascii_))
    record = np.zeros(len(corners), np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")]))
    record["corners"] = corners
    (tmp_path / "cube_binary.stl").write_bytes(b"\0" * 80 + np.uint32(len(corners)).tobytes() + record.tobytes())
    for name in ("cube_ascii.stl", "cube_binary.stl"):
        shape = load_shape(name, 2.0, [tmp_path])
        assert shape.convex and shape.volume == pytest.approx(8 * 0.001, rel=1e-6)
        assert np.allclose(shape.half, 0.1)
    ell = load_shape("ell.obj", 1.0, [ASSETS])
    assert not ell.convex and ell.volume == pytest.approx((0.1 * 0.03 + 0.03 * 0.07) * 0.04)


def test_a_missing_mesh_says_where_it_looked():
    from isaac_runtime.collide.meshes import MeshError

    with pytest.raises(MeshError, match="looked in"):
        load_shape("nowhere.obj", 1.0, [ASSETS])
