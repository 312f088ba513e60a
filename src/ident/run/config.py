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

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Field, field_validator, model_validator

from ident.config import StrictModel, load_config_file, read_yaml
from ident.errors import ConfigError, OptimizationError
from ident.inputs import read_urdf_text

__all__ = [
    "ElitesSection",
    "EmupsoSection",
    "EstimationSection",
    "ExcitationSection",
    "MeasurementSection",
    "QuickSection",
    "RunConfig",
    "check_bound_names",
    "load_run_config",
]

FAMILIES = ("paper_wrist", "paper_arm", "joint_fourier")
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
        ``paper_wrist`` / ``paper_arm`` (the paper's Cartesian modified Fourier series,
        eq. 16-23) or ``joint_fourier`` (joint-space finite Fourier series).
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

    family: Literal["paper_wrist", "paper_arm", "joint_fourier"]
    criterion: Literal["paper", "logdet"] = "paper"
    n_samples: int = Field(default=500, ge=16, le=1_000_000)
    options: dict[str, Any] = Field(default_factory=dict)
    bounds: dict[str, Bound] | None = None


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
        Iterations per run (paper: 30).
    stagnation :
        Stagnation threshold G of eq. 7 (paper: 10).
    n_runs :
        Independent runs (paper: 5), each with its own child random stream.
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
    maxiter: int = Field(default=30, ge=1, le=100_000)
    stagnation: int = Field(default=10, ge=1, le=100_000)
    n_runs: int = Field(default=5, ge=1, le=1000)
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
    """Simulated measurement noise (see :mod:`ident.identify.measurements`).

    Attributes
    ----------
    torque_noise_std :
        Gaussian torque noise [N*m]: one value for all joints or one per robot joint.
    encoder_counts_per_rev :
        Encoder resolution; ``null`` measures q, dq, ddq exactly.
    filter_cutoff_hz :
        Low-pass cut-off before numerical differentiation of encoder positions; ``null``: none.
    """

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


class EstimationSection(StrictModel):
    """Least-squares estimation of the stage's base parameters.

    Attributes
    ----------
    methods :
        Estimators to run, among ``ols`` and ``wls``.
    base_method :
        Base-parameter reduction: ``qr`` (QR with column pivoting) or ``sequential``
        (the paper's column-by-column rank test).
    """

    methods: list[Literal["ols", "wls"]] = ["ols", "wls"]  # pydantic copies mutable defaults
    base_method: Literal["qr", "sequential"] = "qr"

    @field_validator("methods")
    @classmethod
    def _not_empty(cls, value: list[Literal["ols", "wls"]]) -> list[Literal["ols", "wls"]]:
        if not value:
            raise ValueError("give at least one estimator (ols, wls)")
        return list(dict.fromkeys(value))


class QuickSection(StrictModel):
    """Small settings for ``--quick``: a first look in seconds."""

    elites: ElitesSection = ElitesSection(n_particles=6, n_elites=2, maxiter=30)
    emupso: EmupsoSection = EmupsoSection(
        n_particles=8, maxiter=6, stagnation=3, n_runs=2, n_report_elites=2
    )
    n_samples: int = Field(default=120, ge=16, le=1_000_000)


class RunConfig(StrictModel):
    """A whole ``ident run`` config.

    Attributes
    ----------
    name :
        Run name, the prefix of the run folder; defaults to the config file's stem.
    robot :
        Robot config (``.yaml``, DH table) or URDF path, relative to this config file.
    stage :
        Stage to identify: ``wrist`` or ``arm`` (the paper's two stages).
    seed :
        Seed of every random draw of the run.
    """

    name: str | None = None
    robot: Path
    stage: Literal["wrist", "arm"]
    seed: int = Field(default=0, ge=0)
    excitation: ExcitationSection
    elites: ElitesSection = ElitesSection()
    emupso: EmupsoSection = EmupsoSection()
    measurement: MeasurementSection = MeasurementSection()
    estimation: EstimationSection = EstimationSection()
    quick: QuickSection = QuickSection()

    @model_validator(mode="after")
    def _consistent(self) -> RunConfig:
        family = self.excitation.family
        if family.startswith("paper_") and family != f"paper_{self.stage}":
            raise ValueError(
                f"excitation.family '{family}' designs the "
                f"{family.removeprefix('paper_')} stage but stage is '{self.stage}'; "
                f"use 'paper_{self.stage}' or 'joint_fourier'"
            )
        return self

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

    def with_seed(self, seed: int) -> RunConfig:
        """The same run with another seed (``--seed``)."""
        if seed < 0:
            raise ConfigError(f"--seed must be >= 0, got {seed}")
        return self.model_copy(update={"seed": int(seed)})


def load_run_config(path: str | Path) -> RunConfig:
    """Load a run config; resolve the robot path and fill the name from the file stem.

    Raises
    ------
    ConfigError
        Unknown keys (with the closest valid key), bad values, a robot file that does
        not exist (naming both the key and the resolved path), or ``excitation.bounds``
        naming no variable of the family (:func:`check_bound_names`).
    """
    path = Path(path)
    config = load_config_file(RunConfig, path)
    robot = config.robot
    if not robot.is_absolute():
        robot = (path.parent / robot).resolve()
    if not robot.is_file():
        raise ConfigError(
            f"{path}: robot = '{config.robot}' resolves to {robot}, which does not exist; "
            "give the robot config or URDF path relative to this config file."
        )
    if robot.suffix.lower() not in (".yaml", ".yml", ".urdf"):
        raise ConfigError(
            f"{path}: robot = '{config.robot}' must be a robot config (.yaml) or a URDF (.urdf)."
        )
    if robot.suffix.lower() == ".urdf":  # unreadable robots: one line before any run folder
        read_urdf_text(robot)
    else:
        read_yaml(robot)
    config = config.model_copy(update={"robot": robot, "name": config.name or path.stem})
    if config.excitation.bounds:
        check_bound_names(config, path)
    return config


def check_bound_names(config: RunConfig, source: str | Path) -> None:
    """Check that every ``excitation.bounds`` key names a variable of the excitation family.

    Builds the robot, the stage and the family with its bounds override (a fraction of a
    second, no optimization), so that the family's own check of the names (the one the
    pipeline runs) stops ``ident run`` before its run folder is created.

    Parameters
    ----------
    config :
        A run config with its ``robot`` path resolved.
    source :
        The config file, named in the message.

    Raises
    ------
    ConfigError
        One line naming the file, the key ``excitation.bounds.<name>``, the closest valid
        variable name and the family's variables.
    """
    from ident.run.pipeline import get_stage, load_robot, make_family

    robot = load_robot(Path(config.robot))
    try:
        make_family(config, robot, get_stage(robot, config.stage))
    except ConfigError as e:
        raise ConfigError(f"{source}: {e}") from e
