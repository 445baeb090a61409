"""One error family for syntax, semantic and runtime problems in a scene.

Every diagnostic carries a position and prints the gcc way:

    scenes/pendulum.isaac:12:25: error: unknown body `bobb`
       12 |   constraint hang nail(bobb @ (0, 0.05, 0), (0, 1, 0))
          |                        ^~~~
    hint: did you mean `bob`?
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class SourcePos:
    """A place in a scene file: 1-based line and column; `file` as the user named it."""

    file: str
    line: int
    col: int
    length: int = 1

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"

    @classmethod
    def parse(cls, source: str) -> "SourcePos | None":
        """'file:line:col' (as the IR keeps positions) back to a SourcePos; None if it is not one."""
        try:
            file, line, col = source.rsplit(":", 2)
            return cls(file, int(line), int(col))
        except ValueError:
            return None


@dataclass(frozen=True)
class Diagnostic:
    message: str
    pos: SourcePos | None
    hint: str | None = None
    severity: str = "error"

    def format(self, sources: "SourceCache | None" = None) -> str:
        where = f"{self.pos}: " if self.pos else ""
        lines = [f"{where}{self.severity}: {self.message}"]
        text = sources.line(self.pos) if (sources and self.pos) else None
        if text is not None:
            gutter = f"{self.pos.line:>5} | "
            lines.append(gutter + text.rstrip("\n").expandtabs(1))
            underline = "^" + "~" * max(0, min(self.pos.length, len(text) - self.pos.col + 1) - 1)
            lines.append(" " * 5 + " | " + " " * (self.pos.col - 1) + underline)
        if self.hint:
            lines.append(f"hint: {self.hint}")
        return "\n".join(lines)


class SceneError(Exception):
    """A problem in the scene (exit code 2): one or more diagnostics, all reported together."""

    def __init__(self, diagnostics: list[Diagnostic]):
        self.diagnostics = list(diagnostics)
        super().__init__("\n".join(d.message for d in self.diagnostics))

    def format(self, sources: "SourceCache | None" = None) -> str:
        return "\n".join(d.format(sources) for d in self.diagnostics)


class SourceCache:
    """The text of every file a run has read, so a diagnostic can show its source line."""

    def __init__(self):
        self._lines: dict[str, list[str]] = {}

    def add(self, name: str, text: str) -> None:
        self._lines[name] = text.splitlines()

    def alias(self, name: str, other: str) -> None:
        """Let `other` name the same text as `name` (a file as the user reached it, for printing)."""
        if name in self._lines:
            self._lines[other] = self._lines[name]

    def line(self, pos: SourcePos) -> str | None:
        lines = self._lines.get(pos.file)
        if lines is None or not (1 <= pos.line <= len(lines)):
            return None
        return lines[pos.line - 1]


class Reporter:
    """Collects diagnostics during a pass; `raise_if_any` ends the pass with all of them (jlox style)."""

    # more than this many errors in one run means the rest are mostly echoes of the first ones
    LIMIT = 50

    def __init__(self):
        self.diagnostics: list[Diagnostic] = []

    def error(self, message: str, pos: SourcePos | None, hint: str | None = None) -> None:
        diagnostic = Diagnostic(message, pos, hint)
        # the same mistake met again (a part used twice, a loop's body) is reported once
        if len(self.diagnostics) < self.LIMIT and diagnostic not in self.diagnostics:
            self.diagnostics.append(diagnostic)

    def fatal(self, message: str, pos: SourcePos | None, hint: str | None = None) -> "SceneError":
        """Record an error and return the exception that stops the pass now."""
        self.error(message, pos, hint)
        return SceneError(self.diagnostics)

    def raise_if_any(self) -> None:
        if self.diagnostics:
            # reported in the order of the file, the way a reader fixes them
            ordered = sorted(self.diagnostics, key=lambda d: (d.pos is None, d.pos.file if d.pos else "",
                                                              d.pos.line if d.pos else 0, d.pos.col if d.pos else 0))
            raise SceneError(ordered)


def did_you_mean(word: str, candidates, what: str = "") -> str | None:
    """A hint naming the closest candidate, or None when nothing is close."""
    close = difflib.get_close_matches(word, list(candidates), n=1, cutoff=0.6)
    if close:
        return f"did you mean `{close[0]}`?"
    return None


def display_path(path: Path, root: Path | None) -> str:
    """How a file is named in diagnostics and the IR: relative to the scene's folder when it is inside it."""
    try:
        return path.resolve().relative_to(root.resolve()).as_posix() if root else str(path)
    except ValueError:
        return str(path)
