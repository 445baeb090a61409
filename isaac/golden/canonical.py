"""The IR as a golden keeps it: what the scene means, apart from where it is written.

Every declaration of the IR carries its source position ("swing.isaac:12:3"), and the scene its file name; a
comment line, a blank line or a moved declaration changes them and nothing else. `split` takes them out of the
canonical IR into a table of their own (kept in positions.json, never compared), so that the IR golden changes
only when the meaning does:

    meaning, positions = split(ir.to_data(scene))
    positions == {"file": "swing.isaac", "bodies[bob]": "swing.isaac:12:3", ...}
"""
from __future__ import annotations

import re

# a position inside a text (a warning): `file:line:col: `
_POSITION = re.compile(r"(?:[^\s:]+):\d+:\d+: ")


def split(data: dict) -> tuple:
    """(the IR data without positions, {path: position}); paths name list items by their `name` when they have
    one (`bodies[bob]`), else by index. Taken out: every declaration's `source`, and the scene's `file` (a mesh's
    `file` is meaning, and stays)."""
    positions: dict = {}
    top = {key: value for key, value in data.items() if key != "file"}
    if isinstance(data.get("file"), str):
        positions["file"] = data["file"]
    return _strip(top, "", positions), positions


def _strip(value, path: str, positions: dict):
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            if key == "source" and isinstance(item, str):
                positions[path or "scene"] = item
                continue
            out[key] = _strip(item, f"{path}.{key}" if path else key, positions)
        return out
    if isinstance(value, list):
        return [_strip(item, f"{path}[{item_name(item, k)}]", positions) for k, item in enumerate(value)]
    return value


def item_name(item, index: int) -> str:
    """How a list item is named in a path: its `name`, else its index."""
    if isinstance(item, dict) and isinstance(item.get("name"), str):
        return item["name"]
    return str(index)


def without_positions(text: str) -> str:
    """A message with the positions it quotes taken out (warnings name the line they are about)."""
    return _POSITION.sub("", text)
