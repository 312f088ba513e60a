"""The optimizer's cheap safety terms of a swarm: clearances and torques at a few samples per
trajectory (:func:`collision_violations`, :func:`torque_violations`), beside the nominal
inverse dynamics that gives the torques (:func:`joint_torques`). The dense check of the chosen
trajectories is :mod:`ident.excitation.check`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.excitation.constraints import NONFINITE_VIOLATION
from ident.excitation.family import ConstraintViolations, FloatArray
from ident.excitation.safety.model import SafetyModel

__all__ = ["collision_violations", "joint_torques", "torque_violations"]


def joint_torques(model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Nominal inverse dynamics ``pin.rnea`` [N*m or N], shape (n_samples, nv)."""
    from ident.dynamics.pinocchio_check import pinocchio_rnea

    return np.asarray(pinocchio_rnea(model, q, dq, ddq), dtype=float)


def _subsample(n_samples: int, n_check: int) -> npt.NDArray[np.int64]:
    """``n_check`` sample indices spread evenly over ``0..n_samples-1``."""
    if n_check >= n_samples:
        return np.arange(n_samples)
    return np.unique(np.round(np.linspace(0, n_samples, n_check, endpoint=False)).astype(int))


def collision_violations(
    safety: SafetyModel, q: FloatArray, n_check: int | None = None
) -> ConstraintViolations:
    """Cheap clearance constraint of a swarm: distances at ``n_check`` samples per trajectory.

    Uses :meth:`SafetyModel.fast_min_clearances` (vectorized over the swarm; the minimum of
    :meth:`SafetyModel.fast_clearances` over the samples, exact wherever a pair is within the
    margin, so the term equals the exact one at the checked samples).

    Parameters
    ----------
    safety :
        The safety model.
    q :
        Joint positions, shape (n_particles, n_samples, nq).
    n_check :
        Samples per trajectory (evenly spread); default ``safety.config.check_samples``.

    Returns
    -------
    :
        One constraint ``clearance:<pair>`` per link pair:
        ``max(clearance_m - min_t d, 0) / clearance_m`` (with a 1 cm scale when the margin is
        0), i.e. 1 = "touching", 2 = "one margin deep".
    """
    n_check = safety.config.check_samples if n_check is None else int(n_check)
    idx = _subsample(q.shape[1], n_check)
    d = safety.fast_min_clearances(q[:, idx])
    scale = safety.clearance_m if safety.clearance_m > 0.0 else 0.01
    values = np.maximum(safety.clearance_m - d, 0.0) / scale
    values = np.where(np.isfinite(values), values, NONFINITE_VIOLATION)
    return ConstraintViolations(tuple(f"clearance:{p}" for p in safety.pair_names), values)


def torque_violations(
    safety: SafetyModel,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    n_check: int | None = None,
) -> ConstraintViolations:
    """Torque-limit constraint of a swarm at ``n_check`` samples per trajectory.

    Returns
    -------
    :
        ``torque:<joint>`` = ``max(max_t |tau| - effort, 0) / effort`` for the joints with a
        known effort limit (none when no limit is known).
    """
    known = np.flatnonzero(np.isfinite(safety.effort_max))
    names = tuple(f"torque:{safety.limits.joint_names[j]}" for j in known)
    if known.size == 0:
        return ConstraintViolations(names, np.zeros((q.shape[0], 0)))
    n_check = safety.config.check_samples if n_check is None else int(n_check)
    idx = _subsample(q.shape[1], n_check)
    flat = [a[:, idx].reshape(-1, a.shape[2]) for a in (q, dq, ddq)]
    finite = np.all(np.isfinite(np.hstack(flat)), axis=1)
    tau = np.full((flat[0].shape[0], q.shape[2]), np.inf)
    if finite.any():
        tau[finite] = joint_torques(safety.robot_model, *(f[finite] for f in flat))
    peak = np.abs(tau).reshape(q.shape[0], idx.size, -1).max(axis=1)[:, known]
    limit = safety.effort_max[known]
    values = np.maximum(peak - limit, 0.0) / limit
    return ConstraintViolations(names, np.where(np.isfinite(values), values, NONFINITE_VIOLATION))
