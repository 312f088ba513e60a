"""The paper's "initial elites" stage (section 4.1) and seeding a swarm from elites.

Before eMuPSO optimizes the excitation trajectory, the paper runs a small PSO swarm (ten
particles) whose fitness is the *degree of constraint violation* of each candidate; a particle
that satisfies every constraint (violation 0) is promoted to elite and replaced by a new random
particle, and the search stops when five elites exist. A swarm of twenty particles is then
generated around the elites by Gaussian mutation (:func:`spawn_from_elites`) and passed to
:func:`ident.optim.minimize` as ``x0``.

The PSO used here is the standard constriction PSO of :mod:`ident.optim.pso` (global best,
``chi = 0.72984``, ``c1 = c2 = 2.05``, coordinates leaving the box are set on the bound with zero
velocity). After a promotion the promoted particle's personal best is forgotten, so the swarm
is not pulled back to the same elite (otherwise all elites would be near duplicates).

Beyond the paper: a swarm that has not found every elite after ``maxiter`` iterations is
restarted from new random points (up to ``restarts`` times, keeping the elites found). With
collision constraints the violation has local minima where the whole swarm can settle above
zero (``wrist-fourier`` seed 6: one elite, then 100 iterations at violation 0.047), although
other draws find five elites in a few iterations. A search that succeeds within ``maxiter``
is unchanged.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentWarning, OptimizationError
from ident.optim._common import as_rng, parse_bounds
from ident.optim.pso import absorb_bounds
from ident.optim.result import IntermediateResult

__all__ = ["EliteSearchResult", "find_feasible_elites", "spawn_from_elites"]

FloatArray = npt.NDArray[np.float64]

_CHI, _C = 0.72984, 2.05


@dataclass(frozen=True, eq=False)
class EliteSearchResult:
    """Outcome of :func:`find_feasible_elites`; check ``success`` before use.

    Attributes
    ----------
    elites :
        Compliant points found, shape (k, dim), in the order they were found.
    violations :
        Their violation values (<= ``tolerance``), shape (k,).
    nit, nfev :
        Iterations (after the initial swarm) and evaluations of ``violation`` used.
    success :
        True when ``n_elites`` elites were found.
    message :
        Why the search ended.
    """

    elites: FloatArray
    violations: FloatArray
    nit: int
    nfev: int
    success: bool
    message: str

    def __post_init__(self) -> None:
        for name in ("elites", "violations"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)


def find_feasible_elites(
    violation: Callable[[FloatArray], Any],
    bounds: Any,
    *,
    n_particles: int = 10,
    n_elites: int = 5,
    rng: np.random.Generator | int | None = None,
    maxiter: int = 200,
    tolerance: float = 0.0,
    restarts: int = 3,
    callback: Callable[[IntermediateResult], Any] | None = None,
) -> EliteSearchResult:
    """Search compliant points with a PSO swarm minimizing the constraint violation.

    Parameters
    ----------
    violation :
        Vectorized ``(n, dim) -> (n,)`` degree of violation, >= 0, 0 = compliant. NaN/inf
        are treated as +inf (worst).
    bounds :
        ``(low, high)`` per variable (see :func:`ident.optim.minimize`).
    n_particles :
        Swarm size (paper: 10).
    n_elites :
        Stop when this many compliant points were found (paper: 5).
    rng :
        Generator or seed.
    maxiter :
        Maximum iterations after the initial swarm, per attempt.
    tolerance :
        A point is compliant when ``violation <= tolerance``.
    restarts :
        Attempts after the first, each a new random swarm of ``maxiter`` iterations, made only
        while elites are missing (see the module docstring).
    callback :
        Called after every iteration with the least-violating point so far; True stops.

    Returns
    -------
    :
        :class:`EliteSearchResult` (``success`` False if fewer elites were found).
    """
    lower, upper = parse_bounds(bounds)
    if n_particles < 1 or n_elites < 1 or maxiter < 0 or restarts < 0:
        raise OptimizationError(
            f"need n_particles >= 1, n_elites >= 1, maxiter >= 0, restarts >= 0; got "
            f"{n_particles}, {n_elites}, {maxiter}, {restarts}"
        )
    gen = as_rng(rng)
    span = upper - lower
    dim = lower.shape[0]
    x = lower + gen.random((n_particles, dim)) * span
    v = (lower + gen.random((n_particles, dim)) * span - x) / 2.0
    p, pf = x.copy(), np.full(n_particles, np.inf)
    elites: list[FloatArray] = []
    viols: list[float] = []
    best_x, best_f = x[0].copy(), np.inf
    nfev, nit, warned = 0, 0, False
    attempt, attempt_start = 0, 0
    message = ""
    while True:
        f = np.asarray(violation(x), dtype=float)
        if f.shape != (n_particles,):
            raise OptimizationError(
                f"violation returned shape {f.shape}; expected ({n_particles},)"
            )
        nfev += n_particles
        bad = ~np.isfinite(f)
        if bad.any():
            f = np.where(bad, np.inf, f)
            if not warned:
                warned = True
                warnings.warn(
                    "violation returned NaN or inf; treated as the worst value",
                    IdentWarning,
                    stacklevel=2,
                )
        better = f < pf
        p[better], pf[better] = x[better], f[better]
        i = int(np.argmin(f))
        if f[i] < best_f:
            best_x, best_f = x[i].copy(), float(f[i])
        take = np.flatnonzero(f <= tolerance)[: n_elites - len(elites)]
        if take.size:
            elites.extend(x[take].copy())
            viols.extend(f[take].tolist())
            x[take] = lower + gen.random((take.size, dim)) * span
            v[take] = 0.0
            p[take], pf[take] = x[take], np.inf
        if len(elites) >= n_elites:
            message = f"{n_elites} elites found" + (
                f" ({attempt} restart{'s' * (attempt > 1)} of the swarm)" if attempt else ""
            )
            break
        if callback is not None and callback(IntermediateResult(best_x, best_f, nit, nfev)):
            message = "stopped by callback"
            break
        if nit - attempt_start >= maxiter:
            if attempt < restarts:  # a stalled swarm: start again from new random points
                nit += 1  # the new swarm's evaluation is an iteration; maxiter more follow
                attempt, attempt_start = attempt + 1, nit
                x = lower + gen.random((n_particles, dim)) * span
                v = (lower + gen.random((n_particles, dim)) * span - x) / 2.0
                p, pf = x.copy(), np.full(n_particles, np.inf)
                continue
            message = (
                f"only {len(elites)} of {n_elites} elites after {nit} iterations "
                f"({attempt + 1} swarms of {maxiter}; least violation {best_f:.3g}): the "
                "search box holds too few designs that meet the constraints"
            )
            break
        nit += 1
        g = p[int(np.argmin(pf))]
        r1, r2 = gen.random((n_particles, dim)), gen.random((n_particles, dim))
        v = _CHI * (v + _C * r1 * (p - x) + _C * r2 * (g - x))
        x = x + v
        absorb_bounds(x, v, lower, upper)
    k = len(elites)
    return EliteSearchResult(
        elites=np.array(elites).reshape(k, dim),
        violations=np.array(viols),
        nit=nit,
        nfev=nfev,
        success=k >= n_elites,
        message=message,
    )


def spawn_from_elites(
    elites: Any,
    n: int,
    bounds: Any,
    sigma_fraction: float = 0.1,
    rng: np.random.Generator | int | None = None,
    *,
    include_elites: bool = True,
) -> FloatArray:
    """Gaussian offspring of elites, clipped to the box, to seed a swarm (``x0=``).

    Parameters
    ----------
    elites :
        Shape (k, dim), k >= 1.
    n :
        Number of points returned.
    bounds :
        ``(low, high)`` per variable.
    sigma_fraction :
        Standard deviation as a fraction of each variable's range.
    rng :
        Generator or seed.
    include_elites :
        If True the first ``min(k, n)`` rows are the elites themselves (clipped).

    Returns
    -------
    :
        Shape (n, dim); row ``j`` descends from ``elites[j % k]``.
    """
    lower, upper = parse_bounds(bounds)
    e = np.atleast_2d(np.asarray(elites, dtype=float))
    if e.shape[0] < 1 or e.shape[1] != lower.shape[0]:
        raise OptimizationError(
            f"elites must have shape (k >= 1, {lower.shape[0]}), got {np.shape(elites)}"
        )
    if n < 1 or not sigma_fraction >= 0:
        raise OptimizationError(f"need n >= 1 and sigma_fraction >= 0, got {n}, {sigma_fraction}")
    gen = as_rng(rng)
    centers = e[np.arange(n) % e.shape[0]]
    out = centers + gen.standard_normal(centers.shape) * (sigma_fraction * (upper - lower))
    if include_elites:
        m = min(e.shape[0], n)
        out[:m] = e[:m]
    return np.clip(out, lower, upper)
