"""Shared CLI plumbing: one-line error messages, exit codes, SIGTERM handled like Ctrl-C."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from ident.errors import ConfigError, IdentError
from ident.fileio import describe_os_error
from ident.run.rundir import failure_note

# failure_note is re-exported: the commands' one word on what stopped a run

__all__ = [
    "EXIT_INTERRUPTED",
    "EXIT_USER_ERROR",
    "PackageDirOption",
    "check_package_dirs",
    "check_scheduler_address",
    "failure_note",
    "one_line",
    "user_errors",
]

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130
_MAX_MESSAGE = 2000  # characters of one error line


def one_line(message: object) -> str:
    """``message`` on one line (newlines folded) and of bounded length."""
    text = " ".join(str(message).split("\n"))
    return text if len(text) <= _MAX_MESSAGE else text[: _MAX_MESSAGE - 3] + "..."


#: ``--package-dir``, the same option on every command that reads a URDF (checked by
#: :func:`check_package_dirs`).
PackageDirOption = Annotated[
    list[Path] | None,
    typer.Option(
        "--package-dir",
        help="Folder holding the URDF's package:// mesh packages (and xacro's $(find ...) "
        "ones), searched before the config's robot.package_dirs; repeatable.",
    ),
]


def check_package_dirs(package_dirs: list[Path] | None) -> list[Path]:
    """The ``--package-dir`` folders (absolute), each an existing folder.

    Raises
    ------
    ConfigError
        One line naming the first one that is not a folder.
    """
    for folder in package_dirs or ():
        if not folder.is_dir():
            raise ConfigError(
                f"--package-dir {folder}: not a folder; give the folder that holds the "
                "package:// mesh packages (the parent of <package>/meshes)."
            )
    return [folder.resolve() for folder in package_dirs or ()]


_SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")


def check_scheduler_address(address: str | None) -> None:
    """Refuse a ``--scheduler`` that dask.distributed cannot parse, before any work.

    Raises
    ------
    IdentError
        An empty address, one with blanks, or a scheme dask does not know.
    """
    if address is None:
        return
    scheme, _, rest = address.partition("://") if "://" in address else ("tcp", "", address)
    if not rest or any(c.isspace() for c in address) or scheme not in _SCHEDULER_SCHEMES:
        raise IdentError(
            f"--scheduler {address!r}: not a dask.distributed scheduler address; give "
            f"[scheme://]host:port with scheme {', '.join(_SCHEDULER_SCHEMES)} (e.g. "
            "tcp://127.0.0.1:8786), or drop --scheduler."
        )


def _terminate(signum: int, frame: Any) -> None:
    """SIGTERM (kill, systemd, a CI timeout) takes the same path as Ctrl-C."""
    raise KeyboardInterrupt


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers can only be set from the main thread
        return
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def user_errors() -> Iterator[None]:
    """Turn :class:`IdentError` into ``error: ...`` on stderr and exit code 2.

    Ctrl-C and SIGTERM exit with code 130 and a short note instead of a traceback (inside
    the block SIGTERM raises :class:`KeyboardInterrupt`, so that cleanup code written for
    Ctrl-C, such as marking a run folder incomplete, runs for both); the note names the
    folder left incomplete (:class:`ident.run.rundir.FolderInterrupted`). Running out of memory
    and an operating-system failure (a full disk, a read-only folder, no permission:
    :func:`ident.fileio.describe_os_error`) are reported on one line too.
    """
    try:
        with _sigterm_as_interrupt():
            yield
    except IdentError as e:
        typer.echo(f"error: {one_line(e)}", err=True)
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except OSError as e:  # a full disk, a read-only folder, no permission, ...
        typer.echo(f"error: {one_line(describe_os_error(e))}", err=True)
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except MemoryError:
        typer.echo(
            "error: out of memory; make the job smaller (fewer samples, iterations or runs).",
            err=True,
        )
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except KeyboardInterrupt as e:
        folder = getattr(e, "folder", None)  # a FolderInterrupted names what it left
        typer.echo("interrupted" + (f": {folder} is incomplete" if folder else ""), err=True)
        sys.stderr.flush()
        raise typer.Exit(code=EXIT_INTERRUPTED) from None
