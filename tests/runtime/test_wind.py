"""Wind: fields (falloff law, cone, sum of winds), seeded turbulence, drag (terminal velocity, projected area
against the shape's shadow, a plate turning broadside), the procedural model, and the mobile scene (still before
the first breath, moving after it, wider for a stronger breath). Every motion test runs on both solver plans.
The signals a wind's speed may read (envelope of a recording, the microphone): test_signals.py."""
from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from isaac_lang.load import load_scene, load_text
from isaac_runtime import signals
from isaac_runtime.plan import compile_plan
from isaac_runtime.core.rotation import quat_from_axis_angle, quat_rotate, quat_to_matrix
from isaac_runtime.run import RunOptions, simulate
from isaac_runtime.wind import wind_intensity, wind_speed_at
from isaac_runtime.wind import drag as D
from isaac_runtime.wind import fields as F
from isaac_runtime.wind import turbulence as T

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
PLANS = ("dynamics", "procedural")
G = 9.81


def run_text(text: str, solver: str, until: float | None = None, folder=ROOT):
    result = simulate(load_text(text, folder=folder).scene, RunOptions(solver=solver, until=until, folder=folder))
    assert result.error is None, result.error
    return result.recorder.arrays(), result


# ---- drag ---------------------------------------------------------------------------------------------------

FALL = """
scene fall {
  time 0 s .. 4 s
  frames 20 Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 5 ms }
  body ball sphere { radius 5 cm  mass 10 g  wind on }
  wind still { direction (1, 0, 0)  speed 0 m/s }
}
"""


@pytest.mark.parametrize("solver", PLANS)
def test_falling_sphere_reaches_terminal_velocity(solver):
    a, _ = run_text(FALL, solver)
    # v_t = sqrt(2 m g / (rho Cd A)), Cd 0.47 (the sphere's default), A = pi r^2
    v_t = math.sqrt(2 * 0.010 * G / (1.2 * 0.47 * math.pi * 0.05**2))
    v = -a["linear_velocity"][:, 0, 1]
    assert abs(v[-1] - v_t) < 0.01 * v_t, (v[-1], v_t)
    # and on the way: v = v_t tanh(g t / v_t)
    exact = v_t * np.tanh(G * a["time"] / v_t)
    assert np.max(np.abs(v - exact)) < 0.01 * v_t


def fall_with_forces(plan, h: float, steps: int) -> np.ndarray:
    """Velocities of the first body stepped as the procedural plan's prediction does: v += h F / m, forces once
    per step (the wind stage's own model decides F: the compiled kernels wind_relax or wind_drag)."""
    from isaac_runtime.core.data import initial_state
    from isaac_runtime.wind import kernels as K

    wind = plan.forces.wind
    wm, y = K.wind_model(wind), initial_state(plan)
    R = np.tile(np.eye(3), (plan.n + 1, 1, 1))
    weight = np.vstack((plan.forces.weight, np.zeros((1, 3))))
    out = []
    for k in range(steps):
        force, torque, air = weight.copy(), np.zeros_like(weight), np.zeros((plan.n + 1, 4))
        speeds = K.speeds_table(wind, np.array([k * h]))[0]
        if wind.model == "procedural":
            K.wind_relax(wm, y, R, speeds, k * h, h, force, torque, air)
        else:
            K.wind_drag(wm, y, R, speeds, k * h, force, torque, air)
        y[:plan.n, 7:10] += h * force[:plan.n] / plan.mass[:, None]
        y[:plan.n, 0:3] += h * y[:plan.n, 7:10]
        out.append(-y[0, 8])
    return np.array(out)


def test_procedural_drag_never_overshoots_at_a_long_step():
    from isaac_runtime.plan import PlanOptions

    # a 1 g balloon: kappa = 2 g / v_t = 9.3 /s, so kappa h = 2.3 at h = 0.25 s, past explicit drag's limit of 2
    scene = load_text(FALL.replace("mass 10 g", "mass 1 g")).scene
    v_t = math.sqrt(2 * 0.001 * G / (1.2 * 0.47 * math.pi * 0.05**2))
    procedural = compile_plan(scene, PlanOptions(solver="procedural", step=0.25))
    assert procedural.forces.wind.model == "procedural"
    procedural.forces.wind.set_step(0.25)  # stepped by hand below, longer than the scene's frame
    v = fall_with_forces(procedural, 0.25, 12)
    # the first step starts at rest (no drag yet to linearize); from then on the error shrinks without ringing
    error = v[1:] - v_t
    assert np.all(np.sign(error) == np.sign(error[0])) and np.all(np.abs(np.diff(error)) > 0)
    assert np.all(np.abs(error[1:]) < 0.2 * np.abs(error[:-1]) + 1e-12)
    assert abs(v[-1] - v_t) < 1e-6 * v_t
    # the force model, stepped the same way, rings between 0.7 and 2.9 m/s and never settles
    explicit = fall_with_forces(compile_plan(scene, PlanOptions(step=0.25)), 0.25, 12)
    assert np.ptp(explicit[-4:]) > 0.5 * v_t


def test_relaxation_factor():
    z = np.array([0.0, 1e-10, 1e-3, 1.0, 50.0])
    assert np.allclose(D._phi(z), [1.0, 1.0, (1 - math.exp(-1e-3)) / 1e-3, 1 - math.exp(-1), 1 / 50], rtol=1e-12)


PLATE = """
scene plate {
  time 0 s .. 2.5 s
  frames 50 Hz
  gravity (0, 0, 0) m/s2
  solver dynamics { integrator rk4  step 5 ms }
  body plate box { size (20 cm, 20 cm, 4 mm)  mass 50 g  orient axis_angle((0, 1, 0), 60 deg)  wind on }
  constraint pivot nail(plate @ (0, 0, 0), (0, 0, 0))
  wind blow { direction (0, 0, -1)  speed 5 m/s }
}
"""


@pytest.mark.parametrize("solver", PLANS)
def test_flat_plate_turns_to_face_the_wind(solver):
    a, _ = run_text(PLATE, solver)
    normal = quat_rotate(a["orientation"][:, 0], np.tile([0.0, 0.0, 1.0], (len(a["time"]), 1)))
    angle = np.degrees(np.arccos(np.clip(np.abs(normal[:, 2]), 0.0, 1.0)))  # between the plate's normal and the wind
    assert angle[0] == pytest.approx(60.0)
    assert angle[a["time"] >= 2.0].max() < 1.0  # broadside to the wind, and it stays
    assert angle[a["time"] <= 0.5].min() < 2.0  # it got there fast (a quarter chord of lever arm)


SHAPES = {
    "sphere": dict(type="sphere", radius=0.05),
    "box": dict(type="box", size=(0.3, 0.02, 0.1)),
    "plate": dict(type="box", size=(0.2, 0.2, 0.004)),
    "cylinder": dict(type="cylinder", radius=0.05, length=0.3),
    "disc": dict(type="cylinder", radius=0.06, length=0.002),
    "capsule": dict(type="capsule", radius=0.04, length=0.2),
}


@pytest.mark.parametrize("name", SHAPES)
def test_projected_area_is_the_shadow_of_the_shape(name):
    from isaac_ir.ir import Shape

    shape = Shape(**SHAPES[name])
    aero = D.shape_aero(shape, 1.0, np.eye(3))
    bodies = D.stack_bodies([0], [aero], [1.0], [1.0], np.eye(3)[None])
    rng = np.random.default_rng(3)
    for n in list(np.eye(3)) + list(rng.normal(size=(12, 3))):
        n = n / np.linalg.norm(n)
        fast = D.projected_area(bodies, n[None, :])[0]
        # the reference samples its rims (720 points: short by ~1e-5) and spheres (5760 points: by ~6e-4)
        tolerance = 1e-3 if shape.type in ("sphere", "capsule") else 1e-4
        assert fast == pytest.approx(D.projected_area_reference(shape, n), rel=tolerance), n


def test_drag_kernel_matches_its_reference():
    from isaac_ir.ir import Shape

    rng = np.random.default_rng(5)
    shapes = [Shape(**s) for s in SHAPES.values()]
    aeros = [D.shape_aero(s, 0.1, np.diag([1e-3, 2e-3, 3e-3])) for s in shapes]
    k = len(shapes)
    cds = rng.uniform(0.4, 1.2, k)
    bodies = D.stack_bodies(range(k), aeros, cds, np.full(k, 0.1), np.tile(np.diag([1e-3, 2e-3, 3e-3]), (k, 1, 1)))
    u, v, w = rng.normal(size=(3, k, 3)) * np.array([3.0, 1.0, 5.0])[:, None, None]
    R = quat_to_matrix(quat_from_axis_angle(rng.normal(size=(k, 3)) / 1.7, rng.uniform(0, 3, k)))
    result = D.drag(bodies, 1.2, u, v, w, R)
    for i in range(k):
        force, torque = D.drag_reference(aeros[i], cds[i], 1.2, u[i], v[i], w[i], R[i])
        assert np.allclose(result.force[i], force, rtol=1e-12, atol=1e-15)
        assert np.allclose(result.torque[i], torque, rtol=1e-12, atol=1e-15)


def test_drag_of_bodies_the_wind_cannot_turn_is_the_general_kernel_to_the_bit():
    """A sphere, or any body given an `area` and no lever arm: the kernel skips n, A(n) and the torque; the
    force is the general formula's to the last bit, the torque 0."""
    from isaac_ir.ir import Shape

    rng = np.random.default_rng(7)
    aeros = [D.shape_aero(Shape(type="sphere", radius=r), 0.05, None, area=a) for r, a in ((0.02, None), (0.03, 0.012))]
    bodies = D.stack_bodies([0, 1], aeros, [0.47, 1.2], [0.05, 0.05], np.tile(np.eye(3) * 1e-5, (2, 1, 1)))
    constants = D.drag_constants(bodies, 1.2)
    assert not (constants.shaped or constants.turning)
    general = dataclasses.replace(constants, shaped=True, turning=True)
    for _ in range(200):
        u, v, w = rng.normal(size=(3, 2, 3)) * np.array([5.0, 1.0, 3.0])[:, None, None]
        R = quat_to_matrix(quat_from_axis_angle(rng.normal(size=(2, 3)), rng.uniform(0, 3, 2)))
        fast, full = D.drag(bodies, 1.2, u, v, w, R, constants), D.drag(bodies, 1.2, u, v, w, R, general)
        assert np.array_equal(fast.force, full.force) and np.array_equal(fast.area, full.area)
        assert np.array_equal(fast.torque, full.torque) and not fast.torque.any()
        assert np.array_equal(fast.damping, full.damping)


def test_row_cross_product():
    a, b = np.random.default_rng(2).normal(size=(2, 50, 3))
    # (a x b)_i = a_{i+1} b_{i+2} - a_{i+2} b_{i+1}, component by component
    expected = np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                         a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)
    assert np.array_equal(D.cross(a, b), expected)


def test_user_area_replaces_the_shape_area():
    from isaac_ir.ir import Shape

    aero = D.shape_aero(Shape(type="box", size=(1.0, 1.0, 0.01)), 1.0, np.eye(3), area=0.25)
    bodies = D.stack_bodies([0], [aero], [1.0], [1.0], np.eye(3)[None])
    for n in np.eye(3):
        assert D.projected_area(bodies, n[None, :])[0] == 0.25


# ---- fields ---------------------------------------------------------------------------------------------------

def wind_plan(body: str, winds: str, seed: int = 0):
    text = f"scene s {{ seed {seed}  body probe sphere {{ radius 1 cm  mass 1 g  {body}  wind on }}  {winds} }}"
    return compile_plan(load_text(text).scene)


@pytest.mark.parametrize("falloff,power", [("none", 0), ("inverse", 1), ("inverse_square", 2)])
def test_source_falloff_follows_the_law(falloff, power):
    plan = wind_plan("", f"wind w {{ from (0, 0, 0)  toward (1, 0, 0)  speed 4 m/s  falloff {falloff}  distance 2 m }}")
    r = np.array([0.5, 1.0, 2.0, 3.0, 8.0])
    speed = wind_speed_at(plan.forces.wind, np.stack([r, 0 * r, 0 * r], axis=1), 0.0)
    # s(r) = s0 (r0 / r)^p
    assert np.allclose(speed, 4.0 * (2.0 / r) ** power, rtol=1e-12)
    # inside the core (r < 0.1 r0) the speed is held at its value at the core's edge
    assert wind_speed_at(plan.forces.wind, [0.05, 0, 0], 0.0) == pytest.approx(4.0 * (2.0 / 0.2) ** power)
    assert np.allclose(F.falloff_law(r, 2.0, falloff), (2.0 / r) ** power)


def test_source_blows_radially_inside_its_cone():
    plan = wind_plan("", "wind w { from (0, 0, 0)  toward (0, 0, -1)  speed 2 m/s  spread 20 deg  falloff none }")
    wind = plan.forces.wind

    def at(angle_deg):
        a = math.radians(angle_deg)
        return wind.air_velocity(np.array([[math.sin(a), 0.0, -math.cos(a)]]), 0.0)[0]

    assert np.allclose(at(15), 2.0 * np.array([math.sin(math.radians(15)), 0, -math.cos(math.radians(15))]))
    assert 0 < np.linalg.norm(at(22)) < 2.0  # the soft edge, 20..25 deg
    assert np.linalg.norm(at(26)) == 0.0 and np.linalg.norm(at(120)) == 0.0


def test_winds_add_up():
    both = wind_plan("", "wind a { direction (1, 0, 0)  speed 2 m/s }  wind b { direction (0, 0, 1)  speed 3 m/s }")
    assert np.allclose(both.forces.wind.air_velocity([[5.0, 1.0, 2.0]], 0.0), [[2.0, 0.0, 3.0]])
    assert wind_speed_at(both.forces.wind, [0, 0, 0], 0.0, name="b") == pytest.approx(3.0)
    assert wind_speed_at(both.forces.wind, [0, 0, 0], 0.0, velocity=[2.0, 0.0, 3.0]) == pytest.approx(0.0)
    assert wind_speed_at(None, [[0, 0, 0], [1, 1, 1]], 0.0).tolist() == [0.0, 0.0]


def test_speed_follows_time_and_the_signals():
    plan = wind_plan("", "wind a { direction (1, 0, 0)  speed 2 m/s * (1 + sin(t / 1 s)) * gust(1 s) }")
    wind = plan.forces.wind
    speeds = [wind_intensity(wind, "a", t) for t in np.linspace(0, 5, 11)]
    assert len(set(np.round(speeds, 9))) > 5 and min(speeds) >= 0.0
    again = wind_plan("", "wind a { direction (1, 0, 0)  speed 2 m/s * (1 + sin(t / 1 s)) * gust(1 s) }")
    assert speeds == [wind_intensity(again.forces.wind, "a", t) for t in np.linspace(0, 5, 11)]


SPEEDS = [
    "5 m/s + 2 m/s * sin(2 * pi * t / 7 s)",
    "2 m/s * (1 + sin(t / 1 s)) * gust(1 s)",
    "3 m/s * noise(0.5 s, seed = 2) - 1 m/s",
    "max(0 m/s, 4 m/s - t * 1 m/s2) / 2 + abs(cos(t / 1 s)) * 1 m/s",
    "1 m/s * (t / 1 s) ^ 2 - -(smoothstep(0, 1, t / 1 s)) * 1 m/s",
    "clamp(t / 1 s, 0.2, 0.8) * 1 m/s + lerp(1, 3, 0.25) * 1 m/s + step(1, t / 1 s) * 1 m/s",
]


@pytest.mark.parametrize("speed", SPEEDS)
def test_compiled_speed_is_the_evaluator_to_the_bit(speed):
    from isaac_ir import expr as E

    from isaac_runtime.wind.speed import SpeedOfTime, compile_scalar

    fields = wind_plan("", f"wind a {{ direction (1, 0, 0)  speed {speed} }}").forces.wind.fields
    node, functions = fields.speed[0], fields.functions[0]
    compiled, memo = compile_scalar(node, functions), SpeedOfTime(node, functions)
    for t in np.linspace(-1.0, 6.0, 57):
        expected = float(E.evaluate(node, {"t": float(t)}, functions))
        assert float(compiled(float(t))) == expected and memo(float(t)) == expected == memo(float(t))
        assert fields.speed_at(0, float(t)) == expected


def test_keyframed_speed_falls_back_to_the_evaluator():
    from isaac_ir import expr as E

    from isaac_runtime.wind.speed import compile_scalar

    node = E.Op("mul", (E.Keys("linear", (0.0, 1.0, 2.0), (1.0, 3.0, 2.0)), E.Const(2.0)))
    assert [compile_scalar(node)(t) for t in (0.0, 0.5, 1.5, 3.0)] == [2.0, 4.0, 5.0, 4.0]


# ---- turbulence -----------------------------------------------------------------------------------------------

def test_fractal_noise_is_seeded_and_unit_rms():
    t = np.linspace(0.0, 4000.0, 400_001)
    a = T.fbm(t, 11)
    assert np.array_equal(a, T.fbm(t, 11))  # the same seed, the same noise
    assert np.corrcoef(a, T.fbm(t, 12))[0, 1] < 0.05  # another seed, another noise
    assert abs(np.sqrt(np.mean(a**2)) - 1.0) < 0.05 and abs(np.mean(a)) < 0.05


def test_gusts_in_space_and_time():
    field = T.GustField(seed=4, time_scale=0.5)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(5, 3))
    for t in (0.0, 0.37, 12.5):
        fast = field(x, t)
        for i in range(len(x)):
            assert np.allclose(fast[i], T.gust_reference(field, x[i], t), rtol=1e-12, atol=1e-14)
    # nearby points share a gust; points far apart (>> GUST_SPEED * T = 1 m) do not
    times = np.linspace(0, 200, 4001)
    here = np.array([field(np.zeros((1, 3)), t)[0, 0] for t in times])
    near = np.array([field(np.array([[0.05, 0.0, 0.0]]), t)[0, 0] for t in times])
    far = np.array([field(np.array([[30.0, 0.0, 0.0]]), t)[0, 0] for t in times])
    assert np.corrcoef(here, near)[0, 1] > 0.9 and abs(np.corrcoef(here, far)[0, 1]) < 0.2


def test_cached_lattice_gives_the_hashed_noise_to_the_bit():
    """GustField caches the lattice values of the cells its points were in; along a run (points drifting,
    time stepping, callers of two sizes taking turns) it must give value_noise's values exactly."""
    field = T.GustField(seed=9, time_scale=0.4)
    rng = np.random.default_rng(1)
    x = rng.normal(size=(1, 3)) * 0.3
    probes = rng.normal(size=(6, 3))
    for t in np.arange(0.0, 6.0, 0.0025):
        x = x + rng.normal(size=(1, 3)) * 2e-3
        for points in (x, probes):
            phase = t / field.time_scale + np.einsum("coj,ij->coi", field.k, points) / field.length
            noise = T.value_noise(field.frequency * phase + field.offset, field.salt)
            assert np.array_equal(field(points, t), np.sum(field.amplitude * noise, axis=1).T)


def test_gusts_at_one_point_and_at_many_are_value_noise_to_the_bit():
    """The flat per-call kernel (one point as floats, many as arrays) against value_noise, along walks that
    step back in time, jump far (new lattice windows) and cross negative cells."""
    field = T.GustField(seed=21, time_scale=0.3)
    rng = np.random.default_rng(4)
    one, crowd = rng.normal(size=(1, 3)), rng.normal(size=(40, 3)) * 3.0
    t = -2.0
    for step in range(1500):
        t += rng.choice([0.004, 0.002, 0.0, -0.006, 0.9])
        one = one + rng.normal(size=(1, 3)) * 3e-3
        crowd = crowd + rng.normal(size=(40, 3)) * 3e-3
        for points in (one, crowd):
            phase = t / field.time_scale + np.einsum("coj,ij->coi", field.k, points) / field.length
            noise = T.value_noise(field.frequency * phase + field.offset, field.salt)
            expected = np.sum(field.amplitude * noise, axis=1).T
            assert np.array_equal(field(points, t), expected)
            if len(points) == 1:
                assert field.at_one_point(points, t) == tuple(expected[0])


def test_lattice_window_is_the_lattice_to_the_bit():
    """The windows of hashed cells give lattice() at every cell an element walks to (up, down, far)."""
    salts = np.arange(5, dtype=np.uint64) * np.uint64(977)
    with np.errstate(over="ignore"):
        window = T.LatticeWindow(salts * T._GOLDEN)
    rng = np.random.default_rng(8)
    cell = np.floor(rng.normal(size=5) * 50)
    value, rise = np.empty(5), np.empty(5)
    for _ in range(2000):
        cell = cell + rng.choice([0, 1, 1, 2, -1, T.WINDOW + 3, -400], size=5)
        window.look_up(cell, value, rise)
        a = T.lattice(cell, salts)
        assert np.array_equal(value, a) and np.array_equal(rise, T.lattice(cell + 1, salts) - a)


def test_einsum_core_is_np_einsum():
    k, x = np.random.default_rng(3).normal(size=(2, 12, 3))
    assert np.array_equal(T.einsum("fj,ij->if", k, x), np.einsum("fj,ij->if", k, x))


@pytest.mark.parametrize("winds", [
    "wind a { direction (1, 0, 0.4)  speed 5 m/s + 2 m/s * sin(2 * pi * t / 7 s)  turbulence 0.6  gust 0.4 s }",
    "wind a { direction (0, 0, 1)  speed 3 m/s }",
    "wind a { direction (1, 0, 0)  speed 2 m/s  turbulence 0.3 }  "
    "wind b { from (0, 1, -2) m  toward (0, 0, 1)  speed 4 m/s  falloff inverse  distance 1 m  spread 30 deg  "
    "turbulence 0.2  gust 0.3 s }"])
def test_one_point_velocity_is_the_vectorized_one_to_the_bit(winds):
    """velocity() at one point takes the floats path; each row of a many-point call is the same number."""
    fields = wind_plan("", winds).forces.wind.fields
    rng = np.random.default_rng(6)
    x = rng.normal(size=(7, 3))
    for t in np.linspace(0.0, 3.0, 61):
        many = fields.velocity(x, t)
        for i in range(len(x)):
            assert np.array_equal(fields.velocity(x[i:i + 1], t), many[i:i + 1])
            assert fields.velocity_at_one_point(x[i:i + 1], t) == tuple(many[i])
        for w in range(len(fields.names)):
            assert np.array_equal(fields.velocity(x[:1], t, w), fields.velocity(x, t, w)[:1])


@pytest.mark.parametrize("body", ["", "area 120 cm2  drag 1.2"])
def test_one_body_force_path_is_the_general_kernel_to_the_bit(body):
    """One sphere (or a body with an `area`) in the wind, force model: apply's float path adds what the general
    path (the same plan with the float path switched off) adds, and records the same speeds."""
    winds = "wind a { direction (1, 0, 0.4)  speed 5 m/s + 2 m/s * sin(t / 1 s)  turbulence 0.6  gust 0.4 s }"
    fast, general = wind_plan(body, winds).forces.wind, wind_plan(body, winds).forces.wind
    assert fast.one_plain_body == 0
    general.one_plain_body = None
    rng = np.random.default_rng(9)
    for t in np.linspace(0.0, 2.0, 201):
        x, v, w = rng.normal(size=(3, 1, 3))
        R = quat_to_matrix(quat_from_axis_angle(rng.normal(size=(1, 3)), rng.uniform(0, 3, 1)))
        force = np.repeat(rng.normal(size=(1, 1, 3)), 2, axis=0)  # the same forces already there, twice
        torque = np.repeat(rng.normal(size=(1, 1, 3)), 2, axis=0)
        for plan, f, tq in ((fast, force[0], torque[0]), (general, force[1], torque[1])):
            plan.apply(x, v, w, R, t, f, tq)
        assert np.array_equal(force[0], force[1]) and np.array_equal(torque[0], torque[1])
        assert np.array_equal(fast.relative_speed, general.relative_speed)
        assert np.array_equal(fast.last_air_velocity, general.last_air_velocity)


def test_turbulence_is_reproducible_and_scales_with_the_wind():
    winds = "wind a { direction (1, 0, 0)  speed 2 m/s * smoothstep(0, 1, t / 1 s)  turbulence 0.3  gust 0.5 s }"
    one, two, other = wind_plan("", winds, 1), wind_plan("", winds, 1), wind_plan("", winds, 2)
    x = np.array([[0.0, 1.0, 0.0], [0.5, 1.0, 0.2]])
    u1 = one.forces.wind.air_velocity(x, 3.3)
    assert np.array_equal(u1, two.forces.wind.air_velocity(x, 3.3))
    assert not np.allclose(u1, other.forces.wind.air_velocity(x, 3.3))
    assert np.all(one.forces.wind.air_velocity(x, 0.0) == 0.0)  # no wind, no gusts
    samples = np.array([one.forces.wind.air_velocity(x[:1], t)[0] for t in np.linspace(2, 400, 8000)])
    assert samples[:, 0].mean() == pytest.approx(2.0, rel=0.05)
    assert samples.std(axis=0) == pytest.approx([0.6, 0.6, 0.6], rel=0.2)  # I |u| per component


# ---- the plan --------------------------------------------------------------------------------------------------

def test_a_scene_without_wind_has_no_wind_stage(capsys):
    from isaac.cli import main

    plan = compile_plan(load_scene(SCENES / "pendulum.isaac").scene)
    assert plan.forces.wind is None and plan.stages()["wind"] is False
    assert "wind" not in sys.modules.get("isaac_runtime.plan").__dict__  # the stage's module is not imported
    # winds, but no body in them: no stage either
    calm = load_text("scene s { body b sphere { radius 1 cm  mass 1 g }  wind w { direction (1, 0, 0) } }").scene
    assert compile_plan(calm).forces.wind is None
    assert main(["plan", str(SCENES / "pendulum.isaac")]) == 0
    assert "off wind" in capsys.readouterr().out


def test_procedural_plan_uses_the_procedural_model():
    scene = load_text(FALL).scene
    assert compile_plan(scene).forces.wind.model == "force"
    from isaac_runtime.plan import PlanOptions

    assert compile_plan(scene, PlanOptions(solver="procedural")).forces.wind.model == "procedural"


# ---- the breath and the mobile -----------------------------------------------------------------------------

def test_breath_asset_is_the_scripts_output():
    soundfile = pytest.importorskip("soundfile")
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import make_breath
    finally:
        sys.path.pop(0)
    samples, rate = soundfile.read(SCENES / "assets" / "breath.wav")
    assert rate == make_breath.RATE and samples.ndim == 1
    assert np.max(np.abs(samples - make_breath.make_breath(7))) <= 1.0 / 32768 + 1e-12  # 16-bit rounding
    envelope = signals.load_envelope(SCENES / "assets" / "breath.wav", 0.03, 0.3)
    assert envelope.at(np.linspace(0, 1.99, 200)).max() < 0.01  # silent before the first breath
    for start, length, _ in make_breath.BREATHS:
        assert envelope.at(np.linspace(start, start + length, 50)).max() > 0.2


def mobile(solver: str, until: float, breath: str | None = None):
    overrides = {"breath": breath} if breath else None
    result = simulate(load_scene(SCENES / "mobile.isaac", overrides).scene,
                      RunOptions(solver=solver, until=until, folder=SCENES))
    assert result.error is None, result.error
    a = result.recorder.arrays()
    spin = np.linalg.norm(a["angular_velocity"], axis=2).max(axis=1)  # (T,) fastest-turning body
    moved = np.linalg.norm(a["position"] - a["position"][0], axis=2).max(axis=1)  # (T,) furthest-moved body
    return a["time"], spin, moved, result


@pytest.mark.parametrize("solver", PLANS)
def test_mobile_is_still_before_the_first_breath_and_moves_after(solver):
    t, spin, moved, result = mobile(solver, 2.6)
    before = t < 1.95
    assert spin[before].max() < 1e-3 and moved[before].max() < 1e-4
    assert spin[t > 2.2].max() > 0.3 and moved[-1] > 0.02
    assert result.report["max_constraint_error"] < 1e-4


def test_mobile_swings_wider_for_a_stronger_breath():
    t, spin_weak, moved_weak, _ = mobile("procedural", 2.8, "1.5 m/s")
    _, spin_strong, moved_strong, _ = mobile("procedural", 2.8, "3 m/s")
    assert moved_strong.max() > 2.0 * moved_weak.max() > 0
    assert spin_strong.max() > 1.5 * spin_weak.max()


@pytest.mark.slow
@pytest.mark.parametrize("solver", PLANS)
def test_mobile_whole_run(solver):
    t, spin, moved, result = mobile(solver, 7.0)
    assert spin[t < 1.95].max() < 1e-3 and moved.max() > 0.2
