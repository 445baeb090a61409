"""A trajectory given on the command line (`isaac export --trajectory FILE`): read through isaac_ir/files.py
(a regular file, bounded, never a device or a system file) and checked against the scene before anything is
written: an npz of `time` (T,), `bodies` (B,) naming exactly the scene's bodies, `position` (T, B, 3) and
`orientation` (T, B, 4), every number finite. Each refusal is a SceneError (exit 2) saying what is wrong.
"""
from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from isaac_ir.diagnostics import Diagnostic, SceneError
from isaac_ir.files import MiB, Confinement, FileRefused

# bytes: the largest trajectory read, packed and unpacked (a 10,000-frame run of 1,000 bodies is 560 MB)
MAX_TRAJECTORY_BYTES = 1024 * MiB
HINT = "give the trajectory.npz that `isaac run` wrote for this scene"
SHAPES = {"position": 3, "orientation": 4}


def refused(path: Path, message: str) -> SceneError:
    return SceneError([Diagnostic(f"--trajectory {path}: {message}", None, HINT)])


def read_trajectory(path: Path, scene) -> dict:
    """The arrays of the trajectory file at path, checked against the scene; SceneError when unusable."""
    try:
        data = Confinement.for_scene(Path(path).parent).read_bytes(path, MAX_TRAJECTORY_BYTES, anywhere=True)
    except FileRefused as error:
        raise refused(path, f"cannot read it: {error.message}") from None
    arrays = _unpack(path, data)
    _check(path, arrays, [body.name for body in scene.bodies])
    return arrays


def _unpack(path: Path, data: bytes) -> dict:
    """The npz's arrays; none may hold objects (allow_pickle=False), nor unpack beyond the size limit."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            unpacked = sum(item.file_size for item in archive.infolist())
        if unpacked > MAX_TRAJECTORY_BYTES:
            raise refused(path, f"it unpacks to {unpacked / MiB:.0f} MiB, more than the "
                                f"{MAX_TRAJECTORY_BYTES // MiB} MiB a trajectory may hold")
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except SceneError:
        raise
    # not a zip, a member that is not an array, a pickled object, a truncated member
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, NotImplementedError) as error:
        raise refused(path, f"it is not a trajectory.npz ({type(error).__name__})") from None


def _check(path: Path, arrays: dict, scene_bodies: list) -> None:
    missing = [name for name in ("time", "bodies", "position", "orientation") if name not in arrays]
    if missing:
        raise refused(path, f"it has no `{missing[0]}` array (it holds: {', '.join(sorted(arrays)) or 'nothing'})")
    time = arrays["time"]
    if time.ndim != 1 or len(time) == 0 or time.dtype.kind not in "fiu":
        raise refused(path, "its `time` is not a list of frame times")
    names = [str(name) for name in np.asarray(arrays["bodies"]).reshape(-1)]
    if sorted(names) != sorted(scene_bodies):
        other = sorted(set(names) ^ set(scene_bodies))
        raise refused(path, f"it is not a run of this scene: its bodies and the scene's differ (`{other[0]}`)"
                      if other else "it is not a run of this scene: a body is listed twice")
    for key, width in SHAPES.items():
        value = arrays[key]
        if value.dtype.kind not in "fiu" or value.shape != (len(time), len(names), width):
            raise refused(path, f"its `{key}` has shape {value.shape}, not ({len(time)}, {len(names)}, {width})")
    for key in ("time", *SHAPES):
        if not np.all(np.isfinite(arrays[key])):
            frame = int(np.flatnonzero((~np.isfinite(arrays[key])).reshape(len(time), -1).any(axis=1))[0])
            raise refused(path, f"its `{key}` is not finite at frame {frame} (a run that blew up?)")
    if np.any(np.diff(time) < 0):
        raise refused(path, "its frame times go backwards")
