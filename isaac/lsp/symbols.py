"""The outline of a document: its scene, parts and kinds, and inside them the bodies, constraints, sounds and
every other declaration, nested as they are written."""
from __future__ import annotations

from dataclasses import dataclass, field

from .index import SceneIndex

# what the outline shows of each kind of declaration, as LSP's SymbolKind names (see server.py)
OUTLINE_KINDS = {
    "scene": "Module", "part": "Class", "kind": "Function", "instance": "Object", "body": "Object",
    "piece": "Field", "material": "Constant", "constraint": "Struct", "force": "Operator", "wind": "Field",
    "sound": "Event", "camera": "Object", "light": "Object", "let": "Variable",
}


@dataclass
class OutlineItem:
    name: str
    kind: str  # a key of OUTLINE_KINDS
    detail: str  # its first line as written
    first_line: int  # 1-based, in the document
    last_line: int
    name_span: object  # index.Span of its name
    children: list = field(default_factory=list)


def outline(index: SceneIndex) -> list:
    """The declarations of the index's root file, each inside the one whose lines enclose it."""
    declared = sorted((d for d in index.definitions if d.span.path == index.root and d.kind in OUTLINE_KINDS),
                      key=lambda d: (d.extent[0], -d.extent[1], d.order))
    roots, open_items = [], []
    for definition in declared:
        item = OutlineItem(definition.name, definition.kind, definition.header, definition.extent[0],
                           definition.extent[1], definition.span)
        while open_items and open_items[-1].last_line < item.first_line:
            open_items.pop()
        enclosing = next((o for o in reversed(open_items) if o.first_line <= item.first_line
                          and item.last_line <= o.last_line
                          and (o.first_line, o.last_line) != (item.first_line, item.last_line)), None)
        (enclosing.children if enclosing else roots).append(item)
        open_items.append(item)
    return roots
