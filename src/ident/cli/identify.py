"""``ident identify CONFIG``: identify a real robot from its logs.

Validates the config, runs :func:`ident.identify.pipeline.real.identify`, and only when
that succeeded creates a new run folder ``<out>/<name>-<timestamp>/`` with the report (so a
failed identification leaves nothing that looks like a result), the measured motion
(``trajectory.csv``, ``robot.urdf``) and its replay (``replay.html``, unless ``--no-replay``;
a failing replay is reported, never fatal). Any error, Ctrl-C or SIGTERM once the folder
exists marks it incomplete (``run.json``, ``INCOMPLETE``) and names it (exit 2, or 130).
``--scheduler ADDRESS`` hands the chunks of a long log (see
:mod:`ident.identify.estimation.accumulate`) to a running dask.distributed scheduler. Once
the log is read, the estimated memory and time of the identification are printed when above a
minute or 2 GB, and refused above the ceilings ``IDENT_MAX_MEMORY_GB`` / ``IDENT_MAX_HOURS``
(before any run folder).

Exit codes: 0 success (warnings, e.g. a held-out prediction worse than the URDF's nominal
parameters, are printed and recorded in ``result.json``); 1 a warning with
``validation.fail_on_warning: true`` in the config (the run folder is written); 2 bad input or a
failed identification (nothing written as a result).
"""

from __future__ import annotations

import time
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from ident.cli._common import (
    PackageDirOption,
    check_package_dirs,
    check_scheduler_address,
    user_errors,
)

if TYPE_CHECKING:
    from ident.identify.pipeline.core import IdentifyResult
    from ident.inputs import JobEstimate

__all__ = ["identify", "register"]


def register(app: typer.Typer) -> None:
    """Add ``identify`` to the ``ident`` command line."""
    app.command("identify")(identify)


def _print_estimate(estimate: JobEstimate) -> None:
    """Print the estimate of a long identification (above a minute or 2 GB), as ``ident run``."""
    if estimate.seconds > 60.0 or estimate.memory_bytes > 2e9:
        typer.echo(f"estimate: {estimate.describe()}", err=True)


def identify(
    config: Annotated[Path, typer.Argument(help="Identify config (e.g. configs/tx40.yaml).")],
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
    seed: Annotated[
        int, typer.Option(help="Seed of the random states that find the base parameters.")
    ] = 0,
    replay: Annotated[
        bool,
        typer.Option(help="Write replay.html (the measured motion, meshcat) into the run folder."),
    ] = True,
    package_dir: PackageDirOption = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="dask.distributed scheduler address (e.g. tcp://127.0.0.1:8786) for the chunks "
            "of long logs (needs pip install 'ident[dask]'); the result is the same as without."
        ),
    ] = None,
) -> None:
    """Identify base, friction and actuator parameters from CONFIG's measured log."""
    started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
    t_start = time.monotonic()
    from ident.identify.config import load_identify_config
    from ident.identify.estimation.log_chunks import map_large_blocks
    from ident.identify.pipeline.real import identify as run_identify

    # the command owns its process: a long log's temporaries handed back to the system when
    # freed (a library call leaves the caller's allocator as it is)
    map_large_blocks()
    package_dirs = list(package_dir or ())
    with user_errors():
        _check_options(seed, out, package_dirs, scheduler)
        cfg = load_identify_config(config)
        result = run_identify(cfg, rng=seed, scheduler=scheduler, on_estimate=_print_estimate)
        info = {"command": "identify", "config": str(config), "seed": seed}
        if scheduler is not None:
            info["scheduler"] = scheduler
        if package_dirs:
            info["package_dirs"] = [str(d) for d in package_dirs]
        info["started_at"] = started_at
        folder, replay_note = _write_run(result, out, cfg.name, info, replay, package_dirs, t_start)
        _print_summary(result, folder, replay_note)
    if result.warnings and cfg.validation.fail_on_warning:
        typer.echo(
            "error: validation.fail_on_warning is set and the result has warnings.", err=True
        )
        raise typer.Exit(code=1)


def _check_options(seed: int, out: Path, package_dirs: list[Path], scheduler: str | None) -> None:
    """Refuse a bad ``--seed``, ``--out``, ``--package-dir`` or ``--scheduler`` before any work.

    Raises
    ------
    IdentError
        One line naming the option and the fix.
    """
    from ident.inputs import check_number, check_output_dir

    check_number(seed, "--seed", low=0, high=2**63 - 1, integer=True)
    check_output_dir(out, "--out")
    check_package_dirs(package_dirs)
    check_scheduler_address(scheduler)


def _write_run(
    result: IdentifyResult,
    out: Path,
    name: str,
    info: dict[str, Any],
    replay: bool,
    package_dirs: list[Path],
    t_start: float,
) -> tuple[Path, str]:
    """Write the identification into a new run folder under ``out`` (``info``: the fields of
    its ``run.json``; ``t_start``: the command's start, :func:`time.monotonic` [s]); its path
    and the replay's note. Any error or interruption marks the folder incomplete and names
    it."""
    from ident.run.rundir import run_folder

    est = result.estimate
    message = est.message if not result.warnings else "; ".join(result.warnings)
    # any error or interruption from here on marks the folder incomplete and names it
    with run_folder(out, f"{name}", info=info) as rundir:
        replay_note, timings = _save_and_report(result, rundir, replay, package_dirs)
        rundir.update(
            timings_s={k: round(v, 3) for k, v in timings.items()},
            warnings=list(result.warnings),
            missing=None,
            complete_message=None,
        )
        # wall time of the whole command (config, identification, replay, report); the
        # run is complete with its last write
        rundir.update(wall_time_s=round(time.monotonic() - t_start, 3))
        rundir.finish("complete", message, stamp_wall_time=False)
    return rundir.path, replay_note


def _save_and_report(
    result: IdentifyResult, rundir: Any, replay: bool, package_dirs: list[Path]
) -> tuple[str, dict[str, float]]:
    """The estimate first, then the replay and the report (the caller's guard marks the folder
    incomplete when one fails). Returns the replay note and the timings with the replay's and
    report's."""
    from ident.report.identify_report import (
        save_identify_data,
        write_identify_report,
        write_measured_replay,
    )

    save_identify_data(result, rundir.path)  # the estimate is safe before the rest
    # from here 'ident report' can write what is missing
    rundir.update(missing="report", complete_message=result.estimate.message)
    t0 = time.perf_counter()
    replay_note = write_measured_replay(
        result, rundir.path, replay=replay, package_dirs=package_dirs
    )
    rundir.update(replay=replay_note)
    if replay and not replay_note.startswith("replay.html written"):
        typer.echo(f"warning: {replay_note} (run.json says so too)", err=True)
    t1 = time.perf_counter()
    _echo_refinement_estimate(result)
    write_identify_report(result, rundir.path, replay_note=replay_note)
    return replay_note, {
        **result.timings,
        "replay": t1 - t0,
        "report": time.perf_counter() - t1,
    }


def _print_summary(result: IdentifyResult, folder: Path, replay_note: str) -> None:
    """The terminal's summary of a finished identification (the report says it at length)."""
    from ident.identify.assessment.model_intervals import estimated_seconds
    from ident.identify.assessment.verdict import identify_verdict
    from ident.report.identify_report import joint_torque_units

    est = result.estimate
    typer.echo(f"run folder: {folder}")
    typer.echo(
        f"{est.method.upper()}: {len(est.names)} base parameters, relative residual "
        f"{est.relative_residual:.4f}, condition number {est.condition_number:.4g}, "
        f"{result.timings['total']:.1f} s"
    )
    units = joint_torque_units(result)  # N*m per revolute joint, N per prismatic
    for label, p in result.predictions.items():
        rmse = ", ".join(f"{v:.3g} {u}" for v, u in zip(p.metrics.rmse, units, strict=True))
        typer.echo(
            f"held-out {label}: relative residual {p.metrics.total_relative_residual:.4f}; "
            f"RMSE per joint {rmse}"
        )
    mi = result.model_intervals
    if mi is not None:
        nv = len(result.joint_names)
        typer.echo(
            f"intervals of the written model: {mi.n_boot} re-solves of the "
            f"{mi.method.upper()} fit, {mi.seconds:.1f} s (estimated "
            f"{estimated_seconds(mi.n_boot, nv):.1f} s; urdf_update.model_bootstrap: 0 "
            "switches them off)"
        )
    elif result.model_intervals_note:
        typer.echo(f"note: {result.model_intervals_note}", err=True)
    if result.friction is not None:
        f = result.friction
        ranked = ", ".join(f"{x.model} {x.held_out_residual:.4f}" for x in f.fits)
        typer.echo(
            f"friction models (held-out relative residual): {ranked}; winner {f.winner}, "
            f"{100 * f.improvement():.2f} % below {f.baseline}"
        )
        for x in f.fits:
            if x.ambiguous:
                typer.echo(f"note: friction model {x.model} not picked: {x.ambiguous}", err=True)
    if result.actuator is not None:
        typer.echo(result.actuator.line())
    typer.echo(replay_note)
    _echo_model(folder / "result.json")
    verdict = identify_verdict(result)  # the one the report and result.json show
    typer.echo(f"verdict: {verdict.label} ({verdict.reason})")
    typer.echo(f"report: {folder / 'report.html'}")
    for w in result.warnings:
        typer.echo(f"warning: {w}", err=True)


def _echo_refinement_estimate(result: IdentifyResult) -> None:
    """Before a refinement on rollouts (``refinement: rollout``): its bound and CPU estimate,
    from the windows it will use."""
    from ident.identify.assessment.rollout import WINDOW_S, window_count
    from ident.identify.refinement.rollout_refinement import estimated_cpu_s

    cfg = result.config.refinement
    if cfg.method == "none":
        return
    nv = len(result.joint_names)
    n_train = window_count(result, "identification", max_windows=cfg.max_windows)
    n_held = window_count(result, "held-out")
    rate = result.log.sampling_rate_hz
    seconds = estimated_cpu_s(n_train, n_held, rate, nv, cfg.max_iterations)
    typer.echo(
        f"refinement on rollouts: at most {cfg.max_iterations} iterations of {3 * nv + 1} "
        f"rollouts of {n_train} training windows of {WINDOW_S:g} s (at most {cfg.max_windows}: "
        f"refinement.max_windows) and one of {n_held} held-out windows: estimated "
        f"{seconds:.0f} s of CPU or less"
    )


def _echo_model(result_json: Path) -> None:
    """One line on the identified model (its files and reload parity) and one on its MJCF's
    rollout check, from ``result.json``."""
    import json

    from ident.identify.assessment.rollout import rollout_text
    from ident.identify.refinement.rollout_refinement import refinement_text

    data = json.loads(result_json.read_text(encoding="utf-8"))
    typer.echo(rollout_text(data.get("rollout")))  # the MJCF's rollout check, or why not run
    refined = refinement_text(data.get("refinement"))  # None: not asked for
    if refined is not None:
        typer.echo(refined)
    model = data.get("model") or {}
    if not model.get("written"):
        typer.echo(f"model: {model.get('note') or 'not written'}")
        return
    files, parity = model["files"], model["reload_parity"]
    typer.echo(
        f"model ({model['method']}, every link consistent): {files['urdf']}, {files['mjcf']}, "
        f"{files['joint_extras']}"
        + (
            f"; reloaded: URDF {parity['urdf']:.1e}, MJCF {parity['mjcf']:.1e} relative"
            if parity
            else f"; {model['note']}"
        )
    )
