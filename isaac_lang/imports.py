"""Imports that a command's start-up should not pay for: `without(names)` hides modules while another package is
imported, so that it takes the path it has for their absence.

    with without("interegular"):     # lark then skips the terminal-collision check it runs when interegular
        import lark                  # is installed (40 ms of every command's start)

Only for the moment of that import, and only in the thread that makes it: a later `import interegular` works as
usual, and so does one that another thread makes meanwhile (`isaac watch` imports the runtime, numba with it, in
a thread while the scene is loaded, and loading a scene may import scipy).
"""
from __future__ import annotations

import contextlib
import importlib.abc
import sys
import threading


class _Hidden(importlib.abc.MetaPathFinder):
    def __init__(self, names: tuple, why: str):
        self.names, self.why = names, why
        self.thread = threading.get_ident()  # (a finder is asked in the thread that imports)

    def find_spec(self, name, path=None, target=None):
        if threading.get_ident() != self.thread:
            return None
        if any(name == n or name.startswith(n + ".") for n in self.names):
            raise ImportError(f"{name}: hidden while {self.why} is imported (isaac_lang.imports)")
        return None


@contextlib.contextmanager
def without(*names: str, why: str = "another package"):
    """Within the block, importing any of `names` (or their submodules) in this thread raises ImportError; modules
    already imported, and other threads, are unaffected."""
    guard = _Hidden(names, why)
    sys.meta_path.insert(0, guard)
    try:
        yield
    finally:
        sys.meta_path.remove(guard)
