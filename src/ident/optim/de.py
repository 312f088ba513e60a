"""Differential evolution, DE/rand/1/bin.

Storn & Price (1997): for every target ``x_i`` pick three distinct random indices ``r1, r2, r3``
(all different from ``i``), mutant ``v = x_r1 + F (x_r2 - x_r3)``, binomial crossover
(each coordinate from ``v`` with probability ``CR``, and at least coordinate ``j_rand``), then
greedy one-to-one selection. Defaults ``F = 0.5``, ``CR = 0.9`` (Storn & Price's recommended
start). A generation is built from the old population and evaluated in one call (the classic
scheme; scipy's ``updating='deferred'``).

Boundary handling (explicit): a trial coordinate outside the box is replaced by a uniform draw
in the box (as scipy does).

References
----------
R. Storn, K. Price, "Differential Evolution - A Simple and Efficient Heuristic for Global
Optimization over Continuous Spaces", Journal of Global Optimization 11, 1997, pp. 341-359.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import OptimizationError
from ident.optim._common import Problem

__all__ = ["DEFAULTS", "distinct_indices", "run"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {"F": 0.5, "CR": 0.9}
DEFAULT_POPSIZE = 30
MIN_POPSIZE = 4


def distinct_indices(n: int, rng: np.random.Generator) -> npt.NDArray[np.int64]:
    """Shape (n, 3): per row three distinct indices in ``0..n-1``, all different from the row."""
    keys = rng.random((n, n))
    np.fill_diagonal(keys, np.inf)
    return np.argsort(keys, axis=1)[:, :3]


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run DE/rand/1/bin on ``problem``; returns the method-specific parts (none)."""
    scale, cr = float(opts["F"]), float(opts["CR"])
    if not (0.0 <= cr <= 1.0 and scale > 0):
        raise OptimizationError(f"de needs F > 0 and 0 <= CR <= 1, got F={scale}, CR={cr}")
    n, dim, rng = problem.popsize, problem.dim, problem.rng
    lo, hi = problem.lower, problem.upper
    x = problem.initial_population(x0)
    f = problem.evaluate(x)
    stop = problem.end_iteration(0)
    rows = np.arange(n)
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        r = distinct_indices(n, rng)
        mutant = x[r[:, 0]] + scale * (x[r[:, 1]] - x[r[:, 2]])
        cross = rng.random((n, dim)) < cr
        cross[rows, rng.integers(0, dim, size=n)] = True
        trial = np.where(cross, mutant, x)
        out = (trial < lo) | (trial > hi)
        if out.any():
            trial[out] = (lo + rng.random((n, dim)) * (hi - lo))[out]
        ft = problem.evaluate(trial)
        better = ft <= f
        x[better], f[better] = trial[better], ft[better]
        stop = problem.end_iteration(t)
    return {}
