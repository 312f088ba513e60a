"""What the report shows of the constrained estimation: per estimator and link, JSON-ready.

Pure functions of an :class:`~ident.identify.core.IdentifyResult` (nothing is written here):
:func:`consistency_summary` for ``result.json`` and the report table, :func:`identified_model`
for the whole-model URDF and its sidecar.
"""

from __future__ import annotations

import math
from typing import Any

from ident.identify.urdf_update import IdentifiedModel, identified_urdf

__all__ = ["consistency_summary", "identified_model"]


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def consistency_summary(result: Any) -> dict | None:
    """Per-estimator residuals and per-link consistency of an identify result (JSON-ready).

    ``held_out_relative_residual`` is the pipeline's held-out prediction (rows above the
    velocity threshold) where it was computed: the configured least-squares estimate
    (``identified``) and the constrained one. None when the result has no consistency data.
    """
    consistent = result.consistent
    if consistent is None:
        return None
    held_out = {}
    ls_method = result.config.estimation.least_squares_method
    if "identified" in result.predictions:
        held_out[ls_method] = result.predictions["identified"].metrics.total_relative_residual
    if consistent.method in result.predictions:
        metrics = result.predictions[consistent.method].metrics
        held_out[consistent.method] = metrics.total_relative_residual
    estimators = {}
    for name, est in consistent.estimates.items():
        value = held_out.get(name)
        estimators[name] = {
            "success": bool(est.success),
            "message": est.message,
            "relative_residual": est.relative_residual,
            "held_out_relative_residual": None if value is None else _finite(value),
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
    choice = consistent.regularization
    out: dict = {
        "method": consistent.method,
        "seconds": consistent.seconds,
        "estimators": estimators,
        "regularization": None,
    }
    if consistent.constrained is not None:
        out["regularization"] = {
            "weight": consistent.constrained.regularization,
            "prior": "nominal",
            "directions": consistent.problem.options.get("prior_directions", "unseen"),
            "friction": consistent.problem.options.get("friction", "least_squares"),
            "chosen_on": None if choice is None else "last 20 % of the identification rows",
            "grid": None if choice is None else choice.grid.tolist(),
            "validation_relative_residual": None
            if choice is None
            else [_finite(v) for v in choice.validation_residual],
        }
    return out


def identified_model(result: Any) -> IdentifiedModel | None:
    """Whole-model URDF and sidecar of the configured estimate, or None.

    Written only for an estimator whose contract promises consistent standard parameters
    (:class:`~ident.identify.estimators.registry.Contract`, ``consistent``) and whose estimate
    succeeded; an unconstrained estimator's parameters are reported, never written as a model.

    Raises
    ------
    ModelError
        If the estimate is inconsistent although promised (a broken estimator) or the URDF
        unreadable.
    """
    consistent = result.consistent
    if consistent is None or consistent.constrained is None:
        return None
    if not consistent.contract.consistent or not consistent.constrained.success:
        return None
    from ident.model.selection import load_robot

    est = consistent.constrained
    robot = load_robot(result.config.robot)  # the robot the identification used (chain, locks)
    return identified_urdf(
        robot.urdf_text,
        robot.model,
        est.theta,
        consistent.structure.names,
        nominal=consistent.structure.nominal,
        coupled_pair=result.parameters.terms.coupled_wrist,
        source=str(result.config.robot.urdf),
    )
