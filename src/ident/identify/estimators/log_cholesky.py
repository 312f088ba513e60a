"""``log_cholesky``: physically consistent estimate by a smooth unconstrained parametrization.

Every body's pseudo-inertia is written ``J = U U^T`` with

``U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]]``,

so any ``psi = (alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3)`` (Pinocchio's order) gives a
positive definite ``J``, and every positive definite ``J`` has one ``psi`` (Rucker and Wensing
2022). Friction and rotor inertia are ``v^2``, offsets free. The cost of
:mod:`ident.identify.estimators.constrained` is then an unconstrained nonlinear least-squares
problem, solved by ``scipy.optimize.least_squares`` (trust region) with the exact Jacobian
(Pinocchio's ``LogCholeskyParameters.calculateJacobian``). It needs no conic solver and
cross-checks :mod:`ident.identify.estimators.lmi`; being local, it starts from the nominal
bodies (made positive definite when they are not) and the unconstrained extras.

Options (``problem.options``): ``prior_floor``, ``prior_directions`` and ``friction`` (see
:mod:`ident.identify.estimators.constrained`), ``max_nfev`` (default 300), ``start`` (a
``theta`` to start from).

References
----------
C. Rucker and P. M. Wensing, "Smooth parameterization of rigid-body inertia", IEEE Robotics
and Automation Letters 7(2), 2022.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.optimize

from ident.blas import one_blas_thread
from ident.identify.estimation.consistency import parameters_from_pseudo_inertia, pseudo_inertia
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimators.constrained import (
    scaled_problem,
)
from ident.identify.estimators.problem import (
    EstimationProblem,
    ParameterStructure,
    result_from_theta,
)
from ident.identify.estimators.registry import Contract, register_estimator

__all__ = ["log_cholesky", "log_cholesky_from_parameters", "parameters_from_log_cholesky"]

FloatArray = npt.NDArray[np.float64]

_MIN_EIGENVALUE = 1e-4  # relative floor when a nominal body must be made positive definite


def parameters_from_log_cholesky(psi: npt.ArrayLike) -> FloatArray:
    """Standard parameters (10,) of log-Cholesky parameters ``psi`` (10,) (Pinocchio)."""
    return np.asarray(pin.LogCholeskyParameters(np.asarray(psi, dtype=float)).toDynamicParameters())


def log_cholesky_from_parameters(theta_b: npt.ArrayLike) -> FloatArray:
    """Log-Cholesky parameters (10,) of one body's standard parameters (10,).

    The body must be strictly consistent (positive definite pseudo-inertia).
    ``J = V V^T`` with ``V`` upper triangular is a Cholesky factorization of ``J`` with rows
    and columns reversed.

    Raises
    ------
    numpy.linalg.LinAlgError
        If the pseudo-inertia is not positive definite.
    """
    J = pseudo_inertia(theta_b)
    flip = J[::-1, ::-1]
    V = np.linalg.cholesky(flip)[::-1, ::-1]  # upper triangular, J = V V^T
    alpha = np.log(V[3, 3])
    U = V / V[3, 3]
    return np.array(
        [
            alpha,
            np.log(U[0, 0]),
            np.log(U[1, 1]),
            np.log(U[2, 2]),
            U[0, 1],
            U[1, 2],
            U[0, 2],
            U[0, 3],
            U[1, 3],
            U[2, 3],
        ]
    )


def _positive_definite(theta_b: FloatArray, scale_b: FloatArray) -> FloatArray:
    """``theta_b`` with its scaled pseudo-inertia's eigenvalues raised to a small floor."""
    J = pseudo_inertia(theta_b / scale_b)
    values, vectors = np.linalg.eigh(J)
    floor = _MIN_EIGENVALUE * max(float(values[-1]), 1.0)
    J = (vectors * np.maximum(values, floor)) @ vectors.T
    return parameters_from_pseudo_inertia(J) * scale_b


@register_estimator("log_cholesky", contract=Contract(consistent=True, needs_prior=True))
def log_cholesky(problem: EstimationProblem) -> Estimate:
    """Physically consistent WLS estimate by the log-Cholesky parametrization."""
    with one_blas_thread():
        return _log_cholesky(problem)


def _log_cholesky(problem: EstimationProblem) -> Estimate:
    sp = scaled_problem(problem, "log_cholesky")
    structure = sp.structure
    n_std = structure.n_std
    inertial = structure.bodies.reshape(-1)
    free = np.setdiff1d(np.setdiff1d(np.arange(n_std), inertial), structure.nonnegative)
    weight = problem.regularization
    # prior rows M u with u = (theta - nominal) / scale
    G = sp.prior_rows / sp.scale[None, :]
    # the data term in theta: A_theta = A / scale
    A_theta = sp.A / sp.scale[None, :]
    b_theta = sp.b + A_theta @ structure.nominal

    v0 = _start(problem, sp, free)
    active = np.setdiff1d(np.arange(n_std), sp.fixed)

    def full(v_active: FloatArray) -> FloatArray:
        v = v0.copy()
        v[active] = v_active
        return v

    def residual(v_active: FloatArray) -> FloatArray:
        theta, _ = _theta_and_jacobian(full(v_active), structure, free)
        return np.concatenate([A_theta @ theta - b_theta, G @ (theta - structure.nominal)])

    def jacobian(v_active: FloatArray) -> FloatArray:
        _, jac = _theta_and_jacobian(full(v_active), structure, free)
        jac = jac[:, active]
        return np.vstack([A_theta @ jac, G @ jac])

    # a trial step may overflow exp(); the trust region then shrinks it (not an error)
    with np.errstate(over="ignore", invalid="ignore"):
        solution = _solve(residual, jacobian, v0[active], problem)
    theta, _ = _theta_and_jacobian(full(solution.x), structure, free)
    success, message = _outcome(solution, theta)
    return result_from_theta(
        problem,
        theta,
        method="log_cholesky",
        sigma=sp.sigma,
        success=success,
        message=message,
        regularization=weight,
    )


def _theta_and_jacobian(
    v: FloatArray, structure: ParameterStructure, free: npt.NDArray[np.intp]
) -> tuple[FloatArray, FloatArray]:
    """The standard parameters of the log-Cholesky variables ``v`` and their Jacobian
    ``d theta / d v``, shapes (n_std,) and (n_std, n_std): each body's 10 through
    :class:`pinocchio.LogCholeskyParameters`, the nonnegative ones (friction) squared, the
    ``free`` ones as they are."""
    n_std = structure.n_std
    nonnegative = structure.nonnegative
    theta = np.empty(n_std)
    jac = np.zeros((n_std, n_std))
    for index in structure.bodies:
        lc = pin.LogCholeskyParameters(v[index])
        theta[index] = lc.toDynamicParameters()
        jac[np.ix_(index, index)] = lc.calculateJacobian()
    theta[nonnegative] = v[nonnegative] ** 2
    jac[nonnegative, nonnegative] = 2.0 * v[nonnegative]
    theta[free] = v[free]
    jac[free, free] = 1.0
    return theta, jac


def _outcome(solution: Any, theta: FloatArray) -> tuple[bool, str]:
    """Whether the solver's ``solution`` (``scipy.optimize.least_squares``) with the standard
    parameters ``theta`` is an estimate, and the message saying how it ended."""
    # Every finite point of the parametrization is consistent, so an estimate stopped by the
    # evaluation budget is usable: that happens when the optimum lies on the consistency
    # boundary (a degenerate body), which the parametrization reaches only asymptotically.
    success = bool(solution.status >= 0 and np.all(np.isfinite(theta)))
    if solution.status == 0:
        message = (
            f"log-Cholesky: stopped after {solution.nfev} evaluations, still approaching the "
            "consistency boundary (a body near degenerate); the LMI estimator reaches it exactly"
        )
    else:
        message = "ok" if success else f"log-Cholesky: {solution.message}"
    return success, message


def _start(problem: EstimationProblem, sp: Any, free: npt.NDArray[np.intp]) -> FloatArray:
    """The starting point in the log-Cholesky variables: ``options["start"]`` or the WLS
    completion with nominal inertials, every body made positive definite."""
    structure = sp.structure
    inertial = structure.bodies.reshape(-1)
    nonnegative = structure.nonnegative
    start = problem.options.get("start")
    if start is None:
        ls = least_squares_reduced(
            problem.observations, problem.names, method="wls", wls_passes=problem.wls_passes
        )
        start = problem.standard_completion(ls.x)
        start[inertial] = structure.nominal[inertial]
    start = np.asarray(start, dtype=float)
    v0 = np.empty(structure.n_std)
    for index in structure.bodies:
        body = _positive_definite(start[index], sp.scale[index])
        v0[index] = log_cholesky_from_parameters(body)
    v0[nonnegative] = np.sqrt(np.maximum(start[nonnegative], 0.0)) + 1e-6
    v0[free] = start[free]
    # friction kept at its least-squares value (all in ``nonnegative``: theta = v^2)
    v0[sp.fixed] = np.sqrt(structure.nominal[sp.fixed] + sp.scale[sp.fixed] * sp.fixed_u)
    return v0


def _solve(
    residual: Callable[[FloatArray], FloatArray],
    jacobian: Callable[[FloatArray], FloatArray],
    v0: FloatArray,
    problem: EstimationProblem,
) -> scipy.optimize.OptimizeResult:
    """``scipy.optimize.least_squares`` (trust region, exact Jacobian) from ``v0``."""
    return scipy.optimize.least_squares(
        residual,
        v0,
        jac=jacobian,
        method="trf",
        x_scale="jac",
        max_nfev=int(problem.options.get("max_nfev", 300)),
        ftol=1e-10,
        xtol=1e-10,
        gtol=1e-10,
    )
