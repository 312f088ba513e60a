"""Schema of an ``ident fleet`` config: the robot model, the log layout every unit's logs
share, the units (a list, or a folder and a glob: one unit per file) and a ``fleet:`` section.

Example::

    name: ur5-site-a
    robot: {urdf: ur5.urdf}
    log:                                   # the layout of every unit's logs (no path)
      time: {column: t}
      position: {columns: [q/0, q/1, q/2, q/3, q/4, q/5]}
      torque: {columns: [tau/0, tau/1, tau/2, tau/3, tau/4, tau/5]}
    units: {folder: logs, glob: "*.npz"}   # or [{name: u01, logs: [a.npz, b.npz]}, ...]
    model: {rotor_inertia: true, offset: true}
    fleet:
      scheduler: null          # tcp://HOST:8786 for a running cluster; null: a LocalCluster
      workers: 2               # the LocalCluster's worker processes (one thread each)
      window_s: 60             # a chunk task and a window of the drift report [s]
      baseline_s: 600          # each unit's first seconds of motion: its drift reference
      false_alarm: 0.01        # per test: units flagged vs the fleet, windows vs the baseline

Every path is relative to the config file. A unit's logs are in time order; its motion time
runs on from one log to the next.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, PositiveFloat

from ident.config import StrictModel, load_config_file
from ident.errors import ConfigError
from ident.identify.config import resolve_log
from ident.identify.streaming.fleet import ChunkSettings
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.model.selection import RobotSelection

__all__ = [
    "FleetConfig",
    "FleetModel",
    "FleetSection",
    "UnitEntry",
    "UnitFolder",
    "load_fleet_config",
]


class UnitEntry(StrictModel):
    """One unit: its name and its logs (in time order)."""

    name: str = Field(min_length=1)
    logs: list[Path] = Field(min_length=1)


class UnitFolder(StrictModel):
    """One unit per file of ``folder`` matching ``glob``, named by the file's stem."""

    folder: Path
    glob: str = Field(default="*", min_length=1)


class FleetModel(StrictModel):
    """Which columns beyond the rigid bodies: viscous and Coulomb friction always (per unit),
    ``offset`` (per unit) and ``rotor_inertia`` (shared: one motor model)."""

    rotor_inertia: bool = True
    offset: bool = True


class FleetSection(StrictModel):
    """``fleet:``: the cluster, the rows (:class:`~ident.identify.streaming.fleet.
    ChunkSettings`) and the drift report's settings."""

    scheduler: str | None = None
    workers: int = Field(default=2, ge=1, le=256)
    processes: bool = True
    window_s: PositiveFloat = 60.0
    cutoff_hz: PositiveFloat = 20.0
    decimation: int = Field(default=20, ge=1, le=1000)
    velocity_threshold: float = Field(default=0.2, ge=0.0)
    baseline_s: PositiveFloat = 600.0
    false_alarm: float = Field(default=0.01, gt=0.0, lt=0.5)
    logs_in_flight: int = Field(default=4, ge=1, le=1024)

    def chunk_settings(self) -> ChunkSettings:
        """The rows' settings."""
        return ChunkSettings(
            cutoff_hz=self.cutoff_hz,
            decimation=self.decimation,
            velocity_threshold=self.velocity_threshold,
        )


class FleetConfig(StrictModel):
    """An ``ident fleet`` config (module docstring)."""

    name: str = "fleet"
    robot: RobotSelection
    log: LogConfig
    transmission: TransmissionConfig = Field(default_factory=TransmissionConfig)
    model: FleetModel = Field(default_factory=FleetModel)
    units: list[UnitEntry] | UnitFolder
    fleet: FleetSection = Field(default_factory=FleetSection)
    source: Path | None = None

    def unit_logs(self) -> list[tuple[str, list[LogConfig]]]:
        """Per unit, its name and one complete log section per log file."""
        assert isinstance(self.units, list)  # load_fleet_config expands a folder
        return [
            (u.name, [self.log.model_copy(update={"path": p}) for p in u.logs]) for u in self.units
        ]


def _expand(units: list[UnitEntry] | UnitFolder, base: Path, path: Path) -> list[UnitEntry]:
    """The units with absolute, existing log paths (a folder expanded)."""
    if isinstance(units, UnitFolder):
        folder = units.folder if units.folder.is_absolute() else base / units.folder
        if not folder.is_dir():
            raise ConfigError(f"{path}: units.folder = {folder}: no such folder; fix the path.")
        files = sorted(f for f in folder.glob(units.glob) if f.is_file())
        if not files:
            raise ConfigError(
                f"{path}: units.glob = {units.glob!r}: no file in {folder} matches; fix the "
                "glob or the folder."
            )
        return [UnitEntry(name=f.stem, logs=[f]) for f in files]
    out, seen = [], set()
    for k, u in enumerate(units):
        if u.name in seen:
            raise ConfigError(f"{path}: units[{k}].name = {u.name!r} is used twice; rename one.")
        seen.add(u.name)
        logs = [p if p.is_absolute() else base / p for p in u.logs]
        for n, p in enumerate(logs):
            if not p.is_file():
                raise ConfigError(
                    f"{path}: units[{k}].logs[{n}] = {p}: file not found; fix the path."
                )
        out.append(UnitEntry(name=u.name, logs=logs))
    return out


#: Baseline windows the drift test needs: a baseline window is calibrated on the two others.
MIN_BASELINE_WINDOWS = 3


def _check_baseline(fleet: FleetSection, path: Path) -> None:
    """Refuse a baseline too short for the friction-over-time test: each window's rise is
    scaled by the scatter of at least two other baseline windows, so a baseline of fewer than
    :data:`MIN_BASELINE_WINDOWS` windows would leave its own windows (or every window) untested."""
    if fleet.baseline_s < MIN_BASELINE_WINDOWS * fleet.window_s:
        raise ConfigError(
            f"{path}: fleet.baseline_s = {fleet.baseline_s:g} s holds fewer than "
            f"{MIN_BASELINE_WINDOWS} windows of fleet.window_s = {fleet.window_s:g} s (the drift "
            "test calibrates each window on two others of the baseline); set baseline_s to at "
            f"least {MIN_BASELINE_WINDOWS * fleet.window_s:g} s or shorten window_s."
        )


def load_fleet_config(path: str | Path) -> FleetConfig:
    """Load an ``ident fleet`` config; paths made absolute, the units' files checked.

    Raises
    ------
    ConfigError
        Naming the file and key: malformed entries, missing files, no unit.
    """
    path = Path(path)
    cfg = load_config_file(FleetConfig, path)
    base = path.resolve().parent
    if cfg.log.path is not None or cfg.log.files or cfg.log.more:
        raise ConfigError(
            f"{path}: log: the units name the log files; remove log.path, log.files and "
            "log.more (log: holds the layout every log shares)."
        )
    if isinstance(cfg.units, list) and not cfg.units:
        raise ConfigError(f"{path}: units: no unit; list at least one (or give folder and glob).")
    _check_baseline(cfg.fleet, path)
    robot = cfg.robot.resolved(base)
    if not robot.path.exists():
        key = "robot.urdf" if robot.urdf is not None else "robot.description"
        raise ConfigError(f"{path}: {key} = {robot.path}: file not found; fix the path.")
    units = _expand(cfg.units, base, path)
    return cfg.model_copy(
        update={"robot": robot, "log": resolve_log(cfg.log, base), "units": units, "source": path}
    )
