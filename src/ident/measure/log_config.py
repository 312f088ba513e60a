"""Schema of a log section: the files, columns, units, time base and transmission of a log.

The ``log:`` and ``transmission:`` sections of an ``ident identify`` config (the rest of the
config is :mod:`ident.identify.config`); :mod:`ident.measure.logs` reads what they declare and
converts it to SI, once. Paths are relative to the config file until
:func:`ident.identify.config.resolve_log` makes them absolute.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel

__all__ = [
    "POSITION_UNITS",
    "TORQUE_UNITS",
    "VELOCITY_UNITS",
    "CouplingEntry",
    "LogConfig",
    "LogFile",
    "SignalFile",
    "TimeColumn",
    "TimeWindow",
    "TransmissionConfig",
]


# Units a log may use per signal; ``ident.measure.logs`` converts them to SI once.
POSITION_UNITS = ("rad", "deg", "mrad", "m", "mm", "ticks")
TORQUE_UNITS = ("N*m", "N", "A", "mA")
VELOCITY_UNITS = ("rad/s", "deg/s", "rpm", "m/s", "mm/s", "ticks/s")


class SignalFile(StrictModel):
    """Where one signal (positions, torques or velocities) is, and in which units.

    ``columns`` names the columns in joint order (CSV header names, ``<value>/<joint>`` of a
    long CSV, ``<topic>/position/<joint>`` of a ROS log; ``ident logs inspect`` lists them);
    ``null`` takes every column of ``path`` (their count must equal the number of joints).
    A name that is no column but the group of columns ``<name>/<joint>`` (a LeRobot feature
    such as ``observation.state``) stands for the group: its joints must be the model's, but
    for the ``exclude`` ones (a gripper the URDF does not model).
    ``path`` is optional when the columns are in the log's ``path``/``files``. ``unit`` and
    ``side`` override the log-wide ``*_unit`` and ``side``; ``scale`` (one value or one per
    joint) and ``sign`` (+1/-1 per joint) multiply the values after the unit conversion, and
    ``counts_per_rev`` gives the encoder resolution of ``unit: ticks``, ``zero_tick`` (one
    value or one per joint) the tick of the zero angle (``q = (ticks - zero_tick) 2 pi /
    counts_per_rev``).
    """

    path: Path | None = None
    columns: list[str] | None = None
    delimiter: str | None = Field(None, min_length=1, max_length=1)  # one character
    unit: str | None = None
    side: Literal["motor", "joint"] | None = None
    scale: float | list[float] = 1.0
    sign: list[float] | None = None
    counts_per_rev: float | None = Field(default=None, gt=0.0)
    zero_tick: float | list[float] | None = None
    exclude: list[str] = Field(default_factory=list)

    @field_validator("sign")
    @classmethod
    def _signs(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(v not in (1.0, -1.0) for v in value):
            raise ValueError("sign takes +1 or -1 per joint")
        return value


class TimeColumn(StrictModel):
    """A time column: in ``path`` when given, else in the log's files; ``unit`` s, ms, us, ns.

    Non-uniform steps are resampled (see :mod:`ident.measure.timebase`)."""

    path: Path | None = None
    column: str
    unit: Literal["s", "ms", "us", "ns"] = "s"


class LogFile(StrictModel):
    """One log source and the options of its reader (see :mod:`ident.measure.readers`)."""

    path: Path
    format: str | None = None
    delimiter: str | None = None
    header: bool | None = None
    names: list[str] | None = None
    topics: list[str] | None = None
    joint_column: str | None = None
    time_column: str | None = None


class TimeWindow(StrictModel):
    """A part of the log to use, in seconds from its first sample (``null``: open end)."""

    start_s: float | None = None
    end_s: float | None = None


class LogConfig(StrictModel):
    """Where the measured signals are, in which units, and which parts of the time to use.

    Files: ``path`` (one file or bag; ``format`` optional, detected from the file) and/or
    ``files`` (several, joined on time), and/or a ``path`` per signal (the historic form).
    Time: a ``time`` column, a column the reader recognises (``t``, ``time``, ROS stamps), or
    ``sampling_rate_hz`` for logs without time.

    ``command`` (optional): the commanded positions (a position servo's set point, LeRobot's
    ``action``), read beside the measured ones for an actuator model; every key it omits
    (``unit``, ``counts_per_rev``, ``zero_tick``, ``scale``, ``sign``, ``side``,
    ``exclude``) is the ``position`` signal's. The identification uses it with a position
    servo's actuator model (the identify config's ``actuator: {kind: position}``).

    ``torque`` may be absent only for such a log (a position servo logs no torque: its torque
    is the actuator's law ``kp (q_cmd(t - d) - q) - kd dq``); the identify config checks it.
    """

    path: Path | None = None
    format: str | None = None
    files: list[LogFile] = Field(default_factory=list)
    position: SignalFile
    torque: SignalFile | None = None
    velocity: SignalFile | None = None
    command: SignalFile | None = None
    time: TimeColumn | None = None
    sampling_rate_hz: float | None = Field(default=None, gt=0.0)
    position_unit: str = "rad"
    torque_unit: str = "N*m"
    velocity_unit: str = "rad/s"
    side: Literal["motor", "joint"] = "joint"
    max_samples: int | None = Field(default=None, gt=0)
    windows: list[TimeWindow] = Field(default_factory=list)
    gap_factor: float = Field(default=5.0, gt=1.0)
    max_gap_s: float | None = Field(default=None, gt=0.0)
    resample_hz: float | None = Field(default=None, gt=0.0)
    # further logs of the same robot (other trajectories or days), identified together: each
    # entry is a partial log section, the keys it omits are this section's
    more: list[dict] = Field(default_factory=list)

    def all_logs(self) -> list[LogConfig]:
        """This log and the ``more`` ones, each a complete section (without ``more``)."""
        first = self.model_copy(update={"more": []})
        base = first.model_dump(exclude_defaults=True)
        out = [first]
        for k, entry in enumerate(self.more):
            if entry.get("more"):  # an empty list is what a resolved section holds
                raise ValueError(
                    f"log.more[{k}] holds its own 'more:' list; list every further log "
                    "directly under log.more"
                )
            merged = {**base, **entry}
            if "files" in entry or "path" in entry:  # new files: not the first log's signals'
                for key in ("position", "torque", "velocity", "command"):
                    if key in merged and key not in entry and isinstance(merged[key], dict):
                        merged[key] = {k: v for k, v in merged[key].items() if k != "path"}
            out.append(LogConfig.model_validate(merged))
        return out

    @model_validator(mode="after")
    def _one_time_base(self) -> LogConfig:
        if self.time is not None and self.sampling_rate_hz is not None:
            raise ValueError(
                "give exactly one of log.time (a time column) and log.sampling_rate_hz"
            )
        if self.time is None and self.sampling_rate_hz is None and not self._has_log_files():
            raise ValueError(
                "give exactly one of log.time (a time column) and log.sampling_rate_hz"
            )
        for key, value, allowed in (
            ("position_unit", self.position_unit, POSITION_UNITS),
            ("torque_unit", self.torque_unit, TORQUE_UNITS),
            ("velocity_unit", self.velocity_unit, VELOCITY_UNITS),
            ("position.unit", self.position.unit, POSITION_UNITS),
            ("torque.unit", self.torque.unit if self.torque else None, TORQUE_UNITS),
            ("velocity.unit", self.velocity.unit if self.velocity else None, VELOCITY_UNITS),
            ("command.unit", self.command.unit if self.command else None, POSITION_UNITS),
        ):
            if value is not None and value not in allowed:
                raise ValueError(f"log.{key} = {value!r}; allowed: {', '.join(allowed)}")
        return self

    def command_signal(self) -> SignalFile | None:
        """``command`` with the keys it omits taken from ``position`` (None without one)."""
        if self.command is None:
            return None
        own = self.command.model_dump(exclude_unset=True)
        inherited = self.position.model_dump(exclude={"path", "columns", "delimiter"})
        return SignalFile.model_validate({**inherited, **own})

    def _has_log_files(self) -> bool:
        return self.path is not None or bool(self.files)

    def sources(self) -> list[LogFile]:
        """Every file to read: ``path``, ``files``, then the signals' and time's own paths."""
        out = list(self.files)
        if self.path is not None:
            out.insert(0, LogFile(path=self.path, format=self.format))
        for signal in (self.position, self.torque, self.velocity, self.command):
            if signal is not None and signal.path is not None:
                out.append(LogFile(path=signal.path, delimiter=signal.delimiter))
        if self.time is not None and self.time.path is not None:
            out.append(LogFile(path=self.time.path))
        seen: dict[Path, LogFile] = {}
        for f in out:
            seen.setdefault(Path(f.path), f)
        return list(seen.values())


class CouplingEntry(StrictModel):
    """Off-diagonal term of ``q_motor = Rq q_joint``: motor ``motor`` turns ``ratio`` times per
    radian of joint ``joint`` (1-based indices)."""

    motor: int = Field(ge=1)
    joint: int = Field(ge=1)
    ratio: float


class TransmissionConfig(StrictModel):
    """Motor-to-joint transmission.

    ``q_motor = Rq q_joint`` with ``Rq = diag(gear_ratios)`` plus the ``coupling`` entries.
    Joint torques are ``tau = Rt (k * y)`` with ``k`` the ``torque_constants`` [N*m/A] (for a
    current signal) and ``Rt = Rq^T`` (power balance) unless ``torque_matrix`` is given.
    ``zero_offsets`` [rad] are added to the joint angles afterwards (model zero minus the
    robot's zero).
    """

    gear_ratios: list[float] | None = None
    coupling: list[CouplingEntry] = Field(default_factory=list)
    torque_matrix: list[list[float]] | None = None
    torque_constants: list[float] | None = None
    zero_offsets: list[float] | None = None

    @field_validator("gear_ratios")
    @classmethod
    def _nonzero(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(r == 0.0 for r in value):
            raise ValueError("gear ratios must be non-zero")
        return value
