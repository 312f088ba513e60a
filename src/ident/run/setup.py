"""Everything a run needs before it starts, built and checked before any run folder exists.

:func:`prepare_run` loads the robot selection, chooses the stage, builds the excitation family
from the registry with its options and search box, and checks the measurement settings against
the robot. Whatever is wrong in a config is found here, in a fraction of a second, so ``ident
run`` fails with one error line and leaves nothing behind.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.dynamics.stage import Stage, select_stage
from ident.errors import ConfigError, IdentError, ModelError
from ident.excitation.registry import build_family
from ident.excitation.safety import SafetyConfig, SafetyModel, build_safety_model
from ident.measure.mujoco_config import check_joint_counts
from ident.model import Robot
from ident.model.selection import load_robot
from ident.run.config import RunConfig, load_run_config

__all__ = ["RunSetup", "load_run", "make_family", "prepare_run"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RunSetup:
    """A checked run: its config, robot, stage and excitation family.

    Attributes
    ----------
    config :
        The run config (paths resolved).
    robot :
        The selected robot.
    stage :
        The stage to identify.
    family :
        The excitation family, with ``excitation.bounds`` applied to its ``bounds``.
    safety :
        The collision, floor, obstacle and torque model (the config's ``safety`` section, or
        the defaults), which checks every reported trajectory.
    """

    config: RunConfig
    robot: Robot
    stage: Stage
    family: Any
    safety: SafetyModel

    @property
    def bounds(self) -> FloatArray:
        """Search box of the design variables, shape (n_vars, 2)."""
        return np.asarray(self.family.bounds, dtype=float)


def prepare_run(config: RunConfig, source: str | Path = "config") -> RunSetup:
    """Build and check everything of a run config (see the module docstring).

    Raises
    ------
    IdentError
        One line naming ``source``, the key and the fix: robot (file, chain, inertials),
        stage, family and its options, ``excitation.bounds`` names, measurement settings.
    """
    try:
        robot = load_robot(config.robot, source=source)
        spec = config.stage if isinstance(config.stage, str) else config.stage.model_dump()
        stage = select_stage(robot, spec)
        family = make_family(config, robot, stage)
        _check_measurement(config, robot, stage)
        _check_sampling(config, family)
        _check_controller(config, robot)
        safety = build_safety_model(
            robot, config.safety or SafetyConfig(), package_dirs=robot.package_dirs
        )
    except IdentError as e:
        message = str(e)
        if not message.startswith(str(source)):
            message = f"{source}: {message}"
        raise type(e)(message) from e
    return RunSetup(config=config, robot=robot, stage=stage, family=family, safety=safety)


def load_run(path: str | Path) -> RunSetup:
    """Load a run config file and prepare it (:func:`prepare_run`), errors naming the file."""
    return prepare_run(load_run_config(path), source=path)


def make_family(config: RunConfig, robot: Any, stage: Stage) -> Any:
    """The config's excitation family for the stage, its search box overridden by
    ``excitation.bounds``.

    Raises
    ------
    ConfigError
        If the family rejects ``excitation.options``, or a bound names no variable.
    """
    section = config.excitation
    options = dict(section.options)
    options.setdefault("n_samples", section.n_samples)
    family = build_family(section.family, robot, stage, options)
    if section.bounds:
        family.bounds = _override_bounds(family, section.family, section.bounds)
    return family


def _override_bounds(
    family: Any, family_name: str, overrides: dict[str, tuple[float, float]]
) -> FloatArray:
    bounds = np.array(family.bounds, dtype=float, copy=True)
    names = list(family.variable_names)
    for name, (low, high) in overrides.items():
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            if close:
                hint = f"did you mean '{close[0]}'?"
            else:
                nearest = difflib.get_close_matches(name, names, n=1, cutoff=0.0)
                hint = f"no variable is named like it (nearest: '{nearest[0]}')." if nearest else ""
            raise ConfigError(
                f"unknown key 'excitation.bounds.{name}': '{name}' is not a variable of the "
                f"'{family_name}' family; {hint} Variables: {', '.join(names)}."
            )
        bounds[names.index(name)] = (low, high)
    return bounds


def _check_controller(config: RunConfig, robot: Robot) -> None:
    """A home posture has one position per joint, within the position limits."""
    home = config.controller.home
    if home is None:
        return
    if len(home) != robot.nq:
        raise ConfigError(
            f"controller.home has {len(home)} values, the robot has {robot.nq} joints "
            f"({', '.join(robot.joint_names)}); give one position per joint [rad or m]."
        )
    for name, value, low, high in zip(
        robot.joint_names, home, robot.q_lower, robot.q_upper, strict=True
    ):
        if not (np.isfinite(value) and low <= value <= high):
            raise ConfigError(
                f"controller.home: {name} = {value} is outside its limits [{low:g}, {high:g}]."
            )


def _check_sampling(config: RunConfig, family: Any) -> None:
    """Filter cut-offs below the Nyquist frequency of the samples they filter."""
    m = config.measurement
    if m.source == "ideal":
        period = getattr(family, "period", None)
        if m.filter_cutoff_hz is not None and period:
            nyquist = 0.5 * config.excitation.n_samples / float(period)
            if m.filter_cutoff_hz >= nyquist:
                raise ConfigError(
                    f"measurement.filter_cutoff_hz = {m.filter_cutoff_hz:g} Hz is at or above the "
                    f"Nyquist frequency {nyquist:g} Hz of the trajectory's samples "
                    f"(excitation.n_samples = {config.excitation.n_samples} per {period:g} s); "
                    "lower the cut-off or sample more."
                )
        return
    nyquist = 0.5 * m.rate_hz
    pre = config.identification.preprocess
    for key, section in (("lowpass", pre.lowpass), ("torque_lowpass", pre.torque_lowpass)):
        if section is not None and section.cutoff_hz >= nyquist:
            raise ConfigError(
                f"identification.preprocess.{key}.cutoff_hz = {section.cutoff_hz:g} Hz is at or "
                f"above the Nyquist frequency {nyquist:g} Hz of measurement.rate_hz = "
                f"{m.rate_hz:g}; lower it."
            )


def _check_measurement(config: RunConfig, robot: Robot, stage: Stage) -> None:
    """Per-joint measurement settings must have one value per joint of the robot."""
    if config.measurement.source == "mujoco":
        check_joint_counts(config.measurement, robot.nv, joint_names=robot.joint_names)
        if len(stage.moving_joints) != robot.nv:
            raise ConfigError(
                f"measurement.source: mujoco identifies every body of the chain from its log, "
                f"so every joint must move; stage '{stage.name}' holds some. Use stage: whole, "
                "or select a shorter chain (robot.base_link / robot.tip_link)."
            )
        return
    std = config.measurement.torque_noise_std
    if isinstance(std, list) and len(std) != robot.nv:
        raise ConfigError(
            f"measurement.torque_noise_std has {len(std)} values, the robot has {robot.nv} "
            f"joints ({', '.join(robot.joint_names)}); give one value or one per joint."
        )
    if robot.nv < 1:
        raise ModelError("the robot has no moving joint.")
