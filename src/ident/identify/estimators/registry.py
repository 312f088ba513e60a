"""The estimator registry: estimators looked up by the name a config gives.

An estimator is a function ``estimate(problem: EstimationProblem) -> Estimate``
(:class:`~ident.identify.estimators.problem.EstimationProblem`,
:class:`~ident.identify.estimation.estimate.Estimate`) with a :class:`Contract` saying what it
guarantees. Registering one makes it available as ``estimation.method: <name>``. The identification
core, the report, the URDF write-back and the warnings read the contract, never the name.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ident.errors import ConfigError

if TYPE_CHECKING:  # annotations only: the problem module does not import the registry
    from ident.identify.estimation.estimate import Estimate
    from ident.identify.estimators.problem import EstimationProblem

__all__ = [
    "CONTRACTS",
    "ESTIMATORS",
    "UNCONSTRAINED",
    "Contract",
    "Estimator",
    "get_contract",
    "get_estimator",
    "get_repeated_estimator",
    "register_estimator",
    "register_repeated",
]

Estimator = Callable[["EstimationProblem"], "Estimate"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Contract:
    """What an estimator guarantees; the rest of the tool reads this, never the name.

    Attributes
    ----------
    consistent :
        Every estimate it returns (``success``) carries standard parameters ``theta`` that are
        physically consistent: the report says "consistent", the identified URDF is written,
        no inconsistency warning. False: the estimate is reported as is and its consistency
        checked (as for OLS/WLS).
    needs_prior :
        It is pulled toward the nominal parameters with ``problem.regularization`` (the weight
        ``estimation.regularization.weight``, chosen on held-out rows when ``auto``).
    supports_chunks :
        It works on the reduced rows alone (``problem.observations``), so logs of any length
        and several logs can use it. Every estimator of the registry's interface does.
    least_squares :
        It *is* the plain least-squares estimate of the base parameters (OLS or WLS): its
        result is the "identified" estimate itself. Others are computed beside the WLS one,
        WLS-weighted (the essential parameters and the reference comparison use WLS).
    """

    consistent: bool
    needs_prior: bool
    supports_chunks: bool = True
    least_squares: bool = False


#: The contract of an estimator that promises nothing (the default of :func:`register_estimator`).
UNCONSTRAINED = Contract(consistent=False, needs_prior=False)

#: Registered estimators by name.
ESTIMATORS: dict[str, Estimator] = {}
#: Their contracts by name.
CONTRACTS: dict[str, Contract] = {}
#: Factories of an estimator for many problems of one structure, by name (optional).
REPEATED: dict[str, Callable[[], Estimator]] = {}


def register_estimator(
    name: str, fn: Estimator | None = None, *, contract: Contract = UNCONSTRAINED
) -> Callable:
    """Register ``fn`` as the estimator ``name``; also usable as a decorator.

    ``register_estimator("mine", fn, contract=Contract(...))`` or
    ``@register_estimator("mine", contract=...)``. Without a contract the estimator promises
    nothing (:data:`UNCONSTRAINED`): its estimate is checked for consistency and never
    written to a URDF as a consistent model.

    Raises
    ------
    ValueError
        If ``name`` is already registered (remove it from :data:`ESTIMATORS` first to
        replace it).
    """

    def add(estimator: Estimator) -> Estimator:
        if name in ESTIMATORS:
            raise ValueError(f"estimator {name!r} is registered twice")
        ESTIMATORS[name] = estimator
        CONTRACTS[name] = contract
        return estimator

    return add if fn is None else add(fn)


def get_estimator(name: str) -> Estimator:
    """The estimator registered as ``name``.

    Raises
    ------
    ConfigError
        For an unknown name, listing the known ones and the closest match.
    """
    if name not in ESTIMATORS:
        close = difflib.get_close_matches(name, list(ESTIMATORS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(
            f"unknown estimator {name!r}{hint} (known: {', '.join(sorted(ESTIMATORS))})."
        )
    return ESTIMATORS[name]


def get_contract(name: str) -> Contract:
    """The :class:`Contract` of the estimator ``name`` (ConfigError for an unknown name)."""
    get_estimator(name)
    return CONTRACTS.get(name, UNCONSTRAINED)


def register_repeated(name: str, factory: Callable[[], Estimator]) -> None:
    """Register ``factory()`` as the estimator ``name`` for many problems of one structure.

    The instance may keep work between calls (a compiled program) and must return what the
    registered estimator returns for each problem, to the solver's tolerance.
    """
    REPEATED[name] = factory


def get_repeated_estimator(name: str) -> Estimator:
    """The estimator ``name`` for many problems of one structure (a weight grid, a bootstrap):
    a fresh instance of its :func:`register_repeated` factory, else the estimator itself.

    Raises
    ------
    ConfigError
        For an unknown name.
    """
    estimator = get_estimator(name)
    factory = REPEATED.get(name)
    return factory() if factory is not None else estimator
