"""Audio features a golden keeps for a scene with sound: what a listener would notice, not the samples.

    levels      peak and RMS level of the whole render, dBFS
    onsets      the times sounds begin: peaks of the spectral flux (the summed rise of the log-magnitude
                spectrum from one short frame to the next), above an adaptive threshold
    peaks       the strongest peaks of the render's spectrum (mono, averaged over quarter-second segments) that
                stand out of their surroundings (modes, not the bumps of clicks or noise): frequency (Hz,
                interpolated between bins) and level relative to the strongest bin, dB

Samples are not kept: a re-render differs in its last bits, and a golden of 20 s of sound would be megabytes.
"""
from __future__ import annotations

import numpy as np

# short-time frames for onsets: ~10 ms long, hop ~1 ms (an onset is located to about a millisecond)
FRAME_SECONDS = 0.01
HOP_SECONDS = 0.001
# log compression of magnitudes before the flux: log(1 + GAMMA |X|)
GAMMA = 100.0
# an onset's flux stands this far (a fraction of the largest flux) above the mean flux around it...
ONSET_DELTA = 0.1
# ... over this many frames either side, and onsets are at least this far apart (s)
ONSET_WINDOW = 20
ONSET_GAP = 0.03
# spectral peaks kept, the lowest frequency looked at (Hz), and how far below the strongest they may be (dB)
PEAKS = 8
# spectra averaged over segments of this length (s): bins of ~4 Hz, a peak located to a fraction of one
SEGMENT_SECONDS = 0.25
# two peaks closer than this (relative; a quarter-tone is 3 %) are one
PEAK_SPACING = 0.03
LOWEST = 20.0
PEAK_FLOOR_DB = -40.0
# ... and how far above its surroundings (PROMINENCE_WIDTH of its frequency either side) a peak must stand, dB:
# a mode stands out; the bumps of a broadband click or of noise do not
PROMINENCE_DB = 3.0
PROMINENCE_WIDTH = 0.1
# a level of silence (dB), for a render that is all zeros
SILENCE_DB = -200.0


def audio_features(samples: np.ndarray, rate: float) -> dict:
    """The features above of a render (frames, channels) at `rate` samples per second."""
    samples = np.asarray(samples, float).reshape(len(samples), -1)
    mono = samples.mean(axis=1)
    return {"rate": float(rate), "channels": int(samples.shape[1]), "seconds": len(samples) / float(rate),
            "peak_db": _db(np.max(np.abs(samples)) if samples.size else 0.0),
            "rms_db": _db(float(np.sqrt(np.mean(samples ** 2))) if samples.size else 0.0),
            "onsets": onsets(mono, rate), "peaks": spectral_peaks(mono, rate)}


def _db(amplitude: float) -> float:
    # 20 log10(a), held at SILENCE_DB for a = 0
    return float(20.0 * np.log10(amplitude)) if amplitude > 0 else SILENCE_DB


def onsets(mono: np.ndarray, rate: float) -> list:
    """Times (s) where the spectral flux peaks above its local mean by ONSET_DELTA of its largest value."""
    frame = 1 << int(np.ceil(np.log2(max(16, FRAME_SECONDS * rate))))
    hop = max(1, int(round(HOP_SECONDS * rate)))
    if len(mono) < frame or not np.any(mono):
        return []
    starts = np.arange(0, len(mono) - frame + 1, hop)
    window = np.hanning(frame)
    frames = np.lib.stride_tricks.sliding_window_view(mono, frame)[::hop][:len(starts)]
    magnitude = np.log1p(GAMMA * np.abs(np.fft.rfft(frames * window, axis=1)))
    # flux(k) = sum over bins of max(0, |X_k| - |X_k-1|); the first frame rises from silence
    flux = np.concatenate([[magnitude[0].sum()], np.maximum(np.diff(magnitude, axis=0), 0.0).sum(axis=1)])
    kernel = np.ones(2 * ONSET_WINDOW + 1) / (2 * ONSET_WINDOW + 1)
    threshold = np.convolve(flux, kernel, mode="same") + ONSET_DELTA * flux.max()
    picked, last = [], -np.inf
    for k in np.flatnonzero(flux > threshold):
        lo, hi = max(0, k - 3), min(len(flux), k + 4)
        t = (starts[k] + frame / 2) / rate
        if flux[k] == flux[lo:hi].max() and t - last >= ONSET_GAP:
            picked.append(float(t))
            last = t
    return picked


def spectral_peaks(mono: np.ndarray, rate: float) -> list:
    """[{frequency, level}] of the PEAKS strongest local maxima of the averaged spectrum above LOWEST, at least
    PEAK_SPACING apart (relative): the modes a listener hears, not the ripple of repeated strikes."""
    power, resolution = _welch(mono, rate)
    if power is None:
        return []
    level = 10.0 * np.log10(np.maximum(power, 1e-300) / power.max())
    bins = np.arange(1, len(power) - 1)
    local = bins[(power[bins] > power[bins - 1]) & (power[bins] >= power[bins + 1])]
    local = [k for k in local[(local * resolution >= LOWEST) & (level[local] >= PEAK_FLOOR_DB)]
             if _prominence(level, int(k)) >= PROMINENCE_DB]
    local = np.asarray(local, int)
    kept = []
    for k in local[np.argsort(power[local])[::-1]]:
        if all(abs(k - j) > max(2, PEAK_SPACING * j) for j in kept):
            kept.append(int(k))
        if len(kept) == PEAKS:
            break
    return [_interpolated(level, k, resolution) for k in kept]


def _prominence(level: np.ndarray, k: int) -> float:
    """How far (dB) a peak stands above the higher of the lowest points on either side of it, within
    PROMINENCE_WIDTH of its frequency (at least 3 bins)."""
    reach = max(3, int(PROMINENCE_WIDTH * k))
    left, right = level[max(0, k - reach):k], level[k + 1:k + 1 + reach]
    if not len(left) or not len(right):
        return 0.0
    return float(level[k] - max(left.min(), right.min()))


def _welch(mono: np.ndarray, rate: float) -> tuple:
    """(mean power spectrum of Hann-windowed segments of ~SEGMENT_SECONDS, half overlapping; bin width Hz)."""
    segment = 1 << int(np.ceil(np.log2(max(16, SEGMENT_SECONDS * rate))))
    if len(mono) < 16 or not np.any(mono):
        return None, 0.0
    if len(mono) < segment:
        segment = len(mono)
    frames = np.lib.stride_tricks.sliding_window_view(mono, segment)[::segment // 2]
    power = np.mean(np.abs(np.fft.rfft(frames * np.hanning(segment), axis=1)) ** 2, axis=0)
    return power, rate / segment


def _interpolated(level: np.ndarray, k: int, resolution: float) -> dict:
    """The parabola through the peak's bin and its neighbours (in dB): its vertex is the peak (a Hann window's
    main lobe is near a parabola in dB)."""
    a, b, c = level[k - 1], level[k], level[k + 1]
    denominator = a - 2 * b + c
    # p = (a - c) / (2 (a - 2b + c)) bins from k; the height there is b - (a - c) p / 4
    p = 0.5 * (a - c) / denominator if denominator != 0 else 0.0
    return {"frequency": float((k + p) * resolution), "level": float(b - 0.25 * (a - c) * p)}
