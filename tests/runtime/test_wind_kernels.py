"""The compiled wind stage (runtime/wind/kernels.py) against the numpy one it is derived from: WindPlan.apply's
forces, torques and air (both models), WindFields.velocity, GustField and the lattice hash, and speed_at, at
random states of the shipped windy scenes and of hand-made ones (every wind kind, falloff, cone, gusts, signal,
every shape, bodies with an `area`). Relative errors <= 1e-12 (in practice most numbers agree to the last bit; an
ulp of arccos, of a dot product or of expm1 is the difference, amplified only at a cone's rim: assert_air_close)."""
from __future__ import annotations

import numpy as np
import pytest

from isaac_lang.load import load_scene, load_text
from isaac_runtime import signals
from isaac_runtime.plan import PlanOptions, compile_plan
from isaac_runtime.core.rotation import quat_to_matrix
from isaac_runtime.wind import kernels as K
from isaac_runtime.wind import turbulence as T
from isaac_runtime.wind.fields import compile_fields

from .test_wind import SCENES

RTOL = 1e-12
MODELS = {"force": "dynamics", "procedural": "procedural"}

# a static body first (its row is not the first body in the wind), every shape, bodies given an `area`, and a
# body out of the wind (its rows must stay as they were)
BODIES = {
    "shapes": """
      body post static box { size (10, 10, 10) cm  at (0, 0, 0)  wind on }
      body ball sphere { radius 4 cm  mass 20 g  at (0, 1, 0)  wind on }
      body brick box { size (20, 10, 4) cm  mass 80 g  at (0.4, 1.1, 0.1)  orient (10, 20, 30)  wind on }
      body can cylinder { radius 3 cm  length 15 cm  mass 50 g  at (-0.3, 0.9, 0.2)  wind on }
      body calm sphere { radius 2 cm  mass 5 g  at (1, 1, 1) }
      body pill capsule { radius 2 cm  length 10 cm  mass 30 g  at (0.2, 0.7, -0.3)  wind on }
      body rock mesh { file "assets/cube.obj"  scale 0.1  mass 40 g  inertia (1e-4, 2e-4, 3e-4) kg*m2
                       at (-0.5, 1.3, 0)  wind on }
      body kite sphere { radius 5 cm  mass 10 g  at (0.6, 0.5, 0.4)  drag 0.8  area 0.02 m2 }
      body sail box { size (30, 20, 1) cm  mass 60 g  at (-0.6, 0.6, -0.4)  area 0.03 m2 }
    """,
    # nothing the wind can turn (apply's no-torque path)
    "round": """
      body ball sphere { radius 4 cm  mass 20 g  at (0, 1, 0)  wind on }
      body calm sphere { radius 2 cm  mass 5 g  at (1, 1, 1) }
      body kite sphere { radius 5 cm  mass 10 g  at (0.6, 0.5, 0.4)  drag 0.8  area 0.02 m2 }
    """,
    # one body (apply's float path in the force model)
    "one": "body ball sphere { radius 4 cm  mass 20 g  at (0, 1, 0.3)  wind on }",
}

WINDS = {
    "uniform": "wind a { direction (1, 0, 0.4)  speed 3 m/s }",
    "uniform_gusts": "wind a { direction (0.3, -0.2, 1)  speed 5 m/s + 2 m/s * sin(2 * pi * t / 7 s)  "
                     "turbulence 0.6  gust 0.4 s }",
    "source_none": "wind a { from (0, 1, 2) m  toward (0, 0, -1)  speed 4 m/s  falloff none  spread 15 deg }",
    "source_inverse": "wind a { from (0.2, 1, 1.5) m  toward (-0.1, 0, -1)  speed 4 m/s  falloff inverse  "
                      "distance 2 m  spread 35 deg  turbulence 0.3  gust 0.3 s }",
    "source_inverse_square": "wind a { from (0, 2, 0) m  toward (0, -1, 0)  speed 6 m/s  falloff inverse_square  "
                             "spread 50 deg }",
    "signals": "wind a { direction (1, 0, 0)  speed 2 m/s * gust(0.5 s, depth = 0.8) + 1 m/s * noise(0.3 s, seed = 4)"
               "  turbulence 0.2 }  "
               "wind b { from (-1, 1, 0) m  toward (1, 0, 0)  speed 3 m/s * (1 + sin(t / 1 s))  falloff inverse  "
               "turbulence 0.4  gust 0.2 s }",
    "envelope": 'wind a { from (-0.3, 1.4, 2) m  toward (0.15, 0, -1)  speed envelope("assets/breath.wav", '
                "attack = 30 ms, release = 300 ms) * 3 m/s  falloff inverse  distance 2 m  spread 25 deg  "
                "turbulence 0.2  gust 0.3 s }",
    "sum": "wind a { direction (0, 0, -1)  speed 2 m/s  turbulence 0.1 }  wind b { direction (1, 0, 0)  speed 0 m/s }  "
           "wind c { from (0, 1, 2) m  toward (0, 0, -1)  speed 3 m/s  spread 30 deg  turbulence 0.5  gust 0.2 s }",
}


def plan_of(text: str, model: str):
    return compile_plan(load_text(text, folder=SCENES).scene, PlanOptions(solver=MODELS[model], folder=SCENES))


def scene_plan(bodies: str, winds: str, model: str):
    return plan_of(f"scene s {{ time 0 s .. 7 s  seed 5  {BODIES[bodies]}  {WINDS[winds]} }}", model)


def shipped_plan(name: str, model: str):
    return compile_plan(load_scene(SCENES / f"{name}.isaac").scene, PlanOptions(solver=MODELS[model], folder=SCENES))


def random_state(plan, rng, spread: float = 0.3):
    """x near the bodies' starting places, a random unit q, random v and w; (y, x, v, w, R)."""
    n = plan.n
    x = plan.x0 + rng.normal(size=(n, 3)) * spread
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    v, w = rng.normal(size=(n, 3)) * 1.5, rng.normal(size=(n, 3)) * 4.0
    return np.ascontiguousarray(np.concatenate([x, q, v, w], axis=1)), x, v, w, quat_to_matrix(q)


def assert_rows_close(got, expected, rtol=RTOL, floor=0.0):
    """Row by row, |got - expected| <= rtol max(max|expected row|, floor) (a row of zeros must be zeros)."""
    scale = np.maximum(np.max(np.abs(expected), axis=-1, keepdims=True), floor)
    error = np.abs(got - expected)
    assert np.all(error <= rtol * scale), (np.max(error / np.maximum(scale, 1e-300)), got, expected)


def assert_air_close(got, expected):
    """Air velocities: relative to each row, or to a thousandth of the strongest row where it is weaker. At a
    cone's rim c(theta) -> 0 and an ulp of theta (numpy's own arccos, and its BLAS's fused dot product e . d)
    is a relative 1e-12 of u where c ~ 1e-4."""
    assert_rows_close(got, expected, floor=1e-3 * np.max(np.abs(expected), initial=0.0))


def compare_with_apply(plan, rng, trials: int = 40, times=(0.0, 7.0)):
    """wind_drag / wind_relax / wind_apply against WindPlan.apply at random states and times."""
    wind = plan.forces.wind
    wm = K.wind_model(wind)
    inside, outside = wind.bodies.body, np.setdiff1d(np.arange(plan.n), wind.bodies.body)
    for trial in range(trials):
        y, x, v, w, R = random_state(plan, rng)
        if trial == 0 and wind.fields.is_source.any():
            # a body at a source point itself (the air goes along d there)
            w_source = int(np.flatnonzero(wind.fields.is_source)[0])
            y[inside[0], :3] = x[inside[0]] = wind.fields.origin[w_source]
        t = float(rng.uniform(*times))
        start_force, start_torque = rng.normal(size=(2, plan.n, 3)) * rng.choice([0.0, 0.01, 1.0])
        expected_force, expected_torque = start_force.copy(), start_torque.copy()
        wind.apply(x, v, w, R, t, expected_force, expected_torque)
        speeds = K.speeds_table(wind, [t])[0]
        for kernel in ("model", "apply"):
            force, torque, air = start_force.copy(), start_torque.copy(), np.full((plan.n, 4), np.nan)
            if kernel == "apply":
                K.wind_apply(wm, y, R, speeds, t, wind.step, force, torque, air)
            elif wind.model == "force":
                K.wind_drag(wm, y, R, speeds, t, force, torque, air)
            else:
                K.wind_relax(wm, y, R, speeds, t, wind.step, force, torque, air)
            assert_rows_close(force, expected_force)
            assert_rows_close(torque, expected_torque)
            assert_air_close(air[inside, :3], wind.last_air_velocity[inside])
            assert_rows_close(air[inside, 3:], wind.relative_speed[inside, None])
            assert np.isnan(air[outside]).all()
            assert np.array_equal(force[outside], start_force[outside])
            assert np.array_equal(torque[outside], start_torque[outside])


# ---- the drag, against WindPlan.apply ------------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("name", ["mobile", "chimes"])
def test_shipped_scenes_drag_is_apply(name, model):
    plan = shipped_plan(name, model)
    assert K.wind_model(plan.forces.wind).model[0] == (K.PROCEDURAL if model == "procedural" else K.FORCE)
    # the mobile's breath starts at 2 s: most of the times see it blow
    compare_with_apply(plan, np.random.default_rng(11), trials=60, times=(0.0, 7.0))


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("winds", WINDS)
@pytest.mark.parametrize("bodies", BODIES)
def test_hand_made_scenes_drag_is_apply(bodies, winds, model):
    plan = scene_plan(bodies, winds, model)
    compare_with_apply(plan, np.random.default_rng(len(bodies) * 31 + len(winds)))


def test_the_model_holds_plain_arrays_of_fixed_types():
    models = [K.empty_wind_model(), K.wind_model(None), K.wind_model(scene_plan("shapes", "sum", "force").forces.wind),
              K.wind_model(scene_plan("one", "uniform", "procedural").forces.wind)]
    for name in K.WindModel._fields:
        kinds = {(getattr(m, name).dtype, getattr(m, name).ndim) for m in models}
        assert len(kinds) == 1, (name, kinds)
        assert all(getattr(m, name).flags.c_contiguous for m in models)
        assert kinds.pop()[0] in (np.float64, np.int64, np.bool_)
    shapes = K.wind_model(scene_plan("shapes", "sum", "force").forces.wind)
    assert shapes.body.tolist() == [1, 2, 3, 5, 6, 7, 8]  # not the static post (0) nor the calm ball (4)
    assert shapes.shaped.tolist() == [False, True, True, True, True, False, False]
    assert shapes.turning.tolist() == [False, True, True, True, True, False, True]


def test_the_empty_model_does_nothing():
    wm = K.empty_wind_model()
    rng = np.random.default_rng(2)
    y, R = rng.normal(size=(4, 13)), np.tile(np.eye(3), (4, 1, 1))
    force, torque, air = rng.normal(size=(4, 3)), rng.normal(size=(4, 3)), np.zeros((4, 4))
    before = (force.copy(), torque.copy())
    speeds = K.speeds_table(None, [0.0])[0]
    assert speeds.shape == (0,)
    K.wind_drag(wm, y, R, speeds, 0.0, force, torque, air)
    K.wind_relax(wm, y, R, speeds, 0.0, 0.01, force, torque, air)
    K.wind_apply(wm, y, R, speeds, 0.0, 0.01, force, torque, air)
    assert np.array_equal(force, before[0]) and np.array_equal(torque, before[1]) and not air.any()
    out = np.ones((3, 3))
    K.air_velocity(wm, rng.normal(size=(3, 3)), speeds, 0.0, out)
    assert not out.any()


def test_relax_at_a_long_step_and_in_still_air():
    """phi's two branches (kappa h below 1e-8: still air; large: a long step), against apply."""
    plan = scene_plan("shapes", "uniform_gusts", "procedural")
    wind = plan.forces.wind
    for h in (10.0, 1e-13):
        wind.set_step(h)
        compare_with_apply(plan, np.random.default_rng(int(h * 7) + 1), trials=10)


# ---- the field and its gusts ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("winds", WINDS)
def test_air_velocity_is_the_fields_velocity(winds):
    plan = scene_plan("one", winds, "force")
    wind = plan.forces.wind
    wm = K.wind_model(wind)
    rng = np.random.default_rng(3)
    for t in rng.uniform(0.0, 7.0, 25):
        points = rng.normal(size=(30, 3)) * 0.8 + [0.0, 1.0, 0.0]
        speeds = K.speeds_table(wind, [t])[0]
        out = np.empty((30, 3))
        K.air_velocity(wm, points, speeds, t, out)
        assert_air_close(out, wind.fields.velocity(points, t))
        # the one-point path
        assert_rows_close(out[:1], wind.fields.velocity(points[:1], t), floor=1e-3 * np.max(np.abs(out)))
        for w in range(len(wind.fields.names)):
            # one wind alone: the others' speeds set to 0
            alone = np.where(np.arange(len(speeds)) == w, speeds, 0.0)
            K.air_velocity(wm, points, alone, t, out)
            assert_air_close(out, wind.fields.velocity(points, t, w))


def test_gusts_are_the_gust_field():
    plan = scene_plan("one", "sum", "force")
    wind = plan.forces.wind
    wm = K.wind_model(wind)
    rng = np.random.default_rng(4)
    for w in (0, 2):
        field = wind.fields.gusts[w]
        for t in np.concatenate([rng.uniform(-5.0, 50.0, 30), [0.0, 1e6]]):
            points = rng.normal(size=(8, 3)) * 5.0
            expected = field(points, t)
            got = np.array([K.gust(wm, w, tuple(p), t) for p in points])
            assert np.array_equal(got, expected)
            for i, p in enumerate(points):
                assert np.allclose(got[i], T.gust_reference(field, p, t), rtol=1e-12, atol=1e-14)


def test_lattice_is_the_hash_of_turbulence():
    rng = np.random.default_rng(5)
    cells = np.concatenate([np.floor(rng.normal(size=200) * 1e3), [0.0, -1.0, 2.0**52, -(2.0**52), 1e15]])
    for salt in (0, 1, 977, 0xFFFFFFFF * 7919 + 11):
        with np.errstate(over="ignore"):
            salt_mix = (np.uint64(salt) * T._GOLDEN).view(np.int64)
        got = np.array([K.lattice_value(c, salt_mix) for c in cells])
        assert np.array_equal(got, T.lattice(cells, np.uint64(salt)))


# ---- the speeds --------------------------------------------------------------------------------------------------

SPEEDS = [
    "5 m/s + 2 m/s * sin(2 * pi * t / 7 s)",
    "2 m/s * (1 + sin(t / 1 s)) * gust(1 s)",
    "3 m/s * noise(0.5 s, seed = 2) - 1 m/s",
    "2 m/s * gust(0.3 s, depth = 0.9, seed = 7, octaves = 6) + noise()",
    'envelope("assets/breath.wav", attack = 30 ms, release = 300 ms) * 3 m/s',
    'envelope("assets/breath.wav", start = 1.5 s, normalize = 0) * 2 m/s + 1 m/s',
    "max(0 m/s, 4 m/s - t * 1 m/s2) / 2 + abs(cos(t / 1 s)) * 1 m/s",
    "1 m/s * (t / 1 s) ^ 2 - -(smoothstep(0, 1, t / 1 s)) * 1 m/s",
    "clamp(t / 1 s, 0.2, 0.8) * 1 m/s + lerp(1, 3, 0.25) * 1 m/s + step(1, t / 1 s) * 1 m/s",
    "4 m/s",
    "mic(gain = 3) * 1 m/s + 1 m/s",
    # the time scale itself follows t: noise() wants one number, so the table falls back to a loop
    "2 m/s * noise(0.5 s + t * 0.1)",
]


@pytest.mark.parametrize("speed", SPEEDS)
def test_speeds_table_is_speed_at(speed):
    plan = plan_of(f"scene s {{ {BODIES['one']}  wind a {{ direction (1, 0, 0)  speed {speed} }}  "
                   f"wind b {{ direction (0, 1, 0)  speed 1 m/s * sin(t / 1 s) }} }}", "force")
    wind = plan.forces.wind
    times = np.concatenate([np.linspace(-1.0, 8.0, 301), np.random.default_rng(6).uniform(0.0, 7.0, 50)])
    table = K.speeds_table(wind, times)
    assert table.shape == (len(times), 2)
    for g, t in enumerate(times):
        assert table[g].tolist() == [wind.fields.speed_at(w, float(t)) for w in range(2)]
    assert K.speeds_table(wind, times[:1]).tolist() == [table[0].tolist()]
    assert K.speeds_table(wind, []).shape == (0, 2)


def test_signal_functions_take_arrays_of_times():
    """envelope, mic, noise and gust called with an array of times give their calls at each time."""
    envelope = signals.load_envelope(SCENES / "assets" / "breath.wav", 0.03, 0.3)

    class Microphone:
        def level(self):
            return 0.25

    functions = signals.signal_functions({signals.envelope_key("b.wav", 0.03, 0.3): envelope}, Microphone())
    functions.update(T.signal_functions(12345, 0.4))
    calls = [("envelope", ("b.wav",), dict(attack=0.03, release=0.3, start=0.7)), ("mic", (), dict(gain=2.0)),
             ("noise", (), {}), ("noise", (0.25,), dict(seed=3.0, octaves=5.0)), ("gust", (1.0,), dict(depth=0.7))]
    times = np.linspace(-1.0, 7.0, 801)
    for name, args, kwargs in calls:
        at_once = functions[name]({"t": times}, *args, **kwargs)
        one_by_one = [functions[name]({"t": float(t)}, *args, **kwargs) for t in times]
        assert np.shape(at_once) == times.shape and np.asarray(at_once).tolist() == one_by_one, name


def test_speeds_table_falls_back_for_a_function_of_floats_only():
    scene = load_text("scene s { body b sphere { radius 1 cm  mass 1 g  wind on }  "
                      "wind a { direction (1, 0, 0)  speed 2 m/s * noise(1 s) + sin(t / 1 s) } }").scene
    noise = T.signal_functions(7, 0.5)["noise"]

    def noise_of_one_time(env, *args, **kwargs):
        if np.ndim(env["t"]):
            raise TypeError("this noise() takes one time")
        return noise(env, *args, **kwargs)

    class Stand:  # what speeds_table reads of a WindPlan
        fields = compile_fields(scene.winds, [{"noise": noise_of_one_time}], scene.seed)

    times = np.linspace(0.0, 3.0, 61)
    table = K.speeds_table(Stand, times)
    assert table[:, 0].tolist() == [Stand.fields.speed_at(0, float(t)) for t in times]
    assert table[:, 0].tolist() == [float(2.0 * noise({"t": t}, 1.0) + np.sin(t)) for t in times]
