"""Atomic file output: a reader never sees a half-written file.

Used by the CLI, the report writers and the replay writer (the only layers that write).
A write that fails (a full disk, a read-only folder, no permission) raises the
:class:`OSError` and leaves no temporary file behind; the file it was replacing, if any,
is untouched. :func:`describe_os_error` turns such an error into the one line a user reads.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_write_bytes", "atomic_write_text", "describe_os_error"]

# What to do about the operating-system failures a writer meets (errno -> the fix).
_FIXES = {
    errno.ENOSPC: "the disk is full: free some space, or write to another disk",
    errno.EDQUOT: "the disk quota is exceeded: free some space, or write to another disk",
    errno.EROFS: "the file system is read-only: write to another folder",
    errno.EACCES: "no permission: change the folder's permissions, or write to another folder",
    errno.EPERM: "no permission: change the folder's permissions, or write to another folder",
    errno.EIO: "the disk reported an input/output error: check the disk, or use another one",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n) or close other programs",
    errno.ENFILE: "too many open files: raise the limit (ulimit -n) or close other programs",
    errno.ENAMETOOLONG: "the path is too long: use a shorter folder or file name",
}


def describe_os_error(error: OSError) -> str:
    """One line for an operating-system failure: the file, what happened, the fix.

    Examples
    --------
    ``runs/x/report.html: No space left on device (the disk is full: free some space, or
    write to another disk)``
    """
    where = error.filename if error.filename is not None else "a file"
    what = error.strerror or str(error) or type(error).__name__
    fix = _FIXES.get(error.errno or 0)
    return f"{where}: {what}" + (f" ({fix})" if fix else "")


def _temporary_name(path: Path) -> Path:
    """A new name beside ``path`` for its temporary file (hidden, random, not created)."""
    return path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"


def _create_temporary(path: Path, tmp: Path) -> int:
    """Create ``tmp``, the temporary file of ``path`` (exclusive, 0600): its descriptor."""
    return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)


def _write_data(file: BinaryIO, data: bytes, path: Path) -> None:
    """Write all of ``data`` to an open file (the one primitive every writer goes through;
    ``path`` is the file it will become)."""
    file.write(data)
    file.flush()


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename.

    Raises
    ------
    OSError
        The folder cannot be created or written (full disk, read-only, permission); the
        error's ``filename`` is ``path`` and no temporary file is left.
    """
    path = Path(path)
    # the name is chosen before the file exists, so that an interruption at any point
    # (SIGTERM raises KeyboardInterrupt between any two steps, even right after the file
    # appears) removes it: no hidden temporary file is ever left beside the results
    tmp = _temporary_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with os.fdopen(_create_temporary(path, tmp), "wb") as f:
            _write_data(f, data, path)
        # created 0600; give the file the permissions a plain open() would.
        os.chmod(tmp, 0o666 & ~_current_umask())
        os.replace(tmp, path)
    except OSError as e:
        _remove(tmp)
        raise _named(e, path) from None
    except BaseException:
        _remove(tmp)
        raise
    return path


def _remove(tmp: Path) -> None:
    """Remove a temporary file if it exists (whatever stops that is not the error to report)."""
    with contextlib.suppress(OSError):
        tmp.unlink(missing_ok=True)


def _named(error: OSError, path: Path) -> OSError:
    """``error`` with ``path`` (not the temporary file) as its file name."""
    if error.errno is None:
        return error
    named = OSError(error.errno, error.strerror or os.strerror(error.errno), str(path))
    return named


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))
