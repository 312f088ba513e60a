"""Pinocchio as the independent reference for the hand-derived regressor.

Pinocchio evaluates one state at a time, so these functions loop over samples; they are for
verification (tests, ``ident verify``, benchmarks), not for the inner loops.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ident.dynamics.chain import FloatArray, chain_from_model
from ident.dynamics.parameters import parameters_from_model

__all__ = ["compare_with_pinocchio", "pinocchio_regressor", "pinocchio_rnea"]


def _as_samples(q: FloatArray, dq: FloatArray, ddq: FloatArray) -> tuple[FloatArray, ...]:
    return tuple(np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, dq, ddq))


def pinocchio_regressor(
    model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Stack Pinocchio joint-torque regressors over samples.

    Parameters
    ----------
    model :
        Pinocchio model.
    q, dq, ddq :
        Positions [rad or m], velocities, accelerations; shapes (n_samples, nq),
        (n_samples, nv), (n_samples, nv).

    Returns
    -------
    :
        Regressor of shape (n_samples, nv, 10 * (njoints - 1)) so that
        ``regressor @ parameters_from_model(model)`` gives torques [N*m or N].
    """
    q, dq, ddq = _as_samples(q, dq, ddq)
    data = model.createData()
    out = np.empty((q.shape[0], model.nv, 10 * (model.njoints - 1)))
    for k in range(q.shape[0]):  # Pinocchio evaluates one state at a time
        out[k] = pin.computeJointTorqueRegressor(model, data, q[k], dq[k], ddq[k])
    return out


def pinocchio_rnea(model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Inverse dynamics ``pin.rnea`` over samples, torques shape (n_samples, nv)."""
    q, dq, ddq = _as_samples(q, dq, ddq)
    data = model.createData()
    out = np.empty((q.shape[0], model.nv))
    for k in range(q.shape[0]):
        out[k] = pin.rnea(model, data, q[k], dq[k], ddq[k])
    return out


def compare_with_pinocchio(
    model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> dict[str, Any]:
    """Compare the hand-derived regressor with Pinocchio on given states.

    Parameters
    ----------
    model :
        Fixed-base serial Pinocchio model (see :func:`~ident.dynamics.chain.chain_from_model`).
    q, dq, ddq :
        States, shapes (n_samples, nq), (n_samples, nv), (n_samples, nv).

    Returns
    -------
    :
        ``max_abs_error``: largest ``|Y - Y_pin|``; ``max_rel_error``: that divided by
        ``max |Y_pin|`` (the scale of the tensor); ``regressor_scale``: ``max |Y_pin|``;
        ``rnea_max_abs_error`` and ``rnea_max_rel_error``: the same for
        ``Y @ parameters_from_model(model)`` against ``pin.rnea`` [N*m or N];
        ``n_samples``.
    """
    from ident.dynamics.regressor import joint_torque_regressor

    q, dq, ddq = _as_samples(q, dq, ddq)
    chain = chain_from_model(model)
    ours = joint_torque_regressor(chain, q, dq, ddq)
    reference = pinocchio_regressor(model, q, dq, ddq)
    tau = ours @ parameters_from_model(model)
    tau_reference = pinocchio_rnea(model, q, dq, ddq)
    scale = float(np.max(np.abs(reference))) if reference.size else 0.0
    tau_scale = float(np.max(np.abs(tau_reference))) if tau_reference.size else 0.0
    abs_error = float(np.max(np.abs(ours - reference))) if reference.size else 0.0
    tau_error = float(np.max(np.abs(tau - tau_reference))) if tau_reference.size else 0.0
    return {
        "n_samples": int(q.shape[0]),
        "max_abs_error": abs_error,
        "max_rel_error": abs_error / scale if scale > 0.0 else abs_error,
        "regressor_scale": scale,
        "rnea_max_abs_error": tau_error,
        "rnea_max_rel_error": tau_error / tau_scale if tau_scale > 0.0 else tau_error,
    }
