"""A document checked as `isaac check` checks its file: the front end's errors and warnings, each with the file
it is in, from the text held in memory (the editor's, saved or not) and the open files it includes."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from isaac_ir import ir
from isaac.crash import internal_error
from isaac_ir.diagnostics import Diagnostic, SceneError, warning_diagnostic
from isaac_lang.load import load_text


@dataclass(frozen=True)
class Finding:
    """One diagnostic of the front end and the file it is in (None: it names no place, as `--set` ones)."""

    path: Path | None
    diagnostic: Diagnostic


@dataclass
class CheckResult:
    findings: list = field(default_factory=list)
    scene: ir.Scene | None = None  # the checked IR when the scene has no errors
    seconds: float = 0.0  # how long the front end took


def check_text(text: str, path: Path, texts: dict | None = None) -> CheckResult:
    """Check the scene `text` as the file at `path` (includes and assets resolve beside it; `texts`: real path ->
    text of other files held in memory)."""
    started = time.perf_counter()
    result = CheckResult()
    try:
        loaded = load_text(text, path.name, folder=path.parent, texts=texts)
    except SceneError as error:
        result.findings = [_finding(d, path.parent) for d in error.diagnostics]
    except Exception as error:  # a bug of the front end: said at the top of the file, never a dead server
        result.findings = [Finding(path, Diagnostic(internal_error(error), None))]
    else:
        result.scene = loaded.scene
        result.findings = [_finding(warning_diagnostic(text), path.parent) for text in loaded.warnings]
    result.seconds = time.perf_counter() - started
    return result


def _finding(diagnostic: Diagnostic, folder: Path) -> Finding:
    """The file of a diagnostic: its positions name files relative to the scene's folder (as the IR does)."""
    pos = diagnostic.pos
    if pos is None or pos.file.startswith("--set"):
        return Finding(None, diagnostic)
    file = Path(pos.file)
    return Finding(file if file.is_absolute() else folder / file, diagnostic)
