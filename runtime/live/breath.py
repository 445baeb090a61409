"""Live stage, input: the breath, from a microphone or from a WAV file played in real time, one streaming path.

    breath = open_breath("scenes/assets/breath.wav")    # `--mic FILE.wav`; "" the default device; else a device
    signals.use_microphone(breath)     # mic(), and every recording a wind follows, now listen to the breath
    breath.start(at)                   # at: the wall time (time.monotonic) the run's clock starts
    breath.latch()                     # before each run of steps: the level those steps read
    breath.stepped()                   # after them: the breath has reached the poses
    breath.close()

Both sources hand blocks of BLOCK_SECONDS to `Breath.feed(block, captured)`, `captured` the wall time of the
block's first sample: a device through its callback (sounddevice, imported only here and only then), a file
through a thread that hands on each block when the wall clock reaches the block's end, as a device would (the
file starts at `at`, so that its second 2 is the run's second 2; after its end, silence). `feed` runs every
follower over the block: docs/design/sound.md's envelope follower (runtime/signals.py), one per (attack, release) a wind
asks for, at the input's own rate, so that a file fed live gives the envelope `envelope("file")` gives offline.

The breath stands in for every recording a wind's speed follows: `envelope("any.wav", attack, release)` reads the
follower with that attack and release, divided by a reference so that the breath's peak is 1 as the recording's
was (a file: its own peak, known ahead; a device: the loudest level so far, at least DEVICE_REFERENCE of full
scale). `mic(gain)` reads the default follower, 0..1 of full scale, as in `isaac run --mic`.

Latency, measured: `latch` snapshots the followers for the steps about to run and, for every block fed since the
last latch, notes how long its samples waited (the latch's wall time minus each sample's capture time): that is
the time from a breath sample to the wind in the step. `stepped` notes the same to the end of those steps.
"""
from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from .. import signals as S

# s: the block length of both sources (a device's callback period; a file's feeding period)
BLOCK_SECONDS = 0.008
# Hz: a device's sample rate
DEVICE_RATE = 16000
# of full scale: a device's breath reaches the scene's full wind at this level, until a louder one raises it
DEVICE_REFERENCE = 0.1


class Follower:
    """One envelope follower of the input (attack, release), its latest value, the value latched for the steps,
    and the reference that makes the breath's peak 1 (None: the loudest value so far, at least DEVICE_REFERENCE)."""

    def __init__(self, rate: float, attack: float, release: float, reference: float | None):
        self.rate, self.attack, self.release = rate, attack, release
        self.reference = reference
        self.value = self.latched = self.loudest = 0.0

    def feed(self, block: np.ndarray) -> None:
        y = S.follow_envelope(block, self.rate, self.attack, self.release, self.value)
        if len(y):
            self.value = float(y[-1])
            self.loudest = max(self.loudest, float(y.max()))

    def normalized(self) -> float:
        reference = self.reference if self.reference is not None else max(DEVICE_REFERENCE, self.loudest)
        return self.latched / reference if reference > 0 else 0.0


class Breath:
    """The live input (module docstring): followers fed by a source, latched for the steps, latency measured."""

    def __init__(self, source, clock=time.monotonic):
        self.source = source
        self.rate = float(source.rate)
        self.clock = clock
        self._lock = threading.Lock()
        self._followers: dict = {}
        self._default = self._follower(S.DEFAULT_ATTACK, S.DEFAULT_RELEASE)
        self._fresh: list = []  # (captured, samples) of the blocks fed since the last latch
        self._latched: list = []  # the same, of the last latch (for `stepped`)
        self.latencies: list = []  # per block: the mean wait of its samples, s
        self.longest = 0.0  # s: the longest any sample waited
        self.to_pose = 0.0  # s: the longest from a sample to the end of the steps that read it
        self.blocks = self.samples = 0
        self.trace: list = []  # (latch wall time, newest capture time fed, default level) of every latch

    # -- the followers the winds read ------------------------------------------------------------------------

    def _follower(self, attack: float, release: float) -> Follower:
        key = (float(attack), float(release))
        with self._lock:
            if key not in self._followers:
                self._followers[key] = Follower(self.rate, *key, self.source.reference(*key))
            return self._followers[key]

    def level(self) -> float:
        """mic(): the default follower as latched, 0..1 of full scale."""
        return self._default.latched

    def stand_in(self, attack: float, release: float, normalize: float = 1.0) -> float:
        """envelope("file", attack, release, normalize) while the breath stands in for the recording."""
        follower = self._follower(attack, release)
        return follower.normalized() if normalize else follower.latched

    def display_level(self) -> float:
        """What the page's meter shows: the loudest normalized follower a wind reads (the default's if none)."""
        with self._lock:
            followers = [f for f in self._followers.values() if f is not self._default] or [self._default]
            return max(f.normalized() for f in followers)

    # -- the stream --------------------------------------------------------------------------------------------

    def feed(self, block, captured: float) -> None:
        """A block of samples (n,) or (n, channels), its first sample captured at wall time `captured`."""
        block = np.asarray(block, float)
        if block.ndim == 2:
            block = block.mean(axis=1)
        with self._lock:
            for follower in self._followers.values():
                follower.feed(block)
            self._fresh.append((captured, len(block)))

    def latch(self) -> None:
        """The followers' values now are the ones the next steps read; the blocks that reach them, timed."""
        with self._lock:
            now = self.clock()
            for follower in self._followers.values():
                follower.latched = follower.value
            fresh, self._fresh = self._fresh, []
        for captured, n in fresh:
            if n == 0:
                continue
            # sample k of the block was captured at captured + k / rate; it reaches the wind now
            self.latencies.append(now - (captured + (n - 1) / (2.0 * self.rate)))
            self.longest = max(self.longest, now - captured)
            self.blocks += 1
            self.samples += n
        self._latched = fresh
        newest = fresh[-1][0] + (fresh[-1][1] - 1) / self.rate if fresh else float("nan")
        self.trace.append((now, newest, self._default.latched))

    def stepped(self) -> None:
        """The steps that read the last latch are done: the breath has reached the poses."""
        now = self.clock()
        for captured, _ in self._latched:
            self.to_pose = max(self.to_pose, now - captured)

    def start(self, at: float) -> None:
        self.source.start(self, at)

    def close(self) -> None:
        self.source.close()

    def report(self) -> dict:
        """The `input` part of report.json's `realtime` section (times in ms)."""
        waits = np.asarray(self.latencies) * 1e3
        stats = {"mean": float(waits.mean()), "p95": float(np.percentile(waits, 95))} if len(waits) else \
            {"mean": None, "p95": None}
        return {"source": self.source.kind, "name": self.source.name, "rate": self.rate,
                "block": self.source.block, "blocks": self.blocks, "samples": self.samples,
                "latency_mean_ms": stats["mean"], "latency_p95_ms": stats["p95"],
                "latency_max_ms": self.longest * 1e3 if self.blocks else None,
                "to_pose_max_ms": self.to_pose * 1e3 if self.blocks else None}


# ---- sources ---------------------------------------------------------------------------------------------------

class FileSource:
    """A WAV (or FLAC, OGG) file, fed block by block at the wall clock's pace by a thread; silence after its end."""

    kind = "file"

    def __init__(self, path: Path, clock=time.monotonic, sleep=time.sleep):
        self.path, self.name = Path(path), str(path)
        try:
            import soundfile
        except ImportError:
            raise S.SignalError("reading a breath from a file needs the soundfile package",
                                "pip install soundfile") from None
        try:
            samples, rate = soundfile.read(str(self.path), dtype="float64", always_2d=True)
        except Exception as error:  # soundfile raises its own LibsndfileError / RuntimeError
            raise S.SignalError(f"--mic: cannot read `{path}` as sound: {error}",
                                "use a WAV, FLAC or OGG file") from None
        self.samples, self.rate = samples.mean(axis=1), float(rate)
        self.block = max(1, int(round(self.rate * BLOCK_SECONDS)))
        self.clock, self.sleep = clock, sleep
        self._stop = threading.Event()
        self._thread = None

    def reference(self, attack: float, release: float) -> float:
        """The follower's peak over the whole file (what `envelope(...)` divides by offline)."""
        return S.load_envelope(self.path, attack, release).peak or 1.0

    def start(self, breath: Breath, at: float) -> None:
        self._thread = threading.Thread(target=self._play, args=(breath, at), name="isaac-breath", daemon=True)
        self._thread.start()

    def _play(self, breath: Breath, at: float) -> None:
        silence = np.zeros(self.block)
        n = 0
        while not self._stop.is_set():
            due = at + (n + self.block) / self.rate  # a device hands a block on once its last sample is in
            wait = due - self.clock()
            if wait > 0:
                self.sleep(wait)
            block = self.samples[n:n + self.block]
            breath.feed(block if len(block) == self.block else
                        np.concatenate([block, silence[:self.block - len(block)]]), at + n / self.rate)
            n += self.block

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)


class DeviceSource:
    """An input device (sounddevice, PortAudio): its callback feeds the breath from PortAudio's thread."""

    kind = "device"

    def __init__(self, device: str | None, clock=time.monotonic):
        self.name = device or "default input device"
        self.rate = DEVICE_RATE
        self.block = int(round(DEVICE_RATE * BLOCK_SECONDS))
        self.clock = clock
        self._device = int(device) if device and device.isdigit() else (device or None)
        self._sounddevice = _import_sounddevice()
        try:
            info = self._sounddevice.query_devices(self._device, "input")
        except Exception as error:  # ValueError or PortAudioError when there is no such (or no) input device
            raise S.SignalError(f"--mic: no microphone found ({error})", _NO_DEVICE_HINT) from None
        if not info or info.get("max_input_channels", 0) < 1:
            raise S.SignalError(f"--mic: `{self.name}` has no input channel", _NO_DEVICE_HINT)
        self.stream = None

    def reference(self, attack: float, release: float) -> None:
        return None  # the loudest level so far (Follower)

    def start(self, breath: Breath, at: float) -> None:
        def callback(block, frames, time_info, status):
            now = self.clock()
            try:  # how long ago the block's first sample was taken, by PortAudio's own clock
                ago = float(time_info.currentTime - time_info.inputBufferAdcTime)
            except AttributeError:
                ago = 0.0
            if not 0.0 < ago < 1.0:
                ago = frames / self.rate
            breath.feed(np.asarray(block, float).reshape(frames, -1), now - ago)

        try:
            self.stream = self._sounddevice.InputStream(device=self._device, channels=1, samplerate=self.rate,
                                                        blocksize=self.block, callback=callback)
            self.stream.start()
        except Exception as error:  # PortAudioError: the device is busy or refuses the rate
            raise S.SignalError(f"--mic: cannot open `{self.name}`: {error}", _NO_DEVICE_HINT) from None

    def close(self) -> None:
        stream, self.stream = self.stream, None
        if stream is not None:
            stream.stop()
            stream.close()


_NO_DEVICE_HINT = ("plug one in, name a device (`isaac live SCENE --mic DEVICE`; `python -m sounddevice` lists "
                   "them), or rehearse with a recording: --mic breath.wav")


def _import_sounddevice():
    try:
        import sounddevice
    except ImportError:
        raise S.SignalError("--mic with a device needs the sounddevice package",
                            "pip install 'isaac[live]' (sounddevice; it needs PortAudio: apt install "
                            "libportaudio2), or rehearse with a recording: --mic breath.wav") from None
    except OSError as error:  # sounddevice is there, PortAudio is not
        raise S.SignalError(f"--mic needs PortAudio: {error}", "install PortAudio (e.g. apt install libportaudio2), "
                            "or rehearse with a recording: --mic breath.wav") from None
    return sounddevice


def open_breath(option: str, clock=time.monotonic) -> Breath:
    """The breath of `--mic [DEVICE|FILE]`: "" the default device; a name ending in a sound file's suffix, or an
    existing file, a file; else a device (a name or an index)."""
    path = Path(option) if option else None
    if path is not None and (path.suffix.lower() in (".wav", ".flac", ".ogg") or path.is_file()):
        if not path.is_file():
            raise S.SignalError(f"--mic: no such sound file: {path}")
        return Breath(FileSource(path, clock), clock)
    return Breath(DeviceSource(option or None, clock), clock)
