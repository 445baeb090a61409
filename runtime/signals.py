"""Signals from sound: the envelope of a recorded breath and a live microphone, as functions of time.

A wind's speed may be written `envelope("assets/breath.wav", attack = 20 ms, release = 300 ms) * 4 m/s` or
`mic() * 4 m/s`. The envelope follower (docs/design/sound.md#section-9) is a one-pole filter on |x| with separate attack
and release time constants:

    y[n] = y[n-1] + a (|x[n]| - y[n-1]),   a = 1 - exp(-1 / (tau fs)),   tau = attack if |x[n]| > y[n-1]
                                                                           else release

so a step of |x| from 0 to 1 gives y = 1 - exp(-t / attack), and back to 0 gives y = y0 exp(-t / release).
A recording is followed once at its own rate, then kept at CONTROL_RATE for lookups at any t (linear
interpolation; 0 before the recording starts and after it ends). Its peak is scaled to 1 unless
`normalize = 0`. soundfile is imported only when a scene names a recording, sounddevice only when a run asks
for the microphone (`isaac run --mic`).

`signal_functions(...)` gives the callables `isaac_ir.expr.evaluate` takes as `functions`:
name -> f(env, *args, **kwargs), env["t"] a float or an array of times.
"""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from isaac_ir.diagnostics import Diagnostic, SceneError

# s: default attack time constant of the follower (a breath builds up in tens of milliseconds)
DEFAULT_ATTACK = 0.02
# s: default release time constant (air keeps moving a little after the breath stops)
DEFAULT_RELEASE = 0.25
# Hz: a followed envelope is kept at this rate for lookups
CONTROL_RATE = 1000.0
# Hz: the microphone's sample rate, and its block length in samples
MIC_RATE = 16000
MIC_BLOCK = 256


class SignalError(SceneError):
    """A signal cannot be had (missing file, no microphone): a scene error (exit 2) that says what to do."""

    def __init__(self, message: str, hint: str | None = None):
        self.message, self.hint = message, hint
        super().__init__([Diagnostic(message, None, hint)])

    def __str__(self) -> str:
        return self.message


# ---- the envelope follower ---------------------------------------------------------------------------------

def attack_release_coefficients(rate: float, attack: float, release: float) -> tuple:
    """One-pole coefficients a = 1 - exp(-1 / (tau fs)) for the attack and release time constants."""
    if attack < 0 or release < 0:
        raise ValueError("attack and release must not be negative")
    a_up = 1.0 - math.exp(-1.0 / (attack * rate)) if attack > 0 else 1.0
    a_down = 1.0 - math.exp(-1.0 / (release * rate)) if release > 0 else 1.0
    return a_up, a_down


def follow_envelope(x, rate: float, attack: float, release: float, y0: float = 0.0) -> np.ndarray:
    """The follower's output (N,) for samples x (N,) at `rate` Hz, starting from y0."""
    a_up, a_down = attack_release_coefficients(rate, attack, release)
    magnitude = np.abs(np.asarray(x, dtype=float)).tolist()
    out = [0.0] * len(magnitude)
    y = float(y0)
    for n, m in enumerate(magnitude):
        # y += a (|x| - y), a chosen by the direction of the change
        y += (a_up if m > y else a_down) * (m - y)
        out[n] = y
    return np.asarray(out)


@dataclass(frozen=True)
class Envelope:
    """A followed envelope kept at CONTROL_RATE: values at times (s, from the recording's start)."""

    times: np.ndarray  # (m,)
    values: np.ndarray  # (m,)
    peak: float  # the follower's peak before normalization (full scale = 1)

    @property
    def duration(self) -> float:
        return float(self.times[-1]) if len(self.times) else 0.0

    def at(self, t):
        """Envelope at time(s) t: linear interpolation, 0 outside the recording."""
        value = np.interp(t, self.times, self.values, left=0.0, right=0.0)
        return float(value) if np.ndim(t) == 0 else value


def envelope_of_samples(x, rate: float, attack: float, release: float, normalize: bool = True) -> Envelope:
    """Follow samples x (N,) or (N, channels) (mixed to mono) and keep the result at CONTROL_RATE."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 2:
        x = x.mean(axis=1)
    y = follow_envelope(x, rate, attack, release)
    stride = max(1, int(round(rate / CONTROL_RATE)))
    picked = np.arange(0, len(y), stride)
    if len(y) and picked[-1] != len(y) - 1:
        picked = np.append(picked, len(y) - 1)
    values = y[picked]
    peak = float(y.max()) if len(y) else 0.0
    if normalize and peak > 0:
        values = values / peak
    return Envelope(picked / float(rate), values, peak)


@functools.lru_cache(maxsize=32)
def _load_cached(path: str, mtime: float, attack: float, release: float, normalize: bool) -> Envelope:
    try:
        import soundfile
    except ImportError:
        raise SignalError("reading a recording needs the soundfile package",
                          "pip install soundfile (or the `sound` extra: pip install isaac[sound])") from None
    try:
        samples, rate = soundfile.read(path, dtype="float64", always_2d=True)
    except Exception as error:  # soundfile raises its own LibsndfileError / RuntimeError
        raise SignalError(f"cannot read `{path}` as sound: {error}", "use a WAV, FLAC or OGG file") from None
    return envelope_of_samples(samples, float(rate), attack, release, normalize)


def load_envelope(path, attack: float = DEFAULT_ATTACK, release: float = DEFAULT_RELEASE,
                  normalize: bool = True) -> Envelope:
    """The envelope of a sound file (cached: a scene that names it twice reads it once)."""
    path = Path(path)
    if not path.is_file():
        raise SignalError(f"no such sound file: {path}")
    return _load_cached(str(path.resolve()), path.stat().st_mtime, float(attack), float(release), bool(normalize))


def find_asset(name: str, folders) -> tuple:
    """(path or None, places tried) of a file a scene names: absolute, or relative to the first folder that has it."""
    path = Path(name)
    if path.is_absolute():
        return (path if path.is_file() else None), [path.as_posix()]
    tried = []
    for folder in folders:
        candidate = Path(folder) / path
        if candidate.is_file():
            return candidate, tried
        tried.append(candidate.as_posix())
    return None, tried


def resolve_asset(name: str, folders) -> Path:
    """A recording the scene names, or a SignalError saying where it was looked for."""
    found, tried = find_asset(name, folders)
    if found is None:
        raise SignalError(f"no such sound file: `{name}`",
                          "a recording is named relative to the scene's folder; looked in " + ", ".join(tried))
    return found


# ---- the live microphone -----------------------------------------------------------------------------------

class Microphone:
    """The default (or a named) input device, followed block by block in the audio thread; `level()` is the
    latest envelope value, 0..1 of full scale. Time does not enter: a live run paces itself to the wall clock."""

    def __init__(self, device=None, rate: int = MIC_RATE, attack: float = DEFAULT_ATTACK,
                 release: float = DEFAULT_RELEASE, stream_factory=None):
        self.rate, self.attack, self.release = rate, attack, release
        self._level = 0.0
        self._lock = threading.Lock()
        self.stream = (stream_factory or _input_stream)(device, rate, self._on_block)
        self.stream.start()

    def _on_block(self, block, frames, time_info, status) -> None:
        y = follow_envelope(np.asarray(block, float).reshape(frames, -1).mean(axis=1), self.rate, self.attack,
                            self.release, self._level)
        with self._lock:
            self._level = float(y[-1]) if len(y) else self._level

    def level(self) -> float:
        with self._lock:
            return self._level

    def close(self) -> None:
        self.stream.stop()
        self.stream.close()


def _input_stream(device, rate: int, callback):
    try:
        import sounddevice
    except ImportError:  # also when PortAudio itself is missing (sounddevice raises OSError then)
        raise SignalError("the microphone needs the sounddevice package",
                          "pip install 'isaac[mic]' (sounddevice), or drive the wind from a recording: "
                          "envelope(\"breath.wav\")") from None
    except OSError as error:
        raise SignalError(f"the microphone needs PortAudio: {error}",
                          "install PortAudio (e.g. apt install libportaudio2)") from None
    try:
        info = sounddevice.query_devices(device, "input")
    except Exception as error:  # sounddevice raises ValueError or PortAudioError when there is no input device
        raise SignalError(f"no microphone found ({error})",
                          "plug one in, name a device (isaac run --mic DEVICE; `python -m sounddevice` lists "
                          "them), or drive the wind from a recording: envelope(\"breath.wav\")") from None
    if not info or info.get("max_input_channels", 0) < 1:
        raise SignalError("no microphone found: the device has no input channel",
                          "name another device: isaac run --mic DEVICE")
    return sounddevice.InputStream(device=device, channels=1, samplerate=rate, blocksize=MIC_BLOCK,
                                   callback=callback)


_MICROPHONE: Microphone | None = None


def open_microphone(device=None, **options) -> Microphone:
    """Start listening (`isaac run --mic`); later runs in this process use it for mic(). Raises SignalError."""
    global _MICROPHONE
    if _MICROPHONE is None:
        _MICROPHONE = Microphone(device, **options)
    return _MICROPHONE


def close_microphone() -> None:
    global _MICROPHONE
    if _MICROPHONE is not None:
        _MICROPHONE.close()
        _MICROPHONE = None


def microphone() -> Microphone | None:
    """The open microphone, or None when no run asked for one."""
    return _MICROPHONE


def use_microphone(mic) -> None:
    """Make `mic` the microphone that mic() reads (any object with level() and close(): `isaac live`'s breath,
    isaac_runtime.live.breath). One that also has stand_in(attack, release, normalize) stands in for every
    recording a wind follows: envelope("file", ...) then reads it instead of the file."""
    global _MICROPHONE
    _MICROPHONE = mic


# ---- the functions the expression evaluator calls ------------------------------------------------------------

def signal_functions(envelopes: dict, mic: Microphone | None) -> dict:
    """`envelope(file, attack =, release =, start =, normalize =)` and `mic(gain =)` for E.evaluate.

    envelopes: (file, attack, release, normalize) -> Envelope, loaded beforehand (`preload`), so that a missing
    file is an error when the plan is made, not in the middle of a run. Without a microphone, mic() is 0."""

    stand_in = getattr(mic, "stand_in", None)

    def envelope(env, name, attack=DEFAULT_ATTACK, release=DEFAULT_RELEASE, start=0.0, normalize=1.0):
        if stand_in is not None:  # a live breath in place of the recording (isaac live --mic)
            level = stand_in(attack, release, normalize)
            return level if np.ndim(env["t"]) == 0 else np.full(np.shape(env["t"]), level)
        return envelopes[envelope_key(name, attack, release, normalize)].at(np.asarray(env["t"], float) - start)

    def microphone_level(env, gain=1.0):
        level = gain * mic.level() if mic is not None else 0.0
        return level if np.ndim(env["t"]) == 0 else np.full(np.shape(env["t"]), level)

    return {"envelope": envelope, "mic": microphone_level}


def envelope_key(name, attack=DEFAULT_ATTACK, release=DEFAULT_RELEASE, normalize=1.0) -> tuple:
    return (str(name), float(attack), float(release), bool(normalize))


def asset_folders(scene, folder=None) -> list:
    """Where a recording the scene names may be: the scene's folder when the plan knows it, else the folder
    holding the scene file as seen from here (the IR keeps only the file's name), else here."""
    if folder is not None:
        return [Path(folder)]
    here = Path.cwd()
    found = [here] if (here / scene.file).is_file() else []
    found += sorted(d for d in here.iterdir() if d.is_dir() and (d / scene.file).is_file())
    return found + ([here] if here not in found else [])
