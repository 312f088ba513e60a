"""Reading robot logs declared in a config, and converting them to joint-side SI signals.

A log is one or more sources read by the registered readers (:mod:`ident.measure.readers`:
CSV/TSV wide or long, one value per line, ROS 2 bags, MCAP; plain or gzip-compressed): the
config maps columns to positions, torques and optionally velocities for every joint. Tables of
several sources are joined on time (cubic-spline interpolation onto the time stamps of the
position source). Time comes from a time column or a sampling rate; gaps split the log into
segments, windows select parts, non-uniform stamps are resampled onto a uniform grid
(:mod:`ident.measure.timebase`). Units are converted to SI per signal (deg, mrad, ticks, mm;
A, mA through the torque constants; scale and sign), once. The transmission converts
motor-side signals to the joint side:

- positions: ``q = Rq^-1 q_motor + zero_offsets`` with ``Rq = diag(gear_ratios) + coupling``;
- torques: ``tau = Rt (k * y)`` with ``k`` the current-to-torque constants [N*m/A] and
  ``Rt = Rq^T`` by default (power balance ``tau^T dq = y^T dq_motor``).

This is the only module that reads log files; everything after it is in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError, DataError
from ident.identify.config import LogConfig, SignalFile, TransmissionConfig
from ident.inputs import JobEstimate
from ident.measure import timebase
from ident.measure.readers import LogTable, estimate_read, read_tables

__all__ = [
    "RobotLog",
    "Transmission",
    "estimate_log",
    "joint_order",
    "read_csv_columns",
    "read_log",
    "transmission_from_config",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Transmission:
    """Linear motor-to-joint transmission.

    Attributes
    ----------
    position_matrix :
        ``Rq`` with ``q_motor = Rq q_joint``, shape (n_joints, n_joints).
    torque_matrix :
        ``Rt`` with ``tau_joint = Rt y_motor``, shape (n_joints, n_joints).
    torque_constants :
        Signal-to-motor-torque factors [N*m per signal unit], shape (n_joints,).
    zero_offsets :
        Added to the joint angles after the conversion [rad], shape (n_joints,).
    """

    position_matrix: FloatArray
    torque_matrix: FloatArray
    torque_constants: FloatArray
    zero_offsets: FloatArray

    def joint_positions(self, q_motor: FloatArray) -> FloatArray:
        """Joint angles [rad] from motor angles [rad], both shape (n_samples, n_joints);
        ``q_motor`` itself (no copy of a long log) when the transmission does nothing."""
        identity = np.array_equal(self.position_matrix, np.eye(self.position_matrix.shape[0]))
        if identity and not np.any(self.zero_offsets):
            return q_motor  # what the formula gives, bit for bit
        return np.linalg.solve(self.position_matrix, q_motor.T).T + self.zero_offsets

    def joint_torques(self, signal: FloatArray) -> FloatArray:
        """Joint torques [N*m] from the motor-side signal, shape (n_samples, n_joints);
        ``signal`` itself when the transmission does nothing."""
        identity = np.array_equal(self.torque_matrix, np.eye(self.torque_matrix.shape[0]))
        if identity and np.all(self.torque_constants == 1.0):
            return signal
        return (signal * self.torque_constants) @ self.torque_matrix.T

    def coupled_pairs(self) -> list[tuple[int, int]]:
        """``(motor, joint)`` 0-based index pairs of the off-diagonal terms of ``Rq``."""
        off = self.position_matrix - np.diag(np.diag(self.position_matrix))
        return [(int(i), int(j)) for i, j in zip(*np.nonzero(off), strict=True)]


def transmission_from_config(
    cfg: TransmissionConfig, n_joints: int, *, side: str = "motor", source: str = "config"
) -> Transmission:
    """Build the :class:`Transmission` of a config section.

    Parameters
    ----------
    cfg :
        The ``transmission`` section.
    n_joints :
        Number of joints of the log.
    side :
        ``"motor"`` (signals are motor side: gear ratios and coupling apply) or ``"joint"``.
    source :
        File name for messages.

    Raises
    ------
    ConfigError
        If a list has the wrong length, a coupling index is out of range, or ``Rq`` is singular.
    """

    def vector(key: str, value: list[float] | None, default: float) -> FloatArray:
        if value is None:
            return np.full(n_joints, default)
        if len(value) != n_joints:
            raise ConfigError(
                f"{source}: transmission.{key} has {len(value)} entries, the log has "
                f"{n_joints} joints; give one value per joint."
            )
        return np.asarray(value, dtype=float)

    ratios = vector("gear_ratios", cfg.gear_ratios, 1.0)
    if side == "joint":
        if cfg.gear_ratios is not None or cfg.coupling:
            raise ConfigError(
                f"{source}: log.side = joint but transmission.gear_ratios/coupling are set; "
                "use log.side: motor for motor-side signals, or remove them."
            )
    Rq = np.diag(ratios)
    for k, entry in enumerate(cfg.coupling):
        if entry.motor > n_joints or entry.joint > n_joints or entry.motor == entry.joint:
            raise ConfigError(
                f"{source}: transmission.coupling[{k}] = (motor {entry.motor}, joint "
                f"{entry.joint}): indices are 1-based, distinct, at most {n_joints}."
            )
        Rq[entry.motor - 1, entry.joint - 1] = entry.ratio
    if abs(np.linalg.det(Rq)) < 1e-12 * np.prod(np.abs(ratios)):
        raise ConfigError(f"{source}: transmission matrix Rq is singular; check the coupling.")
    if cfg.torque_matrix is not None:
        Rt = np.asarray(cfg.torque_matrix, dtype=float)
        if Rt.shape != (n_joints, n_joints):
            raise ConfigError(
                f"{source}: transmission.torque_matrix has shape {Rt.shape}, expected "
                f"({n_joints}, {n_joints})."
            )
    else:
        Rt = Rq.T.copy()
    return Transmission(
        position_matrix=Rq,
        torque_matrix=Rt,
        torque_constants=vector("torque_constants", cfg.torque_constants, 1.0),
        zero_offsets=vector("zero_offsets", cfg.zero_offsets, 0.0),
    )


def _matrix(a: FloatArray) -> str:
    """One-line matrix text for the records (rows separated by ';')."""
    return "[" + "; ".join(" ".join(f"{v:g}" for v in row) for row in a) + "]"


@dataclass(frozen=True, eq=False)
class RobotLog:
    """A log converted to joint-side SI signals on a uniform time grid.

    Attributes
    ----------
    t :
        Time [s], shape (n_samples,), starting at 0, uniform inside each segment.
    q :
        Joint positions [rad or m], shape (n_samples, n_joints).
    tau :
        Joint torques [N*m or N], shape (n_samples, n_joints).
    sampling_rate_hz :
        Sampling rate [Hz] (the same in every segment).
    joint_names :
        Model joint names, in column order.
    records :
        Human-readable description of every conversion applied, for the report.
    segments :
        ``(start, stop)`` sample ranges without gaps (windows applied), in time order; the
        arrays are their concatenation. One segment ``(0, n_samples)`` for a plain log.
    dq :
        Logged joint velocities [rad/s or m/s], shape (n_samples, n_joints), or None.
    ddq :
        Measured joint accelerations [rad/s^2 or m/s^2], shape (n_samples, n_joints), or None
        (every log read from a file). A source that knows the states (``ident run``'s ideal
        source) gives ``dq`` and ``ddq``; the identification then uses ``q, dq, ddq`` as they
        are, without low-passing or differentiating ``q``.
    warnings :
        What reading changed in the data a user must know (duplicated stamps dropped, a
        backwards jump split, receive times used for missing stamps): count and first place.
    """

    t: FloatArray
    q: FloatArray
    tau: FloatArray
    sampling_rate_hz: float
    joint_names: tuple[str, ...]
    records: tuple[dict, ...] = field(default_factory=tuple)
    segments: tuple[tuple[int, int], ...] = ()
    dq: FloatArray | None = None
    warnings: tuple[str, ...] = ()
    ddq: FloatArray | None = None

    def __post_init__(self) -> None:
        if not self.segments:
            object.__setattr__(self, "segments", ((0, int(self.t.shape[0])),))
        if self.ddq is not None and self.dq is None:
            raise ValueError("RobotLog: measured accelerations (ddq) need the velocities (dq)")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


# Factor from a unit to SI, per signal kind ("ticks" needs counts_per_rev: handled apart).
_UNIT_SCALE = {
    "rad": 1.0,
    "deg": np.pi / 180.0,
    "mrad": 1e-3,
    "m": 1.0,
    "mm": 1e-3,
    "N*m": 1.0,
    "N": 1.0,
    "A": 1.0,
    "mA": 1e-3,
    "rad/s": 1.0,
    "deg/s": np.pi / 180.0,
    "rpm": 2.0 * np.pi / 60.0,
    "m/s": 1.0,
    "mm/s": 1e-3,
}
_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def _per_joint(value: float | list[float] | None, n: int, key: str, source: str) -> FloatArray:
    if value is None:
        return np.ones(n)
    if isinstance(value, int | float):
        return np.full(n, float(value))
    if len(value) != n:
        raise ConfigError(
            f"{source}: log.{key} has {len(value)} entries, give one per joint ({n})."
        )
    return np.asarray(value, dtype=float)


def _to_si(
    raw: FloatArray, signal: SignalFile, unit: str, what: str, source: str
) -> tuple[FloatArray, str]:
    """Unit, scale and sign of one signal -> SI values and a note for the records."""
    n = raw.shape[1]
    if unit in ("ticks", "ticks/s"):
        if signal.counts_per_rev is None:
            raise ConfigError(
                f"{source}: log.{what}.unit = {unit} needs log.{what}.counts_per_rev "
                "(encoder counts per revolution)."
            )
        factor = 2.0 * np.pi / signal.counts_per_rev
    else:
        factor = _UNIT_SCALE[unit]
    gain = factor * _per_joint(signal.scale, n, f"{what}.scale", source)
    gain = gain * _per_joint(signal.sign, n, f"{what}.sign", source)
    if np.all(gain == 1.0):
        return raw, ""
    return raw * gain, f"{what} {unit} x {gain.tolist()}"


def read_csv_columns(
    path: str | Path,
    columns: list[str] | None,
    *,
    n_expected: int | None = None,
    delimiter: str = ",",
    what: str = "signal",
) -> tuple[FloatArray, list[str]]:
    """Read named columns of a text log with a header line (see :func:`_select`).

    Returns the values, shape (n_samples, n_columns), and the column names.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: {what} file not found.")
    (table,) = read_tables(path, "csv", delimiter=delimiter, header=True)
    return _select(table, columns, n_expected, what)


def _select(
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
    import difflib

    close = difflib.get_close_matches(name, available, n=3)
    hint = f" (closest: {', '.join(close)})" if close else ""
    files = ", ".join(sorted({t.source for t in tables}))
    return f"{files}: column '{name}' not found{hint}; `ident logs inspect FILE` lists the columns."


class _Sources:
    """The tables of every file a log config names, read once.

    Readers are told the columns the config names (reader option ``columns``, when every
    signal names its columns), so that a ROS log keeps only those of its topics; a column not
    found is looked up again in the files read whole, so the message lists every column.
    """

    def __init__(self, cfg: LogConfig, *, whole: bool = False) -> None:
        self.cfg = cfg
        signals = [s for s in (cfg.position, cfg.torque, cfg.velocity) if s is not None]
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
        if signal.columns is None:
            table = tables[0]
        else:
            owners = [self._find(tables, c) for c in signal.columns]
            table = owners[0]
            if any(o is not table for o in owners):
                table = _side_by_side(owners, signal.columns, what)
        data, names = _select(table, signal.columns, n_joints, what)
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


def _join(
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
        inside = (t_ref >= t_sorted[0]) & (t_ref <= t_sorted[-1])
        keep &= inside
        out.append(spline(t_ref))
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


# Reading holds the file's columns, then the converted signals (q, tau, dq, t) beside them.
_READ_OVERHEAD = 2.0


def estimate_log(cfg: LogConfig) -> JobEstimate:
    """Memory and time of reading the log of a config (and its ``more`` logs), from the
    files' sizes and headers (:func:`ident.measure.readers.estimate_read`), before reading.
    """
    memory, seconds, names = 0.0, 0.0, []
    for entry in cfg.all_logs():
        for f in entry.sources():
            options = f.model_dump(exclude={"path", "format"})
            estimate = estimate_read(f.path, f.format, **options)
            if estimate is not None:
                memory += estimate.memory_bytes
                seconds += estimate.seconds
                names.append(Path(f.path).name)
    return JobEstimate(
        f"reading the log ({', '.join(dict.fromkeys(names)) or 'no estimate'})",
        _READ_OVERHEAD * memory,
        seconds,
    )


def read_log(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    joint_names: list[str] | tuple[str, ...],
    *,
    source: str = "config",
) -> RobotLog:
    """Read the log of a config (and its ``more`` logs) as joint-side SI signals.

    Several logs become segments of one :class:`RobotLog` (time continues after each log's
    end plus one second, so plots keep them apart); logs at another rate are resampled onto
    the first log's rate. See :func:`_read_one` for one log.
    """
    logs = cfg.all_logs()
    first = _read_one(logs[0], transmission, joint_names, source=source)
    if len(logs) == 1:
        return first
    fs = first.sampling_rate_hz
    parts = [first]
    for k, entry in enumerate(logs[1:]):
        try:
            log = _read_one(entry, transmission, joint_names, source=source)
        except (DataError, ConfigError) as e:
            raise type(e)(f"log.more[{k}]: {e}") from e
        if abs(log.sampling_rate_hz - fs) > 1e-9 * fs:
            log = _to_rate(log, fs)
        parts.append(log)
    t, q, tau, dq, segments, records = [], [], [], [], [], list(first.records)
    warnings = list(first.warnings)
    offset, start = 0.0, 0
    for k, log in enumerate(parts):
        t.append(log.t - log.t[0] + offset)
        offset = t[-1][-1] + 1.0
        q.append(log.q)
        tau.append(log.tau)
        dq.append(log.dq)
        segments += [(a + start, b + start) for a, b in log.segments]
        start += log.n_samples
        if k:
            records += [{**r, "step": f"log {k + 1}: {r['step']}"} for r in log.records]
            warnings += [f"log.more[{k - 1}]: {w}" for w in log.warnings]
    has_dq = all(d is not None for d in dq)
    return RobotLog(
        t=np.concatenate(t),
        q=np.concatenate(q),
        tau=np.concatenate(tau),
        sampling_rate_hz=fs,
        joint_names=first.joint_names,
        records=tuple(records),
        segments=tuple(segments),
        dq=np.concatenate([d for d in dq if d is not None]) if has_dq else None,
        warnings=tuple(warnings),
    )


def _to_rate(log: RobotLog, rate_hz: float) -> RobotLog:
    """``log`` resampled per segment onto ``rate_hz`` (cubic spline)."""
    signals = [log.q, log.tau] + ([log.dq] if log.dq is not None else [])
    t_out, x_out, segments, start = [], [], [], 0
    for a, b in log.segments:
        tg, xg = timebase.resample(
            log.t[a:b], np.concatenate([x[a:b] for x in signals], 1), rate_hz
        )
        t_out.append(tg)
        x_out.append(xg)
        segments.append((start, start + tg.size))
        start += tg.size
    x = np.concatenate(x_out)
    parts = np.split(x, len(signals), axis=1)
    return RobotLog(
        t=np.concatenate(t_out),
        q=parts[0],
        tau=parts[1],
        sampling_rate_hz=rate_hz,
        joint_names=log.joint_names,
        records=(
            *log.records,
            {"step": "resample", "detail": f"onto the first log's rate {rate_hz:g} Hz"},
        ),
        segments=tuple(segments),
        dq=parts[2] if log.dq is not None else None,
        warnings=log.warnings,
    )


def _read_one(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    joint_names: list[str] | tuple[str, ...],
    *,
    source: str = "config",
) -> RobotLog:
    """Read the log of a config and convert it to joint-side SI signals on a uniform grid.

    Parameters
    ----------
    cfg :
        The ``log`` section (paths already absolute).
    transmission :
        The ``transmission`` section.
    joint_names :
        Model joint names the columns map to, in order; their number is the number of columns.
    source :
        Config file name for messages.

    Raises
    ------
    DataError
        For missing or malformed files, columns, NaN/inf values, or a bad time column.
    ConfigError
        For an inconsistent transmission or unit.
    """
    joint_names = tuple(joint_names)
    n_joints = len(joint_names)
    parts = _signal_tables(cfg, joint_names, source)
    files = ", ".join(Path(f.path).name for f in cfg.sources())
    warnings = list(dict.fromkeys(w for _, table in parts for w in table.warnings))
    stamps = _Stamps.of(cfg, parts[0][1], files)
    warnings += stamps.warnings
    arrays, keep, join_note, join_warnings = _join(parts, cfg, stamps.t_join, stamps.rows)
    warnings += join_warnings
    t = stamps.t if keep is None or stamps.t is None else stamps.t[keep]
    q_raw, tau_raw = arrays[0], arrays[1]
    dq_raw = arrays[2] if cfg.velocity is not None else None
    if cfg.max_samples is not None and t is None:
        q_raw, tau_raw = q_raw[: cfg.max_samples], tau_raw[: cfg.max_samples]
        dq_raw = None if dq_raw is None else dq_raw[: cfg.max_samples]
    signals, records = _joint_side(cfg, transmission, q_raw, tau_raw, dq_raw, source)
    n = signals[0].shape[0]
    t, signals, segments, fs, time_note = _uniform_grid(
        cfg, t, signals, stamps, files, source, records
    )
    t, signals, segments = _join_segments(t, signals, segments, n, fs, cfg, records)
    # float64 already (no copy): asarray only tells the type checker
    q, tau = (np.asarray(x, dtype=np.float64) for x in signals[:2])
    dq_out = np.asarray(signals[2], dtype=np.float64) if len(signals) > 2 else None
    records.insert(
        0,
        {
            "step": "read",
            "detail": f"{q.shape[0]} samples x {n_joints} joints from {files}; {time_note}"
            + (f"; {join_note}" if join_note else ""),
        },
    )
    return RobotLog(
        t=t,
        q=q,
        tau=tau,
        sampling_rate_hz=fs,
        joint_names=joint_names,
        records=tuple(records),
        segments=tuple(segments),
        dq=dq_out,
        warnings=tuple(warnings),
    )


def _signal_tables(
    cfg: LogConfig, joint_names: tuple[str, ...], source: str = "config"
) -> list[tuple[FloatArray, LogTable]]:
    """Position, torque (and velocity) columns with their tables; the first part carries the
    table of the time column (``log.time.path``) when the time is in a file of its own."""
    n_joints = len(joint_names)
    sources = _Sources(cfg)
    parts = [
        sources.signal(cfg.position, n_joints, "position", joint_names, source),
        sources.signal(cfg.torque, n_joints, "torque", joint_names, source),
    ]
    if cfg.velocity is not None:
        parts.append(sources.signal(cfg.velocity, n_joints, "velocity", joint_names, source))
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
class _Stamps:
    """A log's time stamps after the one rule for stamps (NaN refused, duplicates dropped,
    backwards jumps split): ``t`` (None without a time column), the rows kept (None: all),
    the stamps the signals are joined on, the warnings, and the names for messages."""

    t: FloatArray | None
    rows: npt.NDArray[np.intp] | None
    t_join: FloatArray | None
    warnings: list[str]
    file: str
    what: str

    @classmethod
    def of(cls, cfg: LogConfig, ref_table: LogTable, files: str) -> _Stamps:
        t_raw = _time_of(ref_table, cfg)
        t_file = cfg.time.path if cfg.time is not None and cfg.time.path is not None else files
        what = f"time column '{cfg.time.column}'" if cfg.time is not None else "time column"
        if t_raw is None:
            return cls(None, None, None, [], str(t_file), what)
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
        return cls(cleaned.t, rows, t_join, list(cleaned.warnings), str(t_file), what)


def _joint_side(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    q_raw: FloatArray,
    tau_raw: FloatArray,
    dq_raw: FloatArray | None,
    source: str,
) -> tuple[list[FloatArray], list[dict]]:
    """The signals in SI units on the joint side (units, scale, sign once per signal, then
    the transmission): ``[q, tau]`` (and ``dq``), and the records of both steps."""
    n_joints = q_raw.shape[1]
    notes = []
    pos_unit = cfg.position.unit or cfg.position_unit
    trq_unit = cfg.torque.unit or cfg.torque_unit
    q_raw, note = _to_si(q_raw, cfg.position, pos_unit, "position", source)
    notes.append(note)
    tau_raw, note = _to_si(tau_raw, cfg.torque, trq_unit, "torque", source)
    notes.append(note)
    if dq_raw is not None:
        assert cfg.velocity is not None
        dq_raw, note = _to_si(
            dq_raw, cfg.velocity, cfg.velocity.unit or cfg.velocity_unit, "velocity", source
        )
        notes.append(note)
    if trq_unit in ("A", "mA") and transmission.torque_constants is None:
        raise ConfigError(
            f"{source}: log.torque_unit = {trq_unit} needs transmission.torque_constants "
            "[N*m/A], one per joint."
        )
    pos_side = cfg.position.side or cfg.side
    trq_side = cfg.torque.side or cfg.side
    vel_side = (cfg.velocity.side if cfg.velocity else None) or cfg.side
    any_motor = "motor" in (pos_side, trq_side, vel_side if dq_raw is not None else "joint")
    trans = transmission_from_config(
        transmission, n_joints, side="motor" if any_motor else "joint", source=source
    )
    identity = Transmission(
        position_matrix=np.eye(n_joints),
        torque_matrix=np.eye(n_joints),
        torque_constants=trans.torque_constants,
        zero_offsets=trans.zero_offsets,
    )
    signals = [
        (trans if pos_side == "motor" else identity).joint_positions(q_raw),
        (trans if trq_side == "motor" else identity).joint_torques(tau_raw),
    ]
    if dq_raw is not None:
        Rq = trans.position_matrix if vel_side == "motor" else np.eye(n_joints)
        signals.append(np.asarray(np.linalg.solve(Rq, dq_raw.T).T, dtype=np.float64))
    records: list[dict] = []
    unit_note = "; ".join(n for n in notes if n)
    if unit_note:
        records.append({"step": "units", "detail": unit_note})
    records.append(
        {
            "step": "transmission",
            "detail": f"positions {pos_side} side, torques {trq_side} side"
            + (f", velocities {vel_side} side" if dq_raw is not None else "")
            + "; q = Rq^-1 q_motor + offsets, tau = Rt (k y); "
            f"Rq = {_matrix(trans.position_matrix)}; "
            f"Rt = {_matrix(trans.torque_matrix)}; "
            f"k = {trans.torque_constants.tolist()}; "
            f"zero offsets [rad] = {trans.zero_offsets.tolist()}",
        }
    )
    return signals, records


def _uniform_grid(
    cfg: LogConfig,
    t: FloatArray | None,
    signals: list[FloatArray],
    stamps: _Stamps,
    files: str,
    source: str,
    records: list[dict],
) -> tuple[FloatArray, list[FloatArray], list[tuple[int, int]], float, str]:
    """The time of the signals: the given rate, or the stamps cut in segments (gaps,
    windows) and, when not uniform or ``log.resample_hz`` is set, resampled per segment
    (a record appended). Returns ``(t, signals, segments, rate [Hz], note)``."""
    windows = [(w.start_s, w.end_s) for w in cfg.windows]
    n = signals[0].shape[0]
    if t is None:
        if cfg.sampling_rate_hz is None:
            raise DataError(
                f"{files}: no time column found; set log.time.column or log.sampling_rate_hz."
            )
        fs = float(cfg.sampling_rate_hz)
        t = np.arange(n) / fs
        segments = _windowed(t, [(0, n)], windows, files, source)
        return t, signals, segments, fs, f"sampling rate {fs:g} Hz (no time column)"
    unit = cfg.time.unit if cfg.time is not None else "s"
    timebase.check_rate(t, f"{stamps.file}: {stamps.what}", unit)
    t = t - t[0]
    summary = timebase.summarize_time(t, gap_factor=cfg.gap_factor)
    raw_segments = timebase.find_segments(t, gap_factor=cfg.gap_factor, max_gap_s=cfg.max_gap_s)
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


def _join_segments(
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
            f"{', '.join(f'{m / fs:.3g} s' for m in lengths)} (gaps split the log"
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
