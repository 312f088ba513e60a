"""``ident logs inspect FILE``: what a log holds, and a config skeleton to start from.

Lists the tables (files, ROS topics) with their columns, value ranges, sampling rate, jitter,
gaps and time anomalies (NaN/inf stamps, duplicates, backwards jumps: count and first place),
then prints a ``log:`` section that names the columns that look like positions,
velocities and torques. Reads through the same reader registry as ``ident identify``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from ident.cli._common import user_errors

if TYPE_CHECKING:  # the readers load lazily: ident logs --help stays fast
    from ident.measure.readers import LogTable

__all__ = ["inspect", "register", "skeleton"]

logs_app = typer.Typer(no_args_is_help=True, help="Look into robot logs before identifying.")

# Column-name patterns of each signal, tried in order (case-insensitive). A name part is
# delimited by anything but a letter: ``q3``, ``q[0]``, ``joint/pos``, ``i_2 (A)``.
_WORD = r"(^|[^a-z])({})([^a-z]|$)"
_PATTERNS = {
    "position": _WORD.format("q|pos|position|angle|joint_pos"),
    "velocity": _WORD.format("dq|qd|vel|velocity|speed"),
    "torque": _WORD.format("tau|torque|effort|trq|cur|current|curr|amp|i|ia|ma"),
}
_CURRENT = re.compile(_WORD.format("cur|current|curr|amp|amps|i|ia|ma"))
_TIME = re.compile(_WORD.format("t|time|stamp|timestamp|sec|secs|seconds"))
_TOPIC_FORMATS = ("rosbag", "mcap", "lerobot")  # the readers that honour --topic
_TOPIC_HELP = "ROS topic, or LeRobot dataset feature, to read (repeatable; default all)."
# unit hints in a name, e.g. ``pos_deg``, ``q[0] (rad)``, ``time[ms]``, ``cur_mA``
_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_UNIT_HINTS = {
    "position": (("deg", "deg"), ("degree", "deg"), ("mrad", "mrad"), ("rad", "rad"), ("mm", "mm")),
    "velocity": (("deg/s", "deg/s"), ("degs", "deg/s"), ("rpm", "rpm"), ("rad/s", "rad/s")),
    "torque": (("nm", "N*m"), ("n*m", "N*m"), ("ma", "mA"), ("a", "A")),
    "time": (("ms", "ms"), ("us", "us"), ("ns", "ns"), ("s", "s")),
}


def register(app: typer.Typer) -> None:
    """Add ``logs`` (with ``inspect``) to the ``ident`` command line."""
    app.add_typer(logs_app, name="logs")


def _classify(name: str) -> str | None:
    lower = name.lower()
    if re.search(r"(cmd|command|des|ref|target)", lower):
        return None  # commanded values are not measurements
    if re.search(r"(tcp|tool|cartesian|pose|robot_|main_|scaling|temperature|voltage)", lower):
        return None  # not per joint (a robot controller's TCP, supply, scaling channels)
    for kind, pattern in _PATTERNS.items():
        if re.search(pattern, lower):
            return kind
    return None


def _unit_hint(name: str, kind: str) -> str | None:
    """The unit a column name states (as a name part: ``_deg``, ``[ms]``, ``(A)``), if any."""
    lower = name.lower()  # parts split at "/" too (``pos_deg/j1``), and kept whole (``deg/s``)
    parts = set(re.split(r"[^a-z*]+", lower)) | set(re.split(r"[^a-z/*]+", lower))
    return next((unit for hint, unit in _UNIT_HINTS[kind] if hint in parts), None)


def _time_candidate(table: LogTable) -> tuple[str, str] | None:
    """A column named like time that mostly increases (its anomalies are reported), and its
    unit, when the reader found none."""
    if table.time is not None:
        return table.time, _unit_hint(table.time, "time") or "s"
    for name, values in table.columns.items():
        if _TIME.search(name.lower()) and values.size > 1:
            with np.errstate(invalid="ignore"):
                forward = np.count_nonzero(np.diff(values) > 0)
            if forward > 0.5 * (values.size - 1):
                return name, _unit_hint(name, "time") or "s"
    return None


def _position_unit(name: str, values: np.ndarray) -> tuple[str, str]:
    """Unit of a position column: from its name, else from its range (beyond 2 pi: degrees?)."""
    hint = _unit_hint(name, "position")
    if hint is not None:
        return hint, "from the column name"
    if np.max(np.abs(values)) > 2.0 * np.pi:
        return "deg", "values beyond 2 pi: degrees? or motor side, or ticks"
    return "rad", "check"


def skeleton(tables: list, path: Path, fmt: str | None) -> str:
    """A ``log:`` YAML section naming the columns that look like each signal, with the
    units their names (or ranges) suggest; currents get a ``transmission`` to fill in."""
    found: dict[str, list[str]] = {"position": [], "velocity": [], "torque": []}
    values: dict[str, np.ndarray] = {}
    time = None
    for table in tables:
        candidate = _time_candidate(table)
        if time is None and candidate is not None:
            time = candidate
        for name, column in table.columns.items():
            kind = _classify(name) if candidate is None or name != candidate[0] else None
            if kind is not None:
                found[kind].append(name)
                values[name] = column
    lines = ["log:", f"  path: {path}"]
    if fmt is not None:
        lines.append(f"  format: {fmt}")
    if time is not None:
        lines.append(f"  time: {{column: {_yaml(time[0])}, unit: {time[1]}}}   # s|ms|us|ns")
    else:
        lines.append("  sampling_rate_hz: 1000.0   # no time column found: set the rate")
    currents = False
    for kind in ("position", "velocity", "torque"):
        cols = found[kind]
        if not cols and kind == "velocity":
            continue
        listed = "[" + ", ".join(_yaml(c) for c in cols) + "]" if cols else "[...]"
        side = ""
        if kind == "position" and cols:
            unit, why = _position_unit(cols[0], np.concatenate([values[c] for c in cols]))
        elif kind == "torque" and cols and all(_CURRENT.search(c.lower()) for c in cols):
            currents, side = True, ", side: motor"
            unit = "mA" if _unit_hint(cols[0], "torque") == "mA" else "A"
            why = "motor currents?"
        else:
            default = {"position": "rad", "velocity": "rad/s", "torque": "N*m"}[kind]
            unit = (_unit_hint(cols[0], kind) if cols else None) or default
            why = "check"
        lines.append(
            f"  {kind}: {{columns: {listed}, unit: {unit}{side}}}"
            f"   # one per joint, in order; unit: {why}"
        )
    lines.append("  side: joint   # positions on the joint side? else motor (transmission)")
    if currents:
        lines += [
            "transmission:   # currents: tau = N k i (motor side), or tau = k i (side: joint)",
            "  gear_ratios: [...]          # one per joint, q_motor = N q_joint",
            "  torque_constants: [...]     # N*m/A of each motor (or at the joint)",
        ]
    return "\n".join(lines)


def _yaml(name: str) -> str:
    """Quote a column name unless YAML reads it back as the same string inside a flow
    sequence (``[q1, q2]``; ``q[0]`` and ``a: b`` need quotes there)."""
    import yaml

    try:
        plain = yaml.safe_load(f"[{name}]") == [name]
    except yaml.YAMLError:
        plain = False
    return name if plain else "'" + name.replace("'", "''") + "'"


def inspect(
    file: Annotated[Path, typer.Argument(help="Log file or ROS 2 bag folder.")],
    format: Annotated[
        str | None, typer.Option("--format", help="Reader name (default: detected).")
    ] = None,
    topic: Annotated[list[str] | None, typer.Option(help=_TOPIC_HELP)] = None,
    max_columns: Annotated[int, typer.Option(min=1, help="Columns listed per table.")] = 60,
) -> None:
    """List the columns/topics of FILE with rates, jitter, gaps and ranges; print a config
    skeleton."""
    from ident.inputs import check_job
    from ident.measure import timebase
    from ident.measure.readers import detect_format, estimate_read, read_tables

    with user_errors():
        fmt = format or detect_format(file)
        _check_topic_flag(topic, fmt, file)
        estimate = estimate_read(file, fmt, topics=topic)
        if estimate is not None:  # from the file's size and headers, before reading it
            check_job(estimate)
            if estimate.seconds > 60.0 or estimate.memory_bytes > 2e9:
                typer.echo(f"estimate: {estimate.describe()}", err=True)
        tables = read_tables(file, fmt, topics=topic)
        typer.echo(f"{file}: format {fmt}, {len(tables)} table(s)")
        for table in tables:
            typer.echo(f"\n{table.source}: {table.n_samples} samples, {len(table.columns)} columns")
            time = _time_candidate(table)
            if table.time is not None and time is None:
                typer.echo(f"  time '{table.time}': not strictly increasing")
            elif time is not None:
                name, unit = time
                t = table.columns[name] * _TIME_SCALE[unit]
                summary = timebase.summarize_time(t)
                typer.echo(f"  time '{name}' [{unit}]: {summary.text(table.line_numbers)}")
                if summary.anomalies.any:
                    typer.echo(
                        "  time rule when identifying: NaN/inf stamps refused, duplicates "
                        "dropped, backwards jumps split into segments (docs/logs.md)"
                    )
            else:
                typer.echo("  no time column: give log.sampling_rate_hz (or log.time.column)")
            for warning in table.warnings:
                typer.echo(f"  warning: {warning}")
            for k, (name, values) in enumerate(table.columns.items()):
                if k == max_columns:
                    typer.echo(f"  ... {len(table.columns) - max_columns} more")
                    break
                kind = "time" if time is not None and name == time[0] else _classify(name)
                if kind == "torque" and _CURRENT.search(name.lower()):
                    kind = "current"
                typer.echo(
                    f"  {name:<40s} min {np.min(values):<12.6g} max {np.max(values):<12.6g}"
                    + (f" ({kind}?)" if kind else "")
                )
        typer.echo("\nconfig skeleton (check every line):\n")
        typer.echo(skeleton(tables, file, format))


def _check_topic_flag(topic: list[str] | None, fmt: str, file: Path) -> None:
    """Refuse ``--topic`` on a log that has no topics (rather than ignore it)."""
    from ident.errors import ConfigError

    if topic and fmt not in _TOPIC_FORMATS:
        raise ConfigError(
            f"--topic {topic[0]}: {file} is a {fmt} log, which has no topics (--topic selects "
            "the topics of a ROS 2 bag or MCAP file, the features of a LeRobot dataset); "
            "remove --topic."
        )


logs_app.command("inspect")(inspect)
