"""Errors that are the user's to fix, or the machine's: reported as one line by the CLI, never as a traceback."""
from __future__ import annotations

import errno
import re

from pipeline.core.optional import MissingPackage
from sim import ParameterError
from vibrobase.errors import InputError


class UserError(InputError):
    """Bad input (file, column, option) — the message says what and where."""


USER_ERRORS = (UserError, ParameterError, MissingPackage, FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError)

MACHINE_ERRNOS = {
    errno.ENOSPC: "no space left on device", errno.EDQUOT: "disk quota exceeded", errno.EROFS: "read-only file system",
    errno.EFBIG: "file too large (the file size limit, ulimit -f)", errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted", errno.ENOENT: "no such file or directory", errno.EEXIST: "file exists",
    errno.ENOTDIR: "not a directory", errno.EISDIR: "is a directory", errno.ENAMETOOLONG: "file name too long",
    errno.ELOOP: "too many levels of symbolic links", errno.EMFILE: "too many open files",
    errno.ENFILE: "too many open files in the system", errno.EIO: "input/output error",
    errno.ENOTEMPTY: "directory not empty", errno.EBUSY: "device or resource busy", errno.EXDEV: "cross-device link",
    errno.ETXTBSY: "text file busy", errno.ENXIO: "no such device or address", errno.ENODEV: "no such device",
    errno.ENOMEM: "out of memory", errno.ECONNREFUSED: "connection refused", errno.ETIMEDOUT: "connection timed out",
    errno.EHOSTUNREACH: "host unreachable", errno.ENETUNREACH: "network unreachable",
    errno.ECONNRESET: "connection reset",
}
"""OSError numbers that the user's files or the machine cause (exit 2, one line), with their wording."""

_ERRNO_IN_TEXT = re.compile(r"\[errno (\d+)\]", re.I)


def _chain(exc: BaseException, depth: int = 10):
    """``exc``, then what caused it (``__cause__``, ``__context__``, a database driver's ``orig``)."""
    seen = set()
    while exc is not None and id(exc) not in seen and depth > 0:
        seen.add(id(exc))
        yield exc
        exc = getattr(exc, "orig", None) or exc.__cause__ or exc.__context__
        depth -= 1


def _os_message(e: OSError, code: int) -> str:
    what = MACHINE_ERRNOS[code]
    name = e.filename if e.filename is not None else None
    if name is None:
        text = str(e).strip()
        return f"{what} ({text})" if text and what not in text.lower() else what
    return f"{what}: {name}" + (f" -> {e.filename2}" if e.filename2 else "")


def machine_error(exc: BaseException) -> str | None:
    """The one-line message of an error the user's files or the machine cause (disk full, read-only, file size
    limit, a corrupt database, not enough memory), or None for anything else (a bug: exit 1)."""
    import sqlite3

    for e in _chain(exc):
        if isinstance(e, OSError):
            code = e.errno
            if code is None:
                m = _ERRNO_IN_TEXT.search(str(e))
                code = int(m.group(1)) if m else None
            if code in MACHINE_ERRNOS:
                return " ".join(_os_message(e, code).split())
        if isinstance(e, MemoryError):
            return f"not enough memory for the sizes asked for ({str(e) or 'MemoryError'}); ask for less"
        if isinstance(e, sqlite3.DatabaseError) and not isinstance(e, (sqlite3.ProgrammingError,
                                                                          sqlite3.InterfaceError)):
            return f"SQLite database: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
    return None


LIBRARY_NOTICES = (DeprecationWarning, PendingDeprecationWarning, FutureWarning)
"""Warnings addressed to a library's developers: shown only when they point into the project's own code
(something to fix here), never when a third-party package warns about its own or another package's internals."""


def _project_file(filename: str) -> bool:
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    try:
        rel = Path(filename).resolve().relative_to(root)
    except (ValueError, OSError):
        return False
    return rel.parts[0] in ("sim", "surrogate", "pipeline", "vibrobase", "bench", "tests") if rel.parts else False


def show_warnings(caught: list) -> None:
    """Print each distinct recorded warning once (a command's warnings come after its success, never before
    an error line); a deprecation notice raised inside a third-party package is dropped (``LIBRARY_NOTICES``)."""
    import sys
    import warnings

    seen = set()
    for w in caught:
        if issubclass(w.category, LIBRARY_NOTICES) and not _project_file(w.filename):
            continue
        key = (w.category, str(w.message), w.filename, w.lineno)
        if key not in seen:
            seen.add(key)
            sys.stderr.write(warnings.formatwarning(w.message, w.category, w.filename, w.lineno))
