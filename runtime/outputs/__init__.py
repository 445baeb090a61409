"""Stage 6, outputs: the trajectory sampled at the frame rate, and files written atomically.

trajectory.npz (docs/outputs.md): time (T,), bodies (B,) unicode, position (T,B,3), orientation (T,B,4) (w,x,y,z),
linear_velocity (T,B,3), angular_velocity (T,B,3), constraint_error (T,), energy (T,).
"""
from __future__ import annotations

import io
import json
import math
import os
import secrets
from pathlib import Path

import numpy as np


class Recorder:
    """Preallocated frame arrays, filled one frame at a time."""

    def __init__(self, frame_times: np.ndarray, names: list):
        T, B = len(frame_times), len(names)
        self.time = frame_times
        self.bodies = np.array(names, dtype=str)
        self.position = np.full((T, B, 3), np.nan)
        self.orientation = np.full((T, B, 4), np.nan)
        self.linear_velocity = np.full((T, B, 3), np.nan)
        self.angular_velocity = np.full((T, B, 3), np.nan)
        self.constraint_error = np.full(T, np.nan)
        self.energy = np.full(T, np.nan)
        # the row of that largest constraint error at each frame, -1 when not known (not in trajectory.npz; the
        # check of runtime/checks.py names the constraints that keep an error from it)
        self.worst = np.full(T, -1, np.int64)
        self.count = 0

    def record(self, state, constraint_error: float, energy: float, worst: int = -1) -> None:
        k = self.count
        self.worst[k] = worst
        self.position[k] = state.x
        self.orientation[k] = state.q
        self.linear_velocity[k] = state.v
        self.angular_velocity[k] = state.w
        self.constraint_error[k] = constraint_error
        self.energy[k] = energy
        self.count += 1

    def record_packed(self, y: np.ndarray, constraint_error: float, energy: float, worst: int = -1) -> None:
        """One frame from the packed state y (n,13) of the kernels: rows [x q v w]."""
        k = self.count
        self.worst[k] = worst
        self.position[k], self.orientation[k] = y[:, 0:3], y[:, 3:7]
        self.linear_velocity[k], self.angular_velocity[k] = y[:, 7:10], y[:, 10:13]
        self.constraint_error[k] = constraint_error
        self.energy[k] = energy
        self.count += 1

    def arrays(self) -> dict:
        """The recorded frames only (a run stopped by a blow-up keeps what it had)."""
        k = self.count
        return {"time": self.time[:k], "bodies": self.bodies, "position": self.position[:k],
                "orientation": self.orientation[:k], "linear_velocity": self.linear_velocity[:k],
                "angular_velocity": self.angular_velocity[:k], "constraint_error": self.constraint_error[:k],
                "energy": self.energy[:k]}


def write_atomic(path: Path, data: bytes) -> None:
    """Write to a temporary file beside path, then rename: a reader never sees half a file.

    The temporary is created with mode 0666 and the process's umask applies, as for any file the user's tools
    write (mkstemp would make it 0600: a viewer.html meant to be shared would be private to its writer)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _create_beside(path)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _create_beside(path: Path) -> tuple:
    """(fd, name) of a new, empty file `.NAME.RANDOM` in path's folder; O_EXCL: never one that exists."""
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}"
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666), tmp
        except FileExistsError:
            continue


# the files `isaac run` writes into its output folder (runtime/outputs/outputset.py: the names that are isaac's in a
# folder written before manifests)
OWNED_FILES = ("trajectory.npz", "events.json", "ir.json", "report.json", "audio.wav", "viewer.html")
OWNED_PLOTS = ("energy.png", "constraint_error.png", "trajectories.png", "spectrogram.png")


def write_npz(path: Path, arrays: dict) -> None:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    write_atomic(path, buffer.getvalue())


def write_json(path: Path, data) -> None:
    """Strict JSON (any reader loads it): a figure that is not finite (a blow-up's NaN or infinity) is null. A list
    (events.json) is written one item a line: a run's thousands of contact events in a third of the time of the
    indented form (the standard library's encoder is compiled only for the unindented one), and one event a line
    to read or grep."""
    try:  # (a run's figures are finite but for a blow-up's: written as they are, numpy's made plain on the way)
        text = _json_text(data)
    except ValueError:  # a NaN or an infinity, which strict JSON refuses: null
        text = _json_text(finite_or_null(data))
    write_atomic(path, (text + "\n").encode())


def _json_text(data) -> str:
    """The JSON of data (write_json's layout); ValueError at a NaN or an infinity. The encoder's `default` makes
    numpy's scalars and arrays plain as it meets them (`_plain`), so that the figures are walked once, by the
    standard library's compiled encoder, instead of copied first (events.json: 0.13 s of a 12,700-event run)."""
    # (a run's events, outputs/events.py, write their blocks of rows themselves)
    json_items = getattr(data, "json_items", None)
    if isinstance(data, list) or json_items is not None:
        encode = json.JSONEncoder(sort_keys=True, allow_nan=False, default=_plain).encode
        items = map(encode, data) if json_items is None else json_items(encode)
        return "[\n" + ",\n".join(items) + "\n]" if len(data) else "[]"
    return json.dumps(data, indent=1, sort_keys=True, allow_nan=False, default=_plain)


def _plain(value):
    """A numpy value the JSON encoder cannot take as it is, as Python's (numpy's floats are Python floats)."""
    if isinstance(value, (np.bool_, np.integer, np.floating, np.ndarray)):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} as JSON")


def finite_or_null(value):
    """value with numpy scalars and arrays made plain, and every NaN or infinity made None."""
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return finite_or_null(value.tolist())
    if isinstance(value, dict):
        return {key: finite_or_null(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)) or hasattr(value, "json_items"):
        return [finite_or_null(item) for item in value]
    if value is None or isinstance(value, (str, int)):
        return value
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
