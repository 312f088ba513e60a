"""Atomic file output: a reader never sees a half-written file.

Used by the CLI, the report writers and the replay writer (the only layers that write).
A write that fails (a full disk, a read-only folder, no permission) raises the
:class:`OSError` and leaves no temporary file behind; the file it was replacing, if any,
is untouched. :func:`describe_os_error` turns such an error into the one line a user reads.
"""

from __future__ import annotations

import errno
import os
import tempfile
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


def _create_temporary(path: Path) -> tuple[int, str]:
    """Open a new temporary file beside ``path``: (file descriptor, its path)."""
    return tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")


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
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = _create_temporary(path)
    except OSError as e:
        raise _named(e, path) from None
    try:
        with os.fdopen(fd, "wb") as f:
            _write_data(f, data, path)
        # mkstemp creates 0600; give the file the permissions a plain open() would.
        os.chmod(tmp, 0o666 & ~_current_umask())
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        raise _named(e, path) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


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
