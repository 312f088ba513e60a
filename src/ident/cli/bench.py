"""``ident bench CONFIG``: the optimizer comparison campaign (paper Tables 4-9, Figures 5-7).

Runs every method on every function of CONFIG for the configured number of seeded runs, on
local worker processes (``--workers``) or on a running dask.distributed scheduler
(``--scheduler tcp://HOST:PORT``, needs ``pip install 'ident[dask]'``), with a progress bar,
then writes a new campaign folder (never overwriting one): ``campaigns/<name>-<timestamp>/``
or ``--out DIR`` (which must not exist or be empty).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["bench", "register"]


def register(app: typer.Typer) -> None:
    """Add ``bench`` to the ``ident`` command line."""
    app.command("bench")(bench)


def _check_out(out: Path | None) -> None:
    from ident.errors import ConfigError

    if out is not None and out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(
            f"--out {out}: exists and is not an empty folder; campaigns are never "
            "overwritten, choose a new folder."
        )


def _new_folder(out: Path | None, name: str) -> Path:
    """Create the campaign folder (after the runs: a failed campaign leaves nothing)."""
    _check_out(out)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        return out
    stamp = time.strftime("%Y%m%d-%H%M%S")
    base = Path("campaigns") / f"{name}-{stamp}"
    folder, k = base, 1
    while folder.exists():
        k += 1
        folder = base.with_name(f"{base.name}-{k}")
    folder.mkdir(parents=True)
    return folder


def bench(
    config: Annotated[Path, typer.Argument(help="Campaign config (e.g. configs/bench.yaml).")],
    workers: Annotated[int, typer.Option(help="Local worker processes.")] = 1,
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
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from ident.bench.campaign import load_campaign_config, make_tasks, run_campaign
    from ident.bench.report import disagreements, write_campaign

    with user_errors():
        cfg = load_campaign_config(config)
        total = len(make_tasks(cfg))
        _check_out(out)
        typer.echo(
            f"{total} runs: {len(cfg.methods)} methods x {len(cfg.function_keys())} functions "
            f"x {cfg.runs} runs, {cfg.max_nfev} evaluations each"
        )
        with Progress(
            TextColumn("[progress.description]{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total}"),
            TimeRemainingColumn(),
            disable=not progress,
        ) as bar:
            task = bar.add_task("bench", total=total)
            result = run_campaign(
                cfg,
                workers=workers,
                scheduler=scheduler,
                progress=lambda done, _total: bar.update(task, completed=done),
            )
        folder = _new_folder(out, cfg.name)
        write_campaign(result, folder)
        typer.echo(f"wall time {result.wall_seconds:.1f} s")
        for line in disagreements(result)[:10]:
            typer.echo(f"  {line}")
        typer.echo(f"report: {folder / 'report.html'}")
