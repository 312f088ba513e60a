"""Shared CLI plumbing: one-line error messages, exit codes, SIGTERM handled like Ctrl-C."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any

import typer

from ident.errors import IdentError

__all__ = ["EXIT_INTERRUPTED", "EXIT_USER_ERROR", "one_line", "user_errors"]

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130
_MAX_MESSAGE = 2000  # characters of one error line


def one_line(message: object) -> str:
    """``message`` on one line (newlines folded) and of bounded length."""
    text = " ".join(str(message).split("\n"))
    return text if len(text) <= _MAX_MESSAGE else text[: _MAX_MESSAGE - 3] + "..."


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
    Ctrl-C, such as marking a run folder incomplete, runs for both). Running out of memory
    is reported on one line too.
    """
    try:
        with _sigterm_as_interrupt():
            yield
    except IdentError as e:
        typer.echo(f"error: {one_line(e)}", err=True)
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except MemoryError:
        typer.echo(
            "error: out of memory; make the job smaller (fewer samples, iterations or runs).",
            err=True,
        )
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.stderr.flush()
        raise typer.Exit(code=EXIT_INTERRUPTED) from None
