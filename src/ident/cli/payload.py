"""``ident payload CONFIG``: the mass, centre of mass and inertia of a payload on an identified arm.

Validates the config (:func:`ident.identify.payload.payload_config.load_payload_config`), reads the
log(s) and estimates the payload (:func:`ident.identify.payload.payload.identify_payload`); only
then creates the run folder ``<out>/<name>-<timestamp>/`` with ``payload.json`` (the estimate,
written first) and the arm + payload model files ``<stem>_payload.urdf`` / ``.xml``
(:func:`ident.identify.model_files.files.model_files`: the URDF's last link's ``<inertial>``
becomes arm + payload). Exit codes: 0 success; 2 bad input or a failed estimate (nothing
written); an error, Ctrl-C or SIGTERM while the folder is written marks it incomplete and names
it (exit 2, or 130).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["payload", "register"]


def register(app: typer.Typer) -> None:
    """Add ``payload`` to the ``ident`` command line."""
    app.command("payload")(payload)


def payload(
    config: Annotated[Path, typer.Argument(help="Payload config (docs/payload.md).")],
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
) -> None:
    """Estimate a payload's mass, centre of mass and inertia from CONFIG's log(s)."""
    from ident.fileio import atomic_write_text
    from ident.identify.corrections.signal_correction import identify_corrected_payload
    from ident.identify.model_files.files import model_files
    from ident.identify.payload.payload import arm_with_payload
    from ident.identify.payload.payload_config import load_payload_config
    from ident.inputs import check_output_dir
    from ident.model.selection import load_robot
    from ident.run.rundir import run_folder

    with user_errors():
        check_output_dir(out, "--out")
        cfg = load_payload_config(config)
        source = str(cfg.source or config)
        robot = load_robot(cfg.robot, source=source)
        result = identify_corrected_payload(cfg, robot)
        theta, names = arm_with_payload(robot, result.phi)
        files = model_files(robot, theta, names)  # every check before the run folder
        summary = result.summary()
        stem = Path(str(robot.urdf_path or robot.name)).stem
        info = {"command": "payload", "config": str(config)}
        with run_folder(out, cfg.name, info=info) as rundir:  # incomplete unless all written
            atomic_write_text(rundir.path / "payload.json", json.dumps(summary, indent=2) + "\n")
            urdf = atomic_write_text(rundir.path / f"{stem}_payload.urdf", files.urdf_text)
            mjcf = atomic_write_text(rundir.path / f"{stem}_payload.xml", files.mjcf)
            rundir.finish("complete", summary["message"])
        mm = 1e3
        com = ", ".join(
            f"{mm * c:.1f} +- {mm * s:.1f}" for c, s in zip(result.com, result.com_std, strict=True)
        )
        typer.echo(f"run folder: {rundir.path}")
        typer.echo(f"payload ({result.method.upper()}): mass {result.mass:.4g} +- "
                   f"{result.mass_std:.2g} kg ({result.std_method} σ)")  # fmt: skip
        typer.echo(f"centre of mass in {result.link}: [{com}] mm")
        typer.echo(
            f"arm from: {result.arm_from}" + (f" ({result.arm_note})" if result.arm_note else "")
        )
        if result.std_note:
            typer.echo(f"note: {result.std_note}")
        inertia = result.inertia_com
        typer.echo(
            "inertia about the centre of mass [kg*m^2]: "
            f"Ixx {inertia[0, 0]:.4g}, Iyy {inertia[1, 1]:.4g}, Izz {inertia[2, 2]:.4g}, "
            f"Ixy {inertia[0, 1]:.3g}, Ixz {inertia[0, 2]:.3g}, Iyz {inertia[1, 2]:.3g}"
        )
        typer.echo(
            f"fit: relative residual {result.wls.relative_residual:.4f}, pseudo-inertia "
            f"smallest eigenvalue {result.min_eigenvalue:.3g}"
        )
        if result.signals is not None:
            typer.echo(f"signals: {result.signals['line']}")
        typer.echo(f"model files: {urdf}, {mjcf}")
        for line in result.warnings:  # payload.json's "warnings" too
            typer.echo(f"warning: {line}", err=True)
