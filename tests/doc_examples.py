"""The scenes the documentation shows: every code block of docs/*.md (and README.md) that declares a scene.

    for example in scene_examples(): example.doc, example.line, example.name, example.text, example.error

A block is fenced (```isaac, or ``` with no language) or indented by four spaces. One that shows a mistake on
purpose is preceded by an HTML comment, `<!-- expect error: unknown body -->`: it must fail to load with that
message. Examples find their includes and assets in `example_folder` (tests/lang/data plus scenes/assets).
"""
from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
SCENE = re.compile(r"^\s*scene\s+(\w+)\s*\{", re.M)
_EXPECT = re.compile(r"<!--\s*expect error:\s*(.*?)\s*-->\s*$")


@dataclass(frozen=True)
class Example:
    doc: str  # docs/language.md
    line: int  # of the block's first line
    name: str  # the scene's name
    text: str
    error: str | None  # the message it must fail with, for a mistake shown on purpose

    @property
    def id(self) -> str:
        return f"{Path(self.doc).stem}:{self.line}:{self.name}"


def scene_examples() -> list:
    examples = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for start, block in _blocks(text):
            found = SCENE.search(block)
            if found:
                line = text.count("\n", 0, start) + 1
                # the line before the block (before its fence, for a fenced one)
                head = text[:start].rstrip("\n").split("\n")
                before = [l for l in head[-2:] if not l.startswith("```")][-1:] or [""]
                expect = _EXPECT.search(before[0])
                examples.append(Example(doc.relative_to(ROOT).as_posix(), line, found.group(1), block,
                                        expect.group(1) if expect else None))
    return examples


def _blocks(text: str):
    """(offset, text) of each fenced block whose language is isaac or none, and of each indented block outside
    fences. Fences are paired line by line (an info string opens, a bare ``` closes)."""
    offset, fence, indented = 0, None, None
    for line in text.splitlines(keepends=True):
        if fence is not None:
            if line.startswith("```"):
                if fence[1] in ("isaac", ""):
                    yield fence[0], "".join(fence[2])
                fence = None
            else:
                fence[2].append(line)
        elif line.startswith("```"):
            fence = (offset + len(line), line[3:].strip(), [])
        elif line.startswith("    ") or (indented is not None and not line.strip()):
            indented = indented or (offset, [])
            indented[1].append(line[4:] if line.startswith("    ") else line)
        if indented is not None and fence is None and not (line.startswith("    ") or not line.strip()):
            yield indented[0], "".join(indented[1])
            indented = None
        offset += len(line)
    if indented is not None:
        yield indented[0], "".join(indented[1])


def example_folder(where: Path) -> Path:
    """A folder with what the examples include and name: tests/lang/data (lib/) and scenes/assets/."""
    folder = Path(where) / "examples"
    if not folder.is_dir():
        shutil.copytree(ROOT / "tests" / "lang" / "data", folder)
        shutil.copytree(ROOT / "scenes" / "assets", folder / "assets")
    return folder
