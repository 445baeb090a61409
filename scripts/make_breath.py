"""Make scenes/assets/breath.wav: a few breaths blown at a microphone, with silences between (deterministic).

    python scripts/make_breath.py [--out scenes/assets/breath.wav] [--seed 7]

Each breath is band-passed noise (the turbulent rush of air on a microphone: most energy 150 Hz - 2.5 kHz) under
a smooth envelope (raised-cosine onset and fade) with a slow wobble, over a -80 dBFS noise floor.
Mono, 16 kHz, 16-bit PCM, 7 s. The same seed gives the same file, byte for byte.
The scene `mobile` relies on the first breath starting at 2.0 s (the mobile is still before it).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfilt

RATE = 16000  # Hz
DURATION = 7.0  # s
NOISE_FLOOR = 1e-4  # -80 dBFS: a quiet room through a microphone
# (start s, length s, peak amplitude): a gentle breath, a strong one, a short puff
BREATHS = ((2.0, 1.2, 0.35), (4.0, 1.0, 0.8), (5.8, 0.6, 0.25))
ONSET, FADE = 0.15, 0.35  # s: the rise and the fall of a breath


def breath_envelope(t: np.ndarray, start: float, length: float, peak: float, wobble: np.ndarray) -> np.ndarray:
    """Raised-cosine rise over ONSET, hold, raised-cosine fall over FADE; 0 outside [start, start + length]."""
    local = t - start
    rise = 0.5 - 0.5 * np.cos(np.pi * np.clip(local / ONSET, 0.0, 1.0))
    fall = 0.5 - 0.5 * np.cos(np.pi * np.clip((length - local) / FADE, 0.0, 1.0))
    inside = (local >= 0.0) & (local <= length)
    return np.where(inside, peak * rise * fall * (1.0 + 0.15 * wobble), 0.0)


def make_breath(seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION * RATE)) / RATE
    rush = sosfilt(butter(2, (150.0, 2500.0), btype="bandpass", fs=RATE, output="sos"), rng.standard_normal(len(t)))
    rush /= np.max(np.abs(rush))
    # a slow wobble of the blowing strength: noise low-passed to 3 Hz, scaled to about +-1
    wobble = sosfilt(butter(2, 3.0, fs=RATE, output="sos"), rng.standard_normal(len(t)))
    wobble /= np.max(np.abs(wobble))
    envelope = sum(breath_envelope(t, *breath, wobble) for breath in BREATHS)
    floor = NOISE_FLOOR * rng.standard_normal(len(t))
    return np.clip(envelope * rush + floor, -1.0, 1.0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    root = Path(__file__).resolve().parents[1]
    parser.add_argument("--out", type=Path, default=root / "scenes" / "assets" / "breath.wav")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    import soundfile

    args.out.parent.mkdir(parents=True, exist_ok=True)
    soundfile.write(str(args.out), make_breath(args.seed), RATE, subtype="PCM_16", format="WAV")
    print(f"wrote {args.out} ({DURATION:g} s, {RATE} Hz mono, breaths at "
          f"{', '.join(f'{s:g} s' for s, _, _ in BREATHS)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
