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

This module and :mod:`ident.measure.log_tables` are the only ones that read log files (through
the readers); everything after them is in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError, DataError
from ident.inputs import JobEstimate
from ident.measure import timebase
from ident.measure.log_config import LogConfig, SignalFile, TransmissionConfig
from ident.measure.log_tables import (
    Stamps,
    join_segments,
    join_signals,
    select_columns,
    signal_tables,
    uniform_grid,
)
from ident.measure.readers import LogTable, estimate_read, read_tables

__all__ = [
    "RobotLog",
    "Transmission",
    "estimate_log",
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
    ratios = _per_joint_vector("gear_ratios", cfg.gear_ratios, 1.0, n_joints, source)
    if side == "joint":
        if cfg.gear_ratios is not None or cfg.coupling:
            raise ConfigError(
                f"{source}: log.side = joint but transmission.gear_ratios/coupling are set; "
                "use log.side: motor for motor-side signals, or remove them."
            )
    Rq = _position_matrix(cfg, ratios, n_joints, source)
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
        torque_constants=_per_joint_vector(
            "torque_constants", cfg.torque_constants, 1.0, n_joints, source
        ),
        zero_offsets=_per_joint_vector("zero_offsets", cfg.zero_offsets, 0.0, n_joints, source),
    )


def _per_joint_vector(
    key: str, value: list[float] | None, default: float, n_joints: int, source: str
) -> FloatArray:
    """``transmission.<key>`` as an array (n_joints,), ``default`` everywhere when unset."""
    if value is None:
        return np.full(n_joints, default)
    if len(value) != n_joints:
        raise ConfigError(
            f"{source}: transmission.{key} has {len(value)} entries, the log has "
            f"{n_joints} joints; give one value per joint."
        )
    return np.asarray(value, dtype=float)


def _position_matrix(
    cfg: TransmissionConfig, ratios: FloatArray, n_joints: int, source: str
) -> FloatArray:
    """``Rq`` (n_joints, n_joints): the gear ``ratios`` on the diagonal and the coupling terms
    (motor row, joint column); raises :class:`ConfigError` for a bad index or a singular Rq."""
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
    return Rq


def _in_si_units(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    q_raw: FloatArray,
    tau_raw: FloatArray,
    dq_raw: FloatArray | None,
    source: str,
) -> tuple[FloatArray, FloatArray, FloatArray | None, str]:
    """The signals (n_samples, n_joints) in SI units (unit, scale, sign once per signal), still
    on their logged side, and the note of the conversions ("" when none)."""
    notes = []
    pos_unit = cfg.position.unit or cfg.position_unit
    q_raw, note = _to_si(q_raw, cfg.position, pos_unit, "position", source)
    notes.append(note)
    trq_unit = "N*m"
    if cfg.torque is not None:  # else NaN: no torque logged
        trq_unit = cfg.torque.unit or cfg.torque_unit
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
    return q_raw, tau_raw, dq_raw, "; ".join(n for n in notes if n)


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
        Joint torques [N*m or N], shape (n_samples, n_joints); NaN when the log has none
        (``log.torque`` absent: a position servo's log, whose torque the actuator model of
        :mod:`ident.identify.actuators` gives from ``q_cmd``).
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
    q_cmd :
        Commanded joint positions [rad or m], shape (n_samples, n_joints), on the samples of
        ``q``; None when the log names none. A position servo's set point before its transport
        delay (``log.command``; LeRobot's ``action``; the simulator's position actuator).
        The position servo's model uses it (``actuator: {kind: position}``,
        :mod:`ident.identify.actuators.servo_fit`); the rest of identification ignores it.
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
    q_cmd: FloatArray | None = None

    def __post_init__(self) -> None:
        if not self.segments:
            object.__setattr__(self, "segments", ((0, int(self.t.shape[0])),))
        if self.ddq is not None and self.dq is None:
            raise ValueError("RobotLog: measured accelerations (ddq) need the velocities (dq)")
        if self.q_cmd is not None and self.q_cmd.shape != self.q.shape:
            raise ValueError(
                f"RobotLog: q_cmd has shape {self.q_cmd.shape}, the positions {self.q.shape}"
            )

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
    """Unit (ticks: less ``zero_tick``), scale and sign of one signal -> SI values and a note
    for the records."""
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
    zero = ""
    if signal.zero_tick is not None:
        if unit != "ticks":
            raise ConfigError(
                f"{source}: log.{what}.zero_tick is the tick of the zero angle of unit: ticks "
                f"positions, the unit here is {unit}; remove it or set log.{what}.unit: ticks."
            )
        offset = _per_joint(signal.zero_tick, n, f"{what}.zero_tick", source)
        raw, zero = raw - offset, f"({what} - zero_tick {offset.tolist()}) "
    gain = factor * _per_joint(signal.scale, n, f"{what}.scale", source)
    gain = gain * _per_joint(signal.sign, n, f"{what}.sign", source)
    if np.all(gain == 1.0) and not zero:
        return raw, ""
    return raw * gain, f"{zero or what + ' '}{unit} x {gain.tolist()}"


def read_csv_columns(
    path: str | Path,
    columns: list[str] | None,
    *,
    n_expected: int | None = None,
    delimiter: str = ",",
    what: str = "signal",
) -> tuple[FloatArray, list[str]]:
    """Read named columns of a text log with a header line (see :func:`select_columns`).

    Returns the values, shape (n_samples, n_columns), and the column names.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: {what} file not found.")
    (table,) = read_tables(path, "csv", delimiter=delimiter, header=True)
    return select_columns(table, columns, n_expected, what)


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
    warnings, q_cmd = list(first.warnings), []
    offset, start = 0.0, 0
    for k, log in enumerate(parts):
        t.append(log.t - log.t[0] + offset)
        offset = t[-1][-1] + 1.0
        q.append(log.q)
        tau.append(log.tau)
        dq.append(log.dq)
        q_cmd.append(log.q_cmd)
        segments += [(a + start, b + start) for a, b in log.segments]
        start += log.n_samples
        if k:
            records += [{**r, "step": f"log {k + 1}: {r['step']}"} for r in log.records]
            warnings += [f"log.more[{k - 1}]: {w}" for w in log.warnings]
    return RobotLog(
        t=np.concatenate(t),
        q=np.concatenate(q),
        tau=np.concatenate(tau),
        sampling_rate_hz=fs,
        joint_names=first.joint_names,
        records=tuple(records),
        segments=tuple(segments),
        dq=_all_or_none(dq),
        warnings=tuple(warnings),
        q_cmd=_all_or_none(q_cmd),
    )


def _all_or_none(parts: list[FloatArray | None]) -> FloatArray | None:
    """The parts one after another when every log has the signal, else None."""
    if any(p is None for p in parts):
        return None
    return np.concatenate([p for p in parts if p is not None])


def _to_rate(log: RobotLog, rate_hz: float) -> RobotLog:
    """``log`` resampled per segment onto ``rate_hz`` (cubic spline)."""
    signals = [log.q, log.tau] + [x for x in (log.dq, log.q_cmd) if x is not None]
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
        q_cmd=parts[-1] if log.q_cmd is not None else None,
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
    cfg, transmission :
        The ``log`` section (paths already absolute) and the ``transmission`` section.
    joint_names :
        Model joint names the columns map to, in order; their number is the number of columns.
    source :
        Config file name for messages.

    Raises :class:`DataError` for missing or malformed files, columns, NaN/inf values, a bad
    time column; :class:`ConfigError` for an inconsistent transmission or unit."""
    joint_names = tuple(joint_names)
    parts = signal_tables(cfg, joint_names, source)
    files = ", ".join(Path(f.path).name for f in cfg.sources())
    warnings = list(dict.fromkeys(w for _, table in parts for w in table.warnings))
    stamps = Stamps.of(cfg, parts[0][1], files)
    warnings += stamps.warnings
    arrays, keep, join_note, join_warnings = join_signals(parts, cfg, stamps.t_join, stamps.rows)
    warnings += join_warnings
    t = stamps.t if keep is None or stamps.t is None else stamps.t[keep]
    breaks = stamps.breaks(keep, arrays[0].shape[0])
    signals, records = _si_signals(cfg, transmission, arrays, t, parts, joint_names, source)
    n = signals[0].shape[0]
    t, signals, segments, fs, time_note = uniform_grid(
        cfg, t, signals, stamps, files, source, records, breaks
    )
    t, signals, segments = join_segments(t, signals, segments, n, fs, cfg, records)
    # float64 already (no copy): asarray only tells the type checker
    q, tau, *more = (np.asarray(x, dtype=np.float64) for x in signals)
    dq_out = more.pop(0) if cfg.velocity is not None else None
    q_cmd = more.pop(0) if cfg.command is not None else None
    detail = (
        f"{q.shape[0]} samples x {q.shape[1]} joints from {files}; {time_note}"
        + (f"; {join_note}" if join_note else "")
        + ("; no torque logged (log.torque absent)" if cfg.torque is None else "")
    )
    records.insert(0, {"step": "read", "detail": detail})
    return RobotLog(t=t, q=q, tau=tau, sampling_rate_hz=fs, joint_names=joint_names,
                    records=tuple(records), segments=tuple(segments), dq=dq_out,
                    warnings=tuple(warnings), q_cmd=q_cmd)  # fmt: skip


def _raw_signals(
    cfg: LogConfig, arrays: list[FloatArray], t: FloatArray | None
) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray | None]:
    """The joined position, torque (velocity, commanded position) columns (n_samples,
    n_joints) as logged, cut to ``log.max_samples`` when the log has no time column ``t``."""
    q_raw, tau_raw = arrays[0], arrays[1]
    dq_raw = arrays[2] if cfg.velocity is not None else None
    cmd_raw = arrays[-1] if cfg.command is not None else None
    if cfg.max_samples is not None and t is None:
        q_raw, tau_raw = q_raw[: cfg.max_samples], tau_raw[: cfg.max_samples]
        dq_raw = None if dq_raw is None else dq_raw[: cfg.max_samples]
        cmd_raw = None if cmd_raw is None else cmd_raw[: cfg.max_samples]
    return q_raw, tau_raw, dq_raw, cmd_raw


def _si_signals(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    arrays: list[FloatArray],
    t: FloatArray | None,
    parts: list[tuple[FloatArray, LogTable]],
    joint_names: tuple[str, ...],
    source: str,
) -> tuple[list[FloatArray], list[dict]]:
    """The joined signals in SI on the joint side, ``[q, tau]`` (then ``dq``, ``q_cmd`` when
    the log has them), positions checked against their source's angle bound; the records."""
    q_raw, tau_raw, dq_raw, cmd_raw = _raw_signals(cfg, arrays, t)
    signals, records = _joint_side(cfg, transmission, q_raw, tau_raw, dq_raw, source)
    unit = cfg.position.unit or cfg.position_unit
    _check_angles(signals[0], parts[0][1], unit, "position", joint_names)
    command = cfg.command_signal()
    if cmd_raw is not None and command is not None:
        q_cmd, record = _command_positions(cfg, command, transmission, cmd_raw, source)
        unit = command.unit or cfg.position_unit
        _check_angles(q_cmd, parts[-1][1], unit, "command", joint_names)
        signals.append(q_cmd)
        records.append(record)
    return signals, records


def _command_positions(
    cfg: LogConfig,
    command: SignalFile,
    transmission: TransmissionConfig,
    raw: FloatArray,
    source: str,
) -> tuple[FloatArray, dict]:
    """Commanded positions (n_samples, n_joints) in SI on the joint side, converted as the
    measured ones are (unit, scale, sign, then the side's transmission and zero offsets)."""
    values, note = _to_si(raw, command, command.unit or cfg.position_unit, "command", source)
    side = command.side or cfg.side
    trans = transmission_from_config(transmission, raw.shape[1], side="motor", source=source)
    if side == "joint":  # the zero offsets only, as for the measured positions
        n = raw.shape[1]
        trans = Transmission(np.eye(n), np.eye(n), trans.torque_constants, trans.zero_offsets)
    detail = f"commanded positions ({side} side)" + (f": {note}" if note else "")
    return trans.joint_positions(values), {"step": "command", "detail": detail}


def _check_angles(
    q: FloatArray, table: LogTable, unit: str, what: str, joint_names: tuple[str, ...]
) -> None:
    """Refuse positions ``q`` [rad] (n_samples, n_joints) beyond the angle bound of their
    source (servo angles: ``LogTable.angle_bound_rad``): logged in another unit than
    ``unit``. The message names the file, the joint column and the unit key to set."""
    bound = table.angle_bound_rad
    if bound is None or unit in ("m", "mm") or q.size == 0:
        return
    peak = np.max(np.abs(q), axis=0)
    if not np.any(peak > bound):
        return
    j = int(np.argmax(peak > bound))
    fix = {
        "deg": f"they look like ticks: set log.{what}.unit: ticks with counts_per_rev "
        "(4096 for a Feetech STS3215) and zero_tick (2048)",
        "ticks": f"check log.{what}.counts_per_rev and zero_tick",
    }.get(
        unit,
        f"they look like ticks or degrees: set log.{what}.unit: deg, or unit: ticks with "
        "counts_per_rev (4096 for a Feetech STS3215) and zero_tick (2048)",
    )
    raise DataError(
        f"{table.source}: log.{what} of joint '{joint_names[j]}' reaches {peak[j]:.4g} rad "
        f"read as {unit}, beyond the +-{bound:.3g} rad a servo's angle stays within; {fix}."
    )


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
    q_raw, tau_raw, dq_raw, unit_note = _in_si_units(
        cfg, transmission, q_raw, tau_raw, dq_raw, source
    )
    pos_side = cfg.position.side or cfg.side
    trq_side = (cfg.torque.side if cfg.torque else None) or cfg.side
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
