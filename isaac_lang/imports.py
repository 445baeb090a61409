"""Imports that a command's start-up should not pay for: `without(names)` hides modules while another package is
imported, so that it takes the path it has for their absence.

    with without("interegular"):     # lark then skips the terminal-collision check it runs when interegular
        import lark                  # is installed (40 ms of every command's start)

Only for the moment of that import: a later `import interegular` works as usual.
"""
from __future__ import annotations

import contextlib
import importlib.abc
import sys


class _Hidden(importlib.abc.MetaPathFinder):
    def __init__(self, names: tuple, why: str):
        self.names, self.why = names, why

    def find_spec(self, name, path=None, target=None):
        if any(name == n or name.startswith(n + ".") for n in self.names):
            raise ImportError(f"{name}: hidden while {self.why} is imported (isaac_lang.imports)")
        return None


@contextlib.contextmanager
def without(*names: str, why: str = "another package"):
    """Within the block, importing any of `names` (or their submodules) raises ImportError; modules already
    imported are unaffected."""
    guard = _Hidden(names, why)
    sys.meta_path.insert(0, guard)
    try:
        yield
    finally:
        sys.meta_path.remove(guard)
