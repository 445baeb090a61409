"""Sweep stage 2, the bundle: the scene and every file it reads, as bytes, so that a task runs on any worker
that has the package installed (no shared file system), and the stable id of each variant.

What a scene reads is named by its string literals: `include "lib/materials.isaac"` (relative to the including
file), `envelope("assets/breath.wav")`, a mesh's `file "assets/cube.obj"`, a sound's texture (relative to the
scene's folder). Every string of the scene and of the files it includes that names an existing file, relative
to either folder, travels; the files keep their places relative to each other (their common folder becomes the
bundle's root), so the worker finds them where the scene looks. An absolute path is left as it is: the worker
must have that file itself.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Bundle:
    """The scene (`scene`: its path inside the bundle, posix) and its files: relative posix path -> bytes."""

    scene: str
    files: dict = field(repr=False)
    digest: str = ""  # sha256 over the paths and bytes: what the variants' ids are made from

    @property
    def text(self) -> str:
        return self.files[self.scene].decode("utf-8")


def collect(scene_path) -> Bundle:
    """Read the scene and, following its string literals (includes recursively), every file it names."""
    scene_path = Path(scene_path).resolve()
    found = {scene_path}
    queue = [scene_path]
    while queue:
        source = queue.pop()
        for name in _strings(source):
            for target in _candidates(name, source.parent, scene_path.parent):
                if target not in found:
                    found.add(target)
                    if target.suffix == ".isaac":
                        queue.append(target)
    root = Path(os.path.commonpath([p.parent for p in found]))
    files = {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(found)}
    scene = scene_path.relative_to(root).as_posix()
    return Bundle(scene, files, _digest(files, scene))


def _strings(path: Path) -> list:
    """The string literals of a scene file (without quotes), from its parse tree; none when it does not parse
    (the variant then fails with that syntax error, reported by the loader)."""
    from lark import Token

    from isaac_ir.diagnostics import Reporter
    from isaac_lang.syntax import parse_text

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    tree = parse_text(text, path.name, Reporter())
    if tree is None:
        return []
    tokens = tree.scan_values(lambda v: isinstance(v, Token) and v.type == "STRING")
    return sorted({str(token)[1:-1] for token in tokens})


def _candidates(name: str, here: Path, scene_folder: Path) -> list:
    """The existing files a string may name: relative to the file it is written in, or to the scene's folder."""
    if not name or Path(name).is_absolute():
        return []
    out = []
    for folder in (here, scene_folder):
        try:
            path = (folder / name).resolve()
            if path.is_file() and path not in out:
                out.append(path)
        except (OSError, RuntimeError, ValueError):  # too long, a loop of links, a NUL byte: not a file
            continue
    return out


def _digest(files: dict, scene: str) -> str:
    sha = hashlib.sha256(scene.encode())
    for name in sorted(files):
        sha.update(b"\0" + name.encode() + b"\0" + hashlib.sha256(files[name]).digest())
    return sha.hexdigest()


def unpack(bundle: Bundle, folder: Path) -> Path:
    """Write the bundle's files under folder; returns the scene file's path there."""
    folder = Path(folder)
    for name, data in bundle.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return folder / bundle.scene


def variant_id(bundle: Bundle, values: dict, options: dict) -> str:
    """A stable id (16 hex digits) of one variant: the scene and its files, the values set, the run options.
    The same sweep run again (on any machine, with any number of workers) gives the same ids."""
    key = json.dumps({"scene": bundle.digest, "set": values, "options": options}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]
