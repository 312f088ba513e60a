"""Schema of an ``ident identify`` config: robot, log files, transmission, processing, model.

Every physical quantity is converted to SI here or in :mod:`ident.identify.logs` (degrees to
radians, amperes to N*m through the torque constants), once. Paths are relative to the config
file. Example (``configs/tx40.yaml``)::

    name: tx40
    robot: {urdf: ../data/staubli-tx40/urdf/tx40_mdh_modified.urdf}
    log:
      sampling_rate_hz: 5000.0
      position: {path: ../data/staubli-tx40/data/pos_read_data.csv.gz}
      torque: {path: ../data/staubli-tx40/data/curr_data.csv.gz}
    transmission:
      gear_ratios: [32, 32, 45, -48, 45, 32]
      coupling: [{motor: 6, joint: 5, ratio: 32}]
      zero_offsets: [0, -1.5707963267948966, 1.5707963267948966, 0, 0, 0]
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel, load_config_file
from ident.errors import ConfigError

__all__ = [
    "CouplingEntry",
    "EssentialConfig",
    "EstimationConfig",
    "FilterConfig",
    "IdentifyConfig",
    "LogConfig",
    "ModelConfig",
    "PreprocessConfig",
    "ReferenceConfig",
    "RobotConfig",
    "SignalFile",
    "TimeColumn",
    "TransmissionConfig",
    "UrdfUpdateConfig",
    "ValidationConfig",
    "load_identify_config",
]


class RobotConfig(StrictModel):
    """The robot model: a URDF and, optionally, the joints the log columns map to (in order)."""

    urdf: Path
    joints: list[str] | None = None


class SignalFile(StrictModel):
    """One CSV file (plain or ``.gz``) holding one signal for every joint.

    ``columns`` names the header columns in joint order; ``null`` takes every column (their
    count must equal the number of joints). Several signals may share one wide file.
    """

    path: Path
    columns: list[str] | None = None
    delimiter: str = Field(",", min_length=1, max_length=1)  # np.loadtxt: one character


class TimeColumn(StrictModel):
    """A time column [s] (strictly increasing, uniform sampling)."""

    path: Path
    column: str


class LogConfig(StrictModel):
    """Where the measured signals are and in which units."""

    position: SignalFile
    torque: SignalFile
    time: TimeColumn | None = None
    sampling_rate_hz: float | None = Field(default=None, gt=0.0)
    position_unit: Literal["rad", "deg"] = "rad"
    torque_unit: Literal["N*m", "A"] = "N*m"
    side: Literal["motor", "joint"] = "joint"
    max_samples: int | None = Field(default=None, gt=0)

    @model_validator(mode="after")
    def _one_time_base(self) -> LogConfig:
        if (self.time is None) == (self.sampling_rate_hz is None):
            raise ValueError(
                "give exactly one of log.time (a time column) and log.sampling_rate_hz"
            )
        return self


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


class FilterConfig(StrictModel):
    """Zero-phase Butterworth low-pass filter on the joint positions."""

    cutoff_hz: float = Field(gt=0.0)
    order: int = Field(default=4, ge=1, le=10)


class PreprocessConfig(StrictModel):
    """Signal processing before the regressor is built (see :mod:`ident.identify.preprocess`)."""

    lowpass: FilterConfig | None = None
    torque_lowpass: FilterConfig | None = None
    trim_samples: int = Field(default=20, ge=0)
    decimation: list[int] = Field(default_factory=list)
    velocity_threshold: list[float] | None = None

    @field_validator("decimation")
    @classmethod
    def _factors(cls, value: list[int]) -> list[int]:
        if any(f < 1 for f in value):
            raise ValueError("decimation factors must be >= 1")
        return value


class ModelConfig(StrictModel):
    """Parameters beyond the rigid bodies (see :mod:`ident.dynamics.friction`).

    Per-joint options take ``true`` (all joints), ``false`` or a list of 1-based joints.
    ``coupled_wrist`` names the two joints whose motor is shared (TX40: ``[5, 6]``).
    """

    viscous: bool | list[int] = True
    coulomb: bool | list[int] = True
    offset: bool | list[int] = True
    rotor_inertia: bool | list[int] = True
    coupled_wrist: list[int] | None = None

    @field_validator("coupled_wrist")
    @classmethod
    def _pair(cls, value: list[int] | None) -> list[int] | None:
        if value is not None and len(value) != 2:
            raise ValueError("coupled_wrist takes two 1-based joints, e.g. [5, 6]")
        return value


class EssentialConfig(StrictModel):
    """Essential-parameter reduction (see :mod:`ident.identify.essential`)."""

    enabled: bool = True
    max_relative_std_pct: float = Field(default=10.0, gt=0.0)
    max_residual_increase: float = Field(default=0.05, ge=0.0)


class EstimationConfig(StrictModel):
    """Estimator choice."""

    method: Literal["ols", "wls"] = "wls"
    essential: EssentialConfig = Field(default_factory=EssentialConfig)


class ValidationConfig(StrictModel):
    """Time split: the first ``identify_fraction`` of the log identifies, the rest validates.

    The identified parameters are checked on the held-out part (rows above the velocity
    threshold): a relative residual worse than the URDF's nominal parameters', or above
    ``max_relative_residual`` when given, is a warning in the terminal, the report and
    ``result.json``. ``fail_on_warning: true`` makes ``ident identify`` exit with code 1 after
    writing the run folder (default: exit 0, the warning is reported).
    """

    identify_fraction: float = Field(default=0.7, gt=0.0, le=1.0)
    max_relative_residual: float | None = Field(default=None, gt=0.0)
    fail_on_warning: bool = False


class ReferenceConfig(StrictModel):
    """Published reference base parameters (CSV: expression, OLS value, OLS rel. std %, WLS
    value, WLS rel. std %, no header) to compare with."""

    base_parameters: Path | None = None
    essential_parameters: Path | None = None
    column: Literal["ols", "wls"] = "wls"


class UrdfUpdateConfig(StrictModel):
    """Writing identified inertial parameters into a copy of the URDF
    (see :mod:`ident.identify.urdf_update`).

    Only standard parameters that a base parameter determines alone and whose relative standard
    deviation is below ``max_relative_std_pct`` are written; a link that would become physically
    inconsistent keeps its nominal inertial.
    """

    max_relative_std_pct: float = Field(default=10.0, gt=0.0)


class IdentifyConfig(StrictModel):
    """Everything ``ident identify`` needs."""

    name: str = "identify"
    robot: RobotConfig
    log: LogConfig
    transmission: TransmissionConfig = Field(default_factory=TransmissionConfig)
    preprocess: PreprocessConfig = Field(default_factory=PreprocessConfig)
    model: ModelConfig = Field(default_factory=ModelConfig)
    estimation: EstimationConfig = Field(default_factory=EstimationConfig)
    validation: ValidationConfig = Field(default_factory=ValidationConfig)
    reference: ReferenceConfig = Field(default_factory=ReferenceConfig)
    urdf_update: UrdfUpdateConfig = Field(default_factory=UrdfUpdateConfig)
    source: Path | None = None


def _resolve(path: Path | None, base: Path) -> Path | None:
    if path is None:
        return None
    path = Path(path).expanduser()
    return path if path.is_absolute() else (base / path)


def load_identify_config(path: str | Path) -> IdentifyConfig:
    """Load an identify config; make its paths absolute (relative to the config file).

    Raises
    ------
    ConfigError
        Naming the file and key, for malformed or missing entries and missing files.
    """
    path = Path(path)
    cfg = load_config_file(IdentifyConfig, path)
    base = path.resolve().parent
    log = cfg.log.model_copy(
        update={
            "position": cfg.log.position.model_copy(
                update={"path": _resolve(cfg.log.position.path, base)}
            ),
            "torque": cfg.log.torque.model_copy(
                update={"path": _resolve(cfg.log.torque.path, base)}
            ),
            "time": None
            if cfg.log.time is None
            else cfg.log.time.model_copy(update={"path": _resolve(cfg.log.time.path, base)}),
        }
    )
    reference = cfg.reference.model_copy(
        update={
            "base_parameters": _resolve(cfg.reference.base_parameters, base),
            "essential_parameters": _resolve(cfg.reference.essential_parameters, base),
        }
    )
    robot = cfg.robot.model_copy(update={"urdf": _resolve(cfg.robot.urdf, base)})
    checks = [
        ("robot.urdf", robot.urdf),
        ("log.position.path", log.position.path),
        ("log.torque.path", log.torque.path),
    ]
    if log.time is not None:
        checks.append(("log.time.path", log.time.path))
    for key in ("base_parameters", "essential_parameters"):
        value = getattr(reference, key)
        if value is not None:
            checks.append((f"reference.{key}", value))
    for key, file in checks:
        if not Path(file).is_file():
            raise ConfigError(f"{path}: {key} = {file}: file not found; fix the path.")
    return cfg.model_copy(
        update={"robot": robot, "log": log, "reference": reference, "source": path}
    )
