"""Where the scene-wide settings were written (`time`, `frames`, `audio { rate }`, `solver ... { step }`), kept
beside the IR (ir.Scene.origins) so that a later stage can point at the setting it has a problem with: the
plan's budgets (runtime/plan/budgets.py) say "this `frames 1e9 Hz` asks for 1e10 frames" at the `1e9 Hz`."""
from __future__ import annotations

from lark import Tree


def setting_origins(expansion) -> tuple:
    """(("scene", pos), ("time", pos), ("audio.rate", pos), ("solver", pos), ("solver.step", pos), ...), each
    pos "file:line:col" of the value as written (the first writing of a setting; the solver: the last block)."""
    found = {}
    if expansion.scene_names:
        found["scene"] = expansion.scene_names[0][1]
    for tree, _, lowerer in expansion.settings:
        name, value = str(tree.children[0]), tree.children[1]
        found.setdefault(name, lowerer.pos(value) or lowerer.pos(tree))
        _block(found, name, value, lowerer)
    for tree, _, lowerer in expansion.solvers[-1:]:
        found["solver"] = lowerer.pos(tree)
        _block(found, "solver", tree.children[1] if len(tree.children) > 1 else None, lowerer)
    return tuple(sorted((name, str(pos)) for name, pos in found.items() if pos is not None))


def _block(found: dict, owner: str, block, lowerer) -> None:
    """The properties of a `{ ... }` as `owner.name`."""
    if not (isinstance(block, Tree) and block.data == "block"):
        return
    for prop in block.children:
        key, value = prop.children
        name = str(key.children[0] if isinstance(key, Tree) else key)
        found.setdefault(f"{owner}.{name}", lowerer.pos(value) or lowerer.pos(prop))
