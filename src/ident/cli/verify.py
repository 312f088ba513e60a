"""``ident verify``: check the hand-derived regressor against Pinocchio, count base parameters."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from ident.cli._common import PackageDirOption, check_package_dirs, user_errors
from ident.errors import ConfigError
from ident.model.selection import RobotSelection, load_robot, selection_from_flags

if TYPE_CHECKING:
    from ident.inputs import JobEstimate

__all__ = ["estimate_verification", "parse_locks", "register", "run_verification", "verify"]

# Largest relative error (to the scale of the regressor tensor and of the torques) accepted.
DEFAULT_TOLERANCE = 1e-9
# The regressor of every state is held at once (about 3 KB per state for 6 joints).
MAX_SAMPLES = 100_000


# The options that select a URDF's chain, beside --robot and --urdf (their help is the
# command's --help).
_LockOption = Annotated[
    list[str] | None,
    typer.Option(
        "--lock",
        help="With --urdf: hold joint NAME fixed at VALUE [rad or m] (0 if omitted), "
        "e.g. the fingers of a gripper; repeatable.",
        metavar="NAME[=VALUE]",
    ),
]
_BaseLinkOption = Annotated[
    str | None, typer.Option("--base-link", help="With --urdf: first link of the chain.")
]
_TipLinkOption = Annotated[
    str | None, typer.Option("--tip-link", help="With --urdf: last link of the chain.")
]
_InertiaCheckOption = Annotated[
    bool,
    typer.Option(
        "--inertia-check/--no-inertia-check",
        help="Refuse moving links with physically impossible inertials.",
    ),
]


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
    lock: _LockOption = None,
    base_link: _BaseLinkOption = None,
    tip_link: _TipLinkOption = None,
    inertia_check: _InertiaCheckOption = True,
    package_dir: PackageDirOption = None,
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
            package_dirs=check_package_dirs(package_dir),
            inertia_check=inertia_check,
        )
        report = run_verification(
            selection,
            samples=samples,
            seed=seed,
            tolerance=tolerance,
            announce=lambda line: typer.echo(line, err=True),
        )
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
    announce: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Load the selected robot, draw states and build the report of :func:`verification_report`.

    The job is refused above the ceilings of :func:`ident.inputs.check_job`; ``announce``
    receives the estimate of a large one (over 10 s or 1 GB) before it starts.
    """
    from ident.dynamics.pinocchio_check import verification_report
    from ident.inputs import check_job, check_number

    check_number(samples, "--samples", low=1, high=MAX_SAMPLES, integer=True)
    check_number(seed, "--seed", low=0, high=2**63 - 1, integer=True)
    # NaN would make every comparison fail (FAILED on a correct regressor); < 0 never passes
    check_number(tolerance, "--tolerance", low=0.0, high=1.0)
    loaded = load_robot(selection)
    source = str(selection.path)
    estimate = check_job(estimate_verification(loaded.model.nv, samples))
    if announce is not None and (estimate.seconds > 10.0 or estimate.memory_bytes > 1e9):
        announce(f"estimate: {estimate.describe()}")
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


def estimate_verification(nv: int, samples: int) -> JobEstimate:
    """Rough peak memory and time of a verification of ``samples`` states of ``nv`` joints.

    The stacked regressor has ``samples * nv`` rows and about ``10 * nv`` columns, held a few
    times over (the Pinocchio one, the hand-derived one, the QR factors of the base-parameter
    counts); the QR costs ``2 m n^2`` flops, counted at 1 GFlop/s.
    """
    from ident.inputs import JobEstimate

    rows, cols = samples * nv, 10 * nv
    memory = 6 * 8.0 * rows * cols + 200e6
    seconds = 4 * rows * cols**2 / 1e9 + 2e-4 * samples * nv
    return JobEstimate(f"verify: {samples} states of {nv} joints", memory, seconds)


def parse_locks(specs: list[str]) -> dict[str, float]:
    """``["NAME", "NAME=VALUE", ...]`` -> ``{NAME: VALUE}`` (0 where no value is given).

    Raises
    ------
    ConfigError
        For an empty name, a value that is not a finite number, or a joint given twice.
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
        if not math.isfinite(value):
            raise ConfigError(f"--lock {spec!r}: the value must be finite (rad or m).")
        if name in out:
            raise ConfigError(f"--lock {spec!r}: joint {name!r} is locked twice; lock it once.")
        out[name] = value
    return out


def _print_table(report: dict[str, Any]) -> None:
    """The verification ``report`` (:func:`run_verification`) as rich tables and notes."""
    from rich.console import Console

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
    console.print(_regressor_table(report))
    counts, notes = _base_parameter_table(report)
    console.print(counts)
    for note in notes:
        console.print(note)
    if "dh_frames" in report:
        console.print(
            "frames: 'model' = parameters about the URDF link (joint) frames, 'DH' = about the "
            "DH frames of the config (the paper's)."
        )
    for pair in report.get("nearly_aligned_axes", []):
        console.print(
            f"nearly aligned axes: {pair['joint']} and {pair['other']} are "
            f"{pair['nominal_deg']:g} deg apart to within {pair['deviation_rad']:.2g} rad (URDF "
            f"angles rounded?); the base parameters treat them as exactly aligned (rank "
            f"tolerance {report['rank_tolerance']:g})"
        )
    if not report["ranks_agree"]:
        console.print("[red]the two base-parameter methods disagree on the rank[/red]")


def _regressor_table(report: dict[str, Any]) -> Any:
    """The regressor's and the torques' largest errors against Pinocchio, ok or FAILED."""
    from rich.table import Table

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
    return checks


def _base_parameter_table(report: dict[str, Any]) -> tuple[Any, list[str]]:
    """The base-parameter counts of the robot and of each stage, per method and frames, and
    a note per stage on the joints that move and the bodies that are unknown."""
    from rich.table import Table

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
    return counts, notes


def register(app: typer.Typer) -> None:
    """Add the ``verify`` command to the CLI."""
    app.command("verify")(verify)
