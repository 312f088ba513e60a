"""``ident payload CONFIG``: the mass, centre of mass and inertia of a payload on an identified arm.

Validates the config (:func:`ident.identify.payload.payload_config.load_payload_config`), reads the
log(s) and estimates the payload (:func:`ident.identify.payload.payload.identify_payload`); only
then creates the run folder ``<out>/<name>-<timestamp>/`` with ``payload.json`` (the estimate,
written first) and the arm + payload model files ``<stem>_payload.urdf`` / ``.xml``
(:func:`ident.identify.model_files.files.model_files`: the URDF's last link's ``<inertial>``
becomes arm + payload). Exit codes: 0 success; 1 ``payload.json`` written but not the model
files (the last body plus the payload is not physically consistent: an unconstrained WLS
payload on an arm it cannot be told from; the warning and ``payload.json``'s ``model_files``
say why); 2 bad input or a failed estimate (nothing written); an error, Ctrl-C or SIGTERM while
the folder is written marks it incomplete and names it (exit 2, or 130).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from ident.cli._common import user_errors

__all__ = ["EXIT_NO_MODEL_FILES", "payload", "register"]

#: Exit code of a run that wrote ``payload.json`` but not the model files (the arm + payload
#: is no physical body; the warning says why).
EXIT_NO_MODEL_FILES = 1


def register(app: typer.Typer) -> None:
    """Add ``payload`` to the ``ident`` command line."""
    app.command("payload")(payload)


def payload(
    config: Annotated[Path, typer.Argument(help="Payload config (docs/payload.md).")],
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
) -> None:
    """Estimate a payload's mass, centre of mass and inertia from CONFIG's log(s)."""
    from ident.identify.corrections.signal_correction import identify_corrected_payload
    from ident.identify.payload.payload import payload_model_files
    from ident.identify.payload.payload_config import load_payload_config
    from ident.inputs import check_output_dir
    from ident.model.selection import load_robot

    with user_errors():
        check_output_dir(out, "--out")
        cfg = load_payload_config(config)
        source = str(cfg.source or config)
        robot = load_robot(cfg.robot, source=source)
        result = identify_corrected_payload(cfg, robot)
        files, not_written = payload_model_files(robot, result)  # every check before the folder
        summary = result.summary()
        summary["model_files"] = {"written": files is not None}
        if not_written:  # the estimate stands; the files that would misstate it are left out
            summary["warnings"].append(not_written)
            summary["model_files"]["note"] = not_written
        stem = Path(str(robot.urdf_path or robot.name)).stem
        paths = _write_payload_run(out, cfg.name, config, summary, files, stem)
        _print_payload(result, paths)
        for line in summary["warnings"]:  # payload.json's "warnings"
            typer.echo(f"warning: {line}", err=True)
    if files is None:  # results written, model files not: not a full success
        raise typer.Exit(code=EXIT_NO_MODEL_FILES)


def _write_payload_run(
    out: Path, name: str, config: Path, summary: dict, files: Any, stem: str
) -> list[Path]:
    """The run folder ``<out>/<name>-<timestamp>/``: ``payload.json`` first, then the model
    files ``files`` (:class:`ident.identify.model_files.files.ModelFiles`, or None: not
    written); the run folder first, then the paths written."""
    from ident.fileio import atomic_write_text
    from ident.run.rundir import run_folder

    info = {"command": "payload", "config": str(config)}
    with run_folder(out, name, info=info) as rundir:  # incomplete unless all written
        paths = [
            atomic_write_text(rundir.path / "payload.json", json.dumps(summary, indent=2) + "\n")
        ]
        if files is not None:
            paths.append(atomic_write_text(rundir.path / f"{stem}_payload.urdf", files.urdf_text))
            paths.append(atomic_write_text(rundir.path / f"{stem}_payload.xml", files.mjcf))
        message = summary["message"]
        if files is None:
            message += "; model files not written"
        rundir.finish("complete", message)
    return [rundir.path, *paths]


def _print_payload(result: Any, paths: list[Path]) -> None:
    """The terminal's summary of ``result`` (:class:`PayloadResult`) and the files written
    (``paths``: the run folder, payload.json, then the model files if written)."""
    mm = 1e3
    com = ", ".join(
        f"{mm * c:.1f} +- {mm * s:.1f}" for c, s in zip(result.com, result.com_std, strict=True)
    )
    typer.echo(f"run folder: {paths[0]}")
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
    if len(paths) > 2:
        typer.echo(f"model files: {paths[2]}, {paths[3]}")
    else:
        typer.echo(
            f"model files: not written (warning below); the estimate is in {paths[1]} "
            f"(exit code {EXIT_NO_MODEL_FILES})"
        )
