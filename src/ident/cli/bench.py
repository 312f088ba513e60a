"""``ident bench CONFIG``: the optimizer comparison campaign (paper Tables 4-9, Figures 5-7).

Runs every method on every function of CONFIG for the configured number of seeded runs, on
local worker processes (``--workers``, at most the CPU count) or on a running
dask.distributed scheduler (``--scheduler tcp://HOST:PORT``, needs
``pip install 'ident[dask]'``), with a progress bar, then writes a new campaign folder (never
overwriting one): ``campaigns/<name>-<timestamp>/`` or ``--out DIR`` (which must not exist or
be empty), with a ``run.json`` that says whether it is complete.

Everything is checked before the first run: the config, ``--workers``, that the output folder
can be created, and the estimated memory and time (printed, and refused above the ceilings
``IDENT_MAX_MEMORY_GB`` / ``IDENT_MAX_HOURS``). A failed or interrupted campaign leaves no
folder. A finished campaign is never thrown away: if ``--out`` was taken meanwhile (another
campaign wrote there), the results go to a new folder beside it and the command says where.
A write that fails (a full disk) or Ctrl-C / SIGTERM while the folder is written leaves it
marked incomplete (``run.json``, ``INCOMPLETE``), named on the one ``error:`` or
``interrupted:`` line (exit 2 or 130).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from ident.cli._common import check_scheduler_address, user_errors

__all__ = ["bench", "register"]

DEFAULT_PARENT = Path("campaigns")


def register(app: typer.Typer) -> None:
    """Add ``bench`` to the ``ident`` command line."""
    app.command("bench")(bench)


def _check_out(out: Path | None) -> None:
    """The campaign folder can be created: new or empty, in a writable place."""
    from ident.inputs import check_output_dir

    if out is not None:
        check_output_dir(out, "--out", must_be_new_or_empty=True)
    else:
        check_output_dir(DEFAULT_PARENT, "campaigns folder")


def bench(
    config: Annotated[Path, typer.Argument(help="Campaign config (e.g. configs/bench.yaml).")],
    workers: Annotated[
        int, typer.Option(help="Local worker processes (1 to the number of CPUs).")
    ] = 1,
    out: Annotated[
        Path | None, typer.Option(help="Campaign folder (new or empty); default campaigns/.")
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="dask.distributed scheduler address, e.g. tcp://127.0.0.1:8786."),
    ] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """Compare eMuPSO with PSO, WOA, GWO, GOA and DE on the benchmark functions of CONFIG."""
    from ident.bench.campaign import (
        check_workers,
        estimate_campaign,
        load_campaign_config,
        make_tasks,
    )
    from ident.bench.report import disagreements
    from ident.inputs import check_job

    with user_errors():
        check_scheduler_address(scheduler)
        cfg = load_campaign_config(config)
        if scheduler is None:
            check_workers(workers)
        _check_out(out)
        estimate = check_job(estimate_campaign(cfg, workers if scheduler is None else 1))
        total = len(make_tasks(cfg))
        typer.echo(
            f"{total} runs: {len(cfg.methods)} methods x {len(cfg.function_keys())} functions "
            f"x {cfg.runs} runs, {cfg.max_nfev} evaluations each"
        )
        typer.echo(f"estimate: {estimate.describe()}")
        result = _run_with_progress(cfg, total, workers, scheduler, progress)
        folder = _write_campaign_folder(result, cfg, config, out, total)
        typer.echo(f"wall time {result.wall_seconds:.1f} s")
        for line in disagreements(result)[:10]:
            typer.echo(f"  {line}")
        typer.echo(f"report: {folder / 'report.html'}")


def _run_with_progress(
    cfg: Any, total: int, workers: int, scheduler: str | None, progress: bool
) -> Any:
    """Run the ``total`` runs of the campaign ``cfg`` (:func:`ident.bench.campaign.
    run_campaign`) behind a progress bar (``progress``: shown); its result."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from ident.bench.campaign import run_campaign

    with Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeRemainingColumn(),
        disable=not progress,
    ) as bar:
        task = bar.add_task("bench", total=total)
        return run_campaign(
            cfg,
            workers=workers,
            scheduler=scheduler,
            progress=lambda done, _total: bar.update(task, completed=done),
        )


def _write_campaign_folder(
    result: Any, cfg: Any, config: Path, out: Path | None, total: int
) -> Path:
    """Write the campaign's ``result`` into a new folder (``out``, else under
    :data:`DEFAULT_PARENT`); its path."""
    from ident.bench.report import write_campaign
    from ident.run.rundir import run_folder

    # created after the runs (a failed campaign leaves nothing); --out taken meanwhile
    # gives <out>-2, ...; any error or interruption while writing marks it incomplete
    parent = out if out is not None else DEFAULT_PARENT
    info = {"command": "bench", "config": str(config)}
    with run_folder(parent, cfg.name, info=info, exact=out is not None) as rundir:
        folder = rundir.path
        if out is not None and folder != out:
            typer.echo(f"{out} was taken meanwhile: results in {folder}", err=True)
        write_campaign(result, folder)
        rundir.finish("complete", f"{total} runs")
    return folder
