"""Pinocchio as the independent reference for the hand-derived regressor.

Pinocchio evaluates one state at a time, so these functions loop over samples; they are for
verification (tests, ``ident verify``, benchmarks), not for the inner loops.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ident.dynamics.base_parameters import (
    METHODS,
    RANK_RTOL,
    compute_base_parameters,
    nearly_aligned_axes,
)
from ident.dynamics.chain import FloatArray, KinematicChain, chain_from_model
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.dynamics.regressor import joint_torque_regressor
from ident.dynamics.stage import paper_stages, stage_observation_matrix, stage_states

__all__ = [
    "compare_with_pinocchio",
    "pinocchio_regressor",
    "pinocchio_rnea",
    "verification_report",
]


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
    if model.nv != model.njoints - 1:  # mimic joints: Pinocchio's regressor rejects them
        return _regressor_from_rnea(model, q, dq, ddq)
    data = model.createData()
    out = np.empty((q.shape[0], model.nv, 10 * (model.njoints - 1)))
    for k in range(q.shape[0]):  # Pinocchio evaluates one state at a time
        out[k] = pin.computeJointTorqueRegressor(model, data, q[k], dq[k], ddq[k])
    return out


def _regressor_from_rnea(
    model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Pinocchio's regressor column by column, for a model with mimic joints, which
    ``pin.computeJointTorqueRegressor`` does not take: RNEA is linear in the parameters, so
    column ``c`` is ``rnea(phi_0 + e_c) - rnea(phi_0)`` with every body's parameters ``phi_0``
    (a unit mass at the frame origin, representable by ``pin.Inertia`` as ``e_c`` alone is not).
    Shape (n_samples, nv, 10 * (njoints - 1))."""
    n_bodies = model.njoints - 1
    base = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    probe = model.copy()
    for b in range(1, model.njoints):
        probe.inertias[b] = pin.Inertia.FromDynamicParameters(base)
    reference = pinocchio_rnea(probe, q, dq, ddq)
    out = np.empty((q.shape[0], model.nv, 10 * n_bodies))
    for b in range(n_bodies):
        for k in range(10):
            probe.inertias[b + 1] = pin.Inertia.FromDynamicParameters(base + np.eye(10)[k])
            out[:, :, 10 * b + k] = pinocchio_rnea(probe, q, dq, ddq) - reference
        probe.inertias[b + 1] = pin.Inertia.FromDynamicParameters(base)
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


def _counts_both_methods(W: FloatArray, names: list[str]) -> dict[str, dict[str, int]]:
    return {method: compute_base_parameters(W, names, method=method).counts() for method in METHODS}


def verification_report(
    model: pin.Model,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    *,
    parameter_map: FloatArray | None = None,
    map_label: str = "dh_frames",
) -> dict[str, Any]:
    """Everything ``ident verify`` reports, as a JSON-ready dict.

    Parameters
    ----------
    model :
        Fixed-base serial Pinocchio model.
    q, dq, ddq :
        Random states within the limits, shapes (n_samples, nq), (n_samples, nv), (n_samples, nv).
    parameter_map :
        Optional block-diagonal matrix ``M`` (10 n, 10 n) from another parameterization to the
        model's (e.g. :meth:`ident.model.Robot.dh_to_model_parameters`); the base-parameter
        counts are then also given for ``W @ M`` under ``map_label``.
    map_label :
        Key of those extra counts.

    Returns
    -------
    :
        The keys of :func:`compare_with_pinocchio`, plus ``rank``, ``n_independent``,
        ``n_dependent``, ``n_unidentifiable``, ``n_params`` (QR method, whole robot),
        ``methods`` (counts of both methods), ``ranks_agree``, ``rank_tolerance``,
        ``nearly_aligned_axes`` (:func:`ident.dynamics.base_parameters.nearly_aligned_axes`
        as dicts ``joint, other, deviation_rad, nominal_deg``), and ``stages``: for a 6-joint
        robot the paper's ``wrist`` and ``arm`` stages (moving joints from the same states,
        other joints held at 0.618 of their range, see
        :func:`ident.dynamics.stage.default_held_positions`), each with ``moving_joints``,
        ``torque_rows``, ``bodies`` (1-based), ``held_positions`` [rad or m] and the counts of
        both methods; empty otherwise.
    """
    q, dq, ddq = _as_samples(q, dq, ddq)
    report: dict[str, Any] = {"robot": model.name, "n_joints": model.nv}
    report.update(compare_with_pinocchio(model, q, dq, ddq))
    chain = chain_from_model(model)
    names = list(parameter_names(chain.n_bodies))
    W = joint_torque_regressor(chain, q, dq, ddq).reshape(-1, len(names))
    methods = _counts_both_methods(W, names)
    report.update(methods["qr"])
    report["methods"] = methods
    report["ranks_agree"] = len({counts["rank"] for counts in methods.values()}) == 1
    # axes aligned up to rounding, which the rank tolerance treats as exactly aligned
    report["rank_tolerance"] = RANK_RTOL
    report["nearly_aligned_axes"] = [
        {"joint": a, "other": b, "deviation_rad": d, "nominal_deg": n}
        for a, b, d, n in nearly_aligned_axes(chain)
    ]
    if parameter_map is not None:
        report[map_label] = _counts_both_methods(W @ parameter_map, names)
    report["stages"] = _paper_stage_counts(chain, q, dq, ddq, names, parameter_map, map_label)
    return report


def _paper_stage_counts(
    chain: KinematicChain,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    names: list[str],
    parameter_map: FloatArray | None,
    map_label: str,
) -> dict[str, Any]:
    """The ``stages`` entry of :func:`verification_report`: per paper stage of a 6R arm without
    mimic joints, its joints, rows, bodies (1-based), held positions and base-parameter counts
    from the states ``q, dq, ddq`` (n_samples, nq or nv); empty for any other robot."""
    stages: dict[str, Any] = {}
    if chain.n_joints != 6 or chain.coupled:  # the paper's stages: a 6R arm, no mimic
        return stages
    for name, stage in paper_stages(chain).items():
        moving = list(stage.moving_joints)
        states = stage_states(stage, q[:, moving], dq[:, moving], ddq[:, moving], chain.nq)
        W_stage = stage_observation_matrix(chain, stage, *states)
        columns = stage.columns
        entry: dict[str, Any] = {
            "moving_joints": [j + 1 for j in stage.moving_joints],
            "torque_rows": [j + 1 for j in stage.torque_rows],
            "bodies": [b + 1 for b in stage.bodies],
            "held_positions": [stage.held_positions[j] for j in stage.held_joints],
            "methods": _counts_both_methods(W_stage, [names[c] for c in columns]),
        }
        if parameter_map is not None:
            mapped = W_stage @ parameter_map[np.ix_(columns, columns)]
            entry[map_label] = _counts_both_methods(mapped, [names[c] for c in columns])
        stages[name] = entry
    return stages
