"""One robot selection for every command: which file, which chain of it, which checks.

The ``robot:`` section of a run or identify config, and the same flags on the command line
(``--robot``, ``--urdf``, ``--lock``, ``--base-link``, ``--tip-link``, ``--package-dir``,
``--no-inertia-check``), build a :class:`RobotSelection`; :func:`load_robot` turns it into an
:class:`ident.model.Robot` the same way for ``verify``, ``run``, ``identify`` and ``replay``, so
they accept and reject exactly the same robots.

YAML forms::

    robot: paper6r.yaml                 # a DH description (.yaml) or a URDF (.urdf)
    robot:
      urdf: panda.urdf                  # or description: paper6r.yaml
      package_dirs: [meshes/]           # where package:// meshes are found (replay)
      base_link: panda_link0            # the chain to identify ...
      tip_link: panda_link8
      lock: {panda_finger_joint1: 0.0}  # ... and joints held fixed (grippers, torsos)
      inertia_check: true               # false: load a file with broken inertials anyway
      velocity_limits: [2.0, 2.0, ...]  # rad/s, lower than the URDF's (one, one per joint,
      acceleration_limits: {j1: 10.0}   # rad/s^2  or a mapping joint name -> value)
      limits:                           # per joint, SI: fill in what the URDF leaves unknown
        j2: {lower: -2.9, upper: 2.9, velocity: 2.0, effort: 87.0}

Relative paths are resolved against the folder of the config file.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import model_validator

from ident.config import StrictModel, file_problem
from ident.errors import ConfigError, ModelError
from ident.model.robot import Robot
from ident.robot.limits import JointLimits, tighten_limits

__all__ = [
    "JointLimitOverride",
    "RobotSelection",
    "load_robot",
    "per_joint_limits",
    "selection_from_flags",
    "set_robot_limits",
]


class JointLimitOverride(StrictModel):
    """One joint's entry of ``robot.limits`` (SI: rad or m, rad/s or m/s, N*m or N).

    Each given value tightens the file's (the tighter holds) and sets one the file leaves
    unknown (no ``<limit>``, ``effort="0"``, ``lower == upper``), so that the checks run.
    """

    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None

    @model_validator(mode="after")
    def _valid(self) -> JointLimitOverride:
        for key in ("lower", "upper", "velocity", "effort"):
            value = getattr(self, key)
            if value is not None and not math.isfinite(value):
                raise ValueError(f"{key} = {value}: give a finite number")
        for key in ("velocity", "effort"):
            value = getattr(self, key)
            if value is not None and not value > 0:
                raise ValueError(f"{key} = {value}: give a positive limit")
        if self.lower is not None and self.upper is not None and not self.lower < self.upper:
            raise ValueError(f"lower = {self.lower} is not below upper = {self.upper}")
        return self


class RobotSelection(StrictModel):
    """The robot file and the chain of it to identify (see the module docstring).

    Attributes
    ----------
    urdf :
        A URDF file.
    description :
        A DH robot description (``configs/paper6r.yaml``); exclusive with ``urdf``.
    package_dirs :
        Folders searched for ``package://`` meshes.
    base_link, tip_link :
        The chain: joints between the two links move, the others are locked (URDF only).
    lock :
        Joints held fixed, name -> position [rad or m] (URDF only).
    joints :
        Optional: the chain's joint names in order, as a check of the selection (a log's
        columns map onto them).
    inertia_check :
        Check the inertials of the moving links (default); ``false`` is the override for a
        file with broken inertials.
    acceleration_limits :
        Joint acceleration limits [rad/s^2 or m/s^2]: one value, one per joint of the chain, or
        a mapping joint name -> value (URDFs carry none; a DH description has its own).
        Excitation trajectories keep within them.
    velocity_limits :
        Joint velocity limits [rad/s or m/s], in the same forms; they tighten the file's
        (the lower of the two holds), e.g. to a controller's published limits.
    limits :
        Per joint name, position, velocity and effort limits (:class:`JointLimitOverride`):
        they tighten the file's and set those it leaves unknown.
    """

    urdf: Path | None = None
    description: Path | None = None
    package_dirs: list[Path] = []
    base_link: str | None = None
    tip_link: str | None = None
    lock: dict[str, float] = {}
    joints: list[str] | None = None
    inertia_check: bool = True
    acceleration_limits: float | list[float] | dict[str, float] | None = None
    velocity_limits: float | list[float] | dict[str, float] | None = None
    limits: dict[str, JointLimitOverride] = {}

    @model_validator(mode="before")
    @classmethod
    def _shorthand(cls, data: Any) -> Any:
        """``robot: file.yaml`` / ``robot: file.urdf`` as a plain path."""
        if isinstance(data, (str, Path)):
            path = Path(data)
            return {"urdf" if path.suffix.lower() == ".urdf" else "description": path}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> RobotSelection:
        if (self.urdf is None) == (self.description is None):
            raise ValueError(
                "give exactly one of robot.urdf (a URDF file) and robot.description (a DH "
                "robot description)"
            )
        if self.description is not None and (self.lock or self.base_link or self.tip_link):
            raise ValueError(
                "robot.lock, robot.base_link and robot.tip_link select a chain of a URDF; a DH "
                "description is a serial chain already"
            )
        for name, value in self.lock.items():
            if not math.isfinite(value):
                raise ValueError(f"robot.lock.{name} = {value}: give a finite position")
        for key, unit in (("acceleration_limits", "rad/s^2"), ("velocity_limits", "rad/s")):
            given = getattr(self, key)
            values = _limit_values(given)
            if any(not (math.isfinite(v) and v > 0) for v in values):
                raise ValueError(
                    f"robot.{key} = {given}: give positive, finite values [{unit}], one, one "
                    "per joint, or a mapping joint name -> value"
                )
        limits = self.acceleration_limits
        if self.description is not None and limits is not None:
            raise ValueError(
                "robot.acceleration_limits: a DH description sets its own (ddq_max); give "
                "them there"
            )
        return self

    @property
    def path(self) -> Path:
        """The robot file."""
        path = self.urdf if self.urdf is not None else self.description
        assert path is not None  # guaranteed by the validator
        return path

    def resolved(self, base: Path) -> RobotSelection:
        """A copy with relative paths taken relative to the folder ``base``."""

        def resolve(p: Path | None) -> Path | None:
            return None if p is None or p.is_absolute() else base / p

        changes: dict[str, Any] = {"package_dirs": [resolve(p) or p for p in self.package_dirs]}
        if self.urdf is not None:
            changes["urdf"] = resolve(self.urdf) or self.urdf
        if self.description is not None:
            changes["description"] = resolve(self.description) or self.description
        return self.model_copy(update=changes)


def load_robot(selection: RobotSelection, *, source: str | Path = "config") -> Robot:
    """The :class:`~ident.model.Robot` of a selection (paths already resolved).

    Raises
    ------
    ModelError
        For a file that is missing, malformed, physically impossible on a moving link, or not
        a serial chain once the selection is applied (the message names the file).
    ConfigError
        If ``joints`` is given and differs from the selected chain's joints.
    """
    problem = file_problem(selection.path)
    if problem is not None:  # the config and its field, not only the path
        key = "robot.urdf" if selection.urdf is not None else "robot.description"
        raise ModelError(f"{source}: {key} = {selection.path} {problem}; check the path.")
    if selection.urdf is not None:
        robot = Robot.from_urdf(
            selection.urdf,
            lock_joints=selection.lock or None,
            base_link=selection.base_link,
            tip_link=selection.tip_link,
            package_dirs=selection.package_dirs,
            inertia_check=selection.inertia_check,
        )
    else:
        robot = Robot.from_config(selection.path)
    configured = _configured_limits(selection, robot, source)
    if configured is not None:
        limits, _ = tighten_limits(JointLimits.from_robot(robot), configured, "robot")
        set_robot_limits(robot, limits)
    if selection.joints is not None and list(selection.joints) != list(robot.joint_names):
        raise ConfigError(
            f"{source}: robot.joints = {selection.joints} must list the selected chain's joints "
            f"in order ({', '.join(robot.joint_names)}); fix the list or the chain selection."
        )
    return robot


def _configured_limits(
    selection: RobotSelection, robot: Robot, source: str | Path
) -> JointLimits | None:
    """The limits the ``robot:`` section sets (``velocity_limits``, ``acceleration_limits``,
    ``limits``), ``inf`` where it sets none; None when it sets none at all.

    Raises
    ------
    ConfigError
        For a list of the wrong length or a joint the chain does not move.
    """
    dq_max = per_joint_limits(selection.velocity_limits, "velocity_limits", robot, source)
    ddq_max = per_joint_limits(selection.acceleration_limits, "acceleration_limits", robot, source)
    if dq_max is None and ddq_max is None and not selection.limits:
        return None
    names = list(robot.joint_names)
    none = np.full(robot.nv, np.inf)
    values = {
        "q_lower": -none,
        "q_upper": none.copy(),
        "dq_max": none.copy() if dq_max is None else dq_max,
        "ddq_max": none.copy() if ddq_max is None else ddq_max,
        "tau_max": none.copy(),
    }
    for name, entry in selection.limits.items():
        if name not in names:
            raise ConfigError(
                f"{source}: robot.limits names {name!r}, not a moving joint of the chain; use "
                f"one of {', '.join(names)}."
            )
        j = names.index(name)
        for key, given in (
            ("q_lower", entry.lower),
            ("q_upper", entry.upper),
            ("dq_max", entry.velocity),
            ("tau_max", entry.effort),
        ):
            if given is not None:
                values[key][j] = min(values[key][j], given) if key == "dq_max" else given
    return JointLimits(
        tuple(names),
        q_lower=values["q_lower"],
        q_upper=values["q_upper"],
        dq_max=values["dq_max"],
        ddq_max=values["ddq_max"],
        tau_max=values["tau_max"],
    )


def _limit_values(given: float | list[float] | dict[str, float] | None) -> list[float]:
    if given is None:
        return []
    if isinstance(given, dict):
        return list(given.values())
    return list(given) if isinstance(given, list) else [given]


def per_joint_limits(
    given: float | list[float] | dict[str, float] | None,
    key: str,
    robot: Robot,
    source: str | Path = "config",
) -> np.ndarray | None:
    """``robot.<key>`` as one value per joint of the chain, shape (nv,); None when not given.

    One value applies to every joint; a list gives one per joint in chain order; a mapping
    names joints (the others keep ``inf``: no limit from the config).

    Raises
    ------
    ConfigError
        For a list of the wrong length or a mapping naming a joint the chain does not move.
    """
    if given is None:
        return None
    names = list(robot.joint_names)
    if isinstance(given, dict):
        unknown = [name for name in given if name not in names]
        if unknown:
            raise ConfigError(
                f"{source}: robot.{key} names {unknown[0]!r}, not a moving joint of the chain; "
                f"use one of {', '.join(names)}."
            )
        return np.array([float(given.get(name, np.inf)) for name in names])
    values = np.atleast_1d(np.asarray(given, dtype=float))
    if values.size not in (1, robot.nv):
        raise ConfigError(
            f"{source}: robot.{key} has {values.size} values, the chain has {robot.nv} joints "
            f"({', '.join(names)}); give one, one per joint, or a mapping joint name -> value."
        )
    return np.broadcast_to(values, (robot.nv,)).copy()


def set_robot_limits(robot: Robot, limits: JointLimits) -> None:
    """Make ``limits`` the robot's (position, velocity, acceleration; read-only copies).

    The limits still unknown (``limits.unknown``) become ``robot.unknown_limits``.
    Everything that keeps a trajectory within limits reads them from the robot
    (:meth:`ident.excitation.constraints.JointLimits.from_robot`): the excitation's constraints,
    the approach and return, and the dense safety check.
    """
    for key in ("q_lower", "q_upper", "dq_max", "ddq_max", "tau_max"):
        value = np.array(getattr(limits, key), dtype=float)
        value.setflags(write=False)
        setattr(robot, key, value)
    robot.unknown_limits = tuple(limits.unknown)


def selection_from_flags(
    *,
    robot: Path | None = None,
    urdf: Path | None = None,
    lock: dict[str, float] | None = None,
    base_link: str | None = None,
    tip_link: str | None = None,
    package_dirs: list[Path] | None = None,
    inertia_check: bool = True,
) -> RobotSelection:
    """The selection given on the command line (``--robot`` is a DH description or a URDF).

    Raises
    ------
    ConfigError
        For a combination of flags no robot satisfies (the message names the flags).
    """
    if (robot is None) == (urdf is None):
        raise ConfigError("give exactly one of --robot CONFIG or --urdf PATH.")
    path = robot if robot is not None else urdf
    assert path is not None
    is_urdf = urdf is not None or path.suffix.lower() == ".urdf"
    if not is_urdf and (lock or base_link or tip_link):
        raise ConfigError(
            "--lock, --base-link and --tip-link work with --urdf only: they select a chain of "
            "a URDF; a --robot DH config describes a serial chain already."
        )
    try:
        return RobotSelection(
            urdf=path if is_urdf else None,
            description=None if is_urdf else path,
            package_dirs=list(package_dirs or []),
            base_link=base_link,
            tip_link=tip_link,
            lock=dict(lock or {}),
            inertia_check=inertia_check,
        )
    except ValueError as e:  # pydantic's ValidationError is a ValueError
        raise ConfigError(f"robot flags: {e}") from e
