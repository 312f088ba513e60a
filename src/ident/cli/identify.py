"""``ident identify CONFIG``: identify a real robot from its logs.

Validates the config, runs :func:`ident.identify.real.identify`, and only when that succeeded
creates a new run folder ``<out>/<name>-<timestamp>/`` with the report (so a failed
identification leaves nothing that looks like a result), the measured motion
(``trajectory.csv``, ``robot.urdf``) and its replay (``replay.html``, unless ``--no-replay``;
a failing replay is reported, never fatal). If writing the report fails, the folder is marked
incomplete.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["identify", "register"]


def register(app: typer.Typer) -> None:
    """Add ``identify`` to the ``ident`` command line."""
    app.command("identify")(identify)


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
) -> None:
    """Identify base, friction and actuator parameters from CONFIG's measured log."""
    from ident.errors import IdentError
    from ident.identify.config import load_identify_config
    from ident.identify.real import identify as run_identify
    from ident.report.identify_report import write_identify_report, write_measured_replay
    from ident.run.rundir import create_run_dir

    with user_errors():
        cfg = load_identify_config(config)
        result = run_identify(cfg, rng=seed)
        rundir = create_run_dir(
            out, f"{cfg.name}", info={"command": "identify", "config": str(config), "seed": seed}
        )
        try:
            t0 = time.perf_counter()
            replay_note = write_measured_replay(result, rundir.path, replay=replay)
            rundir.update(replay=replay_note)
            t1 = time.perf_counter()
            write_identify_report(result, rundir.path, replay_note=replay_note)
            timings = {**result.timings, "replay": t1 - t0, "report": time.perf_counter() - t1}
        except (IdentError, OSError) as e:
            rundir.finish("incomplete", f"writing the report failed: {e}")
            raise IdentError(f"{rundir.path}: writing the report failed ({e}).") from e
        except BaseException:
            rundir.finish("incomplete", "interrupted while writing the report")
            raise
        rundir.update(timings_s={k: round(v, 3) for k, v in timings.items()})
        rundir.finish("complete", result.estimate.message)
        est = result.estimate
        typer.echo(f"run folder: {rundir.path}")
        typer.echo(
            f"{est.method.upper()}: {len(est.names)} base parameters, relative residual "
            f"{est.relative_residual:.4f}, condition number {est.condition_number:.4g}, "
            f"{result.timings['total']:.1f} s"
        )
        for label, p in result.predictions.items():
            rmse = ", ".join(f"{v:.3g}" for v in p.metrics.rmse)
            typer.echo(
                f"held-out {label}: relative residual {p.metrics.total_relative_residual:.4f}; "
                f"RMSE per joint [N*m] {rmse}"
            )
        typer.echo(replay_note)
        typer.echo(f"report: {rundir.path / 'report.html'}")
