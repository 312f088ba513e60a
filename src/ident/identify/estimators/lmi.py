"""``lmi``: physically consistent estimate by semidefinite programming.

Minimizes the WLS-weighted cost of :mod:`ident.identify.estimators.constrained` over the
standard parameters subject to

- every identified body's pseudo-inertia ``J(theta_b) >= eps * J_scale`` (positive definite:
  the parameters of a body with a positive mass density; Wensing, Kim and Slotine 2017);
- optionally ``tr(J(theta_b) Q_b) >= 0`` for the body's bounding ellipsoid ``Q_b``
  (:mod:`ident.robot.ellipsoids`): the mass lies inside the ellipsoid;
- viscous and Coulomb friction and rotor inertia ``>= 0``.

``J_scale = diag(m L^2, m L^2, m L^2, m)`` is the body's scale (see
:meth:`~ident.identify.estimators.problem.ParameterStructure.scales`), so ``eps`` is
dimensionless. The program is written with cvxpy and solved by Clarabel, an interior-point
conic solver: a few hundredths of a second for a 6-joint arm, whatever the log length.

Options (``problem.options``): ``epsilon`` (default 1e-6), ``ellipsoids`` (default True: use
the structure's ellipsoids when it has some), ``prior_floor``, ``prior_directions`` and
``friction`` (see :mod:`ident.identify.estimators.constrained`).

References
----------
P. M. Wensing, S. Kim and J.-J. E. Slotine, "Linear matrix inequalities for physically
consistent inertial parameter identification: a statistical perspective on the mass
distribution", IEEE Robotics and Automation Letters 3(1), 2017.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ident.blas import one_blas_thread
from ident.identify.estimation.consistency import PSEUDO_INERTIA_BASIS
from ident.identify.estimation.estimate import Estimate
from ident.identify.estimators.constrained import (
    ScaledProblem,
    scaled_problem,
)
from ident.identify.estimators.problem import EstimationProblem, result_from_theta
from ident.identify.estimators.registry import Contract, register_estimator, register_repeated

__all__ = ["DEFAULT_EPSILON", "LmiResolver", "lmi"]

DEFAULT_EPSILON = 1e-6


@register_estimator("lmi", contract=Contract(consistent=True, needs_prior=True))
def lmi(problem: EstimationProblem) -> Estimate:
    """Physically consistent WLS estimate by an SDP (see the module docstring)."""
    with one_blas_thread():
        return _lmi(problem)


def _lmi(problem: EstimationProblem) -> Estimate:
    import cvxpy as cp  # optional dependency: only this estimator needs it

    sp = scaled_problem(problem, "lmi")
    options = _options(problem)
    u, program = _program(sp, *options, sp.A, sp.b, sp.prior_rows, sp.fixed_u)
    return _estimate(problem, sp, u, _solve(program, cp))


def _options(problem: EstimationProblem) -> tuple[float, bool]:
    """``epsilon`` and ``ellipsoids`` of ``problem.options``."""
    epsilon = float(problem.options.get("epsilon", DEFAULT_EPSILON))
    return epsilon, bool(problem.options.get("ellipsoids", True))


def _program(
    sp: ScaledProblem,
    epsilon: float,
    use_ellipsoids: bool,
    A: Any,
    b: Any,
    prior_rows: Any,
    fixed_u: Any,
) -> tuple[Any, Any]:
    """The cvxpy variable ``u`` (n_std,) and program of the module docstring.

    The data ``A`` (n, n_std), ``b`` (n,), ``prior_rows`` (n_prior, n_std) and ``fixed_u``
    (n_fixed,) are arrays, or cvxpy Parameters of those shapes (:class:`LmiResolver`); the
    constraints come from ``sp``'s structure, scale and fixed indices.
    """
    import cvxpy as cp

    structure = sp.structure
    u = cp.Variable(structure.n_std)
    basis = PSEUDO_INERTIA_BASIS.reshape(10, 16).T  # (16, 10): vec(J) = basis @ theta_b
    constraints = []
    for k, index in enumerate(structure.bodies):
        # J(theta_b / scale_b) is the body's pseudo-inertia in its own scale (dimensionless)
        offset = structure.nominal[index] / sp.scale[index]
        J = cp.reshape(basis @ offset + basis @ u[index], (4, 4), order="C")
        J = (J + J.T) / 2
        constraints.append(J >> epsilon * np.eye(4))
        ellipsoid = structure.ellipsoids[k] if structure.ellipsoids else None
        if use_ellipsoids and ellipsoid is not None:
            Q = ellipsoid.homogeneous_matrix()
            # tr(J(theta_b) Q) is linear in theta_b: coefficients tr(M_k Q)
            coefficients = np.einsum("kij,ji->k", PSEUDO_INERTIA_BASIS, Q) * sp.scale[index]
            # theta_b = scale_b * (offset + u_b)
            constraints.append(coefficients @ (offset + u[index]) >= 0.0)
    nonnegative = structure.nonnegative
    if nonnegative.size:
        constraints.append(
            cp.multiply(sp.scale[nonnegative], u[nonnegative]) >= -structure.nominal[nonnegative]
        )
    if sp.fixed.size:
        constraints.append(u[sp.fixed] == fixed_u)
    objective = cp.sum_squares(A @ u - b) + cp.sum_squares(prior_rows @ u)
    return u, cp.Problem(cp.Minimize(objective), constraints)


def _solve(program: Any, cp: Any) -> str:
    """Solve with Clarabel; the status (a solver error as a status string)."""
    try:
        with warnings.catch_warnings():  # an inaccurate optimum is said in the message
            warnings.simplefilter("ignore", UserWarning)
            program.solve(solver=cp.CLARABEL)
        return str(program.status)
    except cp.error.SolverError as e:
        return f"solver error: {e}"


def _estimate(problem: EstimationProblem, sp: ScaledProblem, u: Any, status: str) -> Estimate:
    """The :class:`Estimate` of a solved program."""
    import cvxpy as cp

    success = status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and u.value is not None
    theta = sp.theta(u.value if u.value is not None else np.zeros(sp.structure.n_std))
    message = "ok" if success else f"LMI: Clarabel finished with status {status!r}"
    if status == cp.OPTIMAL_INACCURATE:
        message = "LMI: Clarabel reports an inaccurate optimum (consistency checked below)"
    return result_from_theta(
        problem,
        theta,
        method="lmi",
        sigma=sp.sigma,
        success=success,
        message=message,
        regularization=problem.regularization,
    )


class LmiResolver:
    """The ``lmi`` estimator for many problems of one structure (a bootstrap, a weight grid).

    Builds the cvxpy program once per structure, option and shape, with the data ``A``,
    ``b``, the prior rows and the fixed friction values as cvxpy Parameters, and re-solves it
    with each problem's values: cvxpy compiles the program (about 0.1 s for a 7-joint arm,
    most of a plain :func:`lmi` call) once instead of once per problem. Same program, same
    solver: the estimate of each problem is :func:`lmi`'s (to the solver's tolerance).
    """

    def __init__(self) -> None:
        self._programs: dict[tuple, tuple[Any, Any, Any, dict[str, Any]]] = {}

    @property
    def n_programs(self) -> int:
        """Programs compiled so far (one per structure, option set and shape)."""
        return len(self._programs)

    def __call__(self, problem: EstimationProblem) -> Estimate:
        with one_blas_thread():
            return self._solve(problem)

    def _solve(self, problem: EstimationProblem) -> Estimate:
        import cvxpy as cp

        sp = scaled_problem(problem, "lmi")
        options = _options(problem)
        key = (
            id(sp.structure),
            options,
            sp.A.shape,
            sp.prior_rows.shape,
            tuple(int(i) for i in sp.fixed),
        )
        entry = self._programs.get(key)
        if entry is None or entry[0] is not sp.structure:  # an id reused by a new structure
            params = {
                name: cp.Parameter(getattr(sp, name).shape)
                for name in ("A", "b", "prior_rows", "fixed_u")
                if getattr(sp, name).size
            }
            u, program = _program(
                sp,
                *options,
                params.get("A", sp.A),
                params.get("b", sp.b),
                params.get("prior_rows", sp.prior_rows),
                params.get("fixed_u", sp.fixed_u),
            )
            entry = (sp.structure, u, program, params)
            self._programs[key] = entry
        _, u, program, params = entry
        for name, parameter in params.items():
            parameter.value = getattr(sp, name)
        return _estimate(problem, sp, u, _solve(program, cp))


register_repeated("lmi", LmiResolver)
