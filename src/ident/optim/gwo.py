"""Grey wolf optimizer (GWO).

Follows Mirjalili, Mirjalili & Lewis (2014) and their reference MATLAB code: the three best
solutions found so far lead (alpha, beta, delta); ``a`` decreases linearly from 2 to 0 over the
iteration budget (``a = 2 - 2 t / maxiter``, ``t = 0 .. maxiter-1``); for every wolf and
dimension, with fresh uniform ``r1, r2`` per leader,

    A = 2 a r1 - a,  C = 2 r2,  X_k = x_lead_k - A |C x_lead_k - x|,  x <- (X_1 + X_2 + X_3) / 3.

The leaders are the best three *distinct evaluations* so far (the reference code's update can
copy alpha into beta without demoting; we keep a proper top three).

Boundary handling (explicit, as in the reference code): coordinates outside the box are set on
the bound.

References
----------
S. Mirjalili, S. M. Mirjalili, A. Lewis, "Grey Wolf Optimizer", Advances in Engineering
Software 69, 2014, pp. 46-61.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.optim._common import Problem, clip_to_bounds
from ident.optim.woa import a_schedule

__all__ = ["DEFAULTS", "run"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {}
DEFAULT_POPSIZE = 30


def _top3(
    lx: FloatArray, lf: FloatArray, x: FloatArray, f: FloatArray
) -> tuple[FloatArray, FloatArray]:
    cx, cf = np.vstack([lx, x]), np.concatenate([lf, f])
    idx = np.argsort(cf, kind="stable")[:3]
    return cx[idx], cf[idx]


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run GWO on ``problem``; returns the method-specific parts (none)."""
    n, dim, rng = problem.popsize, problem.dim, problem.rng
    a_all = a_schedule(problem.maxiter)
    x = problem.initial_population(x0)
    f = problem.evaluate(x)
    lead_x, lead_f = _top3(np.zeros((0, dim)), np.zeros(0), x, f)
    if lead_x.shape[0] < 3:  # tiny populations: repeat the best
        reps = np.r_[np.arange(lead_x.shape[0]), np.zeros(3 - lead_x.shape[0], int)]
        lead_x, lead_f = lead_x[reps], lead_f[reps]
    stop = problem.end_iteration(0)
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        a = a_all[t - 1]
        r1 = rng.random((3, n, dim))
        r2 = rng.random((3, n, dim))
        big_a = 2.0 * a * r1 - a
        big_c = 2.0 * r2
        lead = lead_x[:, None, :]  # (3, 1, dim)
        x = np.mean(lead - big_a * np.abs(big_c * lead - x[None]), axis=0)
        clip_to_bounds(x, problem.lower, problem.upper)
        f = problem.evaluate(x)
        lead_x, lead_f = _top3(lead_x, lead_f, x, f)
        stop = problem.end_iteration(t)
    return {}
