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
2 pi rad, 1 rad/s and 1 rad/s^2 so that a jump is still seen. An infinite limit is either
genuinely absent (a continuous joint's position) or unknown (``JointLimits.unknown``: the URDF
gives none, 0 or an empty range): the optimizer cannot keep a trajectory within an unknown
limit, so the dense check (:mod:`ident.excitation.check`) names each one as a check not run.
Non-finite states count as a violation of ``NONFINITE_VIOLATION`` so that penalties stay
finite.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ident.excitation.family import ConstraintViolations, FloatArray
from ident.robot.limits import JointLimits, tighten_limits

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


def _excess(value: FloatArray, limit: FloatArray) -> FloatArray:
    """``max(value - limit, 0) / limit`` with 0 where the limit is infinite."""
    with np.errstate(invalid="ignore"):
        out = np.maximum(value - limit, 0.0) / limit
    return np.where(np.isfinite(limit), out, 0.0)


def _sanitize(values: FloatArray) -> FloatArray:
    return np.where(np.isfinite(values), values, NONFINITE_VIOLATION)


@njit(cache=True, nogil=True)
def _sample_extremes(
    q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
    """One pass over the samples (axis 1) of (n_particles, n_samples, nq) states: ``max q``,
    ``min q``, ``max |dq|``, ``max |ddq|`` (NaN when any sample is NaN, as ``np.max``) and
    whether every ``q`` is finite, each of shape (n_particles, nq)."""
    n_p, n_s, nq = q.shape
    q_max = np.full((n_p, nq), -np.inf)
    q_min = np.full((n_p, nq), np.inf)
    dq_max = np.full((n_p, nq), -np.inf)
    ddq_max = np.full((n_p, nq), -np.inf)
    finite = np.ones((n_p, nq), dtype=np.bool_)
    for p in range(n_p):
        for k in range(n_s):
            for j in range(nq):
                v = q[p, k, j]
                if not np.isfinite(v):
                    finite[p, j] = False
                if v > q_max[p, j] or np.isnan(v):
                    q_max[p, j] = v
                if v < q_min[p, j] or np.isnan(v):
                    q_min[p, j] = v
                a = abs(dq[p, k, j])
                if a > dq_max[p, j] or np.isnan(a):
                    dq_max[p, j] = a
                a = abs(ddq[p, k, j])
                if a > ddq_max[p, j] or np.isnan(a):
                    ddq_max[p, j] = a
    return q_max, q_min, dq_max, ddq_max, finite


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
    states = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (q, dq, ddq)))
    q_max, q_min, dq_max, ddq_max, q_finite = _sample_extremes(
        *(np.ascontiguousarray(x) for x in states)
    )
    with np.errstate(invalid="ignore"):
        # max_t (q - upper) == max_t q - upper exactly (rounding is monotonic), same for min
        above = q_max - limits.q_upper
        below = limits.q_lower - q_min
        position = np.maximum(np.maximum(above, below), 0.0) / span
    position = np.where(np.isfinite(span), position, 0.0)
    position = np.where(q_finite, position, NONFINITE_VIOLATION)
    velocity = _excess(dq_max, limits.dq_max)
    acceleration = _excess(ddq_max, limits.ddq_max)
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
