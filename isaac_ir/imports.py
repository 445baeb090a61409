"""Imports that a command's start-up should not pay for.

`without(names)` hides modules while another package is imported, so that it takes the path it has for their
absence:

    with without("interegular"):     # lark then skips the terminal-collision check it runs when interegular
        import lark                  # is installed (40 ms of every command's start)

Only for the moment of that import, and only in the thread that makes it: a later `import interegular` works as
usual, and so does one that another thread makes meanwhile (`isaac watch` imports the runtime, numba with it, in
a thread while the scene is loaded, and loading a scene may import scipy).

`lazily(name)` imports a module that a package imports at its top but uses only on a path a run never takes:
the module's code runs at its first use, if any (the standard library's `importlib.util.LazyLoader`).

    lazily("importlib.metadata")     # numba reads the installed packages' entry points only to compile
    import numba                     # (`from importlib import metadata`)

A first use is any attribute, `__spec__` too: a later `import importlib.metadata` statement runs it (Python's
import asks a module found in sys.modules whether it is still being initialised), `from importlib import
metadata` does not.
"""
from __future__ import annotations

import contextlib
import importlib.abc
import importlib.util
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
            raise ImportError(f"{name}: hidden while {self.why} is imported (isaac_ir.imports)")
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


def lazily(name: str) -> None:
    """Put `name` in sys.modules as a module whose code runs at its first attribute access (module docstring). An
    imported module, or one that cannot be found, is left as it is."""
    if name in sys.modules:
        return
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None or not hasattr(spec.loader, "exec_module"):
        return
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    parent, _, child = name.rpartition(".")
    if parent:
        setattr(sys.modules[parent], child, module)
