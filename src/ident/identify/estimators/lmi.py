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

import numpy as np

from ident.identify.consistency import PSEUDO_INERTIA_BASIS
from ident.identify.estimate import Estimate
from ident.identify.estimators.constrained import (
    scaled_problem,
    single_threaded_blas,
)
from ident.identify.estimators.problem import EstimationProblem, result_from_theta
from ident.identify.estimators.registry import Contract, register_estimator

__all__ = ["DEFAULT_EPSILON", "lmi"]

DEFAULT_EPSILON = 1e-6


@register_estimator("lmi", contract=Contract(consistent=True, needs_prior=True))
def lmi(problem: EstimationProblem) -> Estimate:
    """Physically consistent WLS estimate by an SDP (see the module docstring)."""
    with single_threaded_blas():
        return _lmi(problem)


def _lmi(problem: EstimationProblem) -> Estimate:
    import cvxpy as cp  # optional dependency: only this estimator needs it

    sp = scaled_problem(problem, "lmi")
    structure = sp.structure
    epsilon = float(problem.options.get("epsilon", DEFAULT_EPSILON))
    use_ellipsoids = bool(problem.options.get("ellipsoids", True))
    n_std = structure.n_std
    u = cp.Variable(n_std)
    basis = PSEUDO_INERTIA_BASIS.reshape(10, 16).T  # (16, 10): vec(J) = basis @ theta_b
    constraints = []
    for b, index in enumerate(structure.bodies):
        # J(theta_b / scale_b) is the body's pseudo-inertia in its own scale (dimensionless)
        offset = structure.nominal[index] / sp.scale[index]
        J = cp.reshape(basis @ offset + basis @ u[index], (4, 4), order="C")
        J = (J + J.T) / 2
        constraints.append(J >> epsilon * np.eye(4))
        ellipsoid = structure.ellipsoids[b] if structure.ellipsoids else None
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
        constraints.append(u[sp.fixed] == sp.fixed_u)
    weight = problem.regularization
    objective = cp.sum_squares(sp.A @ u - sp.b) + cp.sum_squares(sp.prior_rows @ u)
    program = cp.Problem(cp.Minimize(objective), constraints)
    try:
        with warnings.catch_warnings():  # an inaccurate optimum is said in the message
            warnings.simplefilter("ignore", UserWarning)
            program.solve(solver=cp.CLARABEL)
        status = program.status
    except cp.error.SolverError as e:
        status = f"solver error: {e}"
    success = status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and u.value is not None
    theta = sp.theta(u.value if u.value is not None else np.zeros(n_std))
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
        regularization=weight,
    )
