"""``ident init``: write a commented run config for a URDF (:mod:`ident.run.init_config`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import PackageDirOption, check_package_dirs, user_errors

__all__ = ["init", "register"]

_SERVO_HELP = (
    "Position servos that log no torque: write an 'ident identify' config for a LeRobot "
    "dataset (--log) instead of a run config."
)


def init(
    urdf: Annotated[Path, typer.Argument(help="The robot's URDF.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Run config to write (YAML).")],
    tip_link: Annotated[
        str | None, typer.Option("--tip-link", help="Last link of the chain to identify.")
    ] = None,
    base_link: Annotated[
        str | None, typer.Option("--base-link", help="First link of the chain (default: root).")
    ] = None,
    lock: Annotated[
        list[str] | None,
        typer.Option("--lock", help="Hold a joint fixed: NAME or NAME=VALUE [rad or m]."),
    ] = None,
    package_dir: PackageDirOption = None,
    servo: Annotated[bool, typer.Option("--servo", help=_SERVO_HELP)] = False,
    log: Annotated[
        Path | None,
        typer.Option("--log", help="With --servo: the LeRobot dataset folder to identify."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Replace an existing --output file.")
    ] = False,
) -> None:
    """Write a run config for the robot of URDF (chain, limits, safety, a simulated
    measurement, a budget; every guess marked), to run with 'ident run CONFIG'; with
    --servo, an identify config for its position servos and a LeRobot dataset."""
    if servo or log is not None:
        _init_servo(urdf, output, servo, log, force)
        return
    with user_errors():
        from ident.cli.verify import parse_locks
        from ident.fileio import atomic_write_text
        from ident.inputs import check_output_file
        from ident.run.init_config import init_config

        check_output_file(output, "--output", force_flag=None if force else "--force")
        with _InitProgress() as display:
            result = init_config(
                urdf,
                output,
                base_link=base_link,
                tip_link=tip_link,
                lock=parse_locks(lock or []),
                package_dirs=check_package_dirs(package_dir),
                progress=display.step,
            )
        atomic_write_text(output, result.text)
    for note in result.notes:
        typer.echo(note)
    typer.echo(
        f"wrote {output}; estimated wall time on an idle 2-core machine (its CPU time): "
        f"'ident run {output} --quick' about {result.quick_seconds:.0f} s, 'ident run "
        f"{output}' about {result.seconds:.0f} s, start-up, safety check, simulation, "
        "identification and report included"
        + _worst_case(result.quick_worst_seconds, result.worst_seconds)
    )


def _worst_case(quick: float, full: float) -> str:
    """The estimates' worst cases [s] (a retry at a wider safety margin), when there are."""
    if max(quick, full) <= 0.0:
        return ""
    return (
        f"; up to {quick:.0f} s and {full:.0f} s if the design is retried at a wider safety margin"
    )


def _init_servo(urdf: Path, output: Path, servo: bool, log: Path | None, force: bool) -> None:
    """``ident init URDF --servo [--log DATASET]``: the identify config of
    :mod:`ident.run.init_servo`, checked, then written."""
    with user_errors():
        from ident.errors import ConfigError
        from ident.fileio import atomic_write_text
        from ident.inputs import check_output_file
        from ident.run.init_servo import init_servo_config

        if not servo:
            raise ConfigError("--log is the dataset of --servo; add --servo, or remove --log.")
        check_output_file(output, "--output", force_flag=None if force else "--force")
        result = init_servo_config(urdf, output, log)
        atomic_write_text(output, result.text)
    for note in result.notes:
        typer.echo(note)
    typer.echo(f"wrote {output}; identify with 'ident identify {output}'")


class _InitProgress:
    """A rich progress line on stderr over the steps of ``init_config`` (a few seconds each
    on large meshes), as ``ident run`` shows its optimization."""

    def __enter__(self) -> _InitProgress:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        from ident.run.init_config import INIT_STEPS

        self.progress = Progress(
            TextColumn("init: {task.description:<40}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=Console(stderr=True),
            transient=True,
        )
        self.progress.__enter__()
        self.steps = INIT_STEPS
        self.task = self.progress.add_task(INIT_STEPS[0], total=len(INIT_STEPS))
        return self

    def __exit__(self, *exc: object) -> None:
        self.progress.__exit__(None, None, None)

    def step(self, name: str) -> None:
        """Progress callback of ``init_config``: step ``name`` starts."""
        self.progress.update(self.task, description=name, completed=self.steps.index(name))


def register(app: typer.Typer) -> None:
    """Add ``ident init`` to the application."""
    app.command(name="init")(init)
