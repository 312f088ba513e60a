"""Robot description files: a DH table, joint limits and link inertials in YAML.

The file declares its units once (``units: {length: mm, angle: deg, mass: kg}``); every value is
converted to SI here, on load, and nowhere else. Example (two links, standard DH)::

    name: planar2r
    units: {length: mm, angle: deg, mass: kg}
    gravity_m_s2: [0.0, -9.81, 0.0]        # always SI, whatever `units` says
    dh:
      convention: standard                 # or: modified (Craig)
      columns: [a, d, alpha, theta]        # order of the values in each row; theta optional
      rows:
        - [400, 0, 0, 0]
        - [300, 0, 0, 0]
    joints:                                # one entry per DH row, in order
      - {name: shoulder, type: revolute, lower: -170, upper: 170, velocity: 180, acceleration: 500}
      - {name: elbow, lower: -150, upper: 150}
    links:                                 # link i is the body moved by joint i
      - mass: 2.0
        first_moment: [-400.0, 0.0, 0.0]   # m*c in DH frame i [kg*length]; or `com` [length]
        inertia_com: {xx: 1000.0, yy: 30000.0, zz: 30000.0}   # [kg*length^2] about the COM,
                                                               # axes parallel to DH frame i
      - ...

Joint limits (``lower``, ``upper``, ``velocity``, ``acceleration``) are in the angle unit for
revolute joints and the length unit for prismatic joints (per second, per second squared);
``effort`` is always SI (N*m or N).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import field_validator, model_validator

from ident.config import StrictModel, read_yaml, validate_config
from ident.errors import ConfigError
from ident.robot.dh import DHTable
from ident.robot.inertia import consistency_problems, parameters_from_com

__all__ = [
    "DH_COLUMNS",
    "LENGTH_UNITS",
    "RobotConfigFile",
    "RobotDescription",
    "description_from_mapping",
    "load_robot_config",
]

FloatArray = npt.NDArray[np.float64]

# SI value = file value / divisor (a division by 1000 is exact where a product by 1e-3 is not)
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 100.0, "mm": 1000.0}
MASS_UNITS: dict[str, float] = {"kg": 1.0, "g": 1000.0}
ANGLE_UNITS: dict[str, float] = {"rad": 1.0, "deg": 180.0 / math.pi}
DH_COLUMNS: tuple[str, ...] = ("a", "d", "alpha", "theta")
_REQUIRED_COLUMNS = ("a", "d", "alpha")


class Units(StrictModel):
    """Units of the numbers in the file (converted to SI on load)."""

    length: Literal["m", "cm", "mm"] = "m"
    angle: Literal["rad", "deg"] = "rad"
    mass: Literal["kg", "g"] = "kg"


class DHSection(StrictModel):
    """The DH table: convention, column order and one row per joint."""

    convention: Literal["standard", "modified"]
    columns: tuple[str, ...] = ("a", "d", "alpha")
    rows: list[list[float]]

    @field_validator("columns")
    @classmethod
    def _known_columns(cls, columns: tuple[str, ...]) -> tuple[str, ...]:
        for name in columns:
            if name not in DH_COLUMNS:
                close = difflib.get_close_matches(name, DH_COLUMNS, n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise ValueError(
                    f"unknown DH column '{name}'{hint}; columns are {', '.join(DH_COLUMNS)}"
                )
        if len(set(columns)) != len(columns):
            raise ValueError("a DH column is listed twice; list each column once")
        missing = [name for name in _REQUIRED_COLUMNS if name not in columns]
        if missing:
            raise ValueError(
                f"missing DH column(s) {', '.join(missing)}; a, d and alpha are required "
                "(theta is optional, default 0)"
            )
        return columns

    @field_validator("rows")
    @classmethod
    def _not_empty(cls, rows: list[list[float]]) -> list[list[float]]:
        if not rows:
            raise ValueError("the DH table needs at least one row")
        return rows


class JointEntry(StrictModel):
    """Name, type and limits of one joint (angle or length units, see ``units``)."""

    name: str | None = None
    type: Literal["revolute", "prismatic"] = "revolute"
    lower: float
    upper: float
    velocity: float | None = None
    acceleration: float | None = None
    effort: float | None = None  # always SI: N*m (revolute) or N (prismatic)

    @model_validator(mode="after")
    def _limits_ordered(self) -> JointEntry:
        if not self.lower < self.upper:
            raise ValueError(
                f"lower = {self.lower} must be below upper = {self.upper}; swap or fix the limits"
            )
        for key in ("velocity", "acceleration", "effort"):
            value = getattr(self, key)
            if value is not None and not value > 0.0:
                raise ValueError(f"{key} = {value} must be > 0 (or omitted when unknown)")
        return self


class InertiaAboutCom(StrictModel):
    """Inertia tensor entries about the centre of mass, axes parallel to DH frame i."""

    xx: float
    yy: float
    zz: float
    xy: float = 0.0
    xz: float = 0.0
    yz: float = 0.0


class LinkEntry(StrictModel):
    """Inertial data of link i (the body moved by joint i), in DH frame i."""

    name: str | None = None
    mass: float
    first_moment: tuple[float, float, float] | None = None
    com: tuple[float, float, float] | None = None
    inertia_com: InertiaAboutCom

    @field_validator("mass")
    @classmethod
    def _positive_mass(cls, mass: float) -> float:
        if not mass > 0.0:
            raise ValueError(f"mass must be > 0, got {mass}; give the link's mass")
        return mass

    @model_validator(mode="after")
    def _one_of_com(self) -> LinkEntry:
        if (self.first_moment is None) == (self.com is None):
            raise ValueError(
                "give exactly one of 'first_moment' (m*c, mass*length) or 'com' (length)"
            )
        return self


class RobotConfigFile(StrictModel):
    """Schema of a robot description file (raw values in the file's units)."""

    name: str
    units: Units = Units()
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    dh: DHSection
    joints: list[JointEntry]
    links: list[LinkEntry]


@dataclass(frozen=True, eq=False)
class RobotDescription:
    """A serial robot described by a DH table, in SI units.

    Attributes
    ----------
    name :
        Robot name (also the URDF robot name).
    dh :
        The DH table [m, rad].
    joint_names, link_names :
        One per joint; link i is the body moved by joint i.
    q_lower, q_upper :
        Position limits [rad or m], shape (n_joints,).
    dq_max, ddq_max, effort_max :
        Velocity [rad/s or m/s], acceleration [rad/s^2 or m/s^2] and effort [N*m or N] limits,
        shape (n_joints,); ``inf`` where the file gives none.
    gravity :
        Gravity acceleration in the base frame [m/s^2], shape (3,).
    mass, com, inertia_com :
        Link masses [kg] (n_joints,), centres of mass in DH frame i [m] (n_joints, 3), and
        inertia tensors about the centre of mass, axes of DH frame i [kg*m^2] (n_joints, 3, 3).
    parameters_dh :
        Standard parameters of each link in Pinocchio order, about the origin of DH frame i and
        in its axes [kg, kg*m, kg*m^2], shape (n_joints, 10).
    source :
        File the description was read from, if any.
    """

    name: str
    dh: DHTable
    joint_names: tuple[str, ...]
    link_names: tuple[str, ...]
    q_lower: FloatArray
    q_upper: FloatArray
    dq_max: FloatArray
    ddq_max: FloatArray
    effort_max: FloatArray
    gravity: FloatArray
    mass: FloatArray
    com: FloatArray
    inertia_com: FloatArray
    parameters_dh: FloatArray
    source: Path | None = None

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return self.dh.n_joints


def load_robot_config(path: str | Path) -> RobotDescription:
    """Read a robot description file and convert it to SI.

    Raises
    ------
    ConfigError
        Naming the file, the key and the fix, for a missing or malformed file, an unknown key,
        a DH table whose rows or columns do not match the joints, limits with
        ``lower >= upper``, a non-positive mass or a physically impossible inertia.
    """
    return description_from_mapping(read_yaml(path), source=Path(path))


def description_from_mapping(data: Mapping[str, Any], source: str | Path) -> RobotDescription:
    """Validate a robot description already read from YAML (for embedding in other configs)."""
    raw = validate_config(RobotConfigFile, data, source)
    return _to_si(raw, Path(source))


def _names(entries: list[Any], prefix: str, source: Path, section: str) -> tuple[str, ...]:
    names = tuple(
        e.name if e.name is not None else f"{prefix}_{i + 1}" for i, e in enumerate(entries)
    )
    seen: set[str] = set()
    for i, name in enumerate(names):
        if name in seen:
            raise ConfigError(
                f"{source}: {section}[{i}].name = {name!r} is used twice; names must be unique."
            )
        seen.add(name)
    return names


def _check_finite(link: LinkEntry, index: int, source: Path) -> None:
    """Name the field of link ``index`` that holds a NaN or infinite value, if any."""
    c = link.inertia_com
    fields = {
        "mass": [link.mass],
        "com": link.com,
        "first_moment": link.first_moment,
        "inertia_com": [c.xx, c.yy, c.zz, c.xy, c.xz, c.yz],
    }
    for field, values in fields.items():
        if values is not None and not np.all(np.isfinite(values)):
            raise ConfigError(
                f"{source}: links[{index}].{field}: values are not finite ({list(values)}); "
                "give finite numbers."
            )


def _to_si(raw: RobotConfigFile, source: Path) -> RobotDescription:
    """The description in SI units (m, rad, kg) of a parsed robot config."""
    _check_table_sizes(raw, source)
    n_rows = len(raw.dh.rows)
    columns = raw.dh.columns
    length = LENGTH_UNITS[raw.units.length]
    angle = ANGLE_UNITS[raw.units.angle]
    mass_unit = MASS_UNITS[raw.units.mass]
    table = np.array(raw.dh.rows, dtype=float)
    column = {name: table[:, columns.index(name)] for name in columns}
    theta = column.get("theta", np.zeros(n_rows))
    joint_types = tuple(j.type for j in raw.joints)
    dh = DHTable(
        convention=raw.dh.convention,
        a=column["a"] / length,
        d=column["d"] / length,
        alpha=column["alpha"] / angle,
        theta=theta / angle,
        joint_types=joint_types,
    )
    # joint variables are angles for revolute joints and lengths for prismatic ones
    motion_unit = np.array([angle if t == "revolute" else length for t in joint_types])

    def limit(key: str) -> FloatArray:
        values = [getattr(j, key) for j in raw.joints]
        return np.array([np.inf if v is None else v for v in values], dtype=float)

    mass, com, inertia_com, parameters = _links_si(raw, source, length, mass_unit)
    arrays = {
        "q_lower": limit("lower") / motion_unit,
        "q_upper": limit("upper") / motion_unit,
        "dq_max": limit("velocity") / motion_unit,
        "ddq_max": limit("acceleration") / motion_unit,
        "effort_max": limit("effort"),
        "gravity": np.array(raw.gravity_m_s2, dtype=float),
        "mass": mass,
        "com": com,
        "inertia_com": inertia_com,
        "parameters_dh": parameters,
    }
    for array in arrays.values():
        array.setflags(write=False)
    return RobotDescription(
        name=raw.name,
        dh=dh,
        joint_names=_names(raw.joints, "joint", source, "joints"),
        link_names=_names(raw.links, "link", source, "links"),
        source=source,
        **arrays,
    )


def _check_table_sizes(raw: RobotConfigFile, source: Path) -> None:
    """Raise :class:`ConfigError` unless dh.rows, joints and links have one entry per joint
    and every DH row one value per column."""
    n_rows = len(raw.dh.rows)
    if len(raw.joints) != n_rows or len(raw.links) != n_rows:
        raise ConfigError(
            f"{source}: dh.rows has {n_rows} rows, joints has {len(raw.joints)} entries and links "
            f"has {len(raw.links)}; give one DH row, one joints entry and one links entry "
            "per joint."
        )
    columns = raw.dh.columns
    for i, row in enumerate(raw.dh.rows):
        if len(row) != len(columns):
            raise ConfigError(
                f"{source}: dh.rows[{i}] has {len(row)} values but dh.columns lists "
                f"{len(columns)} ({', '.join(columns)}); give one value per column."
            )


def _links_si(
    raw: RobotConfigFile, source: Path, length: float, mass_unit: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per link, in SI: mass (n,) [kg], centre of mass (n, 3) [m], inertia about it (n, 3, 3)
    [kg*m^2] and the 10 parameters in DH frame i (n, 10); ``length``, ``mass_unit``: the
    config's units per metre and per kilogram. Raises :class:`ConfigError` for non-finite
    values or a physically inconsistent link."""
    n_rows = len(raw.links)
    mass = np.array([link.mass for link in raw.links], dtype=float) / mass_unit
    com = np.empty((n_rows, 3))
    inertia_com = np.empty((n_rows, 3, 3))
    parameters = np.empty((n_rows, 10))
    for i, link in enumerate(raw.links):
        _check_finite(link, i, source)
        if link.com is not None:
            com[i] = np.array(link.com) / length
        else:
            com[i] = np.array(link.first_moment) / (mass_unit * length) / mass[i]
        c = link.inertia_com
        tensor = np.array([[c.xx, c.xy, c.xz], [c.xy, c.yy, c.yz], [c.xz, c.yz, c.zz]])
        inertia_com[i] = tensor / (mass_unit * length**2)
        parameters[i] = parameters_from_com(mass[i], com[i], inertia_com[i])
        problems = consistency_problems(parameters[i])
        if problems:
            raise ConfigError(
                f"{source}: links[{i}].inertia_com: {problems[0]}; give the inertia about the "
                "link's centre of mass (axes parallel to DH frame i), not about the frame origin."
            )
    return mass, com, inertia_com, parameters
