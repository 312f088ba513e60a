"""Command-line interface: ``ident urdf | verify | run | report | identify | bench | replay``.

Each command lives in its own module of this package and adds itself to :data:`app`
through a ``register(app)`` function; this keeps every command thin and the modules
independent. Commands only parse arguments, call the library and report.
"""

from __future__ import annotations

import importlib
import importlib.util

import typer

__all__ = ["app", "main"]

app = typer.Typer(
    name="ident",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    help="Identify the dynamic parameters of serial robot arms.",
)


@app.callback()
def _root() -> None:
    """Identify the dynamic parameters of serial robot arms."""


# Order of the commands in `ident --help`.
_COMMAND_MODULES = ("robot", "verify", "run", "identify", "bench", "replay", "logs")

for _name in _COMMAND_MODULES:
    _module_name = f"{__name__}.{_name}"
    if importlib.util.find_spec(_module_name) is not None:
        importlib.import_module(_module_name).register(app)


def main() -> None:
    """Console-script entry point."""
    app()
