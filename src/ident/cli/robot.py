"""``ident urdf``: turn a robot description (DH table, limits, inertials) into a URDF file."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["register", "urdf"]


def urdf(
    config: Annotated[Path, typer.Argument(help="Robot description YAML (DH table).")],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="URDF file to write (parents are created).")
    ],
    force: Annotated[
        bool, typer.Option("--force", help="Replace an existing --output file.")
    ] = False,
) -> None:
    """Write the URDF of the robot described in CONFIG (e.g. configs/paper6r.yaml)."""
    with user_errors():
        from ident.fileio import atomic_write_text
        from ident.inputs import check_output_file, check_urdf_numbers
        from ident.robot.robot_config import load_robot_config
        from ident.robot.urdf import urdf_from_description

        check_output_file(output, "--output", force_flag=None if force else "--force")
        description = load_robot_config(config)
        text = urdf_from_description(description)
        check_urdf_numbers(text, str(config))  # never write a URDF Pinocchio then refuses
        atomic_write_text(output, text)
        typer.echo(
            f"wrote {output} ({description.name}: {description.n_joints} joints, "
            f"{description.dh.convention} DH)"
        )


def register(app: typer.Typer) -> None:
    """Add ``ident urdf`` to the application."""
    app.command(name="urdf")(urdf)
