"""What a golden records of a scene: its meaning (the IR) and what its run does (the output).

    record = make_record(scene_path, settings, times=None)   # times: the golden's, when checking against one

A record is plain JSON-able data, one section per golden file:

    ir          the canonical IR without positions (canonical.py), and `positions` apart
    trajectory  the bodies' poses and velocities at chosen times, the constraint error and the energy there
    events      every impact (time, bodies, impulse, speed, point), and each pair's contact frames summed up
    report      the run's figures (report.json without its wall-clock and machine fields)
    audio       features of the sound (audio.py), for scenes that have sounds
    meta        what the goldens were made with: run options, the sampling, the tool's version

The runtime is imported here only, when a run is due.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from isaac_ir import ir
from isaac.golden.canonical import split, without_positions
from isaac.golden.settings import MAX_BODY_SAMPLES, Settings

SCHEMA = "isaac-golden/1"
QUANTITIES = ("position", "orientation", "linear_velocity", "angular_velocity")
# figures of report.json a golden keeps (wall time, real-time factors and the limits of checks depend on the
# machine and the command line, not on the scene)
REPORT_FIGURES = ("solver", "integrator", "step", "steps", "frames", "simulated_time", "stages_run",
                  "stages_skipped", "linear_solvers", "max_constraint_error", "constraint_error_settled",
                  "energy_start", "energy_drift_relative", "warnings", "error")
# impacts kept one by one (the rest are counted)
MAX_IMPACTS = 1000


@dataclass
class Record:
    sections: dict = field(default_factory=dict)  # name -> data (SECTIONS)
    energy_scale: float = 1.0  # J, the report's yardstick for energy differences


def make_record(scene, folder: Path, settings: Settings, times=None, run: bool = True) -> Record:
    """The record of a loaded scene (ir.Scene) simulated with the settings; `times`: sample there (a check)."""
    meaning, positions = split(ir.to_data(scene))
    record = Record({"ir": meaning, "positions": positions})
    if not run:
        return record
    from isaac_runtime.run import RunOptions, simulate

    result = simulate(scene, RunOptions(solver=settings.solver, step=settings.step, until=settings.until,
                                        folder=folder, max_constraint_error=None))
    arrays = result.recorder.arrays()
    chosen = sample_times(arrays["time"], len(scene.bodies), settings) if times is None else np.asarray(times, float)
    record.energy_scale = float(result.report.get("energy_scale") or 1.0)
    record.sections["trajectory"] = trajectory_at(arrays, chosen)
    record.sections["events"] = events_of(result.simulation.events)
    record.sections["report"] = report_figures(result.report)
    if result.audio is not None:
        from isaac.golden.audio import audio_features

        record.sections["audio"] = audio_features(result.audio.render(), result.audio.plan.fs)
    record.sections["meta"] = meta(scene, settings, len(chosen))
    return record


def sample_times(frames: np.ndarray, bodies: int, settings: Settings) -> np.ndarray:
    """The times of the trajectory a golden keeps: the settings' `times`, or every `every` seconds, or about
    `samples` frames evenly spaced (first and last included), fewer for scenes with many bodies."""
    frames = np.asarray(frames, float)
    if len(frames) == 0:
        return frames
    if settings.times is not None:
        return np.asarray([t for t in settings.times if frames[0] - 1e-9 <= t <= frames[-1] + 1e-9], float)
    if settings.every is not None:
        count = int(math.floor((frames[-1] - frames[0]) / settings.every + 1e-9)) + 1
        return frames[0] + settings.every * np.arange(count)
    samples = max(2, min(settings.samples, MAX_BODY_SAMPLES // max(1, bodies)))
    # every stride-th frame, the last one too: a grid as regular as the frames allow
    stride = max(1, math.ceil((len(frames) - 1) / (samples - 1)))
    picks = sorted(set(range(0, len(frames), stride)) | {len(frames) - 1})
    return frames[picks]


def trajectory_at(arrays: dict, times: np.ndarray) -> dict:
    """Every body's pose and velocities at `times` (frames there, or interpolated between the two around),
    with the constraint error and the energy. Times past the run's end (a blow-up) are left out."""
    frames = np.asarray(arrays["time"], float)
    times = np.asarray(times, float)
    times = times[times <= frames[-1] + 1e-9] if len(frames) else times[:0]
    names = [str(n) for n in arrays["bodies"]]
    out = {"time": times.tolist(), "bodies": {}}
    per = {key: _at(frames, np.asarray(arrays[key], float), times) for key in QUANTITIES}
    per["orientation"] = _unit_rows(per["orientation"])
    for b, name in enumerate(names):
        out["bodies"][name] = {key: per[key][:, b].tolist() for key in QUANTITIES}
    for key in ("constraint_error", "energy"):
        out[key] = _at(frames, np.asarray(arrays[key], float), times).tolist()
    return out


def _at(frames: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    """values (T, ...) at times: the frame itself when one is there (to 1e-9 s), else linear between frames."""
    if len(times) == 0:
        return values[:0]
    k = np.clip(np.searchsorted(frames, times - 1e-9), 0, len(frames) - 1)
    exact = np.abs(frames[k] - times) <= 1e-9 * np.maximum(1.0, np.abs(times))
    out = values[k].copy()
    for i in np.flatnonzero(~exact):
        j = max(1, min(int(k[i]), len(frames) - 1))
        u = (times[i] - frames[j - 1]) / (frames[j] - frames[j - 1])
        out[i] = (1 - u) * values[j - 1] + u * values[j]
    return out


def _unit_rows(q: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    return q / np.where(norm > 0, norm, 1.0)


def events_of(events: list) -> dict:
    """Impacts one by one (up to MAX_IMPACTS), and for each pair in contact: frames, first, last, impulse sum."""
    impacts, contacts = [], {}
    for event in events:
        bodies = sorted(str(b) for b in event.get("bodies", ()))
        if event.get("kind", "impact") == "impact":
            impacts.append({"time": float(event["time"]), "bodies": bodies, "impulse": float(event["impulse"]),
                            "normal_speed": float(event.get("normal_speed", 0.0)),
                            "point": [float(v) for v in event.get("point", ())]})
            continue
        pair = contacts.setdefault(" ".join(bodies), {"bodies": bodies, "frames": 0, "first": float(event["time"]),
                                                      "last": float(event["time"]), "impulse": 0.0})
        pair["frames"] += 1
        pair["last"] = float(event["time"])
        pair["impulse"] += float(event["impulse"])
    return {"impacts": impacts[:MAX_IMPACTS], "impact_count": len(impacts),
            "contacts": [contacts[k] for k in sorted(contacts)]}


def report_figures(report: dict) -> dict:
    """report.json's figures that belong to the scene (REPORT_FIGURES), warnings without positions."""
    figures = {key: report.get(key) for key in REPORT_FIGURES}
    figures["warnings"] = [without_positions(str(w)) for w in report.get("warnings", [])]
    return figures


def meta(scene, settings: Settings, samples: int) -> dict:
    from isaac import installed_version

    return {"schema": SCHEMA, "scene": scene.name, "run": settings.run_record(), "samples": samples,
            "isaac": installed_version()}
