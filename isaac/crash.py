"""A bug in isaac, said the same way everywhere: one line, and the file the traceback was written to.

    except Exception as error:
        print(internal_error(error), file=sys.stderr)
"""
from __future__ import annotations

import os
import tempfile
import traceback


def save_traceback(error: BaseException) -> str:
    """Write error's traceback to a new `isaac-crash-*.txt` in the temporary folder; its path."""
    fd, path = tempfile.mkstemp(prefix="isaac-crash-", suffix=".txt")
    with os.fdopen(fd, "w") as handle:
        traceback.print_exception(type(error), error, error.__traceback__, file=handle)
    return path


def internal_error(error: BaseException, path: str | None = None) -> str:
    """`internal error (Kind: message); this is a bug in isaac, not in your scene. The traceback is in PATH`,
    the traceback saved first unless path is given."""
    path = path or save_traceback(error)
    message = " ".join(str(error).split())  # one line, whatever the message holds
    if len(message) > 200:
        message = message[:197] + "..."
    return (f"internal error ({type(error).__name__}: {message}); this is a bug in isaac, not in your scene. "
            f"The traceback is in {path}")
