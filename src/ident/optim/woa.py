"""Whale optimization algorithm (WOA).

Follows the authors' reference MATLAB code (Mirjalili & Lewis 2016), per whale ``i``:

* ``a`` decreases linearly from 2 to 0 over the iteration budget (``a = 2 - 2 t / maxiter``,
  ``t = 0 .. maxiter-1``); ``a2`` from -1 to -2, and ``l = (a2 - 1) * rand + 1`` in ``[a2, 1]``;
* scalars ``r1, r2, p`` per whale: ``A = 2 a r1 - a``, ``C = 2 r2``;
* ``p < 0.5`` and ``|A| < 1``: encircling, ``x = x* - A |C x* - x|`` (``x*`` = best so far);
* ``p < 0.5`` and ``|A| >= 1``: search for prey around a random whale ``x_r``:
  ``x = x_r - A |C x_r - x|``;
* ``p >= 0.5``: spiral, ``x = |x* - x| e^{b l} cos(2 pi l) + x*`` with ``b = 1``.

Boundary handling (explicit, as in the reference code): coordinates outside the box are set on
the bound.

References
----------
S. Mirjalili, A. Lewis, "The Whale Optimization Algorithm", Advances in Engineering Software
95, 2016, pp. 51-67.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.optim._common import Problem, clip_to_bounds

__all__ = ["DEFAULTS", "a_schedule", "run"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {"b": 1.0}
DEFAULT_POPSIZE = 30


def a_schedule(maxiter: int) -> FloatArray:
    """``a = 2 - 2 t / maxiter`` for t = 0 .. maxiter-1 (2 down to just above 0)."""
    return 2.0 - 2.0 * np.arange(maxiter) / max(maxiter, 1)


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run WOA on ``problem``; returns the method-specific parts (none)."""
    n, _dim, rng = problem.popsize, problem.dim, problem.rng
    b = float(opts["b"])
    a_all = a_schedule(problem.maxiter)
    x = problem.initial_population(x0)
    problem.evaluate(x)
    stop = problem.end_iteration(0)
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        a = a_all[t - 1]
        a2 = -1.0 - (t - 1) / problem.maxiter
        leader = problem.best_x
        r1, r2, p = rng.random(n), rng.random(n), rng.random(n)
        big_a = (2.0 * a * r1 - a)[:, None]
        big_c = (2.0 * r2)[:, None]
        l = ((a2 - 1.0) * rng.random(n) + 1.0)[:, None]
        partner = rng.integers(0, n, size=n)
        explore = (np.abs(big_a) >= 1.0)[:, 0]
        ref = np.where(explore[:, None], x[partner], leader)  # x_r or x*
        shrink = ref - big_a * np.abs(big_c * ref - x)
        spiral = np.abs(leader - x) * np.exp(b * l) * np.cos(2.0 * np.pi * l) + leader
        x = np.where((p < 0.5)[:, None], shrink, spiral)
        clip_to_bounds(x, problem.lower, problem.upper)
        problem.evaluate(x)
        stop = problem.end_iteration(t)
    return {}
