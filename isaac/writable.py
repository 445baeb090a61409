"""An output folder checked before any work: a command that would write there (golden --update, sweep --out)
refuses it first, not after running every variant.

The check makes a file and removes it, in the folder or, when the folder is not made yet, in the nearest folder
above it that exists: permission bits alone do not say (root passes them on a folder of mode 555, a read-only
mount refuses everyone).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from isaac_ir.diagnostics import Diagnostic, SceneError

SYSTEM_TREES = ("/proc", "/sys", "/dev")


def writable_folder_problem(folder) -> str | None:
    """Why the outputs cannot be written into `folder` (made if missing), or None."""
    try:
        real = os.path.realpath(folder)
    except ValueError:  # a NUL byte
        return "its name holds a NUL byte"
    if any(real == tree or real.startswith(tree + "/") for tree in SYSTEM_TREES):
        return f"it is in {real.split('/')[1] and '/' + real.split('/')[1]}, not a place for outputs"
    if os.path.lexists(real) and not os.path.isdir(real):
        return "it is a file, not a folder (the outputs are a folder of files)"
    existing = real
    while not os.path.exists(existing):
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        return f"it cannot be made: `{existing}` is a file"
    return _probe(Path(existing))


def _probe(folder: Path) -> str | None:
    try:
        fd, name = tempfile.mkstemp(prefix=".isaac-probe-", dir=folder)
    except OSError as error:
        return f"`{folder}` is not writable ({error.strerror or error})"
    os.close(fd)
    os.unlink(name)
    return None


def check_output_folder(folder, option: str) -> None:
    """A SceneError (exit 2) naming the option when the folder cannot take the outputs."""
    problem = writable_folder_problem(folder)
    if problem is not None:
        raise SceneError([Diagnostic(f"{option} `{folder}`: {problem}", None,
                                     "name a folder you can write, or make this one writable")])
