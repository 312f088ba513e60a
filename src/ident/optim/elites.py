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
    search = _EliteSearch(violation, lower, upper, n_particles, as_rng(rng))
    message = _run_swarms(search, n_elites, tolerance, maxiter, restarts, callback)
    return search.result(n_elites, message)


def _run_swarms(
    search: _EliteSearch,
    n_elites: int,
    tolerance: float,
    maxiter: int,
    restarts: int,
    callback: Callable[[IntermediateResult], Any] | None,
) -> str:
    """Evaluate and move ``search``'s swarm, a new random one per restart, until ``n_elites``
    elites are found, the callback or the budget stops it; returns why it stopped."""
    attempt, attempt_start = 0, 0
    while True:
        f = search.evaluate()
        search.promote(f, tolerance, n_elites)
        if len(search.elites) >= n_elites:
            return f"{n_elites} elites found" + (
                f" ({attempt} restart{'s' * (attempt > 1)} of the swarm)" if attempt else ""
            )
        if callback is not None and callback(
            IntermediateResult(search.best_x, search.best_f, search.nit, search.nfev)
        ):
            return "stopped by callback"
        if search.nit - attempt_start >= maxiter:
            if attempt < restarts:  # a stalled swarm: start again from new random points
                search.nit += 1  # the new swarm's evaluation is an iteration; maxiter more follow
                attempt, attempt_start = attempt + 1, search.nit
                search.new_swarm()
                continue
            return (
                f"only {len(search.elites)} of {n_elites} elites after {search.nit} iterations "
                f"({attempt + 1} swarms of {maxiter}; least violation {search.best_f:.3g}): the "
                "search box holds too few designs that meet the constraints"
            )
        search.nit += 1
        search.move()


class _EliteSearch:
    """The state of :func:`find_feasible_elites`: the swarm, the elites, the counters.

    Attributes
    ----------
    x, v :
        Positions and velocities of the particles, shape (n_particles, dim).
    p, pf :
        Personal best positions (n_particles, dim) and their violations (n_particles,),
        ``inf`` for a new particle.
    elites, viols :
        Compliant points found (each shape (dim,)) and their violations, in order.
    best_x, best_f :
        The least-violating point evaluated so far and its violation.
    nit, nfev :
        Iterations after the initial swarm and evaluations of the violation.
    """

    def __init__(
        self,
        violation: Callable[[FloatArray], Any],
        lower: FloatArray,
        upper: FloatArray,
        n_particles: int,
        gen: np.random.Generator,
    ) -> None:
        self.violation, self.gen = violation, gen
        self.lower, self.upper, self.span = lower, upper, upper - lower
        self.n_particles = n_particles
        self.new_swarm()
        self.elites: list[FloatArray] = []
        self.viols: list[float] = []
        self.best_x, self.best_f = self.x[0].copy(), np.inf
        self.nfev, self.nit, self.warned = 0, 0, False

    def _uniform(self, n: int) -> FloatArray:
        """``n`` points drawn uniformly in the box, shape (n, dim)."""
        return self.lower + self.gen.random((n, self.lower.shape[0])) * self.span

    def new_swarm(self) -> None:
        """Random positions, velocities towards other random points, no personal best."""
        self.x = self._uniform(self.n_particles)
        self.v = (self._uniform(self.n_particles) - self.x) / 2.0
        self.p, self.pf = self.x.copy(), np.full(self.n_particles, np.inf)

    def evaluate(self) -> FloatArray:
        """Violations of the particles, shape (n_particles,), NaN/inf as ``inf`` (an
        :class:`IdentWarning` the first time); the personal and overall bests updated."""
        f = np.asarray(self.violation(self.x), dtype=float)
        if f.shape != (self.n_particles,):
            raise OptimizationError(
                f"violation returned shape {f.shape}; expected ({self.n_particles},)"
            )
        self.nfev += self.n_particles
        bad = ~np.isfinite(f)
        if bad.any():
            f = np.where(bad, np.inf, f)
            if not self.warned:
                self.warned = True
                warnings.warn(  # stacklevel: the caller of find_feasible_elites
                    "violation returned NaN or inf; treated as the worst value",
                    IdentWarning,
                    stacklevel=3,
                )
        better = f < self.pf
        self.p[better], self.pf[better] = self.x[better], f[better]
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_x, self.best_f = self.x[i].copy(), float(f[i])
        return f

    def promote(self, f: FloatArray, tolerance: float, n_elites: int) -> None:
        """Make compliant particles (``f <= tolerance``) elites, up to ``n_elites`` in all, and
        replace each by a new random particle at rest with no personal best (the swarm is
        not pulled back to the same elite)."""
        take = np.flatnonzero(f <= tolerance)[: n_elites - len(self.elites)]
        if take.size:
            self.elites.extend(self.x[take].copy())
            self.viols.extend(f[take].tolist())
            self.x[take] = self._uniform(take.size)
            self.v[take] = 0.0
            self.p[take], self.pf[take] = self.x[take], np.inf

    def move(self) -> None:
        """One constriction-PSO step towards the personal and global bests, bounds absorbed."""
        g = self.p[int(np.argmin(self.pf))]
        r1, r2 = self.gen.random(self.x.shape), self.gen.random(self.x.shape)
        self.v = _CHI * (self.v + _C * r1 * (self.p - self.x) + _C * r2 * (g - self.x))
        self.x = self.x + self.v
        absorb_bounds(self.x, self.v, self.lower, self.upper)

    def result(self, n_elites: int, message: str) -> EliteSearchResult:
        """The outcome; a success when ``n_elites`` elites were found."""
        k = len(self.elites)
        return EliteSearchResult(
            elites=np.array(self.elites).reshape(k, self.lower.shape[0]),
            violations=np.array(self.viols),
            nit=self.nit,
            nfev=self.nfev,
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
