"""The pieces of a golden: sampling, the JSON layout, audio features, and the comparisons' findings."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from isaac.golden.audio import audio_features
from isaac.golden.compare import _rotation_angle, compare_audio, compare_trajectory
from isaac.golden.record import events_of, sample_times, trajectory_at
from isaac.golden.settings import TOLERANCES, Settings, quantity
from isaac.golden.store import dumps
from isaac_ir import units as U

TOL = {k: v[0] for k, v in TOLERANCES.items()}


def test_the_default_grid_is_every_kth_frame_with_the_last():
    frames = np.arange(1001) / 100.0
    times = sample_times(frames, 1, Settings())
    assert len(times) == 101 and times[1] == pytest.approx(0.1) and times[-1] == 10.0
    assert len(sample_times(frames, 1000, Settings())) <= 21  # a big scene keeps fewer samples
    assert list(sample_times(frames, 1, Settings(every=2.5))) == [0.0, 2.5, 5.0, 7.5, 10.0]
    assert list(sample_times(frames, 1, Settings(times=(0.5, 3.0, 12.0)))) == [0.5, 3.0]


def test_the_trajectory_between_frames_is_interpolated():
    arrays = {"time": np.array([0.0, 1.0]), "bodies": np.array(["a"]),
              "position": np.array([[[0.0, 0, 0]], [[2.0, 0, 0]]]),
              "orientation": np.array([[[1.0, 0, 0, 0]], [[1.0, 0, 0, 0]]]),
              "linear_velocity": np.zeros((2, 1, 3)), "angular_velocity": np.zeros((2, 1, 3)),
              "constraint_error": np.zeros(2), "energy": np.array([1.0, 3.0])}
    out = trajectory_at(arrays, np.array([0.0, 0.25, 1.0, 2.0]))  # 2 s is past the run: left out
    assert out["time"] == [0.0, 0.25, 1.0]
    assert out["bodies"]["a"]["position"][1] == [0.5, 0.0, 0.0] and out["energy"][1] == 1.5


def test_rotation_angle_treats_q_and_minus_q_alike():
    q = np.array([[1.0, 0, 0, 0]])
    half = math.radians(10) / 2
    r = np.array([[math.cos(half), 0, 0, math.sin(half)]])
    assert _rotation_angle(q, r)[0] == pytest.approx(math.radians(10))
    assert _rotation_angle(r, -r)[0] == pytest.approx(0.0, abs=1e-15)


def test_a_trajectory_finding_says_how_much_and_when():
    golden = {"time": [0.0, 1.0, 2.0], "bodies": {"a": {
        "position": [[0, 0, 0]] * 3, "orientation": [[1, 0, 0, 0]] * 3, "linear_velocity": [[0, 0, 0]] * 3,
        "angular_velocity": [[0, 0, 0]] * 3}}, "constraint_error": [0, 0, 0], "energy": [1, 1, 1]}
    moved = json.loads(json.dumps(golden))
    moved["bodies"]["a"]["position"] = [[0, 0, 0], [0, 1e-3, 0], [0, 3e-3, 0]]
    (finding,) = compare_trajectory(golden, moved, TOL, 1.0)
    assert finding.what == "position of `a`"
    assert finding.detail == "off by up to 0.003 m (at t = 2 s; beyond 1e-06 from t = 1 s)"
    del moved["bodies"]["a"]
    assert "gone" in str(compare_trajectory(golden, moved, TOL, 1.0)[0])


def test_contact_events_are_summed_per_pair():
    events = [{"time": 0.1, "bodies": ["floor", "box"], "impulse": 1.0, "kind": "impact"},
              {"time": 0.2, "bodies": ["floor", "box"], "impulse": 0.5, "kind": "contact"},
              {"time": 0.3, "bodies": ["box", "floor"], "impulse": 0.5, "kind": "contact"}]
    out = events_of(events)
    assert out["impact_count"] == 1 and out["impacts"][0]["bodies"] == ["box", "floor"]
    assert out["contacts"] == [{"bodies": ["box", "floor"], "frames": 2, "first": 0.2, "last": 0.3, "impulse": 1.0}]


def strikes(times, frequencies=(523.0, 1410.0), rate=44100, seconds=2.0):
    t = np.arange(int(rate * seconds)) / rate
    x = np.zeros_like(t)
    for t0 in times:
        u = np.clip(t - t0, 0, None)
        for k, f in enumerate(frequencies):
            x += np.where(t >= t0, 0.5 ** k * np.sin(2 * np.pi * f * u) * np.exp(-4 * u), 0.0)
    return 0.2 * x[:, None]


def test_audio_features_find_the_strikes_and_the_modes():
    features = audio_features(strikes((0.2, 0.9, 1.4)), 44100)
    assert features["onsets"] == pytest.approx([0.2, 0.9, 1.4], abs=0.006)
    assert [round(p["frequency"]) for p in features["peaks"]] == [523, 1410]
    assert features["peaks"][0]["level"] == pytest.approx(0, abs=1) and features["peak_db"] < 0
    silent = audio_features(np.zeros((1000, 2)), 44100)
    assert silent["onsets"] == [] and silent["peaks"] == [] and silent["channels"] == 2


def test_audio_findings():
    golden = audio_features(strikes((0.2, 0.9)), 44100)
    assert compare_audio(golden, audio_features(strikes((0.2, 0.9)), 44100), TOL) == []
    later = compare_audio(golden, audio_features(strikes((0.2, 0.95)), 44100), TOL)
    assert any("onset #2" in str(f) and "moved by" in str(f) for f in later)
    detuned = compare_audio(golden, audio_features(strikes((0.2, 0.9), (587.0, 1410.0)), 44100), TOL)
    assert any("spectral peak at 52" in str(f) and "gone" in str(f) for f in detuned), detuned


def test_quantities_in_the_toml_take_units():
    assert quantity("1 mm", U.LENGTH, "position") == pytest.approx(1e-3)
    assert quantity(2e-6, U.LENGTH, "position") == 2e-6
    assert quantity("0.5 deg", U.ANGLE, "orientation") == pytest.approx(math.radians(0.5))
    assert quantity("1 dB", U.DIMENSIONLESS, "level") == 1.0
    with pytest.raises(ValueError, match="wants a length, not a time"):
        quantity("1 s", U.LENGTH, "position")


def test_golden_json_keeps_vectors_on_one_line():
    text = dumps({"b": [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], "a": 0.1 + 0.2, "inf": math.inf})
    assert text.splitlines()[0:2] == ["{", ' "a": 0.3,']
    assert "  [1.0, 2.0, 3.0]," in text and '"inf": null' in text
    assert json.loads(text)["b"][1] == [4.0, 5.0, 6.0]
