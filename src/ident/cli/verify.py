"""``ident verify``: check the hand-derived regressor against Pinocchio, count base parameters."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from ident.cli._common import user_errors
from ident.errors import ConfigError
from ident.model.selection import RobotSelection, load_robot, selection_from_flags

__all__ = ["parse_locks", "register", "run_verification", "verify"]

# Largest relative error (to the scale of the regressor tensor and of the torques) accepted.
DEFAULT_TOLERANCE = 1e-9


def verify(
    robot: Annotated[
        Path | None,
        typer.Option("--robot", help="Robot description (DH) config, e.g. configs/paper6r.yaml."),
    ] = None,
    urdf: Annotated[
        Path | None, typer.Option("--urdf", help="URDF of a fixed-base serial robot.")
    ] = None,
    samples: Annotated[int, typer.Option("--samples", help="Number of random states.")] = 200,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the random states.")] = 0,
    tolerance: Annotated[
        float, typer.Option("--tolerance", help="Largest accepted relative error.")
    ] = DEFAULT_TOLERANCE,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    lock: Annotated[
        list[str] | None,
        typer.Option(
            "--lock",
            help="With --urdf: hold joint NAME fixed at VALUE [rad or m] (0 if omitted), "
            "e.g. the fingers of a gripper; repeatable.",
            metavar="NAME[=VALUE]",
        ),
    ] = None,
    base_link: Annotated[
        str | None, typer.Option("--base-link", help="With --urdf: first link of the chain.")
    ] = None,
    tip_link: Annotated[
        str | None, typer.Option("--tip-link", help="With --urdf: last link of the chain.")
    ] = None,
    inertia_check: Annotated[
        bool,
        typer.Option(
            "--inertia-check/--no-inertia-check",
            help="Refuse moving links with physically impossible inertials.",
        ),
    ] = True,
) -> None:
    """Compare the hand-derived regressor with Pinocchio on random states within the limits.

    Also checks regressor @ parameters against pin.rnea and reports base-parameter counts
    (rank, independent, dependent, unidentifiable; QR and the paper's sequential method) for
    the whole robot and, for 6-joint robots, the paper's wrist and arm stages. Exit code 1 if an
    error exceeds --tolerance. A branched URDF (an arm with gripper fingers) is verified with its
    extra joints locked: --lock panda_finger_joint1 --lock panda_finger_joint2.
    """
    with user_errors():
        selection = selection_from_flags(
            robot=robot,
            urdf=urdf,
            lock=parse_locks(lock or []),
            base_link=base_link,
            tip_link=tip_link,
            inertia_check=inertia_check,
        )
        report = run_verification(selection, samples=samples, seed=seed, tolerance=tolerance)
    if as_json:
        typer.echo(json.dumps(report))
    else:
        _print_table(report)
    if not report["passed"]:
        raise typer.Exit(code=1)


def run_verification(
    selection: RobotSelection,
    *,
    samples: int,
    seed: int,
    tolerance: float = DEFAULT_TOLERANCE,
) -> dict[str, Any]:
    """Load the selected robot, draw states and build the report of :func:`verification_report`."""
    from ident.dynamics.pinocchio_check import verification_report

    if samples < 1:
        raise ConfigError(f"--samples must be at least 1, got {samples}.")
    loaded = load_robot(selection)
    source = str(selection.path)
    q, dq, ddq = loaded.random_configurations(samples, rng=seed)
    parameter_map = loaded.dh_to_model_parameters() if loaded.dh is not None else None
    report = verification_report(loaded.model, q, dq, ddq, parameter_map=parameter_map)
    report["source"] = source
    report["locked_joints"] = dict(loaded.locked_joints)
    report["continuous_joints"] = list(loaded.continuous_joints)
    report["seed"] = seed
    report["tolerance"] = tolerance
    report["passed"] = bool(
        report["max_rel_error"] <= tolerance
        and report["rnea_max_rel_error"] <= tolerance
        and report["ranks_agree"]
    )
    return report


def parse_locks(specs: list[str]) -> dict[str, float]:
    """``["NAME", "NAME=VALUE", ...]`` -> ``{NAME: VALUE}`` (0 where no value is given).

    Raises
    ------
    ConfigError
        For an empty name, a value that is not a number, or a joint given twice.
    """
    out: dict[str, float] = {}
    for spec in specs:
        name, sep, text = spec.partition("=")
        name = name.strip()
        if not name:
            raise ConfigError(f"--lock {spec!r}: give a joint name, as NAME or NAME=VALUE.")
        try:
            value = float(text) if sep else 0.0
        except ValueError as e:
            raise ConfigError(
                f"--lock {spec!r}: {text!r} is not a number; give NAME=VALUE in rad or m."
            ) from e
        if name in out:
            raise ConfigError(f"--lock {spec!r}: joint {name!r} is locked twice; lock it once.")
        out[name] = value
    return out


def _print_table(report: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(
        f"[bold]{report['robot']}[/bold] ({report['source']}): {report['n_joints']} joints, "
        f"{report['n_samples']} random states, seed {report['seed']}"
    )
    if report["locked_joints"]:
        held = ", ".join(f"{k} = {v:g}" for k, v in report["locked_joints"].items())
        console.print(f"locked joints (not in the model): {held}")
    if report["continuous_joints"]:
        console.print(
            "continuous joints, modelled as revolute without position limit: "
            + ", ".join(report["continuous_joints"])
        )
    checks = Table(title="Hand-derived regressor vs Pinocchio")
    for column in ("check", "max abs error", "max rel error", "status"):
        checks.add_column(column)
    ok = report["tolerance"]
    for label, abs_key, rel_key in (
        ("Y vs pin.computeJointTorqueRegressor", "max_abs_error", "max_rel_error"),
        ("Y @ parameters vs pin.rnea", "rnea_max_abs_error", "rnea_max_rel_error"),
    ):
        status = "[green]ok[/green]" if report[rel_key] <= ok else "[red]FAILED[/red]"
        checks.add_row(label, f"{report[abs_key]:.2e}", f"{report[rel_key]:.2e}", status)
    console.print(checks)

    counts = Table(title="Base parameters (numerical rank)")
    for column in ("scope", "frames", "method", "rank", "indep.", "dep.", "unident.", "of"):
        counts.add_column(
            column, justify="left" if column in ("scope", "frames", "method") else "right"
        )
    keys = ("rank", "n_independent", "n_dependent", "n_unidentifiable", "n_params")

    def add(scope: str, entry: dict[str, Any]) -> None:
        for frames, label in (("methods", "model"), ("dh_frames", "DH")):
            for method, c in entry.get(frames, {}).items():
                counts.add_row(scope, label, method, *(str(c[key]) for key in keys))

    add("robot", report)
    notes = []
    for name, stage in report["stages"].items():
        add(name, stage)
        held = ", ".join(f"{x:.3g}" for x in stage["held_positions"])
        notes.append(
            f"{name}: joints {stage['moving_joints']} move, torques {stage['torque_rows']}, "
            f"bodies {stage['bodies']} unknown; the other joints held at {held}"
        )
    console.print(counts)
    for note in notes:
        console.print(note)
    if "dh_frames" in report:
        console.print(
            "frames: 'model' = parameters about the URDF link (joint) frames, 'DH' = about the "
            "DH frames of the config (the paper's)."
        )
    if not report["ranks_agree"]:
        console.print("[red]the two base-parameter methods disagree on the rank[/red]")


def register(app: typer.Typer) -> None:
    """Add the ``verify`` command to the CLI."""
    app.command("verify")(verify)
