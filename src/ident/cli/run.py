"""``ident run CONFIG``.

``ident run`` validates the config, creates a new run folder ``<out>/<name>-<timestamp>/``,
runs :func:`ident.run.pipeline.run_pipeline` with a progress bar (stderr), saves the data,
the replay and the report, and prints a one-screen summary (stdout). Ctrl-C, SIGTERM or an
error at any moment once the folder exists saves what finished and marks the folder incomplete
(``run.json`` and ``result.json`` status, ``INCOMPLETE`` file) before exiting, naming the
folder: 130 for Ctrl-C and SIGTERM, 1 for a run that stopped, identified nothing or has no safe
trajectory (its cause on the last ``error:`` lines), 2 only for bad input, found before the
run folder exists.

``ident report RUN_DIR`` (:mod:`ident.cli.report`) regenerates the report from the saved data.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from ident.cli._common import (
    EXIT_USER_ERROR,
    PackageDirOption,
    check_package_dirs,
    failure_note,
    one_line,
    user_errors,
)

__all__ = ["register"]

#: The run ran and failed: nothing identified, no safe trajectory, or it stopped (2 is bad input)
EXIT_NOT_IDENTIFIED = 1


def register(app: typer.Typer) -> None:
    """Add ``run`` to the ``ident`` command line (``report`` is in :mod:`ident.cli.report`)."""
    app.command("run")(run)


def run(
    config: Annotated[Path, typer.Argument(help="Run config (e.g. configs/wrist.yaml).")],
    seed: Annotated[
        int | None, typer.Option(help="Seed of every random draw (overrides the config).")
    ] = None,
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
    quick: Annotated[
        bool, typer.Option("--quick", help="Small settings for a first look (seconds).")
    ] = False,
    replay: Annotated[
        bool, typer.Option(help="Write replay.html (meshcat static page) into the run folder.")
    ] = True,
    package_dir: PackageDirOption = None,
) -> None:
    """Design the excitation of CONFIG's stage, simulate, identify and write a report."""
    from ident.inputs import check_output_dir
    from ident.run.config import load_run_config
    from ident.run.exports.run_exports import check_run_exports
    from ident.run.pipeline import feasible_start
    from ident.run.rundir import run_folder
    from ident.run.setup import prepare_run

    with user_errors():
        check_output_dir(out, "--out")
        package_dirs = check_package_dirs(package_dir)
        cfg = load_run_config(config).with_package_dirs(package_dirs)
        if quick:
            cfg = cfg.quick_version()
        if seed is not None:
            cfg = cfg.with_seed(seed)
        # everything that can be wrong with the config is found before the folder exists
        setup = prepare_run(cfg, source=config)
        check_run_exports(cfg, setup.robot, config)
        _setup_notes(setup)
        name = f"{cfg.name}-quick" if quick else str(cfg.name)
        info = {
            "config": str(config),
            "seed": cfg.seed,
            "quick": quick,
            "command": " ".join(["ident", *sys.argv[1:]]),
            "export_limits": list(setup.limit_notes),
            "safety_margin_note": setup.safety.margin_note,
            "simulation_notes": list(setup.simulation_notes),
        }
        with _ProgressDisplay(cfg, setup.estimate) as display:
            # stage 1, the feasible elites, also before the folder exists: an excitation box
            # that holds no design meeting the constraints is an input error
            start = feasible_start(setup, progress=display.update)
            # any error or interruption from here on marks the folder incomplete, names it
            with run_folder(out, name, info=info, status_copy="result.json") as rundir:
                typer.echo(f"run folder: {rundir.path}", err=True)
                result = _optimize(start, display, rundir)
                exports, replay_note, report_path = _save_and_report(result, rundir, replay)
                rundir.finish("complete", result.message, stamp_wall_time=False)
        _summary(result, rundir.path, report_path, replay_note, exports)
        raise typer.Exit(code=_final_lines(result, exports))


def _final_lines(result: Any, exports: Any) -> int:
    """The run's failures as ``error:`` lines after the summary; returns the exit code.

    Refused exports, then the run's warnings (no safe trajectory: the link pair or limit and
    the time; nothing identified), then, when the executed elite has no estimate, each of its
    estimators' causes (the joint that did not move, the field to change): 1 with a warning,
    2 when only an export was refused (its limits are input), else 0.
    """
    for refusal in exports.refused.values() if exports is not None else ():
        typer.echo(f"error: export refused: {one_line(refusal)}", err=True)
    for warning in result.warnings:
        typer.echo(f"error: {one_line(warning)}", err=True)
    rank = result.executed_rank
    elite = next((e for e in result.elites if e.rank == rank), None)
    if result.warnings and elite is not None and not elite.estimates:
        for method, message in elite.failures.items():
            typer.echo(f"error: elite {rank}, {method}: {one_line(message)}", err=True)
    if result.warnings:
        return EXIT_NOT_IDENTIFIED
    return EXIT_USER_ERROR if exports is not None and exports.refused else 0


def _setup_notes(setup: Any) -> None:
    """What the checked setup changed or expects, on stderr before anything runs."""
    for note in setup.limit_notes:  # export targets' limits the design keeps
        typer.echo(f"limits tightened by {note}", err=True)
    if setup.safety.margin_note:  # the default margin, lowered to one the links can keep
        typer.echo(f"note: {setup.safety.margin_note}", err=True)
    for note in setup.simulation_notes:  # what the MuJoCo model leaves out of the URDF
        typer.echo(f"note: {note}", err=True)
    if max(setup.estimate.seconds, setup.estimate.worst_seconds) > 60.0 or (
        setup.estimate.memory_bytes > 2e9
    ):
        typer.echo(f"estimate: {setup.estimate.describe()}", err=True)


def _optimize(start: Any, display: _ProgressDisplay, rundir: Any) -> Any:
    """Run the pipeline from ``start``; an interrupted or failed run saves what it finished
    (the folder marked incomplete with what is missing) before the error goes on."""
    from ident.errors import IdentError
    from ident.run.pipeline import RunInterrupted, run_pipeline
    from ident.run.rundir import FolderInterrupted

    try:
        return run_pipeline(start, progress=display.update)
    except RunInterrupted as e:
        _save_partial(e.partial, rundir)
        if isinstance(e.cause, KeyboardInterrupt):
            raise FolderInterrupted(rundir.path) from None
        if isinstance(e.cause, IdentError):  # the input was checked: the run failed
            typer.echo(
                f"error: {one_line(e.partial.message)} (run folder: {rundir.path})", err=True
            )
            raise typer.Exit(code=EXIT_NOT_IDENTIFIED) from None
        raise e.cause from None


def _save_and_report(result: Any, rundir: Any, replay: bool) -> tuple[Any, str, Any]:
    """:func:`_save_results` then the report; an error about the run's own files is the run's
    failure (exit 1, the folder marked incomplete), not the input's."""
    from ident.errors import IdentError

    try:
        exports, replay_note = _save_results(result, rundir, replay)
        return exports, replay_note, _write_report(rundir, result.message)
    except IdentError as e:  # the folder is marked already, with the step that failed
        typer.echo(f"error: the run stopped while writing its files: {one_line(e)}", err=True)
        typer.echo(f"(run folder: {rundir.path})", err=True)
        raise typer.Exit(code=EXIT_NOT_IDENTIFIED) from None


def _save_results(result: Any, rundir: Any, replay: bool) -> tuple[Any, str]:
    """Save everything the run computed, then its controller exports and replay; the folder
    is marked incomplete if any of it fails. Returns the exports and the replay note."""
    from ident.report.run_data import save_run_model
    from ident.report.run_report import save_run, write_replay
    from ident.run.exports.run_exports import export_run
    from ident.run.log_measurement import save_logs

    try:
        save_run(result, rundir.path)
        save_logs(result, rundir.path)
        save_run_model(result, rundir.path)  # the identified model: URDF, MJCF, extras
        # controller files of the certified trajectory, checked, written, re-read
        exports = export_run(result, rundir.path)
        if exports is not None:
            rundir.update(exports=exports.lines(rundir.path))
        replay_note = write_replay(rundir.path) if replay else "replay skipped (--no-replay)."
        rundir.update(replay=replay_note)
        if replay and not replay_note.startswith("replay.html written"):
            typer.echo(f"warning: {replay_note} (run.json says so too)", err=True)
    except BaseException as e:
        rundir.finish("incomplete", f"stopped while saving the results: {failure_note(e)}")
        raise
    return exports, replay_note


def _write_report(rundir: Any, message: str) -> Path:
    """The report, last: the data are saved, so if it fails 'ident report RUN_DIR' writes it
    again (``missing: report`` in run.json: that command then marks the run complete with
    ``message``); the run is complete only once it is written (the caller marks it)."""
    from ident.report.run_report import write_report

    rundir.update(missing="report", complete_message=message)
    rundir.stamp_wall_time()
    try:
        path = write_report(rundir.path)
    except BaseException as e:
        rundir.finish(
            "incomplete",
            f"stopped while writing the report ({failure_note(e)}); the data are saved",
        )
        typer.echo(
            f"the data are saved; write the report with: ident report {rundir.path}",
            err=True,
        )
        raise
    rundir.update(missing=None, complete_message=None)
    return path


def _save_partial(partial: Any, rundir: Any) -> None:
    """Save what an interrupted run finished; never hide the original problem."""
    from ident.report.run_report import save_run, write_report
    from ident.run.log_measurement import save_logs

    try:
        save_run(partial, rundir.path)
        save_logs(partial, rundir.path)
        rundir.finish("incomplete", partial.message)
        write_report(rundir.path)
    except BaseException as e:  # noqa: BLE001 - the folder must still be marked
        rundir.finish("incomplete", f"{partial.message}; saving failed: {e}")


class _ProgressDisplay:
    """A rich progress bar over the elite search, the eMuPSO iterations and the estimates."""

    def __init__(self, cfg: Any, estimate: Any = None) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        self.cfg, self.estimate = cfg, estimate
        self.progress = Progress(
            TextColumn("{task.description:<16}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[info]}"),
            TimeElapsedColumn(),
            console=Console(stderr=True),
            transient=False,
        )
        self.tasks: dict[str, Any] = {}

    def __enter__(self) -> _ProgressDisplay:
        self.progress.__enter__()
        cfg = self.cfg
        self.tasks["elites"] = self.progress.add_task(
            "initial elites", total=cfg.elites.maxiter, info=""
        )
        name = "eMuPSO" if cfg.optimizer == "emupso" else cfg.optimizer
        self.tasks["optimize"] = self.progress.add_task(
            name, total=cfg.emupso.n_runs * cfg.emupso.maxiter, info=""
        )
        self.tasks["identify"] = self.progress.add_task(
            "identification", total=cfg.emupso.n_report_elites, info=""
        )
        return self

    def __exit__(self, *exc: Any) -> None:
        self.progress.__exit__(*exc)

    def update(self, event: Any) -> None:
        """Progress callback of :func:`ident.run.pipeline.run_pipeline`."""
        p = self.progress
        if event.phase == "elites":
            p.update(self.tasks["elites"], completed=event.step, info=f"violation {event.best:.3g}")
        elif event.phase == "optimize":
            run = f"run {event.run + 1}/{self.cfg.emupso.n_runs}"
            p.update(
                self.tasks["optimize"], completed=event.step, info=f"{run} best {event.best:.6g}"
            )
        elif event.phase == "elites_done":
            n = len(event.payload)
            p.update(
                self.tasks["elites"],
                total=max(event.step, 1),
                completed=max(event.step, 1),
                info=f"{n} elites in {event.step} iterations",
            )
        elif event.phase == "run_done":
            p.update(self.tasks["optimize"], completed=event.step * self.cfg.emupso.maxiter)
        elif event.phase == "identify":
            p.update(self.tasks["identify"], completed=event.step, total=event.total, info="")
        elif event.phase == "retry":  # the printed estimate's worst case now applies
            p.console.print(f"retrying: {event.payload} {self._retry_time()}".rstrip())

    def _retry_time(self) -> str:
        """The run's worst-case time, which applies once the design is retried (the estimate
        printed at the start gives it after 'up to'); '' without an estimate."""
        from ident.inputs import duration_text

        e = self.estimate
        if e is None or not e.worst_seconds > e.seconds:
            return ""
        return f"The run takes up to {duration_text(e.worst_seconds)} in all (its estimate)."


def _summary(
    result: Any, run_dir: Path, report_path: Path, replay_note: str, exports: Any = None
) -> None:
    """One screen: the chosen elite, the estimate quality, where the files are."""
    from rich.console import Console
    from rich.table import Table

    from ident.report.run_data import load_run
    from ident.report.run_report import evaluation_budget, optimizer_name
    from ident.report.run_verdict import stored_verdict

    console = Console()
    stage = result.stage
    table = Table(title=f"ident run {result.config.name}: {stage.name} stage", show_header=False)
    _stage_rows(table, stage)
    data = load_run(run_dir)  # the saved result: the verdict the reports show
    table.add_row("evaluation budget", evaluation_budget(data))
    table.add_row(f"{optimizer_name(data)} runs", ", ".join(f"{r.fun:.5g}" for r in result.runs))
    if result.elites:
        _elite_rows(table, result)
    table.add_row("replay", replay_note)
    for label, text in _model_rows(data):
        table.add_row(label, text)
    v = stored_verdict(data)
    table.add_row("verdict", f"{v['label']} ({v['reason']})")
    for warning in v.get("warnings") or []:
        table.add_row("warning", warning)
    console.print(table)
    if exports is not None:  # plain lines: paths are never truncated
        for line in exports.lines(run_dir):
            typer.echo(f"Export {line}")
    # plain lines, never truncated by the table layout
    typer.echo(f"Report: {report_path}")
    typer.echo(f"Run folder: {run_dir}")


def _model_rows(data: dict[str, Any]) -> list[tuple[str, str]]:
    """The summary's rows on the identified model (a simulated log's identification: its
    files) and its MJCF's rollout check (or why it did not run), from ``result.json``."""
    from ident.identify.assessment.rollout import rollout_text
    from ident.identify.refinement.rollout_refinement import refinement_text

    rows = [] if data.get("model") is None else [("identified model", _model_text(data["model"]))]
    rows.append(("MJCF rollout", rollout_text(data.get("rollout"))))
    refined = refinement_text(data.get("refinement"))  # None: not asked for
    return rows if refined is None else [*rows, ("MJCF refinement", refined)]


def _stage_rows(table: Any, stage: Any) -> None:
    """The summary's rows of the stage: its base parameters (body frames) and their counts in
    the paper's DH frames."""
    indep, dep, unid = stage.counts
    table.add_row(
        "base parameters",
        f"{len(stage.base_names)} ({indep}/{dep}/{unid} independent/combined/unidentifiable, "
        "body frames)",
    )
    if stage.dh_frames is not None:
        i, d, u = stage.dh_frames.counts
        paper = {"wrist": "15/7/8", "arm": "20/2/8"}.get(stage.name)
        table.add_row(
            "paper's DH frames",
            f"{i}/{d}/{u}" + (f" (paper: {paper})" if paper else ""),
        )


def _elite_rows(table: Any, result: Any) -> None:
    """The summary's rows of the chosen elite (elite 1, marked unsafe, when none was chosen):
    its fitness, its safety and each estimator's errors against the true parameters."""
    from ident.identify.estimation.uncertainty import parameter_std
    from ident.report.run_report import error_measures

    stage = result.stage
    plan = result.executable
    chosen = result.executed_rank or 1
    best = result.elites[chosen - 1]
    table.add_row(
        "chosen elite" if plan is not None and plan.usable else "elite 1 (UNSAFE)",
        f"{chosen}: fitness {best.fitness:.6g}, "
        f"cond (scaled) {best.details.get('cond', float('nan')):.4g}",
    )
    if plan is not None:
        table.add_row("safety", plan.message)
    unc = getattr(getattr(best.log, "result", None), "uncertainty", None)
    for method, est in best.estimates.items():
        sd = parameter_std(est, unc)  # the one σ the report shows
        m = error_measures(
            est.x,
            sd.std,
            stage.true_base,
            best.base_column_norms,
            best.true_torque_norm,
            stage.reference_share,
        )
        major = m.get("max_rel_error_major")
        table.add_row(
            method.upper(),
            ("" if major is None else f"worst error {100 * major:.3g} % (major parameters), ")
            + f"{100 * m['max_rel_error']:.3g} % (torque share >= 1e-4), "
            + f"{100 * m['within_3std']:.0f} % within 3 std ({sd.method}), "
            + f"cond {est.condition_number:.4g}",
        )
    for method, message in best.failures.items():
        table.add_row(method.upper(), f"[red]{message}[/red]")


def _model_text(model: dict[str, Any]) -> str:
    """The identified model's files and reload parity (``model`` of ``result.json``)."""
    if not (model["written"] and model["reload_parity"]):
        return str(model["note"])
    parity = max(model["reload_parity"][k] for k in ("urdf", "mjcf"))
    return (
        f"{model['files']['urdf']}, {model['files']['mjcf']} ({model['method']}, reload "
        f"parity {parity:.1e})"
    )
