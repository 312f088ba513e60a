"""Standard particle swarm optimization (constriction form).

The paper compares eMuPSO with "the Standard PSO (PSO) [35]" ("SPSO" in Tables 6 and 8). Its
reference list is not in our copy of the text; we read [35] as the standard defined by
Bratton & Kennedy (2007), which fixes the Clerc-Kennedy constriction form

    v <- chi * (v + c1 r1 (p_i - x) + c2 r2 (l_i - x)),   x <- x + v,

with ``chi = 0.72984``, ``c1 = c2 = 2.05`` (so ``chi * c = 1.49618``), uniform initial
positions, and either a global-best (``topology="global"``, default here) or a ring
(``topology="ring"``, each particle sees itself and its two neighbours) topology; ``l_i`` is
the best personal best the particle sees. The paper's PSO results (Sphere 4.9e-44 at 30
particles) are typical of the global-best version, hence the default.

Boundary handling (explicit): Bratton & Kennedy let particles fly outside the box and do not
evaluate them; that wastes evaluations of a fixed budget, so we use the SPSO-2007 rule instead:
a coordinate leaving the box is set on the bound and its velocity component set to zero.
Initial velocities are ``(u - x) / 2`` with ``u`` uniform in the box (SPSO 2007). An optional
``vmax_fraction`` clamps velocities (off by default, constriction needs no clamping).

References
----------
D. Bratton, J. Kennedy, "Defining a standard for particle swarm optimization", IEEE Swarm
Intelligence Symposium, 2007, pp. 120-127.
M. Clerc, J. Kennedy, "The particle swarm - explosion, stability, and convergence in a
multidimensional complex space", IEEE Trans. Evol. Comput. 6(1), 2002, pp. 58-73.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import OptimizationError
from ident.optim._common import Problem

__all__ = ["DEFAULTS", "absorb_bounds", "run"]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {
    "chi": 0.72984,
    "c1": 2.05,
    "c2": 2.05,
    "topology": "global",
    "vmax_fraction": None,
}
DEFAULT_POPSIZE = 30
TOPOLOGIES = ("global", "ring")


def absorb_bounds(
    x: FloatArray, v: FloatArray, lower: FloatArray, upper: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """SPSO-2007 rule: out-of-box coordinates go to the bound, their velocity to zero."""
    outside = (x < lower) | (x > upper)
    if outside.any():
        v[outside] = 0.0
        np.clip(x, lower, upper, out=x)
    return x, v


def _neighbour_best(p: FloatArray, pf: FloatArray, topology: str) -> FloatArray:
    """Best personal best each particle sees, shape (n, dim)."""
    if topology == "global":
        return np.broadcast_to(p[int(np.argmin(pf))], p.shape)
    # ring: self, left and right neighbours
    cand = np.stack([np.roll(pf, 1), pf, np.roll(pf, -1)])  # (3, n)
    which = np.argmin(cand, axis=0)  # 0 = left, 1 = self, 2 = right
    idx = (np.arange(pf.shape[0]) + np.array([-1, 0, 1])[which]) % pf.shape[0]
    return p[idx]


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run standard PSO on ``problem``; returns the method-specific parts (none)."""
    if opts["topology"] not in TOPOLOGIES:
        raise OptimizationError(
            f"pso option topology = {opts['topology']!r}; choose one of {TOPOLOGIES}"
        )
    n, lo, hi = problem.popsize, problem.lower, problem.upper
    rng = problem.rng
    chi, c1, c2 = float(opts["chi"]), float(opts["c1"]), float(opts["c2"])
    vmax = None if opts["vmax_fraction"] is None else opts["vmax_fraction"] * problem.span

    x = problem.initial_population(x0)
    v = (problem.uniform(n) - x) / 2.0
    f = problem.evaluate(x)
    p, pf = x.copy(), f.copy()
    stop = problem.end_iteration(0)
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        best = _neighbour_best(p, pf, opts["topology"])
        r1 = rng.random((n, problem.dim))
        r2 = rng.random((n, problem.dim))
        v += c1 * r1 * (p - x)
        v += c2 * r2 * (best - x)
        v *= chi
        if vmax is not None:
            np.clip(v, -vmax, vmax, out=v)
        x += v
        absorb_bounds(x, v, lo, hi)
        f = problem.evaluate(x)
        better = f < pf
        p[better] = x[better]
        pf[better] = f[better]
        stop = problem.end_iteration(t)
    return {}
