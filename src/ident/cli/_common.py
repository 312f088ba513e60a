"""Shared CLI plumbing: one-line error messages and exit codes."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

import typer

from ident.errors import IdentError

__all__ = ["EXIT_INTERRUPTED", "EXIT_USER_ERROR", "user_errors"]

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


@contextlib.contextmanager
def user_errors() -> Iterator[None]:
    """Turn :class:`IdentError` into ``error: ...`` on stderr and exit code 2.

    Ctrl-C exits with code 130 and a short note instead of a traceback.
    """
    try:
        yield
    except IdentError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(code=EXIT_USER_ERROR) from None
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.stderr.flush()
        raise typer.Exit(code=EXIT_INTERRUPTED) from None
