"""Reading the files a scene names: where they may be, what they may be, how large, and how text is decoded.

A scene reads regular files inside its own folder tree, and inside the folders the user names with
`--include-path DIR` (the API: `Limits(include_path=...)`). Everything else is refused before it is opened, so
that its contents never reach a diagnostic: a path outside those folders (absolute, `..`, or a symbolic link that
leads out), a folder, a device (/dev/zero), a FIFO, a socket, anything under /proc or /sys. A file is read
through its descriptor with a bounded `read`, and checked again on that descriptor (a file swapped for a FIFO
between the check and the open is still refused). Text is UTF-8; a byte that is not is reported at its line and
column (lines counted at `\\n` only, as the lexer counts them); a UTF-8 byte-order mark is dropped.
"""
from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path

MiB = 1 << 20
# bytes: the largest scene or included file (the largest example scene is 4 kB; 4 MiB of scene text loads in
# about 10 s)
MAX_TEXT_BYTES = 4 * MiB
# bytes: the largest asset of each kind (a mesh is parsed as text; a recording is decoded to samples)
MAX_ASSET_BYTES = {"mesh": 64 * MiB, "texture": 256 * MiB, "recording": 256 * MiB}
# trees of the system whose files are not data (their "regular" files are generated when read)
SYSTEM_TREES = (Path("/proc"), Path("/sys"), Path("/dev"))
BOM = "\ufeff"
MISSING = "no such file"
WHERE_HINT = ("a scene reads files in its own folder and the folders below it; "
              "name another folder with --include-path DIR")


class FileRefused(Exception):
    """A file that may not or cannot be read: what is wrong with it, and what to do."""

    def __init__(self, message: str, hint: str | None = None):
        super().__init__(message)
        self.message, self.hint = message, hint


class BadEncoding(FileRefused):
    """A file that is not UTF-8 text: the first bad byte's line and column (1-based), and the text decoded with
    replacement characters (so that the line can be shown)."""

    def __init__(self, message: str, line: int, col: int, text: str):
        super().__init__(message, "save the file as UTF-8 text")
        self.line, self.col, self.text = line, col, text


@dataclass(frozen=True)
class Confinement:
    """The folders a scene may read from, resolved (symbolic links followed)."""

    roots: tuple

    @classmethod
    def for_scene(cls, folder, include_path=()) -> "Confinement":
        return cls(tuple(dict.fromkeys(real_path(Path(f)) for f in (folder, *include_path))))

    def allowed(self, path: Path, anywhere: bool = False) -> Path:
        """The real path of `path` when a scene may read it (it need not exist yet); FileRefused when not.
        anywhere: outside the scene's folders too (only the system trees are refused)."""
        real = real_path(path)
        if not anywhere and not any(_inside(real, root) for root in self.roots):
            raise FileRefused("it is outside the scene's folder", WHERE_HINT)
        if any(_inside(real, tree) for tree in SYSTEM_TREES):
            raise FileRefused(f"it is in {next(t for t in SYSTEM_TREES if _inside(real, t))}, not a data file")
        return real

    def regular(self, path: Path, limit: int, anywhere: bool = False) -> Path:
        """The real path of an allowed regular file of at most `limit` bytes (checked with stat, nothing read)."""
        real = self.allowed(path, anywhere)
        try:
            info = os.stat(real)
        except FileNotFoundError:
            raise FileRefused(MISSING) from None
        except ValueError:  # an embedded NUL byte
            raise FileRefused("its name holds a NUL byte") from None
        except OSError as error:
            raise FileRefused(f"cannot look at it: {error.strerror or error}") from None
        _check_kind_and_size(info, limit)
        return real

    def refusal(self, path: Path, limit: int, anywhere: bool = False) -> FileRefused | None:
        """Why a scene may not read the file at path (nothing is opened), or None; a missing file is None (the
        assets stage says so, where a load reads its assets)."""
        try:
            self.regular(path, limit, anywhere)
        except FileRefused as error:
            return None if error.message == MISSING else error
        return None

    def read_bytes(self, path: Path, limit: int, anywhere: bool = False) -> bytes:
        """anywhere: a file the user named on the command line (only the system trees are refused)."""
        return read_bounded(self.regular(path, limit, anywhere), limit)

    def read_text(self, path: Path, limit: int = MAX_TEXT_BYTES) -> str:
        return decode_text(self.read_bytes(path, limit))


def read_bounded(path: Path, limit: int) -> bytes:
    """At most `limit` bytes of a regular file, or FileRefused; never blocks on a FIFO, never reads a device."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except OSError as error:
        raise FileRefused(f"cannot open it: {error.strerror or error}") from None
    try:
        _check_kind_and_size(os.fstat(fd), limit)  # the file opened is the file checked
        chunks, left = [], limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 4 * MiB))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    except OSError as error:
        raise FileRefused(f"cannot read it: {error.strerror or error}") from None
    finally:
        os.close(fd)
    data = b"".join(chunks)
    if len(data) > limit:
        raise FileRefused(f"it is larger than {_size(limit)} (it grew while read)")
    return data


def decode_text(data: bytes) -> str:
    """UTF-8 text without a byte-order mark; BadEncoding at the first byte that is not UTF-8."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        line_start = data.rfind(b"\n", 0, error.start) + 1
        col = len(data[line_start:error.start].decode("utf-8", errors="replace")) + 1
        shown = data.decode("utf-8", errors="replace")
        raise BadEncoding(f"this is not UTF-8 text (byte 0x{data[error.start]:02x})", line, col,
                          shown[1:] if shown.startswith(BOM) else shown) from None
    return text[1:] if text.startswith(BOM) else text


def _check_kind_and_size(info: os.stat_result, limit: int) -> None:
    if not stat.S_ISREG(info.st_mode):
        raise FileRefused(f"it is {_kind(info.st_mode)}, not a regular file")
    if info.st_size > limit:
        raise FileRefused(f"it is {_size(info.st_size)}, more than the {_size(limit)} a scene may read from one file")


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a plain file"


def _size(count: int) -> str:
    return f"{count / MiB:.3g} MiB" if count >= MiB else f"{count} bytes"


def real_path(path) -> Path:
    """The path with every symbolic link followed; FileRefused for a name the system cannot hold (a NUL byte)
    or a chain of links that never ends (a link to itself), which no later open could read either."""
    try:
        real = Path(os.path.realpath(path))
    except ValueError:  # os.path refuses an embedded NUL byte
        raise FileRefused("its name holds a NUL byte", "a file name is text without control characters") from None
    # realpath leaves a loop of links as it found it: the link it stopped at still points somewhere
    if os.path.islink(real):
        raise FileRefused("it is a symbolic link that leads back to itself (a loop of links)")
    return real




def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents
