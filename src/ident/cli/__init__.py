"""Command-line interface: ``ident init | robot | verify | run | report | identify | ...``.

Each command lives in its own module of this package and adds itself to :data:`app`
through a ``register(app)`` function; this keeps every command thin and the modules
independent. Commands only parse arguments, call the library and report.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from typing import Annotated

import typer

__all__ = ["app", "main"]

app = typer.Typer(
    name="ident",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    rich_markup_mode=None,  # plain help: no "<bool>" after flags
    help="Identify the dynamic parameters of serial robot arms.",
)


def _plain_argument_usage() -> None:
    """Show required arguments as ``CONFIG`` in the usage line (typer writes ``{config}``,
    which reads like a literal placeholder); optional ones stay ``[NAME]``."""
    try:
        from typer.core import TyperArgument
    except ImportError:  # another typer: keep its usage line
        return
    if not hasattr(TyperArgument, "_usage_display_name"):
        return

    def usage(self: TyperArgument) -> str:
        name = self.display_name_raw.upper()
        name = name if self.required else f"[{name}]"
        return name + ("..." if self.nargs != 1 else "")

    TyperArgument._usage_display_name = usage  # type: ignore[method-assign]


_plain_argument_usage()


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"ident {version('ident')}")
        except PackageNotFoundError:
            typer.echo("ident (not installed: no package metadata)")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Identify the dynamic parameters of serial robot arms."""


# Order of the commands in `ident --help`.
_COMMAND_MODULES = (
    "init",
    "robot",
    "verify",
    "run",
    "report",
    "identify",
    "repeatability",
    "payload",
    "stream",
    "fleet",
    "logs",
    "bench",
    "replay",
)

for _name in _COMMAND_MODULES:
    _module_name = f"{__name__}.{_name}"
    if importlib.util.find_spec(_module_name) is not None:
        importlib.import_module(_module_name).register(app)


def main() -> None:
    """Console-script entry point: usage errors are one ``error:`` line too (exit 2)."""
    try:
        code = app(standalone_mode=False)
    except typer.TyperException as e:  # usage errors of typer's own click
        if type(e).__name__ == "NoArgsIsHelpError":  # `ident` alone: the help text, as before
            typer.echo(e.ctx.get_help())  # type: ignore[attr-defined]
            sys.exit(getattr(e, "exit_code", 2))
        ctx = getattr(e, "ctx", None)
        hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
        message = " ".join(e.format_message().split())  # type: ignore[attr-defined]
        typer.echo(f"error: {message}{hint}", err=True)
        code = getattr(e, "exit_code", 2)
    except typer.Abort:
        typer.echo("interrupted", err=True)
        code = 130
    sys.exit(code if isinstance(code, int) else 0)
