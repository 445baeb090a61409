"""Golden files on disk: a folder beside the scene, one JSON file per section.

    swing.isaac
    swing.golden/  meta.json  ir.json  positions.json  trajectory.json  events.json  report.json  [audio.json]
    swing.golden.toml   (optional: run options and tolerances, settings.py)

JSON for review in a diff: sorted keys, and each vector on one line (a trajectory reads as rows of numbers).
Files are written atomically; a section the record no longer has (a scene that lost its sound) is removed.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

SECTIONS = ("meta", "ir", "positions", "trajectory", "events", "report", "audio")


def golden_folder(scene: Path) -> Path:
    return Path(scene).with_name(Path(scene).stem + ".golden")


def has_golden(scene: Path) -> bool:
    return (golden_folder(scene) / "ir.json").is_file()


def read_golden(scene: Path) -> dict:
    """The sections on disk (name -> data); ValueError naming the file when one cannot be read."""
    folder = golden_folder(scene)
    out = {}
    for name in SECTIONS:
        path = folder / f"{name}.json"
        if os.path.lexists(path):
            out[name] = _read_section(path, Path(scene).parent)
    return out


# bytes: the largest golden file read (a golden keeps at most 20,000 body-samples: a few MiB)
MAX_GOLDEN_BYTES = 64 << 20


def _read_section(path: Path, folder: Path):
    """One golden file, read as a scene's files are (isaac_ir/files.py) and parsed as JSON; a SceneError at
    the file's line and column that quotes nothing of it."""
    from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos
    from isaac_ir.files import Confinement, FileRefused

    name = f"{path.parent.name}/{path.name}"
    hint = f"record the goldens again with `isaac golden {path.parent.parent / (path.parent.stem + '.isaac')} --update`"
    try:
        return json.loads(Confinement.for_scene(folder).read_text(path, MAX_GOLDEN_BYTES))
    except FileRefused as error:
        raise SceneError([Diagnostic(f"cannot read the golden file: {error.message}", SourcePos(name, 1, 1),
                                     error.hint or hint)]) from None
    except json.JSONDecodeError as error:
        raise SceneError([Diagnostic(f"cannot read the golden file: {error.msg}",
                                     SourcePos(name, error.lineno, error.colno), hint)]) from None
    except (RecursionError, ValueError) as error:  # nesting too deep for the parser; a number too long
        raise SceneError([Diagnostic(f"cannot read the golden file: {str(error)[:200]}", SourcePos(name, 1, 1),
                                     hint)]) from None


def write_golden(scene: Path, sections: dict) -> list:
    """Write every section; remove the files of sections not in `sections`. Returns the paths written."""
    from isaac_runtime.outputs import write_atomic

    folder = golden_folder(scene)
    written = []
    for name in SECTIONS:
        path = folder / f"{name}.json"
        if name in sections:
            write_atomic(path, (dumps(sections[name]) + "\n").encode("utf-8"))
            written.append(path)
        elif path.is_file():
            os.unlink(path)
    return written


def dumps(value, indent: int = 0) -> str:
    """JSON with sorted keys, one key or item per line, and short lists of numbers (vectors) on one line."""
    pad, inner = " " * indent, " " * (indent + 1)
    if isinstance(value, dict):
        if not value:
            return "{}"
        items = [f"{inner}{json.dumps(str(k))}: {dumps(value[k], indent + 1)}" for k in sorted(value)]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(value, list):
        if not value:
            return "[]"
        if len(value) <= INLINE and not any(isinstance(v, (dict, list)) for v in value):
            return "[" + ", ".join(_scalar(v) for v in value) + "]"
        return "[\n" + ",\n".join(inner + dumps(v, indent + 1) for v in value) + "\n" + pad + "]"
    return _scalar(value)


# lists of at most this many numbers or strings (a vector, a quaternion, a pair of names) stay on one line
INLINE = 6


# significant digits of a number in a golden: 1e-12 relative, a thousand times below the finest tolerance
DIGITS = 12


def _scalar(value) -> str:
    if isinstance(value, float):
        if not math.isfinite(value):
            return "null"  # JSON has no infinity (a blown-up run's figure)
        return json.dumps(float(f"{value:.{DIGITS}g}"))
    return json.dumps(value)
