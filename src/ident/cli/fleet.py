"""``ident fleet CONFIG``: many logs of robots of one model identified jointly on
dask.distributed.

Validates the config (:func:`ident.identify.streaming.fleet_config.load_fleet_config`), the
output folder, the scheduler address and the robot before anything runs; then sums every
unit's rows chunk by chunk on the cluster (:mod:`ident.identify.streaming.fleet_run`), solves
the shared rigid-body model with every unit's friction and offsets
(:func:`ident.identify.streaming.fleet.solve_fleet`), and writes the run folder
``<out>/<name>-<timestamp>/`` with ``result.json``, ``drift.json``, ``drift.md`` and
``windows.csv``, marked complete after the last. Exit codes: 0 success; 2 bad input (nothing
written); 130 on Ctrl-C.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import check_scheduler_address, user_errors

__all__ = ["fleet", "register"]


def register(app: typer.Typer) -> None:
    """Add ``fleet`` to the ``ident`` command line."""
    app.command("fleet")(fleet)


def fleet(
    config: Annotated[Path, typer.Argument(help="Fleet config (docs/fleet.md).")],
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
) -> None:
    """Identify a fleet's logs jointly: shared rigid body, per-unit friction; drift report."""
    from ident.errors import ConfigError, IdentError
    from ident.fileio import atomic_write_text
    from ident.identify.streaming.fleet import fleet_columns, solve_fleet
    from ident.identify.streaming.fleet_config import load_fleet_config
    from ident.identify.streaming.fleet_report import fleet_report
    from ident.identify.streaming.fleet_run import ReadLog, fleet_client, fleet_sums
    from ident.inputs import check_output_dir
    from ident.model.selection import load_robot
    from ident.run.rundir import run_folder

    with user_errors():
        cfg = load_fleet_config(config)
        source = str(cfg.source or config)
        check_output_dir(out, "--out")
        f = cfg.fleet
        try:
            check_scheduler_address(f.scheduler)
        except IdentError as e:
            msg = (
                str(e)
                .replace("--scheduler", "fleet.scheduler")
                .replace("drop fleet.scheduler", "set it to null")
            )
            raise ConfigError(f"{source}: {msg}") from None
        model = load_robot(cfg.robot, source=source).model
        cols = fleet_columns(model, cfg.model.rotor_inertia, cfg.model.offset, source)
        joints = tuple(str(model.names[i]) for i in range(1, model.njoints))
        units = cfg.unit_logs()
        sources = [
            [ReadLog(log, cfg.transmission, joints, source) for log in logs] for _, logs in units
        ]
        where = (
            f"scheduler {f.scheduler}" if f.scheduler else f"LocalCluster of {f.workers} worker(s)"
        )
        typer.echo(f"{len(units)} unit(s), {sum(len(s) for s in sources)} log(s); {where}")
        with fleet_client(f.scheduler, f.workers, f.processes) as client:
            sums = fleet_sums(
                client, sources, cols, f.chunk_settings(), f.window_s, f.logs_in_flight
            )
        sol = solve_fleet(sums.units, cols)
        names = [n for n, _ in units]
        report = fleet_report(names, sums, sol, cols, f.model_dump())
        with run_folder(out, cfg.name, info={"command": "fleet", "config": str(config)}) as rd:
            atomic_write_text(rd.path / "result.json", json.dumps(report.result, indent=2) + "\n")
            atomic_write_text(rd.path / "drift.json", json.dumps(report.drift, indent=2) + "\n")
            atomic_write_text(rd.path / "drift.md", report.markdown)
            atomic_write_text(rd.path / "windows.csv", report.windows_csv)
            rd.finish("complete", f"{len(names)} unit(s)")
        _print_summary(report.result, report.drift)
        typer.echo(f"run folder: {rd.path}")


def _print_summary(result: dict, drift: dict) -> None:
    """Throughput, flagged units and alarms on the terminal."""
    tp = result["throughput"]
    typer.echo(
        f"{tp['samples']} samples ({tp['samples'] / 3.6e6:.3g} robot-hours at 1 kHz) in "
        f"{tp['wall_s']:.1f} s on {tp['cores']} core(s): "
        f"{tp['samples_per_s_per_core']:,.0f} samples/s per core "
        f"({tp['samples_per_cpu_s_of_the_chunks']:,.0f} per CPU second of the chunk tasks)"
    )
    across = drift["across_units"]
    if across["status"] == "run":
        flagged = [u["unit"] for u in across["units"] if u["flagged"]]
        typer.echo(
            f"friction against the fleet: {len(flagged)} unit(s) flagged "
            f"{', '.join(flagged)}".rstrip()
        )
    else:
        typer.echo(f"friction against the fleet: not run ({across['reason']})")
    for u in drift["across_time"]["units"]:
        if u["alarms"]:
            typer.echo(
                f"friction rise: {u['unit']}: {u['alarms']} window(s) alarmed, first at "
                f"{u['first_alarm_s']:.0f} s of motion"
            )
