"""Stage 6, outputs as one set: a run's files replace the previous run's as a whole, never file by file.

    with OutputSet(out, "run") as new:          # open: reclaim, check, make the staging folder
        write_npz(new.path / "trajectory.npz", ...)
        new.commit([new.path / "trajectory.npz", ...], scene="pendulum")

open     reclaim what killed runs left beside the folder (below); check the folder is isaac's; make the staging
         folder `.NAME.isaac-new-PID-TAG/` beside it, its manifest saying `"state": "writing"` from the start
write    the caller writes every file of the set into the staging folder (an OSError there, a full disk, becomes a
         SceneError: exit 2, the folder as it was)
commit   the manifest (`.isaac-outputs.json`: `"state": "whole"`, the files of the set); the user's own files of
         the old folder hard-linked in (the old folder stays whole); the two folders exchanged in one rename
         (Linux renameat2 RENAME_EXCHANGE; elsewhere two renames, the old one aside first); any file the user put
         into the old folder meanwhile moved over; the old set removed (its manifest says `removing` first)

Whose files: a folder is isaac's when it holds a manifest, or is empty, or is an earlier isaac's output folder
(report.json and an ir.json of the IR schema, no manifest: its OWNED names are the set). Another folder (`--out .`,
a folder of the user's) is refused with exit 2, as is the current folder or one that holds it. In an isaac folder
the manifest's files are isaac's; every other file is the user's and goes on into each next set, except one named
like a file the new set writes (isaac's names are isaac's, as they always were).

A kill at any instant leaves the old set or the new one at the folder's name: before the exchange the folder is
untouched, after it the new set is whole. What a killed run leaves beside it is reclaimed by the next run that
writes into that parent folder: a sibling named `.NAME.isaac-(new|old)-PID-TAG` holding a manifest (or nothing),
whose process is gone. A whole set whose folder is missing is put back (a kill between the two renames without
RENAME_EXCHANGE); otherwise the user's files in it that the folder lacks are moved to the folder, then it is removed.
"""
from __future__ import annotations

import ctypes
import errno
import json
import os
import re
import secrets
import shutil
import stat
import sys
import threading
import time
from pathlib import Path

from . import OWNED_FILES, OWNED_PLOTS, write_atomic

MANIFEST = ".isaac-outputs.json"
FORMAT = "isaac-outputs/1"
# the staging and aside folders of a swap: `.NAME.isaac-new-PID-TAG`, `.NAME.isaac-old-PID-TAG`
LEFTOVER = re.compile(r"^\.(?P<name>.+)\.isaac-(?P<kind>new|old)-(?P<pid>\d+)-(?P<tag>[0-9a-f]{8})$")
# a temporary of write_atomic (runtime/outputs/__init__.py): `.NAME.` and 12 hex digits
TEMPORARY = re.compile(r"^\.(?P<name>.+)\.[0-9a-f]{12}$")
# without process ids to ask (Windows), a leftover this old (s) is taken as abandoned
ABANDONED_AGE = 3600.0

_active: set = set()  # staging folders this process is still writing (never reclaimed by this process)
_reclaimed: set = set()  # parent folders this process has already reclaimed leftovers in (once is enough)
_lock = threading.Lock()


class OutputSet:
    """One replacement of an output folder by a new set of files (module docstring). Use it as a context manager;
    leaving it without `commit` (an exception, Ctrl-C) removes the staging folder and leaves the old set."""

    def __init__(self, folder, command: str, keep=None):
        self.folder = Path(folder)  # as the user named it (for messages)
        self.target = _real(self.folder)
        self.command = command
        # keep(relative path) -> bool: files of the current set that go on into the new one (isaac export adds to
        # a run's set); None: none of them
        self.keep = keep
        self.path: Path | None = None  # the staging folder, while open
        self.committed = False

    def __enter__(self) -> "OutputSet":
        self.open()
        return self

    def __exit__(self, kind, error, trace) -> bool:
        if not self.committed:
            self.discard()
        if isinstance(error, OSError) and not self.committed:  # a full disk, a lost mount: said, exit 2
            raise _unwritable(self.folder, error) from error
        return False

    def check(self) -> None:
        """Refuse a folder that is not isaac's (a SceneError, exit 2): before any work is done."""
        _refuse_cwd(self.folder, self.target)
        current_set(self.folder, self.target)

    def open(self) -> Path:
        self.target.parent.mkdir(parents=True, exist_ok=True)
        reclaim(self.target.parent)
        self.check()
        path = _sibling(self.target, "new")
        with _lock:
            _active.add(path)
        try:
            self.path = path  # first: a Ctrl-C right after the mkdir is cleaned up too (discard)
            os.mkdir(path)
            _write_first_manifest(path, {"format": FORMAT, "state": "writing", "command": self.command,
                                         "pid": os.getpid()})
            if self.target.is_dir():  # the new folder gets the old one's permissions
                os.chmod(path, stat.S_IMODE(self.target.stat().st_mode))
        except BaseException:
            self.discard()
            raise
        return path

    def to_target(self, path) -> Path:
        """A path in the staging folder as it will be once the set is in place (for messages)."""
        return self.folder / Path(path).relative_to(self.path)

    def commit(self, written, **info) -> list:
        """Swap the set in: `written` (paths in the staging folder) are its files; info goes into the manifest.
        Returns the files' paths as they are now (in the folder)."""
        files = sorted({Path(p).relative_to(self.path).as_posix() for p in written})
        listed = current_set(self.folder, self.target)
        if listed is not None and self.keep is not None:  # what the kept files' manifest said of them stays
            info = {**_described(read_manifest(self.target)), **info}
            files = sorted(set(files) | _link_kept(self.target, self.path, listed, self.keep))
        manifest = {"format": FORMAT, "state": "whole", "command": self.command, "pid": os.getpid(),
                    "written": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), **info, "files": files}
        _write_manifest(self.path, manifest)
        if listed is not None:
            _adopt(self.target, listed)  # an earlier isaac's folder gets its manifest: a leftover of it is known
            _carry(self.target, self.path, set(listed))
        old = _swap(self.path, self.target)
        self.committed = True
        if old is not None:
            give_back(old, self.target, set(listed or ()))
            remove_set(old)
        with _lock:
            _active.discard(self.path)
        return [self.folder / name for name in files]

    def discard(self) -> None:
        if self.path is not None and self.path.exists() and not self.committed:
            remove_set(self.path)  # its manifest last: a second Ctrl-C meanwhile leaves a leftover known as ours
        with _lock:
            _active.discard(self.path)


# -- whose files --------------------------------------------------------------------------------------------------

def current_set(folder: Path, target: Path) -> set | None:
    """The files of the set in target (relative paths), None when there is no folder yet; a SceneError for a
    folder that is not isaac's."""
    if not os.path.lexists(target):
        return None
    if not target.is_dir():
        raise _refused(folder, f"the output folder {folder} is a file", "choose a folder with --out")
    manifest = read_manifest(target)
    if manifest is not None:
        files = manifest.get("files")
        return set(files) if isinstance(files, list) else _earlier_owned(target)
    if not any(os.scandir(target)):
        return set()
    if _earlier_isaac(target):
        return _earlier_owned(target)
    foreign = sorted(entry.name for entry in os.scandir(target))
    shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
    raise _refused(folder, f"the output folder {folder} holds files isaac did not write ({shown}) and no {MANIFEST}: "
                           f"isaac replaces its output folder as a whole, so it writes only into a new or empty "
                           f"folder, or one it wrote",
                   "choose another folder with --out (the default is out/<scene file name>/)")


def _earlier_isaac(target: Path) -> bool:
    """An output folder of an isaac from before manifests: report.json beside an ir.json of the IR schema."""
    try:
        schema = json.loads((target / "ir.json").read_text(encoding="utf-8")).get("schema", "")
    except (OSError, ValueError, AttributeError):
        return False
    return (target / "report.json").is_file() and str(schema).startswith("isaac-ir/")


def _earlier_owned(target: Path) -> set:
    names = list(OWNED_FILES) + [f"plots/{name}" for name in OWNED_PLOTS]
    return {name for name in names if (target / name).is_file()}


def _refuse_cwd(folder: Path, target: Path) -> None:
    here = Path.cwd().resolve()
    if here == target or target in here.parents:
        raise _refused(folder, f"the output folder {folder} is the current folder or holds it: isaac replaces its "
                               f"output folder as a whole", "choose another folder with --out")


def _unwritable(folder: Path, error: OSError):
    what = f" ({error.filename})" if error.filename else ""
    return _refused(folder, f"cannot write the outputs into {folder}: {error.strerror or error}{what}; the folder "
                            f"keeps the files it had", "free some space, or choose another folder with --out")


def _refused(folder: Path, message: str, hint: str):
    from isaac_ir.diagnostics import Diagnostic, SceneError

    return SceneError([Diagnostic(message, None, hint)])


def read_manifest(folder: Path) -> dict | None:
    """The manifest in folder; None without one; {} for one that cannot be read (a kill while it was first
    written: a set still being written)."""
    path = Path(folder) / MANIFEST
    if not os.path.lexists(path):
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) and data.get("format") == FORMAT else {}


def _write_first_manifest(folder: Path, data: dict) -> None:
    """The staging folder's first file, written in place (a temporary beside it would make the folder unknown
    if killed between the two)."""
    with open(folder / MANIFEST, "x", encoding="utf-8") as handle:
        handle.write(json.dumps(data) + "\n")


def _write_manifest(folder: Path, data: dict) -> None:
    write_atomic(Path(folder) / MANIFEST, (json.dumps(data, indent=1, sort_keys=True) + "\n").encode("utf-8"))


def _described(manifest: dict | None) -> dict:
    """A manifest's words about its run (scene, run, result), without the fields of the set itself."""
    own = ("format", "state", "command", "pid", "written", "files")
    return {key: value for key, value in (manifest or {}).items() if key not in own}


def _adopt(target: Path, listed: set) -> None:
    if read_manifest(target) is None:
        _write_manifest(target, {"format": FORMAT, "state": "whole", "command": "adopted", "files": sorted(listed)})


# -- files --------------------------------------------------------------------------------------------------------

def unlisted(folder: Path, listed: set):
    """(relative path, is an empty folder) of everything in folder that is not the set's: the user's. Links are
    not followed (a link is a file here); a temporary of one of isaac's files (write_atomic's `.NAME.RANDOM`, left
    by a kill) is nobody's."""
    folder = Path(folder)
    ours = {MANIFEST, *OWNED_FILES, *OWNED_PLOTS} | {Path(rel).name for rel in listed}
    for root, dirs, files in os.walk(folder):
        base = Path(root)
        links = [d for d in dirs if (base / d).is_symlink()]
        dirs[:] = [d for d in dirs if d not in links]
        for name in files + links:
            rel = (base / name).relative_to(folder).as_posix()
            temporary = TEMPORARY.match(name)
            if rel != MANIFEST and rel not in listed and not (temporary and temporary["name"] in ours):
                yield rel, False
        if base != folder and not dirs and not files and not links:
            yield base.relative_to(folder).as_posix(), True


def _carry(target: Path, staging: Path, listed: set) -> None:
    """Link the user's files of target into the staging folder (copy them where links cannot be made)."""
    for rel, empty_folder in list(unlisted(target, listed)):
        destination = staging / rel
        if os.path.lexists(destination):
            continue  # the new set writes a file of this name: isaac's names are isaac's
        source = target / rel
        try:
            destination.parent.mkdir(parents=True, exist_ok=True)
            if empty_folder:
                destination.mkdir()
            elif source.is_symlink():
                os.symlink(os.readlink(source), destination)
            else:
                _link_or_copy(source, destination)
        except FileNotFoundError:
            continue  # gone since the walk


def _link_kept(target: Path, staging: Path, listed: set, keep) -> set:
    """The files of the current set that keep(relative path) keeps, linked into the staging folder."""
    if keep is None:
        return set()
    kept = set()
    for rel in sorted(listed):
        source, destination = target / rel, staging / rel
        if keep(rel) and source.is_file() and not os.path.lexists(destination):
            destination.parent.mkdir(parents=True, exist_ok=True)
            _link_or_copy(source, destination)
            kept.add(rel)
    return kept


def _link_or_copy(source: Path, destination: Path) -> None:
    try:
        os.link(source, destination)
    except OSError as error:
        if isinstance(error, FileNotFoundError):
            raise
        shutil.copy2(source, destination)


def give_back(old: Path, target: Path, listed: set) -> None:
    """Move the user's files of an old set that target lacks into target (files put there during the swap)."""
    for rel, _ in list(unlisted(old, listed)):
        destination = target / rel
        if os.path.lexists(destination):
            continue
        try:
            destination.parent.mkdir(parents=True, exist_ok=True)
            os.rename(old / rel, destination)
        except OSError:
            continue  # gone since the walk, or not movable: it stays with the old set's leftover


def remove_set(folder: Path) -> None:
    """Remove an old set (or a staging folder): marked `removing` first, its manifest last."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest and manifest.get("state") == "whole":  # a staging folder stays `writing`: none of it is the user's
        _write_manifest(folder, dict(manifest, state="removing"))
    for entry in os.scandir(folder):
        if entry.name == MANIFEST:
            continue
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(entry.path, ignore_errors=True)
        else:
            try:
                os.unlink(entry.path)
            except FileNotFoundError:
                pass
    if any(entry.name != MANIFEST for entry in os.scandir(folder)):
        return  # something appeared in it meanwhile: left, marked, for the next run to reclaim
    try:
        os.unlink(folder / MANIFEST)
    except FileNotFoundError:
        pass  # a folder killed before its manifest was written, or after it was removed
    try:
        os.rmdir(folder)
    except OSError:
        pass


# -- the swap -----------------------------------------------------------------------------------------------------

def _swap(staging: Path, target: Path) -> Path | None:
    """Put the staging folder at target's name; returns where the old folder is now (None: there was none)."""
    if not os.path.lexists(target):
        try:
            os.rename(staging, target)
            return None
        except OSError as error:  # a folder appeared meanwhile: swap with it
            if error.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
    if _exchange(staging, target):
        return staging
    aside = _sibling(target, "old")
    os.rename(target, aside)
    os.rename(staging, target)
    return aside


_RENAME_EXCHANGE, _AT_FDCWD = 2, -100


def _renameat2():
    if not sys.platform.startswith("linux"):
        return None
    try:
        function = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):  # a libc without it (glibc < 2.28, some musl)
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


_exchange_call = _renameat2()


def _exchange(a: Path, b: Path) -> bool:
    """Exchange two folders' names in one step; False where the system or file system cannot."""
    if _exchange_call is None:
        return False
    if _exchange_call(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(code, os.strerror(code), str(b))


def _sibling(target: Path, kind: str) -> Path:
    return target.with_name(f".{target.name}.isaac-{kind}-{os.getpid()}-{secrets.token_hex(4)}")


def _real(folder: Path) -> Path:
    """The folder to swap: its parent resolved, and the folder itself when it is a link to a folder."""
    folder = Path(folder)
    if folder.is_symlink():
        return folder.resolve()
    return Path(os.path.abspath(folder.parent.resolve() / folder.name))


# -- leftovers of killed runs -------------------------------------------------------------------------------------

def reclaim(parent: Path, again: bool = False) -> list:
    """Reclaim the leftovers of killed runs in parent (module docstring), once per process unless again.
    Returns what was reclaimed."""
    parent = Path(parent)
    with _lock:
        if parent in _reclaimed and not again:
            return []
        _reclaimed.add(parent)
    done = []
    try:
        entries = sorted(os.scandir(parent), key=lambda e: e.name)
    except FileNotFoundError:
        return done
    for entry in entries:
        match = LEFTOVER.match(entry.name)
        if match is None or not entry.is_dir(follow_symlinks=False):
            continue
        path = Path(entry.path)
        if abandoned(path, int(match["pid"])) and _reclaim_one(path, parent / match["name"]):
            done.append(path)
    return done


def _reclaim_one(path: Path, target: Path) -> bool:
    manifest = read_manifest(path)
    if manifest is None and any(os.scandir(path)):
        return False  # named like ours, but not ours
    state = (manifest or {}).get("state")  # writing: killed while writing; whole, removing: an old set
    if state == "whole" and not os.path.lexists(target):
        os.rename(path, target)  # a whole set whose folder went: put it back
        return True
    if state in ("whole", "removing") and os.path.isdir(target):
        give_back(path, target, set(manifest.get("files") or ()))
    remove_set(path)
    return True


def abandoned(path: Path, pid: int) -> bool:
    """Whether what process pid left at path is abandoned: that process is gone (this process: not writing it)."""
    if pid == os.getpid():
        with _lock:
            return path not in _active
    if os.name == "nt":
        try:
            return time.time() - path.stat().st_mtime > ABANDONED_AGE
        except OSError:
            return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # another user's process
        return False
    return False
