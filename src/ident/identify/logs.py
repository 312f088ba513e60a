"""Reading robot logs declared in a config, and converting them to joint-side SI signals.

A log is one or more CSV files (plain or gzip-compressed, with a header line): positions and
torques for every joint, either one file per signal or columns of one wide file; time comes
from a time column or from a sampling rate. The transmission converts motor-side signals to
the joint side:

- positions: ``q = Rq^-1 q_motor + zero_offsets`` with ``Rq = diag(gear_ratios) + coupling``;
- torques: ``tau = Rt (k * y)`` with ``k`` the current-to-torque constants [N*m/A] and
  ``Rt = Rq^T`` by default (power balance ``tau^T dq = y^T dq_motor``).

This is the only module that reads log files; everything after it is in SI units.
"""

from __future__ import annotations

import gzip
import io
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError, DataError
from ident.identify.config import LogConfig, SignalFile, TransmissionConfig

__all__ = [
    "RobotLog",
    "Transmission",
    "read_csv_columns",
    "read_log",
    "transmission_from_config",
]

FloatArray = npt.NDArray[np.float64]

# Relative spread of the sampling intervals above which a time column counts as non-uniform.
_UNIFORM_RTOL = 1e-3


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
        """Joint angles [rad] from motor angles [rad], both shape (n_samples, n_joints)."""
        return np.linalg.solve(self.position_matrix, q_motor.T).T + self.zero_offsets

    def joint_torques(self, signal: FloatArray) -> FloatArray:
        """Joint torques [N*m] from the motor-side signal, shape (n_samples, n_joints)."""
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


def _open_text(path: Path) -> io.TextIOBase:
    if path.suffix == ".gz":
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8")
    return open(path, encoding="utf-8")  # noqa: SIM115 - closed by the caller's with


def read_csv_columns(
    path: str | Path,
    columns: list[str] | None,
    *,
    n_expected: int | None = None,
    delimiter: str = ",",
    what: str = "signal",
) -> tuple[FloatArray, list[str]]:
    """Read named columns of a CSV file with a header line.

    Parameters
    ----------
    path :
        CSV file, optionally ``.gz``.
    columns :
        Header names to read, in order; None reads every column.
    n_expected :
        Required number of columns when ``columns`` is None (one per joint).
    delimiter :
        Field separator.
    what :
        Name of the signal, for messages.

    Returns
    -------
    :
        Values of shape (n_samples, n_columns) and the column names.

    Raises
    ------
    DataError
        Naming the file and column: missing file or column, wrong column count, a row with a
        different number of fields or a non-number, NaN or inf values. Positions in a message
        are file line numbers (the header is line 1; blank lines count).
    """
    data, names, _ = _read_csv_lines(
        path, columns, n_expected=n_expected, delimiter=delimiter, what=what
    )
    return data, names


def _read_csv_lines(
    path: str | Path,
    columns: list[str] | None,
    *,
    n_expected: int | None = None,
    delimiter: str = ",",
    what: str = "signal",
) -> tuple[FloatArray, list[str], npt.NDArray[np.int64]]:
    """:func:`read_csv_columns` plus the file line number of every sample, shape (n_samples,)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: {what} file not found.")
    try:
        with _open_text(path) as f:
            header_line = f.readline()
            text = f.read()
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as e:  # zlib: damaged .gz
        raise DataError(f"{path}: cannot read {what} file ({e}).") from e
    header = [h.strip() for h in header_line.strip().split(delimiter)]
    if columns is None:
        if n_expected is not None and len(header) != n_expected:
            raise DataError(
                f"{path}: {what} file has {len(header)} columns ({', '.join(header)}), expected "
                f"{n_expected} (one per joint); list the columns to use in the config."
            )
        index = list(range(len(header)))
        names = header
    else:
        missing = [c for c in columns if c not in header]
        if missing:
            raise DataError(
                f"{path}: column '{missing[0]}' not found; the header has {', '.join(header)}."
            )
        index = [header.index(c) for c in columns]
        names = list(columns)
    numbered = [(k + 2, line) for k, line in enumerate(text.splitlines()) if line.strip()]
    if not numbered:
        raise DataError(f"{path}: {what} file has a header but no samples.")
    line_no = np.array([n for n, _ in numbered], dtype=np.int64)
    rows = [line for _, line in numbered]
    try:
        data = np.loadtxt(rows, delimiter=delimiter, ndmin=2, dtype=float)
    except ValueError as e:
        raise _bad_row(path, header, numbered, delimiter) from e
    if data.shape[1] != len(header):
        raise DataError(
            f"{path}: rows have {data.shape[1]} fields, the header has {len(header)} columns."
        )
    data = data[:, index]
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise DataError(
            f"{path}: column '{names[col]}' has {int(bad[:, col].sum())} NaN/inf value(s), the "
            f"first on line {line_no[row]}; clean or trim the log."
        )
    return data, names, line_no


def _bad_row(
    path: Path, header: list[str], numbered: list[tuple[int, str]], delimiter: str
) -> DataError:
    """The error for the first line that numpy could not read: field count or a non-number."""
    for n, line in numbered:
        fields = line.split(delimiter)
        if len(fields) != len(header):
            return DataError(
                f"{path}: line {n} has {len(fields)} fields, the header has {len(header)} columns."
            )
        for j, cell in enumerate(fields):
            try:
                float(cell)
            except ValueError:
                return DataError(
                    f"{path}: line {n}, column '{header[j]}' (field {j + 1}): "
                    f"{cell.strip()!r} is not a number; clean or trim the log."
                )
    return DataError(f"{path}: a value could not be read as a number.")  # pragma: no cover


@dataclass(frozen=True, eq=False)
class RobotLog:
    """A log converted to joint-side SI signals.

    Attributes
    ----------
    t :
        Time [s], shape (n_samples,), starting at 0, uniform.
    q :
        Joint angles [rad], shape (n_samples, n_joints).
    tau :
        Joint torques [N*m], shape (n_samples, n_joints).
    sampling_rate_hz :
        Sampling rate [Hz].
    joint_names :
        Model joint names, in column order.
    records :
        Human-readable description of every conversion applied, for the report.
    """

    t: FloatArray
    q: FloatArray
    tau: FloatArray
    sampling_rate_hz: float
    joint_names: tuple[str, ...]
    records: tuple[dict, ...] = field(default_factory=tuple)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


def _time_base(cfg: LogConfig, n_samples: int) -> tuple[FloatArray, float, str]:
    if cfg.time is None:
        assert cfg.sampling_rate_hz is not None  # guaranteed by LogConfig validation
        fs = float(cfg.sampling_rate_hz)
        return np.arange(n_samples) / fs, fs, f"sampling rate {fs:g} Hz (no time column)"
    data, _, line_no = _read_csv_lines(cfg.time.path, [cfg.time.column], what="time")
    t = data[:, 0]
    if t.shape[0] != n_samples:
        raise DataError(
            f"{cfg.time.path}: time column '{cfg.time.column}' has {t.shape[0]} samples, the "
            f"signals have {n_samples}."
        )
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0])
        raise DataError(
            f"{cfg.time.path}: time column '{cfg.time.column}' is not strictly increasing at "
            f"line {line_no[k + 1]} ({t[k]:g} s then {t[k + 1]:g} s); sort or clean the log."
        )
    step = float(np.median(dt))
    if np.max(np.abs(dt - step)) > _UNIFORM_RTOL * step:
        raise DataError(
            f"{cfg.time.path}: time column '{cfg.time.column}' is not uniformly sampled "
            f"(intervals {dt.min():g} to {dt.max():g} s); resample the log first."
        )
    return t - t[0], 1.0 / step, f"time column '{cfg.time.column}', {1.0 / step:g} Hz"


def read_log(
    cfg: LogConfig,
    transmission: TransmissionConfig,
    joint_names: list[str] | tuple[str, ...],
    *,
    source: str = "config",
) -> RobotLog:
    """Read the log of a config and convert it to joint-side SI signals.

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
        For an inconsistent transmission.
    """
    n_joints = len(joint_names)

    def read(signal: SignalFile, what: str) -> FloatArray:
        data, _ = read_csv_columns(
            signal.path, signal.columns, n_expected=n_joints, delimiter=signal.delimiter, what=what
        )
        if data.shape[1] != n_joints:
            raise DataError(
                f"{signal.path}: {len(signal.columns or [])} {what} columns listed, the robot "
                f"has {n_joints} joints ({', '.join(joint_names)})."
            )
        return data

    q_raw = read(cfg.position, "position")
    tau_raw = read(cfg.torque, "torque")
    if q_raw.shape[0] != tau_raw.shape[0]:
        raise DataError(
            f"{cfg.position.path} has {q_raw.shape[0]} samples but {cfg.torque.path} has "
            f"{tau_raw.shape[0]}; the signals must be sampled together."
        )
    if cfg.max_samples is not None:
        q_raw, tau_raw = q_raw[: cfg.max_samples], tau_raw[: cfg.max_samples]
    t, fs, time_note = _time_base(cfg, q_raw.shape[0])
    records: list[dict] = [
        {
            "step": "read",
            "detail": f"{q_raw.shape[0]} samples x {n_joints} joints from "
            f"{Path(cfg.position.path).name} and {Path(cfg.torque.path).name}; {time_note}",
        }
    ]
    if cfg.position_unit == "deg":
        q_raw = np.deg2rad(q_raw)
        records.append({"step": "units", "detail": "positions deg -> rad"})
    if cfg.torque_unit == "A" and transmission.torque_constants is None:
        raise ConfigError(
            f"{source}: log.torque_unit = A needs transmission.torque_constants [N*m/A], one "
            "per joint."
        )
    trans = transmission_from_config(transmission, n_joints, side=cfg.side, source=source)
    q = trans.joint_positions(q_raw)
    tau = trans.joint_torques(tau_raw)
    records.append(
        {
            "step": "transmission",
            "detail": f"{cfg.side}-side signals; q = Rq^-1 q_motor + offsets, tau = Rt (k y); "
            f"Rq = {_matrix(trans.position_matrix)}; "
            f"Rt = {_matrix(trans.torque_matrix)}; "
            f"k = {trans.torque_constants.tolist()}; "
            f"zero offsets [rad] = {trans.zero_offsets.tolist()}",
        }
    )
    return RobotLog(
        t=t,
        q=q,
        tau=tau,
        sampling_rate_hz=fs,
        joint_names=tuple(joint_names),
        records=tuple(records),
    )
