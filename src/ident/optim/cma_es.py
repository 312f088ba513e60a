"""CMA-ES through the ``cma`` package (Hansen), behind the same contract as the other methods.

The search runs in the unit box: ``x = low + u (high - low)`` with ``u`` in ``[0, 1]^dim``, so a
single step size ``sigma0`` (a fraction of every variable's range, default 0.3) fits variables of
any unit. The box is enforced by ``cma``'s ``BoundTransform`` (every evaluated point is inside
the bounds).

Iteration 0 evaluates the initial population (``x0`` rows first, the rest uniform, as for every
method); the CMA-ES mean starts at its best point. Every later iteration asks ``cma`` for one
population of ``popsize`` (the ``lambda`` of CMA-ES, fixed by the caller so that the evaluation
budget is exact), evaluates it in one vectorized call and tells ``cma`` the values (``+inf``
values, from a non-finite objective, are told as the worst finite value plus one).

When ``cma`` declares convergence (``tolfun``, ``tolx``, flat fitness, stagnation...) before the
budget is used, the strategy restarts (``restarts=True``, default) with the same population
size from a uniform random mean and ``sigma0``: the rest of the budget is spent searching
elsewhere, the best point ever evaluated is kept by the common machinery.

Randomness: every draw comes from the run's generator (``cma``'s ``randn`` option is given
``rng.standard_normal``; its global ``numpy.random`` seeding is switched off with
``seed=nan``), so the same ``rng`` gives the same result.

References
----------
N. Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772, 2016; the ``cma``
package, https://github.com/CMA-ES/pycma.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import OptimizationError
from ident.optim._common import Problem

__all__ = ["DEFAULTS", "run"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {"sigma0": 0.3, "restarts": True}
DEFAULT_POPSIZE = 20
MIN_POPSIZE = 2


def _strategy(mean: FloatArray, sigma0: float, popsize: int, rng: np.random.Generator) -> Any:
    import cma

    options = {
        "bounds": [0.0, 1.0],
        "popsize": popsize,
        "randn": lambda *shape: rng.standard_normal(shape),
        "seed": np.nan,  # no global numpy seeding: draws come from ``randn``
        "verbose": -9,
        "verb_disp": 0,
        "verb_log": 0,
        "maxiter": np.inf,
        "maxfevals": np.inf,
    }
    return cma.CMAEvolutionStrategy(np.clip(mean, 0.0, 1.0), sigma0, options)


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run CMA-ES on ``problem``; returns the method-specific parts (the restart iterations)."""
    sigma0 = float(opts["sigma0"])
    if not 0.0 < sigma0 <= 1.0:
        raise OptimizationError(f"cma needs 0 < sigma0 <= 1 (fraction of the range), got {sigma0}")
    lo, span = problem.lower, problem.span
    x = problem.initial_population(x0)
    f = problem.evaluate(x)
    stop = problem.end_iteration(0)
    start = x[int(np.argmin(f))] if np.any(np.isfinite(f)) else x[0]
    es = _strategy((start - lo) / span, sigma0, problem.popsize, problem.rng)
    restarts: list[int] = []
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        if es.stop():
            if not opts["restarts"]:
                problem.stop_reason = f"cma converged: {', '.join(sorted(es.stop()))}"
                break
            restarts.append(t)
            es = _strategy(problem.rng.random(problem.dim), sigma0, problem.popsize, problem.rng)
        u = np.asarray(es.ask(), dtype=float)
        x = lo + np.clip(u, 0.0, 1.0) * span
        f = problem.evaluate(x)
        finite = np.isfinite(f)
        worst = float(np.max(f[finite])) + 1.0 if finite.any() else 1.0
        es.tell(list(u), list(np.where(finite, f, worst)))
        stop = problem.end_iteration(t)
    return {"mutation_iterations": np.asarray(restarts, dtype=np.int64)}
