"""What the report shows of the constrained estimation: per estimator and link, JSON-ready.

Pure functions of an :class:`~ident.identify.pipeline.core.IdentifyResult` (nothing is written
here):
:func:`consistency_summary` for ``result.json`` and the report table, :func:`identified_model`
for the whole-model URDF and its sidecar.
"""

from __future__ import annotations

import math
from typing import Any

from ident.identify.model_files.urdf_update import IdentifiedModel, identified_urdf

__all__ = ["consistency_summary", "identified_model", "model_identification"]


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def consistency_summary(result: Any) -> dict | None:
    """Per-estimator residuals and per-link consistency of an identify result (JSON-ready).

    ``held_out_relative_residual`` is the pipeline's held-out prediction (rows above the
    velocity threshold) where it was computed: the configured least-squares estimate
    (``identified``), the constrained one and the identified model's estimator
    (``model``: its method, time and prior weight, when it is not the configured one). None
    when the result has no consistency data.
    """
    consistent = result.consistent
    if consistent is None:
        return None
    model: Any = getattr(result, "model", None)
    beside = model is not None and model is not consistent
    held_out = {}
    ls_method = result.config.estimation.least_squares_method
    if "identified" in result.predictions:
        held_out[ls_method] = result.predictions["identified"].metrics.total_relative_residual
    for ident in (consistent, model) if beside else (consistent,):
        if ident.method in result.predictions:
            held_out[ident.method] = result.predictions[
                ident.method
            ].metrics.total_relative_residual
    estimates = dict(consistent.estimates)
    if beside:
        estimates[model.method] = model.estimates[model.method]
    out: dict = {
        "method": consistent.method,
        "seconds": consistent.seconds,
        "estimators": {
            name: _estimator_entry(est, held_out.get(name)) for name, est in estimates.items()
        },
        "regularization": _regularization(consistent),
        "model": None
        if not beside
        else {
            "method": model.method,
            "seconds": model.seconds,
            "regularization": _regularization(model),
        },
    }
    return out


def _estimator_entry(est: Any, held_out: float | None) -> dict:
    """One estimator's entry of :func:`consistency_summary`."""
    return {
        "success": bool(est.success),
        "message": est.message,
        "relative_residual": est.relative_residual,
        "held_out_relative_residual": None if held_out is None else _finite(held_out),
        "consistent": est.consistent,
        "distance_to_nominal": _finite(est.distance_to_nominal),
        "regularization": est.regularization,
        "links": [
            {
                "link": c.body,
                "consistent": c.consistent,
                "min_pseudo_inertia_eigenvalue": _finite(c.min_eigenvalue),
                "mass": _finite(c.mass),
                "problems": list(c.problems),
            }
            for c in est.consistency
        ],
    }


def _regularization(ident: Any) -> dict | None:
    """The prior of an identification's constrained estimate (None without one)."""
    if ident.constrained is None:
        return None
    choice = ident.regularization
    return {
        "weight": ident.constrained.regularization,
        "prior": "nominal",
        "directions": ident.problem.options.get("prior_directions", "unseen"),
        "friction": ident.problem.options.get("friction", "least_squares"),
        "chosen_on": None if choice is None else "last 20 % of the identification rows",
        "grid": None if choice is None else choice.grid.tolist(),
        "validation_relative_residual": None
        if choice is None
        else [_finite(v) for v in choice.validation_residual],
    }


def identified_model(result: Any) -> IdentifiedModel | None:
    """Whole-model URDF and sidecar of the identified model (``result.model``), or None.

    Written only for an estimator whose contract promises consistent standard parameters
    (:class:`~ident.identify.estimators.registry.Contract`, ``consistent``) and whose estimate
    succeeded; an unconstrained estimator's parameters are reported, never written as a model.
    ``result.model`` is the configured estimator when it promises consistency, else the
    default consistent one computed beside (:data:`ident.identify.pipeline.core.MODEL_METHOD`).

    Raises
    ------
    ModelError
        If the estimate is inconsistent although promised (a broken estimator) or the URDF
        unreadable.
    """
    model = model_identification(result)
    if model is None:
        return None
    from ident.model.selection import load_robot

    est = model.constrained
    robot = load_robot(result.config.robot)  # the robot the identification used (chain, locks)
    return identified_urdf(
        robot.urdf_text,
        robot.model,
        est.theta,
        model.structure.names,
        nominal=model.structure.nominal,
        coupled_pair=result.parameters.terms.coupled_wrist,
        source=str(result.config.robot.urdf),
    )


def model_identification(result: Any) -> Any:
    """The :class:`~ident.identify.estimators.ConsistentIdentification` whose constrained
    estimate is the identified model (``result.model``),
    or None when there is none to write: ``urdf_update.model: none``, an estimator that does
    not promise consistency, or a failed estimate."""
    model = getattr(result, "model", None)
    if model is None or model.constrained is None:
        return None
    if not model.contract.consistent or not model.constrained.success:
        return None
    return model
