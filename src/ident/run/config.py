"""Schema of the run configs (``configs/wrist.yaml``, ``configs/arm.yaml``).

A run config describes one identification stage end to end: the robot, the stage, the
excitation family with its variable bounds, the optimizer procedure of the paper (initial
elites, then eMuPSO runs), the simulated measurement noise and the estimator. Defaults are
the paper's settings (section 4.1): elites from a 10-particle constraint-compliance swarm
until 5 are found, eMuPSO with 20 particles, 30 iterations, G = 10, 5 runs.

Units: SI throughout (m, rad, s, N*m); the variables of an excitation family (and the
``excitation.bounds`` that override their search box) are in the family's own units, as
documented by the family. Relative paths are resolved against the directory of the config
file.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Field, field_validator, model_validator

from ident.config import StrictModel, file_problem, load_config_file, read_yaml
from ident.errors import ConfigError, OptimizationError
from ident.excitation.registry import check_family_name
from ident.excitation.safety import SafetyConfig
from ident.identify.config import (
    EssentialConfig,
    EstimationConfig,
    ModelConfig,
    PreprocessConfig,
    RefinementConfig,
    ValidationConfig,
    refinement_shorthand,
)
from ident.identify.estimators.registry import get_contract, get_estimator
from ident.inputs import read_urdf_text
from ident.measure.mujoco_config import MujocoMeasurement
from ident.model.selection import RobotSelection
from ident.optim import METHODS
from ident.run.examples import missing_section_hint
from ident.run.exports.registry import check_export_names

__all__ = [
    "ElitesSection",
    "EmupsoSection",
    "EstimationSection",
    "ControllerSection",
    "ExcitationSection",
    "LogIdentificationSection",
    "MeasurementSection",
    "QuickSection",
    "RunConfig",
    "StageSection",
    "load_run_config",
]

CRITERIA = ("paper", "logdet")
MM = 1e-3  # m per mm


def _check_bound(value: tuple[float, float]) -> tuple[float, float]:
    """A search interval ``[low, high]``: finite and ``low < high``."""
    low, high = value
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f"bounds must be finite numbers [low, high], got [{low}, {high}]")
    if not low < high:
        raise ValueError(f"bounds must satisfy low < high, got [{low}, {high}]")
    return value


# One ``[low, high]`` pair; a bad pair is reported under its key ``excitation.bounds.<name>``.
Bound = Annotated[tuple[float, float], AfterValidator(_check_bound)]


class ExcitationSection(StrictModel):
    """Excitation trajectory family, its options and the search box of its variables.

    Attributes
    ----------
    family :
        A registered family (:mod:`ident.excitation.registry`): ``joint_fourier`` (joint-space
        finite Fourier series, any chain) or ``paper_wrist`` / ``paper_arm`` (the paper's
        Cartesian modified Fourier series, eq. 16-23, for its two stages).
    criterion :
        ``paper`` (eq. 15 on the scaled base observation matrix) or ``logdet``.
    n_samples :
        Samples per period of the trajectory.
    options :
        Further keyword arguments of the family (see ``docs/excitation.md``), passed through.
    bounds :
        Optional search box per variable, ``{name: [low, high]}``, overriding the family's
        defaults (the paper: +-10). Units are the family's variable units. Each pair must be
        finite with ``low < high``; the names are checked against the family's variables
        by :func:`load_run_config`, before anything runs.
    """

    family: str
    criterion: Literal["paper", "logdet"] = "paper"
    n_samples: int = Field(default=500, ge=16, le=1_000_000)
    options: dict[str, Any] = Field(default_factory=dict)
    bounds: dict[str, Bound] | None = None

    @field_validator("family")
    @classmethod
    def _registered(cls, value: str) -> str:
        try:
            return check_family_name(value)
        except ConfigError as e:
            raise ValueError(str(e).removeprefix(f"excitation.family '{value}' ")) from e


class ElitesSection(StrictModel):
    """Initial elites: a constraint-compliance PSO swarm (paper section 4.1)."""

    n_particles: int = Field(default=10, ge=2, le=10_000)
    n_elites: int = Field(default=5, ge=1, le=1000)
    maxiter: int = Field(default=100, ge=1, le=100_000)


class EmupsoSection(StrictModel):
    """eMuPSO runs started from the elites by Gaussian mutation.

    Attributes
    ----------
    n_particles :
        Swarm size (paper: 20).
    maxiter :
        Iterations per run (default 150; paper: 30).
    stagnation :
        Stagnation threshold G of eq. 7 (paper: 10).
    n_runs :
        Independent runs (default 1; paper: 5), each with its own child random stream. The
        default, one run of 150 iterations (3020 evaluations with 20 particles), was chosen
        with ``benchmarks/bench_excitation.py --split both`` (``docs/optimizers.md``): on the
        joint-space Fourier problems one long run beat five short ones for every method.
    sigma_fraction :
        Standard deviation of the Gaussian mutation that spawns the swarm from the elites,
        as a fraction of each variable's search range.
    n_report_elites :
        How many of the best distinct feasible archive members are measured, identified and
        tabulated (the paper's Tables 2-3 show 6).
    options :
        Further keyword arguments of ``ident.optim.minimize(method="emupso")``.
    """

    n_particles: int = Field(default=20, ge=2, le=10_000)
    maxiter: int = Field(default=150, ge=1, le=100_000)
    stagnation: int = Field(default=10, ge=1, le=100_000)
    n_runs: int = Field(default=1, ge=1, le=1000)
    sigma_fraction: float = Field(default=0.1, gt=0.0, le=1.0)
    n_report_elites: int = Field(default=6, ge=1, le=100)
    options: dict[str, Any] = Field(default_factory=dict)

    @field_validator("options")
    @classmethod
    def _known_options(cls, value: dict[str, Any]) -> dict[str, Any]:
        # names and types now, not after the run folder exists (also for quick.emupso)
        from ident.optim import method_defaults
        from ident.optim._common import check_options

        try:
            check_options("emupso", value, method_defaults("emupso"))
        except OptimizationError as e:
            raise ValueError(str(e)) from e
        return value


class MeasurementSection(StrictModel):
    """``measurement: {source: ideal, ...}``: Pinocchio's RNEA on the true parameters plus
    noise (see :mod:`ident.measure.ideal`); the default source.

    Attributes
    ----------
    torque_noise_std :
        Gaussian torque noise [N*m]: one value for all joints or one per robot joint.
    encoder_counts_per_rev :
        Encoder resolution; ``null`` measures q, dq, ddq exactly.
    filter_cutoff_hz :
        Low-pass cut-off before numerical differentiation of encoder positions; ``null``: none.
    """

    source: Literal["ideal"] = "ideal"
    torque_noise_std: float | list[float] = 0.0
    encoder_counts_per_rev: int | None = Field(default=None, ge=1)
    filter_cutoff_hz: float | None = Field(default=None, gt=0.0)

    @field_validator("torque_noise_std")
    @classmethod
    def _non_negative(cls, value: float | list[float]) -> float | list[float]:
        values = value if isinstance(value, list) else [value]
        if any(not v >= 0.0 for v in values):
            raise ValueError("torque noise standard deviations must be >= 0 N*m")
        return value


def _registered_estimator(name: str) -> str:
    """``name`` if the estimator registry knows it (a ValueError naming the known ones)."""
    try:
        get_estimator(name)
    except ConfigError as e:
        raise ValueError(str(e)) from e
    return name


class EstimationSection(StrictModel):
    """Least-squares estimation of the stage's base parameters.

    Attributes
    ----------
    methods :
        Estimators to report, names of the estimator registry
        (:mod:`ident.identify.estimators`: ``ols``, ``wls``, ``lmi``, ``log_cholesky`` or a
        registered one); OLS and WLS are always computed, at most one other estimator is run.
    base_method :
        Base-parameter reduction: ``qr`` (QR with column pivoting) or ``sequential``
        (the paper's column-by-column rank test).
    """

    methods: list[Annotated[str, AfterValidator(_registered_estimator)]] = ["ols", "wls"]
    base_method: Literal["qr", "sequential"] = "qr"

    @field_validator("methods")
    @classmethod
    def _at_most_one_other(cls, value: list[str]) -> list[str]:
        if not value:
            raise ValueError("give at least one estimator (ols, wls)")
        value = list(dict.fromkeys(value))
        others = [m for m in value if not get_contract(m).least_squares]
        if len(others) > 1:
            raise ValueError(
                f"at most one estimator besides ols and wls, got {', '.join(others)}; keep one"
            )
        return value


#: ``measurement.source``: ``ideal`` (RNEA + noise, the default) or ``mujoco`` (closed-loop
#: simulation writing a controller-like log, identified like a measured log).
Measurement = Annotated[MeasurementSection | MujocoMeasurement, Field(discriminator="source")]


class LogIdentificationSection(StrictModel):
    """How a simulated log (``measurement.source: mujoco``) is identified: the sections of an
    ``ident identify`` config, which the run writes next to the log (``identify.yaml``)."""

    preprocess: PreprocessConfig = PreprocessConfig()
    model: ModelConfig = ModelConfig(offset=False)
    estimation: EstimationConfig = EstimationConfig(essential=EssentialConfig(enabled=False))
    validation: ValidationConfig = ValidationConfig()
    refinement: RefinementConfig = RefinementConfig()

    @field_validator("refinement", mode="before")
    @classmethod
    def _method_shorthand(cls, value: object) -> object:
        return refinement_shorthand(value)


class ControllerSection(StrictModel):
    """The trajectory a controller runs (``trajectory.csv``): rate, periods, home posture.

    Attributes
    ----------
    rate_hz :
        Controller rate [Hz] of ``trajectory.csv``.
    n_periods :
        Excitation periods between the approach from home and the return to it.
    home :
        Home posture [rad or m], one value per joint; ``null``: the excitation's start
        posture (the approach then only brings the robot up to speed).
    export :
        Controller files written besides ``trajectory.csv`` into ``<run>/exports/``, from
        :mod:`ident.run.exports.registry` (``ros2``, ``urscript``, ``franka``; see
        ``docs/execute.md``); default none.
    """

    rate_hz: float = Field(default=1000.0, gt=0.0, le=100_000.0, allow_inf_nan=False)
    n_periods: int = Field(default=1, ge=1, le=1000)
    home: list[float] | None = None
    export: list[str] = Field(default_factory=list)

    @field_validator("export")
    @classmethod
    def _registered_exports(cls, value: list[str]) -> list[str]:
        try:
            return check_export_names(value)
        except ConfigError as e:
            raise ValueError(str(e).removeprefix("controller.export: ")) from e


class QuickSection(StrictModel):
    """Small settings for ``--quick``: a first look in seconds."""

    elites: ElitesSection = ElitesSection(n_particles=6, n_elites=2, maxiter=30)
    emupso: EmupsoSection = EmupsoSection(
        n_particles=8, maxiter=6, stagnation=3, n_runs=2, n_report_elites=2
    )
    n_samples: int = Field(default=120, ge=16, le=1_000_000)


class StageSection(StrictModel):
    """A custom stage: which joints move, where the others are held, which bodies are unknown.

    Attributes
    ----------
    moving :
        Joint names that move; their torques are used.
    held :
        Positions of held joints [rad or m]; default 0.618 of each joint's range.
    bodies :
        Joints whose bodies are unknown; default every body from the first moving joint on.
    name :
        Label in the report.
    """

    moving: list[str]
    held: dict[str, float] = {}
    bodies: list[str] | None = None
    name: str = "custom"


class RunConfig(StrictModel):
    """A whole ``ident run`` config.

    Attributes
    ----------
    name :
        Run name, the prefix of the run folder; defaults to the config file's stem.
    robot :
        The robot selection (:mod:`ident.model.selection`): a DH description (``.yaml``) or
        a URDF path relative to this config file, or a mapping with the chain to identify.
    stage :
        Stage to identify: ``whole`` (every joint moves, every body is unknown: the default),
        ``wrist`` / ``arm`` (the paper's two stages of a 6R arm with a spherical wrist), or a
        custom stage (:class:`StageSection`).
    seed :
        Seed of every random draw of the run.
    optimizer :
        Method of ``ident.optim.minimize`` for the runs started from the elites: ``pso`` (the
        default: the best on the robots from a URDF, UR5 and Panda, and shared-best with CMA-ES
        over all of ident's excitation problems, docs/optimizers.md), ``emupso``
        (the paper's, with the ``emupso`` section's options; the paper's configs use it) or
        any registered method (``pso``, ``de``, ...; options in ``optimizer_options``). The
        swarm size, iterations and runs come from the ``emupso`` section for every method.
    safety :
        The collision, floor, obstacle and torque constraints (docs/safety.md). Given, they
        enter the optimization; absent, the defaults (floor at z = 0, self-collision, 0.03 m)
        still decide, at the controller's rate, which reported trajectory is usable.
    controller :
        Rate, periods and home posture of ``trajectory.csv`` (:class:`ControllerSection`).
    """

    name: str | None = None
    robot: RobotSelection
    stage: str | StageSection = "whole"
    seed: int = Field(default=0, ge=0)
    excitation: ExcitationSection
    elites: ElitesSection = ElitesSection()
    emupso: EmupsoSection = EmupsoSection()
    optimizer: str = "pso"
    optimizer_options: dict[str, Any] = Field(default_factory=dict)
    safety: SafetyConfig | None = None
    controller: ControllerSection = ControllerSection()
    measurement: Measurement = MeasurementSection()
    estimation: EstimationSection = EstimationSection()
    identification: LogIdentificationSection = LogIdentificationSection()
    quick: QuickSection = QuickSection()

    @staticmethod
    def missing_key_hint(key: str) -> str:
        """A working example of a missing section (read by the loader's message)."""
        return missing_section_hint(key)

    @field_validator("optimizer")
    @classmethod
    def _known_method(cls, value: str) -> str:
        if value not in METHODS:
            close = difflib.get_close_matches(value, list(METHODS), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ValueError(f"unknown optimizer; {hint}methods: {', '.join(METHODS)}")
        return value

    @model_validator(mode="before")
    @classmethod
    def _default_source(cls, data: Any) -> Any:
        """A ``measurement`` section without ``source`` is the ideal one."""
        if isinstance(data, dict) and isinstance(data.get("measurement"), dict):
            data = {**data, "measurement": {"source": "ideal", **data["measurement"]}}
        return data

    def quick_version(self) -> RunConfig:
        """The same run with the ``quick`` settings (``--quick``)."""
        excitation = self.excitation.model_copy(update={"n_samples": self.quick.n_samples})
        return self.model_copy(
            update={
                "elites": self.quick.elites,
                "emupso": self.quick.emupso,
                "excitation": excitation,
            }
        )

    def with_package_dirs(self, package_dirs: list[Path]) -> RunConfig:
        """The same run with ``package_dirs`` (``--package-dir``, absolute) searched for the
        URDF's ``package://`` meshes before ``robot.package_dirs``."""
        if not package_dirs:
            return self
        robot = self.robot.model_copy(
            update={"package_dirs": [*package_dirs, *self.robot.package_dirs]}
        )
        return self.model_copy(update={"robot": robot})

    def with_seed(self, seed: int) -> RunConfig:
        """The same run with another seed (``--seed``)."""
        if seed < 0:
            raise ConfigError(f"--seed must be >= 0, got {seed}")
        return self.model_copy(update={"seed": int(seed)})


def load_run_config(path: str | Path) -> RunConfig:
    """Load a run config; resolve the robot paths and fill the name from the file stem.

    Only the file is checked here (keys, values, the robot file exists); the robot, the stage
    and the family are built and checked by :func:`ident.run.setup.prepare_run`, still before
    any run folder exists.

    Raises
    ------
    ConfigError
        Unknown keys (with the closest valid key), bad values, a robot file that does not
        exist (naming both the key and the resolved path).
    """
    path = Path(path)
    config = load_config_file(RunConfig, path)
    robot = config.robot.resolved(path.parent.resolve())
    problem = file_problem(robot.path)
    if problem is not None:
        key = "robot.urdf" if robot.urdf is not None else "robot.description"
        which = "does not exist" if problem == "not found" else problem
        raise ConfigError(
            f"{path}: {key} = '{config.robot.path}' resolves to {robot.path}, which {which}; "
            "give the robot description or URDF path relative to this config file."
        )
    if robot.description is not None and robot.path.suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(
            f"{path}: robot = '{config.robot.path}' must be a robot description (.yaml) or a "
            "URDF (.urdf)."
        )
    if robot.urdf is not None:  # unreadable robots: one line before any run folder
        read_urdf_text(robot.path)
    else:
        read_yaml(robot.path)
    update: dict[str, Any] = {"robot": robot, "name": config.name or path.stem}
    if config.safety is not None and config.safety.srdf is not None:
        srdf = path.parent.resolve() / config.safety.srdf
        problem = file_problem(srdf)
        if problem is not None:
            which = "does not exist" if problem == "not found" else problem
            raise ConfigError(
                f"{path}: safety.srdf = '{config.safety.srdf}' resolves to {srdf}, which "
                f"{which}; give MoveIt's .srdf path relative to this config file."
            )
        update["safety"] = config.safety.model_copy(update={"srdf": srdf})
    return config.model_copy(update=update)
