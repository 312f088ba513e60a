"""Common interface of excitation-trajectory families and their batch results.

An *excitation family* maps a design vector ``x`` (the variables an optimizer moves, e.g. the
coefficients ``a0, b0, ..., f0`` of the paper's eq. 16-19) to one joint trajectory per particle
of a swarm, sampled over one period, together with the violations of the constraints of eq. 24
(joint limits, periodic continuity, reachability). Everything is vectorized over particles
(axis 0) and samples (axis 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from ident.trajectory import JointTrajectory

__all__ = [
    "ConstraintViolations",
    "ExcitationFamily",
    "FloatArray",
    "TrajectoryBatch",
    "check_design",
    "feasibility_advice",
    "sample_times",
]

FloatArray = npt.NDArray[np.float64]


def sample_times(n_samples: int, period: float) -> FloatArray:
    """Sample times ``t_k = k T / n``, k = 0..n-1, of one period [s], shape (n_samples,).

    ``t = T`` is not included: it is the first sample of the next period.
    """
    return np.arange(n_samples, dtype=np.float64) * (period / n_samples)


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==
class ConstraintViolations:
    """Per-particle, per-constraint violation magnitudes.

    Attributes
    ----------
    names :
        Constraint names, e.g. ``"position:joint_1"``, ``"velocity:joint_5"``,
        ``"acceleration:joint_6"``, ``"continuity:joint_6"``, ``"reachability"``.
    values :
        Violation magnitudes, shape (n_particles, n_constraints), dimensionless and >= 0;
        0 means satisfied. Each is the worst excess over the samples, relative to the limit
        (see :mod:`ident.excitation.constraints`): 0.1 means "10 % beyond the limit".
    """

    names: tuple[str, ...]
    values: FloatArray

    def __post_init__(self) -> None:
        values = np.array(self.values, dtype=float, copy=True)
        if values.ndim != 2 or values.shape[1] != len(self.names):
            raise ValueError(
                f"values must have shape (n_particles, {len(self.names)}), got {values.shape}"
            )
        values.setflags(write=False)
        object.__setattr__(self, "values", values)

    @property
    def n_particles(self) -> int:
        """Number of particles."""
        return self.values.shape[0]

    def total(self) -> FloatArray:
        """Sum of the violation magnitudes of each particle, shape (n_particles,)."""
        return self.values.sum(axis=1)

    def feasible(self) -> npt.NDArray[np.bool_]:
        """True where a particle violates no constraint, shape (n_particles,)."""
        return ~np.any(self.values > 0.0, axis=1)

    def as_dict(self, particle: int) -> dict[str, float]:
        """The violated constraints of one particle, ``{name: magnitude}`` (only > 0)."""
        row = self.values[particle]
        return {name: float(v) for name, v in zip(self.names, row, strict=True) if v > 0.0}

    @staticmethod
    def concatenate(*parts: ConstraintViolations) -> ConstraintViolations:
        """Join the constraints of several reports on the same particles."""
        names = tuple(name for p in parts for name in p.names)
        return ConstraintViolations(names, np.concatenate([p.values for p in parts], axis=1))


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==
class TrajectoryBatch:
    """One sampled excitation trajectory per particle.

    Attributes
    ----------
    t :
        Sample times [s], shape (n_samples,), uniform over one period ``[0, T)``.
    q, dq, ddq :
        Joint positions [rad], velocities [rad/s], accelerations [rad/s^2], of ALL joints of
        the robot (held joints constant), shape (n_particles, n_samples, nq).
    traced_points :
        Cartesian path of the traced point (e.g. the flange or the wrist centre) in the base
        frame [m], shape (n_particles, n_samples, 3), or ``None`` for joint-space families.
    violations :
        Constraint violations of each particle.
    joint_names :
        Names of the ``nq`` joints, in column order.
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    traced_points: FloatArray | None
    violations: ConstraintViolations
    joint_names: tuple[str, ...] = ()

    @property
    def n_particles(self) -> int:
        """Number of trajectories."""
        return self.q.shape[0]

    @property
    def n_samples(self) -> int:
        """Samples per trajectory."""
        return self.q.shape[1]

    def particle(self, i: int) -> JointTrajectory:
        """Trajectory of particle ``i`` as a :class:`ident.trajectory.JointTrajectory`."""
        names = self.joint_names or tuple(f"joint_{k + 1}" for k in range(self.q.shape[2]))
        return JointTrajectory(
            t=self.t.copy(),
            q=self.q[i].copy(),
            dq=self.dq[i].copy(),
            ddq=self.ddq[i].copy(),
            joint_names=names,
        )


@runtime_checkable
class ExcitationFamily(Protocol):
    """What the objective and the optimizers need from an excitation family.

    Attributes
    ----------
    variable_names :
        Names of the design variables, in the column order of ``x``.
    bounds :
        Search box, shape (n_vars, 2): lower and upper bound of each variable.
    traced_frame :
        Name of the Cartesian point the family moves (``"flange"``, ``"wrist_centre"``), or
        ``None`` for joint-space families.
    moving_joints :
        Indices (0-based) of the joints that move; the others are held.
    held_positions :
        Positions [rad] of all joints, shape (nq,); the entries of the held joints are used.
    period :
        Duration of one period [s].
    """

    variable_names: tuple[str, ...]
    bounds: FloatArray
    traced_frame: str | None
    moving_joints: tuple[int, ...]
    held_positions: FloatArray
    period: float

    def trajectories(self, x: FloatArray) -> TrajectoryBatch:
        """Trajectories of a swarm; ``x`` of shape (n_particles, n_vars)."""
        ...


def check_design(x: npt.ArrayLike, n_vars: int) -> FloatArray:
    """Return ``x`` as a float array of shape (n_particles, n_vars).

    A single design vector of shape (n_vars,) becomes a swarm of one particle.

    Raises
    ------
    ValueError
        If the trailing dimension is not ``n_vars``.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != n_vars:
        raise ValueError(f"design x must have shape (n_particles, {n_vars}), got {x.shape}")
    return x


#: What to try when no design of the search box meets the constraints, for any family.
GENERIC_ADVICE = (
    "narrow excitation.bounds, lower the family's amplitudes in excitation.options, or relax "
    "the limits of the robot (robot.acceleration_limits) or the safety section"
)


def feasibility_advice(family: object, violated: tuple[str, ...] = ()) -> str:
    """What to change when no design of ``family``'s search box meets the constraints.

    A family may explain itself with a method ``feasibility_advice(violated) -> str`` that
    names its own settings and their values (an empty string: nothing of its own to blame);
    the advice never mentions options of another family.

    Parameters
    ----------
    family :
        The excitation family.
    violated :
        Names of the constraints violated most often by designs of the box
        (``"velocity:<joint>"``, ``"floor"``, ...), most frequent first.

    Returns
    -------
    :
        One sentence (no final period).
    """
    own = getattr(family, "feasibility_advice", None)
    advice = own(tuple(violated)) if callable(own) else ""
    return advice or GENERIC_ADVICE
