"""Sweep stage 3, one task: a variant run on a worker, the way `isaac run --set ...` runs it.

The worker unpacks the bundle into a temporary folder, loads the scene from there with the variant's values,
simulates it (runtime/run.py `simulate`) and writes the outputs of `isaac run` (`write_outputs`) into that
folder. It sends back a record (status, diagnostic, every scalar of report.json) and, when outputs are kept,
the files' bytes: the client writes them, so a worker on another machine needs no shared disk.

Statuses: `ok`; `scene-error` (the loader or planner raised SceneError: the diagnostic is its text);
`blow-up` (the run stopped on a NumericalError: the outputs up to then are kept, as `isaac run` keeps them);
`tolerance` (the run finished but broke a tolerance of report.json's `checks`, where `isaac run` exits 3);
`error` (anything else: a bug in isaac, with its traceback).
"""
from __future__ import annotations

import numbers
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from isaac.sweep.bundle import Bundle, unpack

OUTPUT_FILES = ("trajectory.npz", "events.json", "audio.wav", "ir.json", "report.json")
FAILED = ("scene-error", "blow-up", "tolerance", "error")


@dataclass(frozen=True)
class Task:
    """What one variant is: its id and place in the sweep, the values set, how to run it, whether to keep files."""

    id: str
    index: int
    values: dict  # parameter -> value text (`--set NAME=VALUE`)
    solver: str | None = None
    step: float | None = None
    until: float | None = None
    keep: bool = True  # send back the output files

    def options(self) -> dict:
        return {"solver": self.solver, "step": self.step, "until": self.until}


def run_variant(bundle: Bundle, task: Task) -> dict:
    """{"record": {...}, "files": {name: bytes}}; never raises for a problem in the scene."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="isaac-sweep-") as tmp:
        scene_file = unpack(bundle, Path(tmp) / "scene")
        out = Path(tmp) / "out"
        record = _run(bundle, scene_file, task, out)
        files = _read_outputs(out) if task.keep else {}
    record["variant_wall_time"] = time.perf_counter() - started
    return {"record": record, "files": files}


def _run(bundle: Bundle, scene_file: Path, task: Task, out: Path) -> dict:
    from isaac_ir.diagnostics import SceneError, SourceCache
    from isaac_lang.load import load_text

    from isaac_runtime.run import RunOptions, simulate, write_outputs

    sources = SourceCache()
    try:
        scene = load_text(bundle.text, name=scene_file.name, overrides=task.values, folder=scene_file.parent,
                          sources=sources).scene
        result = simulate(scene, RunOptions(solver=task.solver, step=task.step, until=task.until,
                                            folder=scene_file.parent))
        out.mkdir(parents=True, exist_ok=True)
        write_outputs(scene, result, out)
    except SceneError as error:
        return {"status": "scene-error", "diagnostic": error.format(sources)}
    except Exception as error:  # a bug in isaac: the traceback goes into the table, the sweep goes on
        return {"status": "error", "diagnostic": f"internal error ({type(error).__name__}: {error})\n"
                                                 + traceback.format_exc()}
    if result.error is not None:
        record = {"status": "blow-up", "diagnostic": str(result.error)}
    else:
        broken = broken_checks(result.report)
        record = {"status": "tolerance" if broken else "ok", "diagnostic": "; ".join(broken) or None}
    record.update(report_scalars(result.report))
    return record


def broken_checks(report: dict) -> list:
    """The tolerances the finished run broke (report.json's `checks`: name -> {ok, value, limit, ...}), each
    said in a line; `isaac run` exits 3 for these."""
    broken = []
    for name, check in (report.get("checks") or {}).items():
        if isinstance(check, dict) and check.get("ok") is False:
            broken.append(f"{name}: {check.get('value')!r} above the limit {check.get('limit')!r}"
                          + (f" at t = {check['time']:.6g} s" if isinstance(check.get("time"), float) else ""))
    return broken


def report_scalars(report: dict, prefix: str = "") -> dict:
    """Every scalar of report.json (str, number, bool, None), nested dicts flattened as `outer.inner`; lists
    (stages run, warnings) stay in the kept report.json."""
    out = {}
    for key, value in report.items():
        if isinstance(value, dict):
            out.update(report_scalars(value, f"{prefix}{key}."))
        elif value is None or isinstance(value, (str, bool)):
            out[f"{prefix}{key}"] = value
        elif isinstance(value, numbers.Integral):  # numpy's integers too
            out[f"{prefix}{key}"] = int(value)
        elif isinstance(value, numbers.Real):
            out[f"{prefix}{key}"] = float(value)
    return out


def _read_outputs(out: Path) -> dict:
    return {name: (out / name).read_bytes() for name in OUTPUT_FILES if (out / name).is_file()}
