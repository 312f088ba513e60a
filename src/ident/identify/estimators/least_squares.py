"""``ols`` and ``wls``: unconstrained least squares of the base parameters.

They solve the reduced problem exactly as :func:`ident.identify.estimation.estimate.least_squares`
solves the rows (same estimate, standard deviations and residuals). When the problem carries a
:class:`~ident.identify.estimators.problem.ParameterStructure`, the result also holds the
standard parameters closest to the nominal ones that give the estimated base values
(:meth:`~ident.identify.estimators.problem.EstimationProblem.standard_completion`) and their
per-body consistency: what writing an unconstrained estimate into a URDF would give.
"""

from __future__ import annotations

import dataclasses

from ident.identify.estimation.consistency import body_consistency
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimators.problem import EstimationProblem
from ident.identify.estimators.registry import Contract, register_estimator

__all__ = ["ols", "wls"]

_LEAST_SQUARES = Contract(consistent=False, needs_prior=False, least_squares=True)


def _solve(problem: EstimationProblem, method: str) -> Estimate:
    est = least_squares_reduced(
        problem.observations,
        problem.names,
        method=method,
        wls_passes=problem.wls_passes,
    )
    structure = problem.structure
    if structure is None:
        return est
    theta = problem.standard_completion(est.x)
    return dataclasses.replace(
        est,
        theta=theta,
        consistency=body_consistency(theta, structure.bodies, structure.body_names),
        distance_to_nominal=structure.distance_to_nominal(theta),
    )


@register_estimator("ols", contract=_LEAST_SQUARES)
def ols(problem: EstimationProblem) -> Estimate:
    """Ordinary least squares of the base parameters (one pooled noise variance)."""
    return _solve(problem, "ols")


@register_estimator("wls", contract=_LEAST_SQUARES)
def wls(problem: EstimationProblem) -> Estimate:
    """Weighted least squares: one noise variance per group, ``problem.wls_passes`` solves."""
    return _solve(problem, "wls")
