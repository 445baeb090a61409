"""One error family for syntax, semantic and runtime problems in a scene.

Every diagnostic carries a position and prints the gcc way:

    scenes/pendulum.isaac:12:25: error: unknown body `bobb`
       12 |   constraint hang nail(bobb @ (0, 0.05, 0), (0, 1, 0))
          |                        ^~~~
    hint: did you mean `bob`?
"""
from __future__ import annotations

import dataclasses
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
            text, col = _window(printable(text), self.pos.col)
            lines.append(gutter + text)
            underline = "^" + "~" * max(0, min(self.pos.length, len(text) - col + 1, ECHO_WIDTH) - 1)
            lines.append(" " * 5 + " | " + " " * (col - 1) + underline)
        if self.hint:
            lines.append(f"hint: {self.hint}")
        return "\n".join(lines)


# the most characters of a source line echoed under a diagnostic (a longer line is cut around the caret)
ECHO_WIDTH = 160


def _window(text: str, col: int) -> tuple:
    """(the part of a long line around column col, col within that part)."""
    if len(text) <= ECHO_WIDTH:
        return text, col
    start = max(0, min(col - 1 - ECHO_WIDTH // 2, len(text) - ECHO_WIDTH))
    head = "..." if start > 0 else ""
    part = text[start:start + ECHO_WIDTH]
    tail = "..." if start + ECHO_WIDTH < len(text) else ""
    return head + part + tail, col - start + len(head)


class SceneError(Exception):
    """A problem in the scene (exit code 2): one or more diagnostics, all reported together."""

    def __init__(self, diagnostics: list[Diagnostic], sources: "SourceCache | None" = None):
        self.diagnostics = list(diagnostics)
        self.sources = sources  # the texts the scene was read from, when the loader knows them
        super().__init__("\n".join(d.message for d in self.diagnostics))

    def format(self, sources: "SourceCache | None" = None) -> str:
        """Every diagnostic with its source line and caret (from `sources`, else from the texts the scene was read
        from)."""
        sources = sources if sources is not None else self.sources
        return "\n".join(d.format(sources) for d in self.diagnostics)


def source_lines(text: str) -> list:
    """The lines of a text as the lexer counts them: a line ends at `\n` alone (with a `\r` before it dropped),
    so that a form feed, a lone `\r` or a Unicode line separator inside a line leaves the line numbers where the
    lexer has them (str.splitlines would break there too)."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


# control characters and separators of the echoed line, each shown as one blank so that the caret stays under
# its column (the lexer counts every character as one column)
_BLANKS = {code: " " for code in list(range(0x20)) + [0x7F, 0x85, 0x2028, 0x2029]}


def printable(line: str) -> str:
    """A source line as a terminal can show it, one character per column."""
    return line.translate(_BLANKS)


class SourceCache:
    """The text of every file a run has read, so a diagnostic can show its source line."""

    def __init__(self):
        self._lines: dict[str, list[str]] = {}

    def add(self, name: str, text: str) -> None:
        self._lines[name] = source_lines(text)

    def alias(self, name: str, other: str) -> None:
        """Let `other` name the same text as `name` (a file as the user reached it, for printing)."""
        if name in self._lines:
            self._lines[other] = self._lines[name]

    def lines(self, name: str) -> list[str] | None:
        """Every line of a file read so far (None if it was not)."""
        return self._lines.get(name)

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
        self.warnings: list[str] = []  # of the front end, as text (`warn`)
        self._at: dict = {}  # (file, line, col) -> index of the diagnostic reported there
        self._again: dict = {}  # index -> how many more times that place was reached (loop iterations, parts)

    def error(self, message: str, pos: SourcePos | None, hint: str | None = None) -> None:
        diagnostic = Diagnostic(message, pos, hint)
        # one diagnostic per place in the source: a loop's body or a part used twice reaches it again, with other
        # names (`link3`, `link4`) but the same mistake
        where = (pos.file, pos.line, pos.col) if pos is not None else None
        if where is not None and where in self._at:
            index = self._at[where]
            self._again[index] = self._again.get(index, 0) + 1
            return
        if len(self.diagnostics) < self.LIMIT and diagnostic not in self.diagnostics:
            if where is not None:
                self._at[where] = len(self.diagnostics)
            self.diagnostics.append(diagnostic)

    def warn(self, message: str, pos: SourcePos | None, hint: str | None = None) -> None:
        """A warning of the front end, kept as text (`file:line:col: message`, a last line `hint: ...`), once per
        place in the source (a loop reaches it again)."""
        text = (f"{pos}: " if pos is not None else "") + message + (f"\nhint: {hint}" if hint else "")
        if text not in self.warnings:
            self.warnings.append(text)

    def replace(self, index: int, diagnostic: Diagnostic) -> None:
        """Put a better diagnostic in the place of one already reported (the same position)."""
        self.diagnostics[index] = diagnostic

    def fatal(self, message: str, pos: SourcePos | None, hint: str | None = None) -> "SceneError":
        """Record an error and return the exception that stops the pass now."""
        self.error(message, pos, hint)
        return SceneError(self.reported())

    def reported(self) -> list:
        """The diagnostics, each saying how many more times its place was reached."""
        out = []
        for index, diagnostic in enumerate(self.diagnostics):
            again = self._again.get(index, 0)
            if again:
                note = f"(reached {again} more time{'s' if again > 1 else ''}: a loop or a part repeats this line)"
                diagnostic = dataclasses.replace(diagnostic, hint=f"{diagnostic.hint} {note}" if diagnostic.hint
                                                 else note)
            out.append(diagnostic)
        return out

    def raise_if_any(self) -> None:
        if self.diagnostics:
            # reported in the order of the file, the way a reader fixes them
            ordered = sorted(self.reported(), key=lambda d: (d.pos is None, d.pos.file if d.pos else "",
                                                             d.pos.line if d.pos else 0, d.pos.col if d.pos else 0))
            raise SceneError(ordered)


def warning_diagnostic(text: str, severity: str = "warning") -> Diagnostic:
    """A warning of the front end or the plan (`file:line:col: message`, or a bare message) as a Diagnostic, so
    that it prints the gcc way (`file:line:col: warning: message`, the source line, a caret); a last line
    `hint: ...` is its hint."""
    text, sep_hint, hint = text.partition("\nhint: ")
    head, sep, rest = text.partition(": ")
    pos = SourcePos.parse(head) if sep else None
    return Diagnostic(rest if pos is not None else text, pos, hint=hint if sep_hint else None, severity=severity)


def counted(count: int, noun: str) -> str:
    """`1 body`, `2 bodies`, `1 pair`, `3 pairs`: a count with its noun in the right number."""
    if count == 1:
        return f"1 {noun}"
    plural = noun[:-1] + "ies" if noun.endswith("y") and noun[-2:-1] not in "aeiou" else noun + "s"
    return f"{count} {plural}"


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
    except (ValueError, RuntimeError, OSError):  # outside the folder; a NUL byte; a loop of symbolic links
        return str(path)
