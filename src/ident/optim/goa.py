"""Grasshopper optimization algorithm (GOA).

Follows Saremi, Mirjalili & Lewis (2017) and their reference MATLAB code. Each iteration,
for every grasshopper ``i``

    x_i <- c * sum_{j != i} c * (ub - lb) / 2 * s(d~_ij) * (x_j - x_i) / d_ij  +  T,

where ``T`` is the best solution so far (the target), ``d_ij`` the Euclidean distance,
``s(r) = f e^{-r/l} - e^{-r}`` with ``f = 0.5``, ``l = 1.5``, and ``c`` decreases linearly from
``c_max = 1`` to ``c_min = 4e-5`` over the iteration budget: ``c = c_max - t (c_max - c_min) /
maxiter`` for ``t = 1 .. maxiter``. The **distance normalization** of the reference code maps
every distance into ``[2, 4)`` before applying ``s``: ``d~_ij = 2 + rem(d_ij, 2)`` (it keeps
``s`` in its repulsion/comfort zone whatever the box size). The reference code pads an odd
dimension with a dummy variable; we do not (it only exists for its 2-D plotting helper).

Boundary handling (explicit, as in the reference code): coordinates outside the box are set on
the bound. Cost: O(popsize^2 * dim) per iteration (vectorized).

References
----------
S. Saremi, S. Mirjalili, A. Lewis, "Grasshopper Optimisation Algorithm: Theory and
Application", Advances in Engineering Software 105, 2017, pp. 30-47.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.optim._common import Problem, clip_to_bounds

__all__ = ["DEFAULTS", "c_schedule", "run", "social_force"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {"c_max": 1.0, "c_min": 4e-5, "attraction": 0.5, "length": 1.5}
DEFAULT_POPSIZE = 30
MIN_POPSIZE = 2


def c_schedule(maxiter: int, c_max: float = 1.0, c_min: float = 4e-5) -> FloatArray:
    """``c = c_max - t (c_max - c_min) / maxiter`` for t = 1 .. maxiter (ends at ``c_min``)."""
    t = np.arange(1, maxiter + 1)
    return c_max - t * (c_max - c_min) / max(maxiter, 1)


def social_force(r: FloatArray, attraction: float = 0.5, length: float = 1.5) -> FloatArray:
    """``s(r) = f exp(-r / l) - exp(-r)`` (eq. 2.3 of the GOA paper)."""
    return attraction * np.exp(-r / length) - np.exp(-r)


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run GOA on ``problem``; returns the method-specific parts (none)."""
    n = problem.popsize
    half_span = problem.span / 2.0
    cs = c_schedule(problem.maxiter, opts["c_max"], opts["c_min"])
    x = problem.initial_population(x0)
    problem.evaluate(x)
    stop = problem.end_iteration(0)
    off_diag = ~np.eye(n, dtype=bool)
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        c = cs[t - 1]
        diff = x[None, :, :] - x[:, None, :]  # diff[i, j] = x_j - x_i
        dist = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        s = social_force(2.0 + np.remainder(dist, 2.0), opts["attraction"], opts["length"])
        w = np.where(off_diag, s / (dist + np.finfo(float).eps), 0.0)
        total = np.einsum("ij,ijk->ik", w, diff) * (c * half_span)
        x = c * total + problem.best_x
        clip_to_bounds(x, problem.lower, problem.upper)
        problem.evaluate(x)
        stop = problem.end_iteration(t)
    return {}
