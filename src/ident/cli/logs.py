"""``ident logs inspect FILE``: what a log holds, and a config skeleton to start from.

Lists the tables (files, ROS topics) with their columns, value ranges, sampling rate, jitter
and gaps, then prints a ``log:`` section that names the columns that look like positions,
velocities and torques. Reads through the same reader registry as ``ident identify``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ident.cli._common import user_errors

__all__ = ["inspect", "register", "skeleton"]

logs_app = typer.Typer(no_args_is_help=True, help="Look into robot logs before identifying.")

# Column-name patterns of each signal, tried in order (case-insensitive).
_PATTERNS = {
    "position": (r"(^|[/_.])(q|pos|position|angle|joint_pos)([/_.]|\d|$)",),
    "velocity": (r"(^|[/_.])(dq|qd|vel|velocity|speed)([/_.]|\d|$)",),
    "torque": (r"(^|[/_.])(tau|torque|effort|cur|current|trq|i)([/_.]|\d|$)",),
}


def register(app: typer.Typer) -> None:
    """Add ``logs`` (with ``inspect``) to the ``ident`` command line."""
    app.add_typer(logs_app, name="logs")


def _classify(name: str) -> str | None:
    lower = name.lower()
    if re.search(r"(cmd|command|des|ref|target)", lower):
        return None  # commanded values are not measurements
    for kind, patterns in _PATTERNS.items():
        if any(re.search(p, lower) for p in patterns):
            return kind
    return None


def skeleton(tables: list, path: Path, fmt: str | None) -> str:
    """A ``log:`` YAML section naming the columns that look like each signal."""
    found: dict[str, list[str]] = {"position": [], "velocity": [], "torque": []}
    time_note = None
    for table in tables:
        if time_note is None and table.time is not None:
            time_note = table.time
        for name in table.columns:
            kind = _classify(name) if name != table.time else None
            if kind is not None:
                found[kind].append(name)
    lines = ["log:", f"  path: {path}"]
    if fmt is not None:
        lines.append(f"  format: {fmt}")
    if time_note is not None:
        lines.append(f"  time: {{column: {_yaml(time_note)}}}   # seconds; unit: ms|us|ns")
    else:
        lines.append("  sampling_rate_hz: 1000.0   # no time column found: set the rate")
    for kind, unit in (("position", "rad"), ("velocity", "rad/s"), ("torque", "N*m")):
        cols = found[kind]
        if not cols and kind == "velocity":
            continue
        listed = "[" + ", ".join(_yaml(c) for c in cols) + "]" if cols else "[...]"
        lines.append(f"  {kind}: {{columns: {listed}, unit: {unit}}}   # one per joint, in order")
    lines.append("  side: joint   # or motor (then set transmission.gear_ratios)")
    return "\n".join(lines)


def _yaml(name: str) -> str:
    """Quote a column name when YAML would not read it back as the same string."""
    import yaml

    return name if yaml.safe_load(name) == name and ":" not in name else repr(name)


def inspect(
    file: Annotated[Path, typer.Argument(help="Log file or ROS 2 bag folder.")],
    format: Annotated[
        str | None, typer.Option("--format", help="Reader name (default: detected).")
    ] = None,
    topic: Annotated[
        list[str] | None, typer.Option(help="ROS topic to read (repeatable; default all).")
    ] = None,
    max_columns: Annotated[int, typer.Option(help="Columns listed per table.")] = 60,
) -> None:
    """List the columns/topics of FILE with rates, jitter, gaps and ranges; print a config
    skeleton."""
    from ident.measure import timebase
    from ident.measure.readers import detect_format, read_tables

    with user_errors():
        fmt = format or detect_format(file)
        tables = read_tables(file, fmt, topics=topic)
        typer.echo(f"{file}: format {fmt}, {len(tables)} table(s)")
        for table in tables:
            typer.echo(f"\n{table.source}: {table.n_samples} samples, {len(table.columns)} columns")
            if table.time is not None:
                t = table.columns[table.time]
                if np.all(np.diff(t) > 0):
                    typer.echo(f"  time '{table.time}': {timebase.summarize_time(t).text()}")
                else:
                    typer.echo(f"  time '{table.time}': not strictly increasing")
            else:
                typer.echo("  no time column: give log.sampling_rate_hz (or log.time.column)")
            for k, (name, values) in enumerate(table.columns.items()):
                if k == max_columns:
                    typer.echo(f"  ... {len(table.columns) - max_columns} more")
                    break
                kind = _classify(name) if name != table.time else "time"
                typer.echo(
                    f"  {name:<40s} min {np.min(values):<12.6g} max {np.max(values):<12.6g}"
                    + (f" ({kind}?)" if kind else "")
                )
        typer.echo("\nconfig skeleton (check every line):\n")
        typer.echo(skeleton(tables, file, format))


logs_app.command("inspect")(inspect)
