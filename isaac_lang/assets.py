"""Stage 3b, assets: every file a scene names is found and read when the scene is checked, before anything runs.

The files: a mesh body's `file`, a material's `texture`, a recording in `envelope("breath.wav")` (a wind's speed,
a sound's graph) and `scrape(..., texture = "file")`. They are named relative to the scene's folder (a mesh
relative to the file that names it, which lowering has turned into the same thing); the runtime looks for them
in the same place (isaac_runtime.signals.find_asset). A missing or unreadable file is a positioned error at the
quoted name when it can be found in the source, else at the declaration that names it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from isaac_ir import expr as E
from isaac_ir.diagnostics import Reporter, SourceCache, SourcePos
from isaac_ir.files import MAX_ASSET_BYTES, Confinement

# files read as sound (their header, by soundfile): recordings
SOUND_SUFFIXES = (".wav", ".flac", ".ogg", ".aiff", ".aif", ".mp3")
# how many lines after a declaration's start its quoted file name is looked for
SEARCH_LINES = 40


@dataclass(frozen=True)
class Asset:
    kind: str  # mesh | texture | recording
    name: str  # as the IR has it: relative to the scene's folder, or absolute
    source: str  # the declaration that names it, "file:line:col"


def named_assets(scene) -> list:
    """Every file the scene names, once per (kind, name, declaration), in the order of the scene."""
    found = []
    for body in scene.bodies:
        if body.shape.file:
            found.append(Asset("mesh", body.shape.file, body.source))
    for material in scene.materials:
        if material.texture:
            found.append(Asset("texture", material.texture, material.source))
    for owner, tree in [(w, w.speed) for w in scene.winds] + [(s, s.graph) for s in scene.sounds]:
        found += [Asset(kind, name, owner.source) for kind, name in _files_in(tree)]
    return list(dict.fromkeys(found))


def _files_in(tree) -> list:
    """(kind, name) of the files an expression names: envelope("file"), texture = "file". Iterative: an
    expression may be long."""
    files, stack = [], [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, E.Call):
            if node.fn == "envelope" and node.args and isinstance(node.args[0], E.Str):
                files.append(("recording", node.args[0].value))
            files += [("texture", value.value) for key, value in node.kwargs
                      if key == "texture" and isinstance(value, E.Str)]
            stack += list(node.args) + [value for _, value in node.kwargs]
        elif isinstance(node, E.Op):
            stack += list(node.args)
        elif isinstance(node, E.Vec):
            stack += list(node.items)
        elif isinstance(node, E.Deriv):
            stack.append(node.arg)
    return files


def check_assets(scene, folder: Path, reporter: Reporter, sources: SourceCache) -> None:
    """Resolve and read each named file; report every one that is missing or unreadable."""
    for asset in named_assets(scene):
        problem = _read(asset, resolve(asset.name, folder))
        if problem is not None:
            message, hint = problem
            reporter.error(message, _position(asset, sources), hint)


def resolve(name: str, folder: Path) -> Path:
    """Where the runtime will look for a named file: as written when absolute, else in the scene's folder."""
    path = Path(name)
    return path if path.is_absolute() else Path(folder) / path


def _read(asset: Asset, path: Path):
    """None when the file is there and can be read, else (message, hint)."""
    what = {"mesh": "mesh file", "texture": "texture file", "recording": "sound file"}[asset.kind]
    if not path.exists():
        return (f"no such {what}: `{asset.name}`",
                f"looked for {path}; a file is named relative to the scene's folder"
                + (" (a mesh: relative to the file that names it)" if asset.kind == "mesh" else ""))
    if not path.is_file():
        return f"the {what} `{asset.name}` is not a regular file", f"{path} is a folder or a device"
    try:
        with open(path, "rb") as handle:
            handle.read()
    except OSError as error:
        return f"cannot read the {what} `{asset.name}`: {error.strerror or error}", f"check the permissions of {path}"
    if asset.kind == "recording" or path.suffix.lower() in SOUND_SUFFIXES:
        return _read_sound(asset, path)
    return None


def _read_sound(asset: Asset, path: Path):
    try:
        import soundfile
    except (ImportError, OSError) as error:  # a core dependency; its C library may still be missing
        return (f"cannot read the sound file `{asset.name}`: soundfile cannot be imported ({error})",
                "pip install soundfile")
    try:
        soundfile.info(str(path))
    except Exception as error:  # soundfile raises LibsndfileError / RuntimeError for what it cannot read
        return f"cannot read `{asset.name}` as sound: {error}", "use a WAV, FLAC or OGG file"
    return None


def _position(asset: Asset, sources: SourceCache) -> SourcePos | None:
    """The quoted file name in the source after its declaration's start, else the declaration."""
    decl = SourcePos.parse(asset.source)
    if decl is None:
        return None
    lines = sources.lines(decl.file) or []
    parts = Path(asset.name).parts
    # the name as written may be shorter than the IR's (a mesh named relative to an included file)
    written = ['"' + "/".join(parts[k:]) + '"' for k in range(len(parts))]
    for number in range(decl.line, min(len(lines), decl.line + SEARCH_LINES) + 1):
        text = lines[number - 1]
        start = decl.col - 1 if number == decl.line else 0
        for quoted in written:
            col = text.find(quoted, start)
            if col >= 0:
                return SourcePos(decl.file, number, col + 1, len(quoted))
    return decl


def refused_assets(scene, folder, confinement: Confinement | None) -> list:
    """[(asset, FileRefused)] of the textures and recordings a scene names that it may not
    read: one outside the scene's folders, a device, a FIFO, a file too large, one under /proc, /sys or /dev
    (meshes are confined where they are named: isaac_ir/meshfile.py)."""
    if confinement is None:
        return []
    found = []
    for asset in named_assets(scene):
        if asset.kind != "mesh":
            refused = confinement.refusal(resolve(asset.name, folder or "."), MAX_ASSET_BYTES[asset.kind])
            found += [(asset, refused)] if refused is not None else []
    return found
