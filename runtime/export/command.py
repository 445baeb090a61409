"""`isaac export`: find (or make) the run of a scene, then write it as RIB or glTF.

The trajectory comes from, in order: --trajectory FILE; the output folder's trajectory.npz when that folder's
ir.json is this very scene (same canonical IR); else a new run of the scene (which writes the usual outputs too).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from isaac_lang import ir


def load_trajectory(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as data:
        return dict(data)


def trajectory_for(scene, scene_path: Path, out: Path, given: Path | None = None) -> tuple:
    """(arrays, where they came from). May run the scene (and then writes its outputs into out)."""
    if given is not None:
        return load_trajectory(given), str(given)
    saved = out / "trajectory.npz"
    if saved.is_file() and (out / "ir.json").is_file():
        try:
            same = json.loads((out / "ir.json").read_text()) == json.loads(ir.to_json(scene))
        except (OSError, ValueError):
            same = False
        if same:
            return load_trajectory(saved), f"{saved} (this scene's last run)"
    from ..run import RunOptions, run_scene

    code = run_scene(scene, out, RunOptions(folder=scene_path.parent), scene_path=scene_path)
    if code != 0 and not saved.is_file():
        raise RuntimeError(f"the run of {scene_path} wrote no trajectory")
    return load_trajectory(saved), f"a new run ({saved})"


def export(scene, scene_path: Path, out: Path, fmt: str, trajectory: Path | None = None, rib_options=None) -> list:
    """Write the export; returns the written paths."""
    arrays, source = trajectory_for(scene, scene_path, out, trajectory)
    folder = scene_path.parent
    if fmt == "rib" and rib_options is not None:
        _check_frames(rib_options.frames, len(arrays["time"]))
    if fmt == "rib":
        from .rib import write_rib

        paths = write_rib(out / "rib", scene, arrays, rib_options, folder)
    else:
        from .gltf import write_gltf

        paths = [write_gltf(out / f"{scene.name}.{fmt}", scene, arrays, folder)]
    where = paths[0] if len(paths) == 1 else f"{len(paths)} files in {paths[0].parent}/"
    print(f"{scene.name}: {fmt} from {source}: {where}")
    return paths


def _check_frames(frames: slice, count: int) -> None:
    """--frames must select at least one frame of the run (a SceneError, exit 2, says which there are)."""
    if not range(count)[frames]:
        from isaac_lang.diagnostics import Diagnostic, SceneError

        start, stop, step = frames.start, frames.stop, frames.step
        one = step is None and start is not None and stop == start + 1  # `--frames 42`
        parts = (start, stop) + ((step,) if step else ())
        spec = str(start) if one else ":".join("" if v is None else str(v) for v in parts)
        raise SceneError([Diagnostic(f"--frames {spec} selects no frame: the run has {count} frames, "
                                     f"0 to {count - 1}", None, "e.g. --frames 0:100:10, or --frames 42")])
