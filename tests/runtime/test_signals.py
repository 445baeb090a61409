"""The signals a wind's speed may read (runtime/signals.py): the envelope follower (on a step, on a noise burst,
on a recording in a wind; a missing file is a scene error at the wind) and the microphone (its errors without
sounddevice or a device, its level per block, silence and a warning without --mic)."""
from __future__ import annotations

import dataclasses
import math
import sys
import types

import numpy as np
import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_runtime import signals
from isaac_runtime.plan import compile_plan
from isaac_runtime.wind import compile_wind, wind_intensity

from .test_wind import SCENES, wind_plan


# ---- the envelope follower ------------------------------------------------------------------------------------

def test_envelope_follower_tracks_on_off_with_its_attack_and_release():
    rate, attack, release = 16000.0, 0.02, 0.3
    t = np.arange(int(2.0 * rate)) / rate
    on = (t >= 0.5) & (t < 1.0)
    y = signals.follow_envelope(np.where(on, 1.0, 0.0), rate, attack, release)
    # a step of |x| from 0 to 1: y = 1 - exp(-t / attack); back to 0: y = y1 exp(-t / release)
    rising = on
    assert np.allclose(y[rising], 1 - np.exp(-(t[rising] - 0.5 + 1 / rate) / attack), atol=1e-9)
    falling = t >= 1.0
    y1 = y[np.flatnonzero(on)[-1]]
    assert np.allclose(y[falling], y1 * np.exp(-(t[falling] - 1.0 + 1 / rate) / release), atol=1e-9)
    assert np.all(y[t < 0.5] == 0.0)
    # the same through a noise burst on a file, looked up at any t: 63 % at attack, 37 % at release
    noise = np.random.default_rng(1).uniform(-1, 1, len(t))
    env = signals.envelope_of_samples(np.where(on, noise, 0.0), rate, attack, release, normalize=False)
    plateau = 0.5  # the mean of |x| for x uniform in [-1, 1]
    assert env.at(0.5 + attack) == pytest.approx(plateau * (1 - math.exp(-1)), rel=0.08)
    assert env.at(1.0 + release) == pytest.approx(env.at(1.0) * math.exp(-1), rel=0.08)
    assert env.at(-1.0) == 0.0 and env.at(5.0) == 0.0
    assert env.at(np.array([0.25, 0.75])).shape == (2,)


def test_envelope_of_a_recording_in_a_wind(tmp_path):
    soundfile = pytest.importorskip("soundfile")
    rate = 16000
    t = np.arange(2 * rate) / rate
    soundfile.write(tmp_path / "puff.wav", np.where((t > 1.0) & (t < 1.5), 0.5, 0.0), rate)
    text = ("scene s { body b sphere { radius 1 cm  mass 1 g  wind on }  wind w { direction (1, 0, 0) "
            "speed envelope(\"puff.wav\", attack = 10 ms, release = 100 ms, start = 0.5 s) * 4 m/s } }")
    scene = load_text(text, folder=tmp_path).scene
    # the plan does not know the scene's folder (the IR keeps the file's name): give it, as a caller that does
    wind = compile_wind(scene, compile_plan(dataclasses.replace(scene, winds=())), folder=tmp_path)
    absolute = text.replace("puff.wav", (tmp_path / "puff.wav").as_posix())
    assert compile_plan(load_text(absolute, folder=tmp_path).scene).forces.wind is not None
    with pytest.raises(SceneError, match="outside"):  # a recording outside the scene's folder is not read
        load_text(absolute, folder=tmp_path / "elsewhere")
    assert wind_intensity(wind, "w", 1.4) == 0.0  # the recording starts at 0.5 s: its silence lasts until 1.5 s
    assert wind_intensity(wind, "w", 1.5 + 0.01) == pytest.approx(4 * (1 - math.exp(-1)), rel=0.01)
    assert wind_intensity(wind, "w", 1.9) == pytest.approx(4.0, rel=1e-3)


def test_missing_recording_is_a_scene_error_at_the_wind(tmp_path):
    text = ("scene s {\n  body b sphere { radius 1 cm  mass 1 g  wind on }\n"
            "  wind w { direction (1, 0, 0)  speed envelope(\"nope.wav\") * 4 m/s }\n}")
    with pytest.raises(SceneError) as error:  # the front end reads it (isaac_lang/assets.py), at the file's name
        load_text(text, folder=tmp_path)
    assert (error.value.diagnostics[0].pos.line, error.value.diagnostics[0].pos.col) == (3, 48)
    with pytest.raises(SceneError) as error:  # and the plan still says so, at the wind, for an IR made elsewhere
        compile_plan(load_text(text, folder=tmp_path, assets=False).scene)
    diagnostic = error.value.diagnostics[0]
    assert "no such sound file" in diagnostic.message and "nope.wav" in diagnostic.message
    assert (diagnostic.pos.line, diagnostic.pos.col) == (3, 3)
    assert "relative to the scene's folder" in diagnostic.hint


# ---- the microphone -------------------------------------------------------------------------------------------

def test_microphone_without_sounddevice_says_so(monkeypatch):
    monkeypatch.setitem(sys.modules, "sounddevice", None)  # import fails
    with pytest.raises(signals.SignalError, match="needs the sounddevice package") as error:
        signals.open_microphone()
    assert "envelope" in error.value.hint and isinstance(error.value, SceneError)


def test_microphone_without_a_device_says_so(monkeypatch):
    fake = types.ModuleType("sounddevice")

    def query_devices(device=None, kind=None):
        raise ValueError("No input device matching ''")

    fake.query_devices = query_devices
    monkeypatch.setitem(sys.modules, "sounddevice", fake)
    with pytest.raises(signals.SignalError, match="no microphone found"):
        signals.open_microphone()
    assert signals.microphone() is None


def test_isaac_run_mic_without_sounddevice_is_exit_2(monkeypatch, capsys):
    from isaac.cli import main

    monkeypatch.setitem(sys.modules, "sounddevice", None)
    code = main(["run", str(SCENES / "mobile.isaac"), "--mic", "--until", "0.01", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "needs the sounddevice package" in err and "Traceback" not in err


def test_microphone_level_follows_its_blocks():
    class Stream:
        def __init__(self, device, rate, callback):
            self.callback = callback

        def start(self):
            pass

    mic = signals.Microphone(stream_factory=Stream, attack=0.001, release=0.5)
    mic.stream.callback(np.full((1600, 1), 0.8), 1600, None, None)  # 0.1 s of blowing
    assert mic.level() == pytest.approx(0.8, rel=1e-6)
    functions = signals.signal_functions({}, mic)
    assert functions["mic"]({"t": 0.0}, gain=2.0) == pytest.approx(1.6, rel=1e-6)
    assert functions["mic"]({"t": np.zeros(3)}).shape == (3,)


def test_mic_without_a_microphone_is_silent_and_warned():
    plan = wind_plan("", "wind w { direction (1, 0, 0)  speed mic() * 4 m/s }")
    assert wind_intensity(plan.forces.wind, "w", 1.0) == 0.0
    assert any("--mic" in w for w in plan.warnings)
