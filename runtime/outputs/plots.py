"""Plots of a run (`isaac run --plots`; needs the `plots` extra, matplotlib):

    energy.png          kinetic + potential energy, and its drift from the start
    constraint_error.png the largest constraint violation per frame (log scale)
    trajectories.png    x, y and z of every body against time
    spectrogram.png     of audio.wav, when the scene has sound

    write_plots(out / "plots", arrays, audio=out / "audio.wav", title="pendulum")
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import write_atomic

# more bodies than this: the trajectory plot has no legend (it would cover the lines)
LEGEND_BODIES = 12


def write_plots(folder: Path, arrays: dict, audio: Path | None = None, title: str = "") -> list:
    """Write the PNGs listed above into folder; returns their paths. Imports matplotlib (Agg, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    folder = Path(folder)
    time = np.asarray(arrays["time"], float)
    paths = [
        _save(folder / "energy.png", _energy(Figure(figsize=(8, 5)), time, np.asarray(arrays["energy"]), title)),
        _save(folder / "constraint_error.png",
              _constraint_error(Figure(figsize=(8, 3.5)), time, np.asarray(arrays["constraint_error"]), title)),
        _save(folder / "trajectories.png",
              _trajectories(Figure(figsize=(8, 7)), time, np.asarray(arrays["position"]),
                            [str(n) for n in arrays["bodies"]], title)),
    ]
    if audio is not None and Path(audio).is_file():
        paths.append(_save(folder / "spectrogram.png", _spectrogram(Figure(figsize=(8, 4)), Path(audio), title)))
    return paths


def _energy(fig, time, energy, title):
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(time, energy, color="C0")
    top.set_ylabel("energy (J)")
    top.set_title(f"{title}: kinetic + gravitational potential energy")
    drift = energy - energy[0] if len(energy) else energy
    bottom.plot(time, drift, color="C3")
    bottom.set_ylabel("E(t) - E(0) (J)")
    bottom.set_xlabel("time (s)")
    for axis in (top, bottom):
        axis.grid(alpha=0.3)
    return fig


def _constraint_error(fig, time, error, title):
    axis = fig.subplots()
    positive = np.where(error > 0, error, np.nan)
    if np.isfinite(positive).any():
        axis.semilogy(time, positive, color="C2")
    else:
        axis.plot(time, error, color="C2")
        axis.text(0.5, 0.5, "no constraint error (or no constraints)", transform=axis.transAxes, ha="center")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("max constraint error (m or rad)")
    axis.set_title(f"{title}: constraint error")
    axis.grid(alpha=0.3, which="both")
    return fig


def _trajectories(fig, time, position, names, title):
    axes = fig.subplots(3, 1, sharex=True)
    for b, name in enumerate(names):
        for i, axis in enumerate(axes):
            axis.plot(time, position[:, b, i], label=name if i == 0 else None, lw=1.2)
    for i, axis in enumerate(axes):
        axis.set_ylabel(f"{'xyz'[i]} (m)")
        axis.grid(alpha=0.3)
    axes[0].set_title(f"{title}: centre of mass of each body")
    axes[-1].set_xlabel("time (s)")
    if len(names) <= LEGEND_BODIES:
        axes[0].legend(loc="upper right", fontsize="small", ncol=min(len(names), 4))
    return fig


def _spectrogram(fig, audio: Path, title):
    from scipy.io import wavfile

    rate, samples = wavfile.read(audio)
    samples = np.asarray(samples, float)
    if samples.ndim > 1:
        samples = samples.mean(axis=1)  # the channels mixed down
    axis = fig.subplots()
    if len(samples) >= 256:
        with np.errstate(divide="ignore", invalid="ignore"):  # silence is -inf dB: drawn blank, not warned
            axis.specgram(samples, NFFT=1024 if len(samples) >= 1024 else 256, Fs=rate, noverlap=512
                          if len(samples) >= 1024 else 128, cmap="magma", scale="dB")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("frequency (Hz)")
    axis.set_title(f"{title}: spectrogram of {audio.name}")
    return fig


def _save(path: Path, fig) -> Path:
    import io

    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png", dpi=100)
    write_atomic(path, buffer.getvalue())
    return path
