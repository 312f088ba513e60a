"""The estimator registry: estimators looked up by the name a config gives.

An estimator is a function ``estimate(problem: EstimationProblem) -> Estimate``
(:class:`~ident.identify.estimators.problem.EstimationProblem`,
:class:`~ident.identify.estimate.Estimate`). Registering one makes it available as
``estimation.method: <name>``.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from typing import TYPE_CHECKING

from ident.errors import ConfigError

if TYPE_CHECKING:  # annotations only: the problem module does not import the registry
    from ident.identify.estimate import Estimate
    from ident.identify.estimators.problem import EstimationProblem

__all__ = ["ESTIMATORS", "Estimator", "get_estimator", "register_estimator"]

Estimator = Callable[["EstimationProblem"], "Estimate"]

#: Registered estimators by name.
ESTIMATORS: dict[str, Estimator] = {}


def register_estimator(name: str, fn: Estimator | None = None) -> Callable:
    """Register ``fn`` as the estimator ``name``; also usable as a decorator.

    ``register_estimator("mine", fn)`` or ``@register_estimator("mine")``.

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
