"""The compiled core's decorators, its on-disk cache, and the notice for the first run on a machine.

Three kinds of compiled functions, all numba `njit` with numpy's error model (a division by zero gives inf or NaN,
which the step loop reports as a blow-up with its time and body, instead of raising inside a kernel), the GIL
released (the live mode steps in a thread while the page is served) and no reference counting (`_nrt=False`:
the kernels allocate nothing, they write into the scratch; numba refuses to compile one that would allocate,
and counting the references of every array of the model at every call was most of the time of a step):

    @kernel   an inner function, called only from compiled code: compiled as part of the entry point that calls
              it, so that LLVM may inline it there (a cached function can only be called, never inlined: numba
              links its machine code, not its IR)
    @inlined  an inner function that takes the model, the active rows or the scratch (named tuples of dozens of
              arrays): numba inlines it itself, at the IR level, since passing them to a call costs hundreds of
              words of arguments
    @entry    an entry point, called from Python: its machine code, with every kernel inlined into it, is cached
              on disk (the first run on a machine compiles, later runs load it)

Kernels take plain arrays, scalars and named tuples of arrays only (MuJoCo's model/data split), never Python
objects, so one signature serves every scene. numba checks a cached entry point against its own source file
only; `_refresh_cache` also drops the cache when any file of the compiled core has changed. A cached entry is
loaded without what only compiling needs: numba's refresh of its implementations (`_loads_without_refreshing`)
and the parse of its module for linking (`_rebuild_library`), 0.03 s instead of about 0.6 s on a slow machine.
"""
from __future__ import annotations

import hashlib
import os
import sys
import time
from pathlib import Path

from isaac_ir.imports import lazily, without

from ..outputs import write_atomic

# numba imports scipy, when it is installed, only to refuse a scipy older than 1.0 (pyproject asks for newer):
# 20 to 30 ms of every run's start (the stages that need scipy import what they use of it); and yaml, to read a
# .numba_config.yaml in the working folder, when there is one (10 ms). It imports importlib.metadata for the entry
# points of its extensions, which it reads only to compile (`_defer_extensions`): that code runs if used (20 ms)
lazily("importlib.metadata")
with without("scipy", *(() if os.path.isfile(".numba_config.yaml") else ("yaml",)), why="numba"):
    import numba
import llvmlite.binding as ll  # (numba's own LLVM binding, imported with it)

OPTIONS = {"error_model": "numpy", "nogil": True, "_nrt": False}
# the packages whose source the cached entry points are built from
_RUNTIME = Path(__file__).resolve().parent.parent
_SOURCES = ("core", "dynamics", "procedural", "wind", "capture")
# where the names of the symbols each cached library defines are kept (`_defined_names`)
_SYMBOLS = _RUNTIME / "core" / "__pycache__"


def kernel(function):
    """An inner compiled function (module docstring)."""
    return numba.njit(**OPTIONS)(function)


def inlined(function):
    """An inner compiled function inlined into its callers by numba (module docstring)."""
    return numba.njit(inline="always", **OPTIONS)(function)


def entry(function):
    """A compiled entry point, cached on disk (module docstring)."""
    dispatcher = numba.njit(cache=True, **OPTIONS)(function)
    _loads_without_refreshing(dispatcher)
    return dispatcher


def _source_digest() -> str:
    digest = hashlib.sha256(numba.__version__.encode())
    for package in _SOURCES:
        for path in sorted((_RUNTIME / package).glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


def _refresh_cache() -> None:
    """Drop numba's cache files of the core when its sources differ from the ones they were compiled from (a
    changed kernel that an entry point inlines would otherwise be served stale)."""
    try:
        digest = _source_digest()
        stamp = _RUNTIME / "core" / "__pycache__" / "isaac-kernels.digest"
        if stamp.exists() and stamp.read_text() == digest:
            return
        for package in _SOURCES:
            for cached in (_RUNTIME / package / "__pycache__").glob("*.nb[ic]"):
                cached.unlink(missing_ok=True)
        for listed in _SYMBOLS.glob("isaac-symbols-*.txt"):
            listed.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:
        pass  # a read-only install: numba then caches elsewhere, by its own rules


_refresh_cache()


def _loads_without_refreshing(dispatcher) -> None:
    """Let the entry point load its cached machine code without numba's `refresh()` of its target context first.

    A refresh installs every implementation numba has (its typing and lowering registries: unicode, sets, lists,
    random, the numpy API: 0.3 to 0.45 s here, a third of a cached run's start) and only compiling needs them;
    rebuilding cached code needs the context's code generator and the C helpers its `init` installed. A miss
    then compiles, and numba's compiler refreshes both contexts itself before compiling (CompilerBase.__init__).
    The library is rebuilt by `_rebuild_library`, which skips the parse of its module for linking. Any other
    numba (no such private methods): its own way."""
    cache = dispatcher._cache
    load, guard = getattr(cache, "_load_overload", None), getattr(cache, "_guard_against_spurious_io_errors", None)
    init = getattr(dispatcher, "_compilation_chain_init_hook", None)
    if load is None or guard is None or init is None:
        return

    def load_overload(sig, target_context):
        codegen = target_context.codegen()
        numbas = codegen.unserialize_library
        # (numba holds its compiler lock over a load: no other load sees the library maker swapped)
        codegen.unserialize_library = lambda state: _rebuild_library(codegen, state, numbas)
        loaded = None
        try:
            with guard():  # (an unreadable cache file counts as a miss, as numba's own load_overload has it)
                loaded = load(sig, target_context)
        finally:
            del codegen.unserialize_library
        if loaded is None:
            init()  # a miss: the extensions as numba has them before it compiles (`_defer_extensions`)
        return loaded

    cache.load_overload = load_overload
    _defer_extensions(dispatcher)


def _defer_extensions(dispatcher) -> None:
    """numba initialises the extensions installed beside it (the `numba_extensions` entry points of every
    installed package: importlib.metadata imported and the packages' metadata read, 30 ms here) before the first
    call of any dispatcher, for the types they may add to what it compiles. A cached entry point compiles nothing;
    its load, on a miss, initialises them before numba compiles (`load_overload` above)."""
    dispatcher._compilation_chain_init_hook = lambda: None


def _rebuild_library(codegen, state, numbas):
    """A code library from numba's cache, as numba's `unserialize_library(state)` rebuilds it but for its module
    for linking: numba parses that LLVM bitcode (every function of the entry, about 1 MB for the dynamics step:
    0.13 s of its 0.16 s load here) to learn which symbols the library defines, and keeps it for linking the
    library into other compiled code, which never calls our entry points. The names are read from a list kept
    beside numba's files (`_defined_names`), the module parsed only if something links against it
    (`_CachedLibrary`). Anything unexpected: numba's own way."""
    try:
        name, kind, (object_code, link_bitcode) = state
        defined = codegen._engine._defined_symbols
        ours = kind == "object" and codegen._library_class is _JITCodeLibrary  # (the class numba would build)
        names = _defined_names(link_bitcode) if ours else None
    except Exception:  # noqa: BLE001 (another layout of numba's cache)
        names = None
    if names is None:
        return numbas(state)
    library = _CachedLibrary(codegen, name)
    library.link_bitcode = link_bitcode
    library.enable_object_caching()
    library._set_compiled_object(object_code)
    library._finalize_final_module()
    # what numba's _load_defined_symbols records of the module for linking: its defined functions and globals
    defined |= names
    return library


def _defined_names(bitcode: bytes) -> set | None:
    """The functions and globals that an LLVM module (bitcode) defines: listed in a file named by its hash, made
    the first time by parsing it. None when neither works."""
    listed = _SYMBOLS / f"isaac-symbols-{hashlib.sha256(bitcode).hexdigest()[:32]}.txt"
    try:
        return set(listed.read_text(encoding="utf-8").split("\n")) - {""}
    except OSError:
        pass
    try:  # (what numba's JitEngine._load_defined_symbols takes of a module)
        module = ll.parse_bitcode(bitcode)
        names = {g.name for group in (module.functions, module.global_variables) for g in group
                 if not g.is_declaration}
    except Exception:  # noqa: BLE001
        return None
    try:  # written whole or not at all (another process may read it meanwhile)
        write_atomic(listed, ("\n".join(sorted(names)) + "\n").encode("utf-8"))
    except OSError:
        pass  # a read-only install: parsed at every start, as numba does
    return names


try:
    from numba.core.codegen import JITCodeLibrary as _JITCodeLibrary
except ImportError:  # another numba: `_rebuild_library` leaves every library to it
    _JITCodeLibrary = object


class _CachedLibrary(_JITCodeLibrary):
    """A library rebuilt from numba's cache whose module for linking is parsed only when something links against
    it (`_rebuild_library`)."""

    link_bitcode = None

    def _get_module_for_linking(self):
        if self._shared_module is None and self.link_bitcode is not None:
            self._shared_module = ll.parse_bitcode(self.link_bitcode)
        return super()._get_module_for_linking()


def is_cached(dispatcher) -> bool:
    """Whether numba's on-disk cache holds machine code for this entry point (from this source and numba version).
    Reads numba's index file; any doubt counts as not cached (the notice is then shown needlessly, no harm)."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:
        return False


class Bound:
    """An entry point called many times by one caller with arguments of unchanging types (a run's model, active
    rows, scratch, state and buffers: one signature serves every scene). The first call goes through numba's
    dispatcher, which types every argument (about 140 arrays in named tuples: 20 us), then loads or compiles;
    the later ones call that overload's compiled wrapper directly (2.4 us). A scene whose audio or collision stage
    steps one call at a time makes thousands of calls (the cradle: 5,000 in 5 s)."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self.call = None

    def __call__(self, *args):
        if self.call is not None:
            return self.call(*args)
        result = self.dispatcher(*args)
        overloads = self.dispatcher.overloads
        if len(overloads) == 1:  # the one there is served this call (typing the arguments again costs 0.8 ms)
            self.call = _ONLY_OVERLOAD.get(self.dispatcher)
            if self.call is None:  # (reading it hashes its signature, 0.45 ms: once a process)
                self.call = _ONLY_OVERLOAD[self.dispatcher] = next(iter(overloads.values())).entry_point
        else:
            overload = overloads.get(tuple(self.dispatcher.typeof_pyval(a) for a in args))
            if overload is not None:  # (else every call goes through the dispatcher, as before)
                self.call = overload.entry_point
        return result


# entry point -> the compiled wrapper of its one overload, found by the first Bound of the process
_ONLY_OVERLOAD: dict = {}


def load_in_background(*dispatchers) -> None:
    """Load the machine code that numba's cache holds for these entry points in a thread, so that it overlaps what
    the caller does meanwhile (`isaac run` parses and plans the scene: loading an entry takes 20 to 50 ms, most of
    it LLVM reading the entry's bitcode, which releases the GIL). Only what is cached for this machine and this
    source is loaded: a first run compiles in the foreground, with its notice. The first call of an entry waits for
    its load (numba's compiler lock); a load that fails here is simply done again there. The process waits for the
    thread at exit (a scene refused before its run)."""
    import atexit
    import threading

    signatures = [(d, sig) for d in dispatchers for sig in _cached_signatures(d)]
    if not signatures:
        return
    thread = threading.Thread(target=_load_all, args=(signatures,), name="isaac-load-core", daemon=True)
    thread.start()
    atexit.register(thread.join)


def _load_all(signatures) -> None:
    for dispatcher, sig in signatures:
        try:
            dispatcher.compile(sig)
        except Exception:  # noqa: BLE001 (the entry's first call loads or compiles it again, and reports)
            return


def _cached_signatures(dispatcher) -> list:
    """The argument types of the overloads numba's cache holds for this entry, this machine and this source."""
    try:
        from numba.core.registry import cpu_target

        codegen, cache = cpu_target.target_context.codegen(), dispatcher._cache
        return [key[0] for key in cache._cache_file._load_index() if key == cache._index_key(key[0], codegen)]
    except Exception:  # noqa: BLE001 (numba's cache layout is its own: any doubt, nothing is preloaded)
        return []


class CompileNotice:
    """One line on stderr when a run is about to compile the core (nothing cached yet for the entry points it
    uses), and one when the compiling is over, with how long it took:

        notice = CompileNotice.begin(run, measure, ...)    # before the first call of any of them
        ...                                                   # the calls (the first ones compile)
        notice.end()
    """

    announced = False  # per process: the notice is shown once

    def __init__(self, started: float):
        self.started = started

    @classmethod
    def begin(cls, *dispatchers) -> "CompileNotice":
        if cls.announced or all(d.signatures or is_cached(d) for d in dispatchers):
            return cls(0.0)
        cls.announced = True
        if not os.environ.get("ISAAC_QUIET_COMPILE"):
            print("isaac: compiling the simulation core (once per machine; later runs load it from the cache) ...",
                  file=sys.stderr, flush=True)
        return cls(time.perf_counter())

    def end(self) -> None:
        if self.started and not os.environ.get("ISAAC_QUIET_COMPILE"):
            print(f"isaac: compiled in {time.perf_counter() - self.started:.1f} s", file=sys.stderr, flush=True)
        self.started = 0.0
