"""Choosing the weight of the prior toward the nominal parameters on held-out data.

The prior ``lambda ||D (theta - theta_nominal)||^2`` fixes the directions of ``theta`` that the
data do not see (and pulls the weakly seen ones toward the URDF). Too small a weight lets the
constrained estimate wander along those directions to the edge of physical consistency; too
large a weight biases what the data do see. :func:`choose_regularization` fits every weight of
a grid on the identification rows and keeps the one that predicts the validation rows best
(relative residual), preferring the *smallest* weight whose validation residual is within
``tolerance`` of the best: the weakest prior that predicts unseen data as well as the best
one, so the estimate stays as close to the data as held-out prediction allows.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.identify.estimation.estimate import Estimate
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimators.problem import EstimationProblem
from ident.identify.estimators.registry import get_repeated_estimator

__all__ = ["DEFAULT_GRID", "RegularizationChoice", "choose_regularization"]

FloatArray = npt.NDArray[np.float64]

#: Default weights tried (0 = constraints only).
DEFAULT_GRID: tuple[float, ...] = (0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0)


@dataclass(frozen=True, eq=False)
class RegularizationChoice:
    """The chosen prior weight and what every weight of the grid gave.

    Attributes
    ----------
    weight :
        Chosen ``lambda``.
    grid :
        Weights tried, shape (n_grid,).
    validation_residual :
        Relative residual ``||y - W x|| / ||y||`` on the validation rows per weight,
        shape (n_grid,).
    identification_residual :
        Relative residual on the identification rows per weight, shape (n_grid,).
    consistent :
        Whether every body was consistent per weight, shape (n_grid,).
    estimate :
        The estimate of the chosen weight on the identification rows.
    """

    weight: float
    grid: FloatArray
    validation_residual: FloatArray
    identification_residual: FloatArray
    consistent: npt.NDArray[np.bool_]
    estimate: Estimate


def relative_residual(observations: ReducedObservations, x: npt.ArrayLike) -> float:
    """``||y - W x|| / ||y||`` over every group of reduced rows."""
    total = float(observations.yty.sum())
    return float(np.sqrt(observations.residual_ss(x).sum() / total)) if total > 0 else np.inf


def choose_regularization(
    problem: EstimationProblem,
    validation: ReducedObservations,
    *,
    method: str = "lmi",
    grid: tuple[float, ...] | list[float] = DEFAULT_GRID,
    tolerance: float = 5e-3,
) -> RegularizationChoice:
    """Pick the prior weight of a constrained estimator on held-out rows.

    Parameters
    ----------
    problem :
        Identification problem (its ``regularization`` is ignored).
    validation :
        Reduced validation rows in the same coordinates as ``problem.observations``.
    method :
        Registered estimator that reads ``problem.regularization``.
    grid :
        Weights to try, >= 0.
    tolerance :
        Relative slack: the smallest weight whose validation residual is at most
        ``(1 + tolerance)`` times the smallest one is chosen.
    """
    estimator = get_repeated_estimator(method)  # one program, re-solved per weight
    weights = np.asarray(sorted(float(w) for w in grid))
    if weights.size == 0 or weights[0] < 0:
        raise ValueError(f"grid must hold weights >= 0, got {list(grid)}")
    if problem.weights is None:  # fit the WLS weights once, not once per grid point
        from ident.identify.estimation.estimate import least_squares_reduced

        wls = least_squares_reduced(
            problem.observations, problem.names, method="wls", wls_passes=problem.wls_passes
        )
        w = np.where(problem.observations.n_rows > 0, 1.0 / wls.sigma, 0.0)
        problem = dataclasses.replace(problem, weights=w)
    estimates = [estimator(dataclasses.replace(problem, regularization=w)) for w in weights]
    val = np.array([relative_residual(validation, e.x) if e.success else np.inf for e in estimates])
    ident = np.array([e.relative_residual for e in estimates])
    consistent = np.array([bool(e.consistent) for e in estimates])
    best = float(np.min(val))
    chosen = int(np.flatnonzero(val <= best * (1.0 + tolerance))[0])
    return RegularizationChoice(
        weight=float(weights[chosen]),
        grid=weights,
        validation_residual=val,
        identification_residual=ident,
        consistent=consistent,
        estimate=estimates[chosen],
    )
