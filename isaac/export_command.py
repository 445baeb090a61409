"""`isaac export`: find (or make) the run of a scene, then write it as RIB or glTF.

The trajectory comes from, in order: --trajectory FILE; the output folder's trajectory.npz when that folder's
ir.json is this very scene (same canonical IR); else a new run of the scene (which writes the usual outputs too).
The export's files join the folder's set (runtime/outputs/outputset.py): with a new run, in the same set as the run's
files; else in a new set made of the folder's files (a new RIB export replaces the old rib/, a glTF its file).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from isaac_ir import ir


def load_trajectory(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return dict(data)


def saved_trajectory(scene, out: Path, given: Path | None = None) -> tuple:
    """(arrays, where they came from) of --trajectory or of this very scene's last run in out; (None, None)."""
    if given is not None:
        from isaac.trajectory_file import read_trajectory

        return read_trajectory(given, scene), str(given)
    saved = out / "trajectory.npz"
    if saved.is_file() and (out / "ir.json").is_file():
        try:
            same = json.loads((out / "ir.json").read_text()) == json.loads(ir.to_json(scene))
        except (OSError, ValueError):
            same = False
        if same:
            return load_trajectory(saved), f"{saved} (this scene's last run)"
    return None, None


def export(scene, scene_path: Path, out: Path, fmt: str, trajectory: Path | None = None, rib_options=None) -> list:
    """Write the export; returns the written paths (in out)."""
    from isaac_runtime.outputs.outputset import OutputSet

    arrays, source = saved_trajectory(scene, out, trajectory)
    if arrays is None:
        return _export_with_a_run(scene, scene_path, out, fmt, rib_options)
    replaced = (lambda rel: rel.startswith("rib/")) if fmt == "rib" else (lambda rel: rel == f"{scene.name}.{fmt}")
    with OutputSet(out, "export", keep=lambda rel: not replaced(rel)) as folder:
        paths = _write(folder.path, scene, scene_path, fmt, arrays, rib_options)
        folder.commit(paths)
    return _said(scene, fmt, source, [folder.to_target(p) for p in paths])


def _export_with_a_run(scene, scene_path: Path, out: Path, fmt: str, rib_options) -> list:
    """A new run of the scene; the export is written into the run's set."""
    from isaac_runtime.run import RunOptions, run_scene

    written = []  # relative to the folder (the staging folder they are written into goes away)

    def more(folder: Path, result) -> list:
        paths = _write(folder, scene, scene_path, fmt, result.recorder.arrays(), rib_options)
        written[:] = [Path(p).relative_to(folder) for p in paths]
        return paths

    run_scene(scene, out, RunOptions(folder=scene_path.parent), scene_path=scene_path, more=more)
    return _said(scene, fmt, f"a new run ({out / 'trajectory.npz'})", [out / p for p in written])


def _write(folder: Path, scene, scene_path: Path, fmt: str, arrays: dict, rib_options) -> list:
    if fmt == "rib" and rib_options is not None:
        _check_frames(rib_options.frames, len(arrays["time"]))
    if fmt == "rib":
        from isaac_runtime.export.rib import write_rib

        return write_rib(folder / "rib", scene, arrays, rib_options, scene_path.parent)
    from isaac_runtime.export.gltf import write_gltf

    return [write_gltf(folder / f"{scene.name}.{fmt}", scene, arrays, scene_path.parent)]


def _said(scene, fmt: str, source: str, paths: list) -> list:
    where = paths[0] if len(paths) == 1 else f"{len(paths)} files in {paths[0].parent}/"
    print(f"{scene.name}: {fmt} from {source}: {where}")
    return paths


def _check_frames(frames: slice, count: int) -> None:
    """--frames must select at least one frame of the run (a SceneError, exit 2, says which there are)."""
    if not range(count)[frames]:
        from isaac_ir.diagnostics import Diagnostic, SceneError

        start, stop, step = frames.start, frames.stop, frames.step
        one = step is None and start is not None and stop == start + 1  # `--frames 42`
        parts = (start, stop) + ((step,) if step else ())
        spec = str(start) if one else ":".join("" if v is None else str(v) for v in parts)
        raise SceneError([Diagnostic(f"--frames {spec} selects no frame: the run has {count} frames, "
                                     f"0 to {count - 1}", None, "e.g. --frames 0:100:10, or --frames 42")])
