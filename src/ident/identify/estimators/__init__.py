"""Estimators of the identification model, behind one registry.

Every estimator is a function ``estimate(problem: EstimationProblem) -> Estimate`` registered
by name (``estimation.method`` in an identify config) with a :class:`Contract` (consistent,
needs a prior, supports chunks, is the least-squares estimate itself):

``ols``, ``wls``
    Unconstrained least squares of the base parameters (:mod:`.least_squares`).
``lmi``
    Physically consistent standard parameters by semidefinite programming (:mod:`.lmi`).
``log_cholesky``
    The same problem through a smooth unconstrained parametrization (:mod:`.log_cholesky`).

See ``docs/consistent-identification.md`` ("Extending") to add one.
"""

from ident.identify.estimators import least_squares, lmi, log_cholesky  # noqa: F401 (register)
from ident.identify.estimators.identification import (
    ConsistentIdentification,
    bounding_ellipsoids,
    consistent_identification_reduced,
)
from ident.identify.estimators.problem import (
    EstimationProblem,
    ParameterStructure,
    result_from_theta,
)
from ident.identify.estimators.registry import (
    CONTRACTS,
    ESTIMATORS,
    Contract,
    get_contract,
    get_estimator,
    get_repeated_estimator,
    register_estimator,
)
from ident.identify.estimators.regularization import (
    DEFAULT_GRID,
    RegularizationChoice,
    choose_regularization,
)

__all__ = [
    "CONTRACTS",
    "DEFAULT_GRID",
    "ESTIMATORS",
    "ConsistentIdentification",
    "Contract",
    "EstimationProblem",
    "ParameterStructure",
    "RegularizationChoice",
    "bounding_ellipsoids",
    "choose_regularization",
    "consistent_identification_reduced",
    "get_contract",
    "get_estimator",
    "get_repeated_estimator",
    "register_estimator",
    "result_from_theta",
]
