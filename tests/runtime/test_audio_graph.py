"""The audio graph (runtime/audio/graph.py, nodes.py, iir.py, listener.py, render.py): compiling sound
expressions, event factors on exciters, triggers and envelopes, filters, the listener, blocks."""
from __future__ import annotations

import numpy as np
import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_runtime.audio import compile_audio
from isaac_runtime.audio.iir import PoleFilter, one_pole, residuez
from isaac_runtime.audio.nodes import biquad

FS = 22050

BASE = """
scene s {{
  time 0 s .. 1 s
  audio {{ rate 22050 Hz  channels {channels} }}
  listener {{ at (0, 0, 1)  {listener} }}
  material al {{ density 2700 kg/m3  young 69 GPa  poisson 0.33  loss 0.001 }}
  body floor plane {{ }}
  body bar box {{ size (30 cm, 1 cm, 3 cm)  material al  at (0, 0.2, 0) }}
  body bell sphere {{ radius 5 cm  mass 1 kg  at ({x}, 0, 0)  modes ((440, 3, 1), (1100, 6, 0.5)) }}
  {sounds}
}}
"""


def plan_of(sounds: str, channels: int = 1, listener: str = "", x: float = 0.0, **kw):
    text = BASE.format(sounds=sounds, channels=channels, listener=listener, x=x)
    return compile_audio(load_text(text, name="s.isaac").scene, **kw)


def hit(time, bodies=("bar", "floor"), impulse=0.5, speed=1.0, point=(0.15, 0.195, 0.0)):
    return {"time": time, "bodies": list(bodies), "point": list(point), "normal": [0.0, 1.0, 0.0],
            "impulse": impulse, "tangential_speed": 0.0, "normal_speed": speed, "kind": "impact"}


def render(plan, events=(), **kw):
    return plan.render(plan.synthetic_record(list(events), **kw))


# ---- compiling ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("sound, message", [
    ("sound a on collide(bar, floor) { play modal(barr) }", "unknown body `barr`"),
    ("sound a on collide(bar, floor) { play modal(al) }", "that is a material"),
    ("sound a on at(0.5 s) { play modal() }", "needs a body here"),
    ("sound a on always { play modal(floor) }", "has no modes"),
    ("sound a on always { play noise(purple) }", "unknown noise colour"),
    ("sound a on always { play sine(freq = 440 Hz) }", "missing its argument #1"),
])
def test_mistakes_are_scene_errors_at_the_sound(sound, message):
    with pytest.raises(SceneError) as error:
        plan_of(sound)
    assert message in error.value.format()  # the message or its hint
    assert error.value.diagnostics[0].pos is not None  # file:line:col of the sound


def test_describe_lists_sounds_and_modes():
    plan = plan_of("sound ring on collide(bar, floor) { play modal(bar) * impulse }")
    text = plan.describe()
    assert "sound ring on collide(bar, floor)" in text and "free-free bar" in text and "577 Hz" in text


# ---- event factors and triggers -------------------------------------------------------------------------

def test_event_factors_become_each_hits_strength():
    plan = plan_of("sound ring on collide(bar, floor) { play lowpass(modal(bar) * impulse * 2, 4 kHz) }")
    both = render(plan, [hit(0.1, impulse=1.0), hit(0.3, impulse=0.2)])
    one = render(plan, [hit(0.1, impulse=1.0)])
    other = render(plan, [hit(0.3, impulse=0.2)])
    # a product by `impulse` held at the latest hit would cut the first ring to a fifth at 0.3 s
    assert both == pytest.approx(one + other, abs=1e-9)
    assert np.abs(one).max() == pytest.approx(5 * np.abs(other).max(), rel=0.02)


def test_factors_that_cannot_move_are_held_from_each_hit():
    plan = plan_of("sound tone on collide(bar, floor) { play sine(1000 Hz) * impulse }")
    y = render(plan, [hit(0.2, impulse=0.5), hit(0.6, impulse=0.1)])[:, 0]
    k1, k2 = round(0.2 * FS), round(0.6 * FS)
    at_bar = 1.0 / np.hypot(0.2, 1.0)  # the listener's distance gain: the bar is 1.02 m away
    assert np.abs(y[:k1]).max() == 0.0
    assert np.abs(y[k1:k2]).max() == pytest.approx(0.5 * at_bar, rel=1e-3)
    assert np.abs(y[k2:]).max() == pytest.approx(0.1 * at_bar, rel=1e-3)


def test_at_trigger_starts_at_its_sample():
    plan = plan_of("sound ding on at(0.25 s) { play modal(bell) * impulse }")
    y = render(plan)[:, 0]
    k = round(0.25 * FS)
    assert np.abs(y[:k]).max() == 0.0 and abs(y[k]) > 0.0
    assert np.flatnonzero(np.abs(y) > 1e-3 * np.abs(y).max())[0] - k <= 2


def test_decay_and_adsr_restart_at_hits():
    plan = plan_of("sound d on collide(bar, floor) { play decay(sine(500 Hz), 0.1 s) + adsr(sine(700 Hz), 5 ms, "
                   "10 ms, 0.5, 50 ms) }")
    y = render(plan, [hit(0.2), hit(0.6)])[:, 0]
    k1, k2 = round(0.2 * FS), round(0.6 * FS)
    assert np.abs(y[:k1]).max() == 0.0  # nothing before the first trigger
    assert np.abs(y[k2 - 200:k2]).max() < 0.01  # both envelopes have died away ...
    assert np.abs(y[k2:k2 + 400]).max() > 1.0  # ... and start again at the second hit


def test_always_sound_plays_from_the_start_and_expressions_of_t_work():
    plan = plan_of("sound hum on always { play sine(200 Hz + 200 Hz * t / 1 s) * 0.5 }")
    y = render(plan)[:, 0]
    assert np.abs(y).max() == pytest.approx(0.5, rel=1e-3)
    zero_crossings = np.flatnonzero(np.diff(np.sign(y[: FS // 10])) != 0)
    assert len(zero_crossings) == pytest.approx(2 * 200 * 0.1 * 1.05, abs=3)  # about 210 Hz on average


def test_rendering_does_not_depend_on_the_block_size():
    sounds = ("sound a on collide(bar, floor) { play bandpass(modal(bar) * impulse + noise(pink) * 0.01, "
              "1 kHz + 500 Hz * t / 1 s, 2) }\n"
              "sound b on collide(bar, floor) { play impact() * impulse }")
    events = [hit(0.1), hit(0.1004, impulse=0.2), hit(0.55)]
    big = render(plan_of(sounds, block=2048), events)
    small = render(plan_of(sounds, block=256), events)
    assert small == pytest.approx(big, abs=1e-9)


def test_the_offline_render_equals_the_streamed_blocks():
    """render() goes OFFLINE_BLOCKS blocks at a time; a stream goes block by block: the same samples."""
    from isaac_runtime.audio.render import Renderer

    sounds = ("sound a on collide(bar, floor) { play pan(bandpass(modal(bar) * impulse + noise(pink) * 0.01, "
              "1 kHz + 500 Hz * t / 1 s, 2), sin(t / 0.2 s)) }\n"
              "sound b on collide(bar, floor) { play impact() * impulse }\n"
              "sound c on always { play decay(sine(300 Hz), 0.3 s) * 0.1 }")
    plan = plan_of(sounds, channels=2, block=512)
    record = plan.synthetic_record([hit(0.1), hit(0.1004, impulse=0.2), hit(0.55)])
    renderer = Renderer(plan, record, plan.block)
    streamed = []
    while renderer.position < plan.samples:
        streamed.append(renderer.next_block(final=True))
    offline = plan.render(record)
    assert offline == pytest.approx(np.concatenate(streamed, axis=1).T, abs=1e-12)


def test_noise_is_seeded_and_reproducible():
    plan = plan_of("sound n on always { play noise() }")
    a, b = render(plan), render(plan)
    assert np.array_equal(a, b)
    assert abs(np.std(a) - 1.0) < 0.05


# ---- filters (numpy only) -------------------------------------------------------------------------------

@pytest.mark.parametrize("coefficients", [biquad("bandpass", 1000, 1, FS), biquad("lowpass", 300, 0.5, FS),
                                          biquad("highpass", 5000, 0.707, FS), one_pole(0.01),
                                          ([0.049922035, -0.095993537, 0.050612699, -0.004408786],
                                           [1.0, -2.494956002, 2.017265875, -0.522189400])])
def test_pole_filter_equals_lfilter_across_blocks(coefficients):
    from scipy.signal import lfilter

    x = np.random.default_rng(1).standard_normal(5000)
    reference = lfilter(*coefficients, x)
    f = PoleFilter(*coefficients)
    cuts = [0, 1000, 1030, 1100, 3000, 5000]
    out = np.concatenate([f.run(x[a:b]) for a, b in zip(cuts, cuts[1:])])
    assert out == pytest.approx(reference, abs=2e-6 * np.abs(reference).max())


def test_swept_filter_equals_a_filter_retuned_every_period():
    """run_swept (all the periods' tables at once) against set + run period by period, mono and stereo, in two
    blocks, the last period cut short."""
    from isaac_runtime.audio.nodes import biquads

    period, rng = 128, np.random.default_rng(3)
    for channels in ((), (2,)):
        x = rng.standard_normal(channels + (5 * period + 37,))
        b, a = biquads("bandpass", np.geomspace(200.0, 9000.0, 6), np.linspace(0.6, 8.0, 6), FS)
        swept, stepped = PoleFilter(b[0], a[0], channels), PoleFilter(b[0], a[0], channels)
        y = np.concatenate([swept.run_swept(x[..., :3 * period], b[:3], a[:3], period),
                            swept.run_swept(x[..., 3 * period:], b[3:], a[3:], period)], axis=-1)
        reference = []
        for i in range(6):
            stepped.set(b[i], a[i])
            reference.append(stepped.run(x[..., i * period:(i + 1) * period]))
        reference = np.concatenate(reference, axis=-1)
        assert y == pytest.approx(reference, abs=1e-12 * np.abs(reference).max())
        assert swept.state == pytest.approx(stepped.state, abs=1e-12 * np.abs(stepped.state).max())


def test_biquads_at_once_equal_one_by_one():
    from isaac_runtime.audio.nodes import biquads

    freq, q = np.array([5.0, 300.0, 2000.0, 12000.0]), np.array([0.3, 0.7071, 2.0, 30.0])
    for kind in ("lowpass", "highpass", "bandpass"):
        b, a = biquads(kind, freq, q, FS)
        for i in range(len(freq)):
            b1, a1 = biquad(kind, freq[i], q[i], FS)
            assert b[i] == pytest.approx(b1, rel=1e-13, abs=1e-16) and a[i] == pytest.approx(a1, rel=1e-13)


def test_cos_and_sin_from_the_half_angle_tangent():
    from isaac_runtime.audio.nodes import cos_sin

    angle = np.concatenate([np.linspace(-50.0, 50.0, 100001), np.pi * np.arange(-9, 10), [np.pi / 2, 0.0]])
    cos, sin = cos_sin(angle)
    assert np.abs(cos - np.cos(angle)).max() < 1e-15 and np.abs(sin - np.sin(angle)).max() < 1e-15


def test_residuez_reassembles_the_transfer_function():
    b, a = biquad("bandpass", 2000, 3, FS)
    poles, residues, k = residuez(b, a)
    z = np.exp(1j * np.linspace(0.1, 3.0, 7))
    direct = np.polyval(b[::-1], 1 / z) / np.polyval(a[::-1], 1 / z)
    parts = k + sum(r / (1 - p / z) for p, r in zip(poles, residues))
    assert parts == pytest.approx(direct, rel=1e-9)


# ---- the listener ---------------------------------------------------------------------------------------

def test_listener_pans_and_falls_off_with_distance():
    right = render(plan_of("sound ding on at(0.1 s) { play modal(bell) }", channels=2, x=2.0))
    left = render(plan_of("sound ding on at(0.1 s) { play modal(bell) }", channels=2, x=-2.0))
    near = render(plan_of("sound ding on at(0.1 s) { play modal(bell) }", channels=2, x=0.0))
    assert np.abs(right[:, 1]).max() > 2 * np.abs(right[:, 0]).max()
    assert np.abs(left[:, 0]).max() > 2 * np.abs(left[:, 1]).max()
    # distance sqrt(5) against 1 m: g = 1 / max(d, 1 m), equal power pan
    total = lambda y: np.sqrt(np.sum(y**2))
    assert total(right) / total(near) == pytest.approx(1 / np.sqrt(5), rel=1e-3)


def test_listener_delay_shifts_the_onset_by_distance_over_speed_of_sound():
    plan = plan_of("sound ding on at(0.1 s) { play modal(bell) }", listener="delay on", x=34.3)
    y = render(plan)[:, 0]
    delay = np.hypot(34.3, 1.0) / 343.0
    onset = np.flatnonzero(np.abs(y) > 1e-3 * np.abs(y).max())[0]
    assert abs(onset - (0.1 + delay) * FS) <= 2


def test_explicit_pan_keeps_its_place():
    plan = plan_of("sound p on always { play pan(sine(300 Hz), -1) }", channels=2)
    y = render(plan)
    assert np.abs(y[:, 1]).max() < 1e-12 and np.abs(y[:, 0]).max() > 0.9


def test_the_language_reference_example_compiles_and_plays():
    """docs/language.md's `sounding` scene: its sounds compile and render (cutoff =, decay(2 s), scrape(bar))."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "language.md").read_text()
    block = next(b for b in re.findall(r"^```isaac\n(.*?)^```", text, re.S | re.M) if "scene sounding" in b)
    import dataclasses

    scenes = Path(__file__).resolve().parents[2] / "scenes"  # where its assets/breath.wav is
    plan = compile_audio(load_text(block, name="example.isaac", folder=scenes).scene)
    plan = dataclasses.replace(plan, end=1.0)  # the first second is enough
    assert [s.sound.name for s in plan.sounds] == ["clank", "scrape", "hiss", "chime", "room"]
    events = [{"time": 0.2, "bodies": ["bar", "floor"], "point": [0, 0, 0], "normal": [0, 1, 0], "impulse": 0.3,
               "tangential_speed": 0.0, "normal_speed": 1.0, "kind": "impact"}]
    record = plan.synthetic_record(events, end=1.0, wind={("listener", "breath"): ([0.0, 1.0], [3.0, 3.0])},
                                   contacts={("bar", "floor"): ([0.0, 1.0], [1.0, 1.0], [1.0, 1.0])})
    y = plan.render(record)
    assert np.isfinite(y).all() and np.abs(y).max() > 0
