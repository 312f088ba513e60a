"""A log's signal columns gathered from its tables and put on one uniform time grid.

The table side of :mod:`ident.measure.logs`: the columns of every signal found in the tables the
readers return (:mod:`ident.measure.readers`), signals of several sources joined on time (cubic
spline onto the position stamps), the stamps cleaned by the one rule for stamps, the log cut at
its gaps and windows and resampled onto a uniform grid where its stamps are not
(:mod:`ident.measure.timebase`). Nothing here converts units: :mod:`ident.measure.logs` does.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError, DataError
from ident.measure import timebase
from ident.measure.log_config import LogConfig, SignalFile
from ident.measure.readers import LogTable, read_tables

__all__ = [
    "Stamps",
    "expand_groups",
    "join_segments",
    "join_signals",
    "joint_order",
    "select_columns",
    "signal_tables",
    "uniform_grid",
]

FloatArray = npt.NDArray[np.float64]


_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def select_columns(
    table: LogTable, columns: list[str] | None, n_expected: int | None, what: str
) -> tuple[FloatArray, list[str]]:
    """Columns of one table, in order; None takes every column but the time column."""
    if columns is None:
        names = [c for c in table.columns if c != table.time]
        if n_expected is not None and len(names) != n_expected:
            raise DataError(
                f"{table.source}: {what} file has {len(names)} columns ({', '.join(names)}), "
                f"expected {n_expected} (one per joint); list the columns to use in the config."
            )
    else:
        names = list(columns)
        for c in names:
            if c not in table.columns:
                raise DataError(
                    f"{table.source}: column '{c}' not found; the header has "
                    f"{', '.join(table.columns)}."
                )
    data = _block([table.columns[c] for c in names])
    if data is None:
        data = np.column_stack([table.columns[c] for c in names])
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        where = (
            f"line {table.line_numbers[row]}" if table.line_numbers is not None else f"sample {row}"
        )
        raise DataError(
            f"{table.source}: column '{names[col]}' has {int(bad[:, col].sum())} NaN/inf "
            f"value(s), the first on {where}; clean or trim the log."
        )
    return data, names


def _block(columns: list[FloatArray]) -> FloatArray | None:
    """The (n_samples, k) array whose columns are ``columns``, as a view, when they are
    evenly spaced columns of one float64 block (a reader's 2-D array: a numpy archive's
    ``q``, a ROS topic's values); None otherwise (the caller copies them). A long log's
    signals are then not copied once more."""
    first = columns[0]
    base = first.base
    if (
        base is None
        or first.dtype != np.float64
        or any(c.base is not base or c.strides != first.strides for c in columns)
        or any(c.shape != first.shape or c.dtype != np.float64 for c in columns)
    ):
        return None
    address = [c.__array_interface__["data"][0] for c in columns]
    spacing = address[1] - address[0] if len(columns) > 1 else 8
    steps = np.diff(address)
    if spacing <= 0 or np.any(steps != spacing):
        return None
    view = np.lib.stride_tricks.as_strided(
        first, shape=(first.shape[0], len(columns)), strides=(first.strides[0], spacing)
    )
    return view if np.shares_memory(view, base) else None


def _find(tables: list[LogTable], name: str) -> LogTable:
    for table in tables:
        if name in table.columns:
            return table
    available = [c for t in tables for c in t.columns]
    raise DataError(_missing_message(name, available, tables))


def _missing_message(name: str, available: list[str], tables: list[LogTable]) -> str:
    close = difflib.get_close_matches(name, available, n=3)
    hint = f" (closest: {', '.join(close)})" if close else ""
    files = ", ".join(sorted({t.source for t in tables}))
    shown = ", ".join(available[:40]) + (" ..." if len(available) > 40 else "")
    return (
        f"{files}: column '{name}' not found{hint}; the log has {shown} "
        "(`ident logs inspect FILE` lists them)."
    )


def _group(name: str, tables: list[LogTable]) -> list[str]:
    """The columns ``<name>/<x>`` of the first table that has them when ``name`` is no
    column itself (a LeRobot feature, a ROS topic's field), else ``[]``."""
    for table in tables:
        if name in table.columns:
            return []
    for table in tables:
        found = [c for c in table.columns if c.startswith(name + "/")]
        if found:
            return found
    return []


def expand_groups(
    signal: SignalFile,
    tables: list[LogTable],
    joint_names: tuple[str, ...],
    what: str,
    source: str = "config",
) -> list[str] | None:
    """``signal.columns`` with every group name replaced by its columns but the ``exclude``
    ones; a group's columns must then name the model's joints, one each (DataError naming
    the group, the names without a joint, the joints without a column and the fix)."""
    if signal.columns is None:
        return None
    out: list[str] = []
    unused = list(signal.exclude)
    for name in signal.columns:
        members = _group(name, tables)
        if not members:
            out.append(name)  # a column (or a missing one: named when it is looked up)
            continue
        kept = [c for c in members if c.split("/")[-1] not in signal.exclude]
        unused = [x for x in unused if not any(c.split("/")[-1] == x for c in members)]
        if joint_order(kept, joint_names) is None:
            raise DataError(_group_mismatch(name, kept, joint_names, tables, what))
        out += kept
    found = all(any(c in t.columns for t in tables) for c in out)
    if unused and found:
        raise ConfigError(
            f"{source}: log.{what}.exclude names {', '.join(unused)}, which no group of "
            f"log.{what}.columns holds; remove it or fix the name."
        )
    return out


def _group_mismatch(
    name: str, kept: list[str], joint_names: tuple[str, ...], tables: list[LogTable], what: str
) -> str:
    """The message of a group whose names are not the model's joints."""
    source = next(t.source for t in tables if any(c.startswith(name + "/") for c in t.columns))
    names = [c[len(name) + 1 :] for c in kept]

    def names_joint(column: str, joint: str) -> bool:
        return joint_order([column], (joint,)) is not None

    extra = [
        n
        for c, n in zip(kept, names, strict=True)
        if not any(names_joint(c, j) for j in joint_names)
    ]
    missing = [j for j in joint_names if not any(names_joint(c, j) for c in kept)]
    return (
        f"{source}: log.{what}.columns: '{name}' names {', '.join(names) or 'nothing'}, the "
        f"URDF's joints are {', '.join(joint_names)}"
        + (f"; not in the URDF: {', '.join(extra)}" if extra else "")
        + (f"; no column for: {', '.join(missing)}" if missing else "")
        + f"; leave a column out with log.{what}.exclude: [name], or list the columns one "
        "per joint in joint order."
    )


class _Sources:
    """The tables of every file a log config names, read once.

    Readers are told the columns the config names (reader option ``columns``, when every
    signal names its columns), so that a ROS log keeps only those of its topics; a column not
    found is looked up again in the files read whole, so the message lists every column.
    """

    def __init__(self, cfg: LogConfig, *, whole: bool = False) -> None:
        self.cfg = cfg
        signals = [
            s for s in (cfg.position, cfg.torque, cfg.velocity, cfg.command) if s is not None
        ]
        wanted: list[str] | None = None
        if not whole and all(s.columns is not None for s in signals):
            wanted = [c for s in signals for c in s.columns or []]
            if cfg.time is not None:
                wanted.append(cfg.time.column)
        self.by_path: dict[Path, list[LogTable]] = {}
        for f in cfg.sources():
            options = f.model_dump(exclude={"path", "format"})
            if options.get("time_column") is None and cfg.time is not None:
                options["time_column"] = cfg.time.column
            options["columns"] = wanted
            self.by_path[Path(f.path)] = read_tables(f.path, f.format, **options)
        self.all = [t for tables in self.by_path.values() for t in tables]
        self.whole = wanted is None

    def _find(self, tables: list[LogTable], name: str) -> LogTable:
        """:func:`_find`, with the message of the files read whole when ``name`` is missing."""
        try:
            return _find(tables, name)
        except DataError:
            if self.whole:
                raise
            whole = _Sources(self.cfg, whole=True)
            _find(whole.all, name)  # raises, listing every column
            raise

    def signal(
        self,
        signal: SignalFile,
        n_joints: int,
        what: str,
        joint_names: tuple[str, ...],
        source: str = "config",
    ) -> tuple[FloatArray, LogTable]:
        if signal.path is not None:
            tables = self.by_path[Path(signal.path)]
        elif signal.columns is None:
            raise ConfigError(
                f"log.{what}.columns is missing: name the {n_joints} {what} columns "
                f"(`ident logs inspect FILE` lists them), or give log.{what}.path."
            )
        else:
            tables = self.all
        columns = expand_groups(signal, tables, joint_names, what, source)
        if columns is None:
            table = tables[0]
        else:
            owners = [self._find(tables, c) for c in columns]
            table = owners[0]
            if any(o is not table for o in owners):
                table = _side_by_side(owners, columns, what)
        data, names = select_columns(table, columns, n_joints, what)
        if data.shape[1] != n_joints:  # the config's list is wrong, not the file
            raise ConfigError(
                f"{source}: log.{what}.columns lists {data.shape[1]} columns "
                f"({', '.join(names)}), the robot has {n_joints} joints "
                f"({', '.join(joint_names)}); list one {what} column per joint, in joint order."
            )
        order = joint_order(names, joint_names)
        if order is not None and order != list(range(n_joints)):
            data = data[:, order]  # columns named after the joints: matched by name
        return data, table


def joint_order(names: list[str], joint_names: tuple[str, ...]) -> list[int] | None:
    """Column of each joint when the column names name the model's joints, else None.

    A column names joint ``j`` when it is ``j`` or ends with ``j`` after a separator
    (``q_shoulder``, ``position/shoulder``, ``tau.shoulder``); the longest joint name wins.
    None unless every joint is named by exactly one column (then the config's order is
    kept: columns in joint order).
    """
    owner: dict[str, int] = {}
    for k, name in enumerate(names):
        found = [
            j
            for j in joint_names
            if name == j or (name.endswith(j) and name[-len(j) - 1] in "_/.:-")
        ]
        if not found:
            return None
        joint = max(found, key=len)
        if joint in owner:
            return None
        owner[joint] = k
    if len(owner) != len(joint_names):
        return None
    return [owner[j] for j in joint_names]


def _side_by_side(owners: list[LogTable], columns: list[str], what: str) -> LogTable:
    """One table of columns that come from several files sampled together (one value per
    line per file): equal lengths, and equal time columns when they have any."""
    first = owners[0]
    for table in owners[1:]:
        same_time = (table.time is None and first.time is None) or (
            table.time is not None
            and first.time is not None
            and np.array_equal(table.columns[table.time], first.columns[first.time])
        )
        if table.n_samples != first.n_samples or not same_time:
            raise DataError(
                f"{what} columns come from {first.source} ({first.n_samples} samples) and "
                f"{table.source} ({table.n_samples} samples) with different time stamps; "
                "columns of one signal must be sampled together."
            )
    cols = {c: o.columns[c] for c, o in zip(columns, owners, strict=True)}
    if first.time is not None:
        cols[first.time] = first.columns[first.time]
    return LogTable(
        columns=cols,
        time=first.time,
        source=", ".join(dict.fromkeys(o.source for o in owners)),
    )


def _time_of(table: LogTable, cfg: LogConfig) -> FloatArray | None:
    if cfg.time is not None and cfg.time.column in table.columns:
        return table.columns[cfg.time.column] * _TIME_SCALE[cfg.time.unit]
    if table.time is not None and cfg.sampling_rate_hz is None:
        return table.columns[table.time]
    return None


def _time_name(table: LogTable, cfg: LogConfig) -> str:
    """``file: time column 'x'`` for messages."""
    name = cfg.time.column if cfg.time is not None else table.time
    return f"{table.source}: time column '{name}'"


def join_signals(
    parts: list[tuple[FloatArray, LogTable]],
    cfg: LogConfig,
    t_ref: FloatArray | None,
    rows: npt.NDArray[np.int64] | None,
) -> tuple[list[FloatArray], npt.NDArray[np.bool_] | None, str, list[str]]:
    """Bring every signal onto the samples of the first (positions): same table or equal
    length without time -> as is; else cubic-spline interpolation onto its time stamps.

    ``t_ref``: the position stamps as logged [s] of the rows ``rows`` the time rule keeps
    (:func:`ident.measure.timebase.clean_time`); None without time. Another source joined on
    time has its duplicated stamps dropped (warned) and must otherwise increase.

    Returns the signals on the kept rows, the mask of those rows where every source has data
    (None: all), a note for the records and the warnings.
    """
    ref_data, ref_table = parts[0]
    t_ref_raw = _time_of(ref_table, cfg)
    out = [ref_data if rows is None else ref_data[rows]]
    n = out[0].shape[0]
    notes: list[str] = []
    warnings: list[str] = []
    keep = np.ones(n, dtype=bool)
    for data, table in parts[1:]:
        if table is ref_table:
            out.append(data if rows is None else data[rows])
            continue
        t_other = _time_of(table, cfg)
        same = t_ref_raw is not None and t_other is not None and np.array_equal(t_ref_raw, t_other)
        if t_ref is None or t_other is None or same:
            if data.shape[0] != ref_data.shape[0]:
                raise DataError(
                    f"{ref_table.source} has {ref_data.shape[0]} samples but {table.source} has "
                    f"{data.shape[0]}; the signals must be sampled together (or give both a "
                    "time column to join them on)."
                )
            out.append(data if rows is None else data[rows])
            continue
        values, inside = _on_time(data, table, cfg, t_other, t_ref, warnings)
        keep &= inside
        out.append(values)
        notes.append(f"{table.source} joined on time (cubic spline onto the position stamps)")
    if not keep.all():
        if not keep.any():
            raise DataError(
                f"{ref_table.source}: the log files do not overlap in time; check the time columns."
            )
        out = [d[keep] for d in out]
        notes.append(f"kept the {int(keep.sum())} position samples where every source has data")
        return out, keep, "; ".join(notes), warnings
    return out, None, "; ".join(notes), warnings


def _on_time(
    data: FloatArray,
    table: LogTable,
    cfg: LogConfig,
    t_other: FloatArray,
    t_ref: FloatArray,
    warnings: list[str],
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """``data`` (stamped ``t_other`` [s]) by cubic spline at the position stamps ``t_ref`` [s],
    and the mask of the stamps inside its time span; appends the time cleaning's warnings."""
    from scipy.interpolate import make_interp_spline

    what = _time_name(table, cfg)
    found = timebase.find_anomalies(t_other)
    if found.n_backwards and not found.n_nonfinite:
        assert found.first_backwards is not None
        raise DataError(
            f"{what}: time goes back {found.n_backwards} time(s), the first at "
            f"{timebase.place(found.first_backwards, table.line_numbers)}; a file joined "
            "on time needs increasing stamps: split it into several logs (log.more) or "
            "fix its clock."
        )
    cleaned = timebase.clean_time(t_other, what, table.line_numbers)
    t_sorted = cleaned.t
    warnings += cleaned.warnings
    if t_sorted.size < 4:
        raise DataError(f"{what}: {t_sorted.size} distinct stamps, at least 4 to join on.")
    spline = make_interp_spline(t_sorted, data[cleaned.index], k=3, axis=0)
    return spline(t_ref), (t_ref >= t_sorted[0]) & (t_ref <= t_sorted[-1])


def signal_tables(
    cfg: LogConfig, joint_names: tuple[str, ...], source: str = "config"
) -> list[tuple[FloatArray, LogTable]]:
    """Position, torque (and velocity, and commanded position) columns with their tables (the
    torque NaN on the positions' table when the log has none, ``log.torque`` absent); the
    first part carries the table of the time column (``log.time.path``) when the time is in
    a file of its own."""
    n_joints = len(joint_names)
    sources = _Sources(cfg)
    parts = [
        sources.signal(cfg.position, n_joints, "position", joint_names, source),
    ]
    if cfg.torque is not None:
        parts.append(sources.signal(cfg.torque, n_joints, "torque", joint_names, source))
    else:  # no torque logged (a position servo's log): NaN, on the positions' own samples
        parts.append((np.full(parts[0][0].shape, np.nan), parts[0][1]))
    if cfg.velocity is not None:
        parts.append(sources.signal(cfg.velocity, n_joints, "velocity", joint_names, source))
    command = cfg.command_signal()
    if command is not None:
        parts.append(sources.signal(command, n_joints, "command", joint_names, source))
    if cfg.time is not None and cfg.time.path is not None:
        t_table = sources.by_path[Path(cfg.time.path)][0]
        t_table.column(cfg.time.column)
        if t_table.n_samples != parts[0][0].shape[0]:
            raise DataError(
                f"{cfg.time.path}: time column '{cfg.time.column}' has {t_table.n_samples} "
                f"samples, the signals have {parts[0][0].shape[0]}."
            )
        parts[0] = (parts[0][0], t_table if t_table is parts[0][1] else _with_time(parts, t_table))
    return parts


@dataclass(frozen=True, eq=False)
class Stamps:
    """A log's time stamps after the one rule for stamps (NaN refused, duplicates dropped,
    backwards jumps split): ``t`` (None without a time column), the rows kept (None: all),
    the stamps the signals are joined on, the warnings, the names for messages, and the rows
    where a recording starts (the position table's ``segment_starts``)."""

    t: FloatArray | None
    rows: npt.NDArray[np.intp] | None
    t_join: FloatArray | None
    warnings: list[str]
    file: str
    what: str
    starts: tuple[int, ...] = ()

    def breaks(self, keep: npt.NDArray[np.bool_] | None, n_rows: int) -> list[int]:
        """Where a recording starts, as indices of the samples kept (the time rule's
        ``rows``, then the join's mask ``keep``); ``n_rows``: the samples when the rule and
        the join keep them all."""
        if not self.starts:
            return []
        if self.rows is not None:
            rows = self.rows
        else:
            rows = np.arange(keep.size if keep is not None else n_rows)
        if keep is not None:
            rows = rows[keep]
        at = np.searchsorted(rows, np.asarray(self.starts))
        return sorted({int(k) for k in at if 0 < k < rows.size})

    @classmethod
    def of(cls, cfg: LogConfig, ref_table: LogTable, files: str) -> Stamps:
        t_raw = _time_of(ref_table, cfg)
        t_file = cfg.time.path if cfg.time is not None and cfg.time.path is not None else files
        what = f"time column '{cfg.time.column}'" if cfg.time is not None else "time column"
        starts = ref_table.segment_starts
        if t_raw is None:
            return cls(None, None, None, [], str(t_file), what, starts)
        limit = cfg.max_samples or t_raw.size
        cleaned = timebase.clean_time(
            t_raw[:limit],
            f"{t_file}: {what}",
            ref_table.line_numbers,
            gap_factor=cfg.gap_factor,
            max_gap_s=cfg.max_gap_s,
        )
        if cleaned.index.size == t_raw.size:  # every row kept: no copy of the signals
            rows, t_join = None, t_raw
        else:
            rows, t_join = cleaned.index, t_raw[cleaned.index]
        return cls(cleaned.t, rows, t_join, list(cleaned.warnings), str(t_file), what, starts)


def uniform_grid(
    cfg: LogConfig,
    t: FloatArray | None,
    signals: list[FloatArray],
    stamps: Stamps,
    files: str,
    source: str,
    records: list[dict],
    breaks: list[int] | None = None,
) -> tuple[FloatArray, list[FloatArray], list[tuple[int, int]], float, str]:
    """The time of the signals: the given rate, or the stamps cut in segments (gaps, the
    ``breaks`` where a recording starts, windows) and, when not uniform or
    ``log.resample_hz`` is set, resampled per segment (a record appended). Returns
    ``(t, signals, segments, rate [Hz], note)``."""
    windows = [(w.start_s, w.end_s) for w in cfg.windows]
    n = signals[0].shape[0]
    breaks = breaks or []
    if t is None:
        if cfg.sampling_rate_hz is None:
            raise DataError(
                f"{files}: no time column found; set log.time.column or log.sampling_rate_hz."
            )
        fs = float(cfg.sampling_rate_hz)
        t = np.arange(n) / fs
        segments = _windowed(t, timebase.split_segments([(0, n)], breaks), windows, files, source)
        return t, signals, segments, fs, f"sampling rate {fs:g} Hz (no time column)"
    unit = cfg.time.unit if cfg.time is not None else "s"
    timebase.check_rate(t, f"{stamps.file}: {stamps.what}", unit)
    t = t - t[0]
    summary = timebase.summarize_time(t, gap_factor=cfg.gap_factor)
    raw_segments = timebase.find_segments(t, gap_factor=cfg.gap_factor, max_gap_s=cfg.max_gap_s)
    raw_segments = timebase.split_segments(raw_segments, breaks)
    segments = _windowed(t, raw_segments, windows, files, source)
    fs = cfg.resample_hz or summary.rate_hz
    time_note = f"{stamps.what}: {summary.text()}"
    uniform = all(timebase.is_uniform(t[a:b]) for a, b in segments)
    if cfg.resample_hz is None and uniform:
        return t, signals, segments, 1.0 / float(np.median(np.diff(t))), time_note
    t, signals, segments = _resampled(t, signals, segments, fs, files)
    records.append(
        {
            "step": "resample",
            "detail": f"non-uniform time stamps resampled onto a uniform {fs:g} Hz grid "
            "(not-a-knot cubic spline per segment; error <= 5/384 (2 pi f h_max)^4 "
            "of the amplitude at frequency f)",
        }
    )
    return t, signals, segments, fs, time_note


def _resampled(
    t: FloatArray,
    signals: list[FloatArray],
    segments: list[tuple[int, int]],
    fs: float,
    files: str,
) -> tuple[FloatArray, list[FloatArray], list[tuple[int, int]]]:
    """Every segment of at least 4 samples resampled onto a uniform ``fs`` [Hz] grid."""
    out_t: list[FloatArray] = []
    out_x: list[list[FloatArray]] = [[] for _ in signals]
    new_segments: list[tuple[int, int]] = []
    for a, b in segments:
        if b - a < 4:
            continue
        stacked = np.concatenate([x[a:b] for x in signals], axis=1)
        tg, xg = timebase.resample(t[a:b], stacked, fs)
        start = sum(x.size for x in out_t)
        out_t.append(tg)
        new_segments.append((start, start + tg.size))
        for k, x in enumerate(np.split(xg, len(signals), axis=1)):
            out_x[k].append(x)
    if not new_segments:
        raise DataError(f"{files}: no segment has enough samples to resample.")
    signals = [np.concatenate(x).astype(np.float64, copy=False) for x in out_x]
    return np.concatenate(out_t), signals, new_segments


def join_segments(
    t: FloatArray,
    signals: list[FloatArray],
    segments: list[tuple[int, int]],
    n: int,
    fs: float,
    cfg: LogConfig,
    records: list[dict],
) -> tuple[FloatArray, list[FloatArray], list[tuple[int, int]]]:
    """The segments' samples one after another (gaps and samples outside the windows
    dropped, a record appended), or the log as it is when it is one segment of its ``n``
    samples."""
    if len(segments) == 1 and segments[0] == (0, n):
        return t, signals, segments
    windows = [(w.start_s, w.end_s) for w in cfg.windows]
    kept = [(a, b) for a, b in segments if b > a]
    index = np.concatenate([np.arange(a, b) for a, b in kept])
    lengths = [b - a for a, b in kept]
    starts = np.concatenate([[0], np.cumsum(lengths)])
    records.append(
        {
            "step": "segments",
            "detail": f"{len(lengths)} segment(s) of "
            f"{', '.join(f'{m / fs:.3g} s' for m in lengths)} (gaps or episodes split the log"
            + (f"; windows {windows}" if windows else "")
            + ")",
        }
    )
    segments = [(int(s), int(s + m)) for s, m in zip(starts[:-1], lengths, strict=True)]
    return t[index], [x[index] for x in signals], segments


def _windowed(
    t: FloatArray,
    segments: list[tuple[int, int]],
    windows: list[tuple[float | None, float | None]],
    files: str,
    source: str,
) -> list[tuple[int, int]]:
    """Segments cut to ``log.windows``; each window must be ordered, not negative, and hold
    samples of the log (its time from 0 to its end)."""
    for k, (start_s, end_s) in enumerate(windows):
        where = f"log.windows[{k}] = [{start_s}, {end_s}] s"
        here = f"{source}: {where}"
        values = [v for v in (start_s, end_s) if v is not None]
        if any(not np.isfinite(v) or v < 0 for v in values):
            raise ConfigError(
                f"{here}: times are seconds from the log's first sample, finite and >= 0."
            )
        if start_s is not None and end_s is not None and end_s <= start_s:
            raise ConfigError(f"{here}: end_s must be after start_s; swap them.")
        if not timebase.windows_to_segments(t, segments, [(start_s, end_s)]):
            raise DataError(
                f"{files}: {where} holds no sample: the log runs from 0 to {t[-1]:.6g} s; "
                "choose a window inside it (ident logs inspect shows the duration)."
            )
    return timebase.windows_to_segments(t, segments, windows)


def _with_time(parts: list[tuple[FloatArray, LogTable]], t_table: LogTable) -> LogTable:
    """The position table with the separate time file's columns added (same sample count)."""
    table = parts[0][1]
    return LogTable(
        columns={**table.columns, **t_table.columns},
        time=t_table.time,
        source=table.source,
        line_numbers=t_table.line_numbers,
    )
