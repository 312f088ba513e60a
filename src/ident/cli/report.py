"""``ident report RUN_DIR``: rewrite the report of a run folder from its saved data.

- an ``ident run`` folder (``result.json`` format ``ident-run/1``): ``figures/*.png``,
  ``report.md`` and ``report.html`` from ``result.json`` and the CSV files, and
  ``replay.html`` when it is missing;
- an ``ident identify`` folder: ``report.html`` from ``report.md`` and ``figures/*.png``
  (the identification itself is not repeated; run ``ident identify`` again for that).

Anything else (a bench folder, a file, a folder without ``run.json``) is a user error: exit 2
with one ``error:`` line, before anything is written. A failure or Ctrl-C / SIGTERM while the
report is written marks the folder incomplete (``missing: report`` in ``run.json``); the next
successful ``ident report`` marks it complete again.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["register", "report"]


def register(app: typer.Typer) -> None:
    """Add ``report`` to the ``ident`` command line."""
    app.command("report")(report)


def report(
    run_dir: Annotated[
        Path, typer.Argument(help="A run folder written by 'ident run' or 'ident identify'.")
    ],
) -> None:
    """Rewrite the report of RUN_DIR from its saved data.

    A run of 'ident run': report.md, report.html and the figures (and the replay if missing).
    A run of 'ident identify': report.html from report.md (its figures are written once, when
    the identification runs, from arrays that are not kept).
    """
    from ident.errors import IdentError
    from ident.run.rundir import read_status, rewriting, unfinished_note

    with user_errors():
        if not run_dir.is_dir():
            raise IdentError(
                f"{run_dir}: not a folder; give a run folder of 'ident run' or 'ident identify'."
            )
        # a clear message for a folder that is not a run; a word for one that did not finish
        note = unfinished_note(run_dir, read_status(run_dir))
        if note is not None:
            typer.echo(f"warning: {note}", err=True)
        kind = _kind(run_dir)  # every input read and checked before anything is written
        # an error or interruption while writing marks the folder incomplete (missing: the
        # report); a later success where the report was all that was missing completes it
        if kind == "run":
            from ident.report.run_data import load_run

            data = load_run(run_dir)
            with rewriting(run_dir, "report"):
                _rewrite_run_report(run_dir)
            from ident.report.run_verdict import stored_verdict

            _echo_verdict(stored_verdict(data))
        else:
            data, markdown = _identify_inputs(run_dir)
            with rewriting(run_dir, "report"):
                _rewrite_identify_report(run_dir, data, markdown)
            if isinstance(data.get("verdict"), dict):  # older folders have none
                _echo_verdict(data["verdict"])


def _rewrite_run_report(run_dir: Path) -> None:
    """report.md, report.html and the figures of an 'ident run' folder (the replay if missing)."""
    from ident.report.run_report import write_replay, write_report

    if not (run_dir / "replay.html").is_file():
        typer.echo(write_replay(run_dir), err=True)
    typer.echo(str(write_report(run_dir)))


def _identify_inputs(run_dir: Path) -> tuple[dict, str]:
    """``result.json`` and ``report.md`` of an 'ident identify' folder (read before writing)."""
    from ident.errors import IdentError

    path = run_dir / "report.md"
    try:
        markdown = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise IdentError(f"{path}: unreadable ({e}); run 'ident identify' again.") from e
    data = json.loads((run_dir / "result.json").read_text(encoding="utf-8"))
    return data, markdown


def _rewrite_identify_report(run_dir: Path, data: dict, markdown: str) -> None:
    """report.html of an 'ident identify' folder from its report.md."""
    from ident.fileio import atomic_write_text
    from ident.report.html import markdown_to_html

    title = f"ident identify: {data.get('name')}"
    page = markdown_to_html(markdown, title=title, base_dir=run_dir)
    typer.echo(str(atomic_write_text(run_dir / "report.html", page)))


def _echo_verdict(entry: dict) -> None:
    """The run's verdict as result.json stores it (stderr: stdout names the report)."""
    typer.echo(f"verdict: {entry.get('label')} ({entry.get('reason')})", err=True)


def _kind(run_dir: Path) -> str:
    """``run`` or ``identify``; IdentError for any other folder."""
    from ident.errors import IdentError
    from ident.report.run_data import FORMAT

    path = run_dir / "result.json"
    if not path.is_file():
        raise IdentError(
            f"{run_dir}: no result.json; not a finished run of 'ident run' or 'ident identify' "
            "(a bench folder's report is written by 'ident bench')."
        )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise IdentError(f"{path}: not valid JSON ({e}); the run folder is damaged.") from e
    if isinstance(data, dict) and data.get("format") == FORMAT:
        return "run"
    if isinstance(data, dict) and "base_parameters" in data and (run_dir / "report.md").is_file():
        return "identify"
    raise IdentError(
        f"{path}: neither an 'ident run' result (format {FORMAT}) nor an 'ident identify' "
        "result with its report.md; a bench folder's report is written by 'ident bench'."
    )
