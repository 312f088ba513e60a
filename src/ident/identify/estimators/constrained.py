"""Shared set-up of the constrained estimators: weights, scaled least-squares terms.

Both constrained estimators minimize, over the standard parameters ``theta``,

``(1/m) sum_j w_j^2 ||R_j K theta - z_j||^2 + lambda ||D (theta - theta_nominal)||^2``

with ``m`` the number of rows and ``w_j = 1 / sigma_j`` the WLS weights (so the first term is
about 1 at the WLS optimum: the mean squared *standardized* residual), ``D`` the diagonal of
:meth:`~ident.identify.estimators.problem.ParameterStructure.prior_weights`. They work on
``theta = nominal + S u`` with ``S = diag(scale)`` so that every unknown is of order one.

The prior weight used is ``lambda + lambda_0`` with a fixed floor ``lambda_0``
(:data:`PRIOR_FLOOR`, option ``prior_floor``). Directions of ``theta`` that the data do not
see change no prediction, so held-out data cannot choose their weight; without a floor the
constraints alone leave them anywhere on the optimal face (measured on a simulated UR5: a
standard-parameter error 12x larger than with the floor, see
``docs/consistent-identification.md``). With the data term about 1 per row, ``1e-4`` costs a
departure of one scale unit from the nominal as much as a 1e-4 increase of the mean squared
standardized residual: it fixes the unseen directions and leaves the seen ones to the data.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.identify.estimate import least_squares_reduced
from ident.identify.estimators.problem import EstimationProblem, ParameterStructure

__all__ = ["PRIOR_FLOOR", "ScaledProblem", "prior_weight", "scaled_problem", "single_threaded_blas"]

#: Fixed part of the prior weight (see the module docstring).
PRIOR_FLOOR = 1e-4

FloatArray = npt.NDArray[np.float64]


def single_threaded_blas() -> contextlib.AbstractContextManager:
    """BLAS on one thread: these problems are small (tens of columns) and many (a weight
    grid, trust-region steps), and threads only add synchronisation (3x to 30x slower
    measured on a loaded 2-core machine)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional speed-up
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


@dataclass(frozen=True, eq=False)
class ScaledProblem:
    """``min ||A u - b||^2 + lambda ||P u||^2`` with ``theta = nominal + scale * u``.

    Attributes
    ----------
    A, b :
        Data term, shapes (n, n_std) and (n,).
    prior :
        Diagonal ``P = D S`` of the prior term, shape (n_std,) (1 on inertial parameters).
    scale :
        ``S``, shape (n_std,).
    sigma :
        Per-group noise standard deviation behind the weights [N*m], shape (n_groups,).
    structure :
        The parameter structure.
    """

    A: FloatArray
    b: FloatArray
    prior: FloatArray
    scale: FloatArray
    sigma: FloatArray
    structure: ParameterStructure

    def theta(self, u: npt.ArrayLike) -> FloatArray:
        """Standard parameters of the scaled unknowns."""
        return self.structure.nominal + self.scale * np.asarray(u, dtype=float)


def prior_weight(problem: EstimationProblem) -> float:
    """``lambda + lambda_0``: the problem's weight plus the floor (option ``prior_floor``)."""
    return float(problem.regularization) + float(problem.options.get("prior_floor", PRIOR_FLOOR))


def scaled_problem(problem: EstimationProblem, method: str) -> ScaledProblem:
    """Weights (given, or from WLS), stacked triangle and scaling of ``problem``."""
    structure = problem.require_structure(method)
    obs = problem.observations
    if problem.weights is not None:
        weights = np.asarray(problem.weights, dtype=float)
        with np.errstate(divide="ignore"):
            sigma = np.where(weights > 0, 1.0 / weights, np.inf)
    else:
        wls = least_squares_reduced(obs, problem.names, method="wls", wls_passes=problem.wls_passes)
        sigma = np.asarray(wls.sigma, dtype=float)
        weights = np.where(obs.n_rows > 0, 1.0 / sigma, 0.0)
    Rs, zs = obs.stacked(weights)
    scale = structure.scales()
    RK = Rs @ problem.K
    root_m = np.sqrt(max(problem.n_rows, 1))
    A = RK * scale[None, :] / root_m
    b = (zs - RK @ structure.nominal) / root_m
    prior = structure.prior_weights() * scale
    return ScaledProblem(A=A, b=b, prior=prior, scale=scale, sigma=sigma, structure=structure)
