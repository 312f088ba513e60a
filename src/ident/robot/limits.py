"""Joint limits of a robot chain and the one rule that combines limits of several origins.

The URDF's limits, the run config's (``robot.limits``, ``robot.velocity_limits``,
``robot.acceleration_limits``) and an export target's published ones (libfranka, UR
datasheets) meet in :func:`tighten_limits`; the excitation constraints
(:mod:`ident.excitation.constraints`), the approach and return and the dense safety check read
the result from the robot.

A limit is known (a finite value), genuinely absent (a continuous joint's position: ``inf``)
or **unknown**: the file gives none, or gives 0 or an empty range. An unknown limit is ``inf``
in the arrays (nothing can be compared with it) *and* an :class:`UnknownLimit` with the reason,
so that every check that cannot run names it instead of passing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "DEFAULT_Q_RANGE",
    "LIMIT_KINDS",
    "JointLimits",
    "UnknownLimit",
    "default_position_box",
    "describe_unknown",
    "tighten_limits",
]

#: The kinds of joint limit, as the checks name them (``torque`` is the URDF's ``effort``).
LIMIT_KINDS = ("position", "velocity", "acceleration", "torque")

#: The guessed half range of a joint whose position limits are unknown: a turn each way for a
#: revolute joint [rad]; a metre each way for a prismatic one [m] (a linear axis or a lift: a
#: range in radians, +-3.14 m, would send a slider far beyond any real travel).
DEFAULT_Q_RANGE = {"revolute": np.pi, "prismatic": 1.0}

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class UnknownLimit:
    """A limit a check needs but nobody gave (see the module docstring).

    Attributes
    ----------
    kind :
        One of :data:`LIMIT_KINDS`.
    joint :
        The joint's name.
    reason :
        Why it is unknown, e.g. ``"the URDF gives effort 0"``.
    """

    kind: str
    joint: str
    reason: str

    @property
    def check(self) -> str:
        """The name of the check it leaves out: ``<kind>:<joint>``."""
        return f"{self.kind}:{self.joint}"

    def describe(self) -> str:
        """``"torque not checked on j1: the URDF gives effort 0"``."""
        return describe_unknown(self.check, self.reason)


def describe_unknown(check: str, reason: str) -> str:
    """``"<kind> not checked on <joint>: <reason>"`` for a check named ``<kind>:<joint>``."""
    kind, _, joint = check.partition(":")
    return f"{kind} not checked on {joint}: {reason}"


@dataclass(frozen=True, eq=False)
class JointLimits:
    """Joint limits used by the trajectory constraints (SI).

    Attributes
    ----------
    joint_names :
        One per joint.
    q_lower, q_upper :
        Position limits [rad], shape (nq,); ``-inf``/``inf`` where unknown.
    dq_max, ddq_max :
        Velocity [rad/s] and acceleration [rad/s^2] limits, shape (nq,); ``inf`` where unknown.
    tau_max :
        Effort limits [N*m or N], shape (nq,); ``inf`` where unknown (default: all unknown).
    unknown :
        The limits that are ``inf`` above because nobody gave them, with the reason (a
        continuous joint's position is unlimited, not unknown, and is not listed).
    prismatic :
        True for a prismatic joint (positions in m), shape (nq,); default: all revolute.
    """

    joint_names: tuple[str, ...]
    q_lower: FloatArray
    q_upper: FloatArray
    dq_max: FloatArray
    ddq_max: FloatArray
    tau_max: FloatArray = None  # type: ignore[assignment]  # None: all unknown (inf)
    unknown: tuple[UnknownLimit, ...] = ()
    prismatic: npt.NDArray[np.bool_] = None  # type: ignore[assignment]  # None: all revolute

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if self.tau_max is None:
            object.__setattr__(self, "tau_max", np.full(n, np.inf))
        prismatic = np.zeros(n, dtype=bool) if self.prismatic is None else self.prismatic
        prismatic = np.array(prismatic, dtype=bool, copy=True)
        if prismatic.shape != (n,):
            raise ValueError(f"JointLimits.prismatic must have shape ({n},), got {prismatic.shape}")
        prismatic.setflags(write=False)
        object.__setattr__(self, "prismatic", prismatic)
        object.__setattr__(self, "unknown", tuple(self.unknown))
        for name in ("q_lower", "q_upper", "dq_max", "ddq_max", "tau_max"):
            value = np.array(getattr(self, name), dtype=float, copy=True)
            if value.shape != (n,):
                raise ValueError(f"JointLimits.{name} must have shape ({n},), got {value.shape}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def from_robot(cls, robot: Any) -> JointLimits:
        """Limits of an :class:`ident.Robot` (or any object with the same attributes)."""
        names = tuple(robot.joint_names)
        n = len(names)
        ddq = getattr(robot, "ddq_max", None)
        tau = getattr(robot, "tau_max", None)
        chain = getattr(robot, "chain", None)  # an ident.Robot's: the joint types
        prismatic = (
            np.zeros(n, dtype=bool) if chain is None else chain.prismatic[chain.joint_bodies]
        )
        return cls(
            joint_names=names,
            q_lower=np.asarray(robot.q_lower, dtype=float),
            q_upper=np.asarray(robot.q_upper, dtype=float),
            dq_max=np.asarray(robot.dq_max, dtype=float),
            ddq_max=np.full(n, np.inf) if ddq is None else np.asarray(ddq, dtype=float),
            tau_max=np.full(n, np.inf) if tau is None else np.asarray(tau, dtype=float),
            unknown=tuple(getattr(robot, "unknown_limits", ())),
            prismatic=prismatic,
        )

    @property
    def nq(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    def finite_position_box(self) -> tuple[FloatArray, FloatArray]:
        """Position limits with unknown ones replaced by the guess :data:`DEFAULT_Q_RANGE`
        (``[-pi, pi]`` rad, ``[-1, 1]`` m for a prismatic joint), shapes (nq,)."""
        return default_position_box(self.q_lower, self.q_upper, self.prismatic)


def default_position_box(
    q_lower: FloatArray, q_upper: FloatArray, prismatic: npt.NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray]:
    """``q_lower``, ``q_upper`` [rad or m], shapes (n,), with each infinite (unknown or absent)
    bound replaced by the guess of :data:`DEFAULT_Q_RANGE` for its joint's type (``prismatic``,
    shape (n,)): the finite box the optimizer and the reference states sample."""
    half = np.where(prismatic, DEFAULT_Q_RANGE["prismatic"], DEFAULT_Q_RANGE["revolute"])
    lower = np.where(np.isfinite(q_lower), q_lower, -half)
    upper = np.where(np.isfinite(q_upper), q_upper, half)
    return lower, upper


_LIMIT_KINDS = (
    ("q_lower", "position lower", "rad"),
    ("q_upper", "position upper", "rad"),
    ("dq_max", "velocity", "rad/s"),
    ("ddq_max", "acceleration", "rad/s^2"),
    ("tau_max", "effort", "N*m"),
)


def tighten_limits(
    limits: JointLimits, bound: JointLimits, source: str
) -> tuple[JointLimits, tuple[str, ...]]:
    """The element-wise tighter of ``limits`` and ``bound``, and what ``bound`` changed.

    The one place where joint limits of different origins (the URDF, the run config, an export
    target such as libfranka) are combined: positions ``[max(lower), min(upper)]``, velocities
    accelerations and efforts ``min``; ``inf`` (``-inf`` for a lower bound) means no limit. An
    unknown limit of ``limits`` that ``bound`` sets (both sides, for a position) is known
    afterwards; the others stay unknown.

    Parameters
    ----------
    limits :
        The limits so far, shape (nq,) each.
    bound :
        Further limits for the same joints (same ``joint_names``).
    source :
        Who sets ``bound`` (``"franka"``, ``"robot.velocity_limits"``), for the notes.

    Returns
    -------
    :
        The tightened limits, and one note per kind of limit ``bound`` tightened by more than
        round-off (1e-9 relative):
        ``"<source>: velocity limits [rad/s] <joint> 2.175 -> 2.124, <joint> ..."``.

    Raises
    ------
    ValueError
        If the joint names differ.
    """
    if tuple(bound.joint_names) != tuple(limits.joint_names):
        raise ValueError(
            f"{source}: limits for joints {list(bound.joint_names)}, the robot's are "
            f"{list(limits.joint_names)}"
        )
    values = {
        "q_lower": np.maximum(limits.q_lower, bound.q_lower),
        "q_upper": np.minimum(limits.q_upper, bound.q_upper),
        "dq_max": np.minimum(limits.dq_max, bound.dq_max),
        "ddq_max": np.minimum(limits.ddq_max, bound.ddq_max),
        "tau_max": np.minimum(limits.tau_max, bound.tau_max),
    }
    notes = []
    for key, quantity, unit in _LIMIT_KINDS:
        before, after = getattr(limits, key), values[key]
        changed = [
            f"{limits.joint_names[j]} {before[j]:.6g} -> {after[j]:.6g}"
            for j in np.flatnonzero(before != after)
            # round-off (a URDF's 6.28318530718 for 2 pi) is applied, not reported
            if not abs(after[j] - before[j]) <= 1e-9 * max(1.0, abs(after[j]))
        ]
        if changed:
            notes.append(f"{source}: {quantity} limits [{unit}] {', '.join(changed)}")
    unknown = tuple(u for u in limits.unknown if not _now_known(u, limits.joint_names, values))
    names, prismatic = tuple(limits.joint_names), limits.prismatic  # the joint types kept
    return JointLimits(names, unknown=unknown, prismatic=prismatic, **values), tuple(notes)


_KIND_ARRAYS = {
    "position": ("q_lower", "q_upper"),
    "velocity": ("dq_max",),
    "acceleration": ("ddq_max",),
    "torque": ("tau_max",),
}


def _now_known(
    unknown: UnknownLimit, names: tuple[str, ...], values: dict[str, FloatArray]
) -> bool:
    """True when every array of ``unknown``'s kind is finite at its joint in ``values``."""
    j = names.index(unknown.joint)
    return all(np.isfinite(values[key][j]) for key in _KIND_ARRAYS[unknown.kind])
