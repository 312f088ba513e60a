"""Constraints of an excitation trajectory (paper eq. 24 plus what a real robot needs).

Each constraint yields a dimensionless violation magnitude per particle, 0 when satisfied:

- ``position:<joint>``: ``max_t max(q - q_upper, q_lower - q, 0) / (q_upper - q_lower)``
- ``velocity:<joint>``: ``max_t max(|dq| - dq_max, 0) / dq_max``
- ``acceleration:<joint>``: ``max_t max(|ddq| - ddq_max, 0) / ddq_max``
- ``continuity:<joint>``: the periodic trajectory must end in the state it starts from (the
  paper's "initial and final conditions of the trajectory must be the same", eq. 24):
  ``|q(T) - q(0)| / range + |dq(T) - dq(0)| / dq_max + |ddq(T) - ddq(0)| / ddq_max``, counted
  when it exceeds a relative tolerance of 1e-8 (round-off of the analytic formulas).
- ``reachability``: how far the Cartesian path leaves the workspace, relative to a length the
  family documents (see :mod:`ident.excitation.ik` and :mod:`ident.excitation.wrist`).

Infinite limits never count as violated; for continuity, an infinite scale is replaced by
2 pi rad, 1 rad/s and 1 rad/s^2 so that a jump is still seen. Non-finite states count as a
violation of ``NONFINITE_VIOLATION`` so that penalties stay finite.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ident.excitation.family import ConstraintViolations, FloatArray

__all__ = [
    "CONTINUITY_TOLERANCE",
    "NONFINITE_VIOLATION",
    "JointLimits",
    "continuity_violations",
    "evaluate_constraints",
    "limit_violations",
    "penalty",
    "tighten_limits",
]

CONTINUITY_TOLERANCE = 1e-8
NONFINITE_VIOLATION = 1e3


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
    """

    joint_names: tuple[str, ...]
    q_lower: FloatArray
    q_upper: FloatArray
    dq_max: FloatArray
    ddq_max: FloatArray

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        for name in ("q_lower", "q_upper", "dq_max", "ddq_max"):
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
        return cls(
            joint_names=names,
            q_lower=np.asarray(robot.q_lower, dtype=float),
            q_upper=np.asarray(robot.q_upper, dtype=float),
            dq_max=np.asarray(robot.dq_max, dtype=float),
            ddq_max=np.full(n, np.inf) if ddq is None else np.asarray(ddq, dtype=float),
        )

    @property
    def nq(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    def finite_position_box(self) -> tuple[FloatArray, FloatArray]:
        """Position limits with unknown ones replaced by ``[-pi, pi]`` [rad], shapes (nq,)."""
        lower = np.where(np.isfinite(self.q_lower), self.q_lower, -np.pi)
        upper = np.where(np.isfinite(self.q_upper), self.q_upper, np.pi)
        return lower, upper


_LIMIT_KINDS = (
    ("q_lower", "position lower", "rad"),
    ("q_upper", "position upper", "rad"),
    ("dq_max", "velocity", "rad/s"),
    ("ddq_max", "acceleration", "rad/s^2"),
)


def tighten_limits(
    limits: JointLimits, bound: JointLimits, source: str
) -> tuple[JointLimits, tuple[str, ...]]:
    """The element-wise tighter of ``limits`` and ``bound``, and what ``bound`` changed.

    The one place where joint limits of different origins (the URDF, the run config, an export
    target such as libfranka) are combined: positions ``[max(lower), min(upper)]``, velocities
    and accelerations ``min``; ``inf`` (``-inf`` for a lower bound) means no limit.

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
    return JointLimits(joint_names=tuple(limits.joint_names), **values), tuple(notes)


def _excess(value: FloatArray, limit: FloatArray) -> FloatArray:
    """``max(value - limit, 0) / limit`` with 0 where the limit is infinite."""
    with np.errstate(invalid="ignore"):
        out = np.maximum(value - limit, 0.0) / limit
    return np.where(np.isfinite(limit), out, 0.0)


def _sanitize(values: FloatArray) -> FloatArray:
    return np.where(np.isfinite(values), values, NONFINITE_VIOLATION)


def limit_violations(
    q: FloatArray, dq: FloatArray, ddq: FloatArray, limits: JointLimits
) -> ConstraintViolations:
    """Position, velocity and acceleration limit violations.

    Parameters
    ----------
    q, dq, ddq :
        Joint states [rad, rad/s, rad/s^2], shape (n_particles, n_samples, nq).
    limits :
        Joint limits.

    Returns
    -------
    :
        ``3 * nq`` constraints ``position:<joint>``, ``velocity:<joint>``,
        ``acceleration:<joint>``.
    """
    span = limits.q_upper - limits.q_lower
    with np.errstate(invalid="ignore"):
        above = np.max(q - limits.q_upper, axis=1)
        below = np.max(limits.q_lower - q, axis=1)
        position = np.maximum(np.maximum(above, below), 0.0) / span
    position = np.where(np.isfinite(span), position, 0.0)
    position = np.where(np.all(np.isfinite(q), axis=1), position, NONFINITE_VIOLATION)
    velocity = _excess(np.max(np.abs(dq), axis=1), limits.dq_max)
    acceleration = _excess(np.max(np.abs(ddq), axis=1), limits.ddq_max)
    names = tuple(
        f"{kind}:{joint}"
        for kind in ("position", "velocity", "acceleration")
        for joint in limits.joint_names
    )
    values = np.concatenate([position, velocity, acceleration], axis=1)
    return ConstraintViolations(names, _sanitize(values))


def continuity_violations(
    start: Sequence[FloatArray], end: Sequence[FloatArray], limits: JointLimits
) -> ConstraintViolations:
    """Periodic continuity: the state at the end of the period equals the start state.

    Parameters
    ----------
    start, end :
        ``(q, dq, ddq)`` at ``t = 0`` and at ``t = T`` [rad, rad/s, rad/s^2], each of shape
        (n_particles, nq).
    limits :
        Joint limits (they give the scales of the three terms).

    Returns
    -------
    :
        ``nq`` constraints ``continuity:<joint>``.
    """
    lower, upper = limits.finite_position_box()
    scales = (
        upper - lower,
        np.where(np.isfinite(limits.dq_max), limits.dq_max, 1.0),
        np.where(np.isfinite(limits.ddq_max), limits.ddq_max, 1.0),
    )
    jump = sum(
        np.abs(np.asarray(e) - np.asarray(s)) / scale
        for s, e, scale in zip(start, end, scales, strict=True)
    )
    jump = np.where(jump > CONTINUITY_TOLERANCE, jump, 0.0)
    names = tuple(f"continuity:{joint}" for joint in limits.joint_names)
    return ConstraintViolations(names, _sanitize(np.asarray(jump, dtype=float)))


def evaluate_constraints(
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    limits: JointLimits,
    *,
    start: Sequence[FloatArray] | None = None,
    end: Sequence[FloatArray] | None = None,
    reachability: FloatArray | None = None,
) -> ConstraintViolations:
    """All constraints of a batch of trajectories.

    Parameters
    ----------
    q, dq, ddq :
        Joint states, shape (n_particles, n_samples, nq).
    limits :
        Joint limits.
    start, end :
        States at ``t = 0`` and ``t = T`` for the continuity constraint (both or neither).
    reachability :
        Dimensionless distance outside the workspace per particle, shape (n_particles,); adds
        a ``reachability`` constraint when given.

    Returns
    -------
    :
        The concatenated constraint report.
    """
    parts = [limit_violations(q, dq, ddq, limits)]
    if (start is None) != (end is None):
        raise ValueError("give both start and end states for the continuity constraint")
    if start is not None and end is not None:
        parts.append(continuity_violations(start, end, limits))
    if reachability is not None:
        reach = _sanitize(np.maximum(np.asarray(reachability, dtype=float), 0.0))
        parts.append(ConstraintViolations(("reachability",), reach[:, None]))
    return ConstraintViolations.concatenate(*parts)


def penalty(violations: ConstraintViolations, weight: float) -> FloatArray:
    """Graded constraint penalty of each particle.

    ``weight * (1 + total violation)`` for an infeasible particle, 0 for a feasible one: the
    step puts every infeasible particle behind every feasible one (when the criterion stays
    below ``weight``), the graded part lets a swarm move toward feasibility.

    Parameters
    ----------
    violations :
        Constraint report.
    weight :
        Penalty weight (dimension of the fitness).

    Returns
    -------
    :
        Shape (n_particles,), finite.
    """
    total = violations.total()
    return np.where(total > 0.0, weight * (1.0 + total), 0.0)
