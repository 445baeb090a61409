"""`isaac run --plots`: energy, constraint error and trajectories, and a spectrogram when there is sound."""
from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main

pytest.importorskip("matplotlib", reason="plots need the `plots` extra (matplotlib)")

from isaac_runtime.outputs.plots import write_plots  # noqa: E402

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_run_with_plots_writes_the_three_plots(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(out), "--until", "0.2", "--quiet",
                 "--plots"]) == 0
    names = sorted(p.name for p in (out / "plots").iterdir())
    assert names == ["constraint_error.png", "energy.png", "trajectories.png"]
    for name in names:
        assert (out / "plots" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "plots:" in capsys.readouterr().out


def test_a_spectrogram_when_there_is_sound(tmp_path):
    audio = tmp_path / "audio.wav"
    with wave.open(str(audio), "wb") as handle:
        handle.setnchannels(2)
        handle.setsampwidth(2)
        handle.setframerate(8000)
        tone = (8000 * np.sin(2 * np.pi * 440 * np.arange(8000) / 8000)).astype("<i2")
        handle.writeframes(np.repeat(tone, 2).tobytes())
    T = 11
    arrays = {"time": np.linspace(0, 1, T), "bodies": np.array(["a", "b"]), "position": np.zeros((T, 2, 3)),
              "energy": np.ones(T), "constraint_error": np.zeros(T)}
    paths = write_plots(tmp_path / "plots", arrays, audio, title="tone")
    assert [p.name for p in paths] == ["energy.png", "constraint_error.png", "trajectories.png", "spectrogram.png"]
