"""Shared set-up of the constrained estimators: weights, scaled least-squares terms.

Both constrained estimators minimize, over the standard parameters ``theta``,

``(1/m) sum_j w_j^2 ||R_j K theta - z_j||^2 + lambda_0 ||D (theta - theta_nominal)||^2
+ lambda ||G D (theta - theta_nominal)||^2``

with ``m`` the number of rows and ``w_j = 1 / sigma_j`` the WLS weights (so the first term is
about 1 at the WLS optimum: the mean squared *standardized* residual), ``D`` the diagonal of
:meth:`~ident.identify.estimators.problem.ParameterStructure.prior_weights`. They work on
``theta = nominal + S u`` with ``S = diag(scale)`` so that every unknown is of order one.

**Which directions the chosen weight acts on** (option ``prior_directions``). By default
(``"unseen"``) ``G`` projects onto the null space of ``K S``: the directions of ``theta``
that change no base parameter, which no data can see. The prior then chooses, among the
standard parameters with the base values the data and the constraints want, the ones closest
to the nominal, and does not shrink the base parameters the data determine toward the URDF.
``"all"`` (``G = I``) also shrinks the seen directions. On the TX40 log the "unseen" prior
fits and predicts better (relative residual +0.8 % instead of +1.0 % over WLS on the
identification rows, +0.2 % instead of +1.5 % on the whole log, held-out -1.2 % instead of
-0.6 %, friction held in both; ``docs/consistent-identification.md``).

``lambda_0`` (:data:`PRIOR_FLOOR`, option ``prior_floor``) is a fixed floor on every
inertial direction. Directions of ``theta`` that the data do not see change no prediction, so
held-out data cannot choose their weight; without a floor the constraints alone leave them
anywhere on the optimal face (measured on a simulated UR5: standard-parameter errors hundreds
of times larger than with the floor, see ``docs/consistent-identification.md``). With the
data term about 1 per row, ``1e-4`` costs a departure of one scale unit from the nominal as
much as a 1e-4 increase of the mean squared standardized residual; on a poorly exciting log
it also steadies the weakly seen directions.

**Friction** (option ``friction``). With ``"least_squares"`` (default) every viscous and
Coulomb friction parameter that is a base parameter alone (``structure.friction``) and that the
unconstrained minimum of the same weighted cost (the WLS estimate) finds positive is kept at
that value; the others (negative ones) stay free with their sign constraint. The consistency
constraints act on the links' mass distributions; left free, friction columns correlated with
the inertial columns the constraints move absorb part of the correction (on the TX40 log the
wrist's Coulomb friction moves by 4 to 7 %, a third of its standard deviation, and its viscous
friction, which the log does not determine, by 40 to 70 %), so a controller's friction
compensation would change with a constraint that says nothing about friction. Holding them
costs nothing measurable in residual there (+0.81 % over WLS either way). ``"free"``
estimates them jointly: better when WLS's friction is itself poor (a poorly exciting log).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.identify.estimation.estimate import least_squares_reduced
from ident.identify.estimators.problem import EstimationProblem, ParameterStructure

__all__ = [
    "PRIOR_DIRECTIONS",
    "PRIOR_FLOOR",
    "ScaledProblem",
    "scaled_problem",
]

#: Fixed part of the prior weight (see the module docstring).
PRIOR_FLOOR = 1e-4
#: Values of the option ``prior_directions`` (the first is the default).
PRIOR_DIRECTIONS = ("unseen", "all")
#: Values of the option ``friction`` (the first is the default).
FRICTION_MODES = ("least_squares", "free")

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class ScaledProblem:
    """``min ||A u - b||^2 + ||M u||^2`` with ``theta = nominal + scale * u``.

    Subject to ``u[fixed] = fixed_u`` (and each estimator's consistency constraints).

    Attributes
    ----------
    A, b :
        Data term, shapes (n, n_std) and (n,).
    prior :
        Diagonal ``P = D S`` of the prior term, shape (n_std,) (1 on inertial parameters).
    prior_rows :
        ``M``, the weighted prior: rows ``sqrt(lambda_0) P`` (every inertial direction) over
        ``sqrt(lambda) G P`` (see the module docstring), shape (n_prior, n_std).
    fixed :
        Indices of ``theta`` kept at their least-squares values (friction), shape (n_fixed,).
    fixed_u :
        Their scaled values, shape (n_fixed,).
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
    prior_rows: FloatArray
    fixed: npt.NDArray[np.intp]
    fixed_u: FloatArray
    scale: FloatArray
    sigma: FloatArray
    structure: ParameterStructure

    def theta(self, u: npt.ArrayLike) -> FloatArray:
        """Standard parameters of the scaled unknowns."""
        return self.structure.nominal + self.scale * np.asarray(u, dtype=float)


def scaled_problem(problem: EstimationProblem, method: str) -> ScaledProblem:
    """Weights (given, or from WLS), stacked triangle, scaling, prior and fixed friction.

    Raises
    ------
    DataError
        If an option has an unknown value.
    """
    structure = problem.require_structure(method)
    directions = str(problem.options.get("prior_directions", PRIOR_DIRECTIONS[0]))
    friction = str(problem.options.get("friction", FRICTION_MODES[0]))
    for name, value, allowed in (
        ("prior_directions", directions, PRIOR_DIRECTIONS),
        ("friction", friction, FRICTION_MODES),
    ):
        if value not in allowed:
            raise DataError(f"{method}: option {name} = {value!r}; use one of {allowed}.")
    weights, sigma = _group_weights(problem)
    Rs, zs = problem.observations.stacked(weights)
    scale = structure.scales()
    K = problem.K
    RK = Rs @ K
    root_m = np.sqrt(max(problem.n_rows, 1))
    A = RK * scale[None, :] / root_m
    b = (zs - RK @ structure.nominal) / root_m
    prior = structure.prior_weights() * scale
    prior_rows = _prior_rows(problem, K, scale, prior, directions)
    fixed = np.zeros(0, dtype=np.intp)
    fixed_theta = np.zeros(0)
    if friction == "least_squares" and structure.friction.size:
        fixed, fixed_theta = _least_squares_friction(structure.friction, K, Rs, zs)
    return ScaledProblem(
        A=A,
        b=b,
        prior=prior,
        prior_rows=prior_rows,
        fixed=fixed,
        fixed_u=(fixed_theta - structure.nominal[fixed]) / scale[fixed],
        scale=scale,
        sigma=sigma,
        structure=structure,
    )


def _group_weights(problem: EstimationProblem) -> tuple[FloatArray, FloatArray]:
    """The row weight of each group of ``problem``'s rows and the noise standard deviation
    behind it [N*m], shapes (n_groups,): ``problem.weights`` when given (``inf`` where the
    weight is 0), else ``1 / sigma`` of its WLS estimate (0 for a group without rows)."""
    obs = problem.observations
    if problem.weights is not None:
        weights = np.asarray(problem.weights, dtype=float)
        with np.errstate(divide="ignore"):
            sigma = np.where(weights > 0, 1.0 / weights, np.inf)
    else:
        wls = least_squares_reduced(obs, problem.names, method="wls", wls_passes=problem.wls_passes)
        sigma = np.asarray(wls.sigma, dtype=float)
        weights = np.where(obs.n_rows > 0, 1.0 / sigma, 0.0)
    return weights, sigma


def _prior_rows(
    problem: EstimationProblem, K: FloatArray, scale: FloatArray, prior: FloatArray, directions: str
) -> FloatArray:
    """``M`` of :class:`ScaledProblem`: the floor ``sqrt(lambda_0) P`` on every inertial
    direction over ``sqrt(lambda) G P``, ``G`` the identity or, with ``directions ==
    "unseen"``, rows spanning the null space of ``K S`` (the directions no data see); ``scale``
    is ``S`` and ``prior`` the diagonal of ``P``, shapes (n_std,), ``K`` ``problem.K``."""
    G = np.eye(prior.size)
    if directions == "unseen":
        # rows spanning the null space of K S: the directions no data see
        _, s, Vt = np.linalg.svd(K * scale[None, :])
        rank = int(np.sum(s > s[0] * max(K.shape) * np.finfo(float).eps)) if s.size else 0
        G = Vt[rank:]
    floor = float(problem.options.get("prior_floor", PRIOR_FLOOR))
    inertial = np.flatnonzero(prior)
    return np.vstack(
        [
            np.sqrt(floor) * np.diag(prior)[inertial],
            np.sqrt(float(problem.regularization)) * G * prior[None, :],
        ]
    )


def _least_squares_friction(
    friction: npt.NDArray[np.intp], K: FloatArray, Rs: FloatArray, zs: FloatArray
) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """Friction parameters that are a base parameter alone and positive at the unconstrained
    minimum ``x = argmin ||Rs x - zs||`` (the WLS estimate), with their values."""
    x = np.linalg.lstsq(Rs, zs, rcond=None)[0]
    # K comes from a numerical decomposition: entries below 1e-9 of the largest are zeros
    support = np.abs(K) > 1e-9 * np.abs(K).max()
    fixed, values = [], []
    for i in friction:
        (rows,) = np.nonzero(support[:, i])
        if rows.size != 1 or np.count_nonzero(support[rows[0]]) != 1:
            continue  # friction inside a combination: left to the estimator
        value = x[rows[0]] / K[rows[0], i]
        if value > 0:
            fixed.append(int(i))
            values.append(float(value))
    return np.asarray(fixed, dtype=np.intp), np.asarray(values, dtype=float)
