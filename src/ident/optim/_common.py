"""Machinery shared by every optimizer: bounds, budget, population evaluation, callback.

Every method is written as ``run(problem, **options) -> dict`` and talks to the objective only
through :class:`Problem`, which

* counts evaluations and never lets ``max_nfev`` be exceeded (one population per iteration,
  plus the initial population: ``nfev = popsize * (nit + 1)``);
* replaces NaN/inf objective values by ``+inf`` (worst), counts them and warns once;
* keeps the best point ever evaluated, so the result never depends on a method's bookkeeping;
* records the per-iteration history and calls the user's callback.
"""

from __future__ import annotations

import difflib
import math
import warnings
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentWarning, OptimizationError
from ident.optim.result import IntermediateResult

__all__ = [
    "Problem",
    "as_rng",
    "check_options",
    "clip_to_bounds",
    "parse_bounds",
    "plan_iterations",
]

FloatArray = npt.NDArray[np.float64]

DEFAULT_MAXITER = 1000


def as_rng(rng: np.random.Generator | int | np.random.SeedSequence | None) -> np.random.Generator:
    """Return a Generator for ``rng`` (a Generator is used as is)."""
    return np.random.default_rng(rng)


def parse_bounds(bounds: Any) -> tuple[FloatArray, FloatArray]:
    """Read bounds as (low, high) arrays of shape (dim,).

    Parameters
    ----------
    bounds :
        A sequence of ``(low, high)`` pairs, or an array of shape (dim, 2) or (2, dim).
        A (2, 2) array is read as (dim, 2), i.e. one row per variable, like scipy.

    Raises
    ------
    OptimizationError
        If the shape is wrong, a value is not finite, or ``low >= high`` for a variable.
    """
    try:
        b = np.asarray(bounds, dtype=float)
    except (TypeError, ValueError) as e:
        raise OptimizationError(
            f"bounds must be (low, high) pairs of numbers, got {bounds!r}"
        ) from e
    if b.ndim != 2 or 2 not in b.shape:
        raise OptimizationError(
            f"bounds must have shape (dim, 2) or (2, dim), got shape {b.shape}; "
            "pass one (low, high) pair per variable."
        )
    if b.shape[1] != 2:
        b = b.T
    lower, upper = b[:, 0].copy(), b[:, 1].copy()
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
        raise OptimizationError("bounds must be finite; a swarm needs a box to sample from.")
    bad = np.flatnonzero(lower >= upper)
    if bad.size:
        i = int(bad[0])
        raise OptimizationError(
            f"bounds of variable {i}: low = {lower[i]} >= high = {upper[i]}; "
            "each pair must satisfy low < high."
        )
    return lower, upper


def clip_to_bounds(x: FloatArray, lower: FloatArray, upper: FloatArray) -> FloatArray:
    """Clip positions (n, dim) to the box, in place, and return them."""
    return np.clip(x, lower, upper, out=x)


def plan_iterations(
    popsize: int, maxiter: int | None, max_nfev: int | None, *, default_maxiter: int
) -> int:
    """Number of iterations that will really be run.

    One iteration evaluates one population; the initial population costs one more, so
    ``nfev = popsize * (maxiter + 1) <= max_nfev``.

    Raises
    ------
    OptimizationError
        If ``max_nfev`` is smaller than one population, or a count is not positive.
    """
    if popsize < 1:
        raise OptimizationError(f"popsize must be >= 1, got {popsize}")
    if maxiter is not None and maxiter < 0:
        raise OptimizationError(f"maxiter must be >= 0, got {maxiter}")
    if max_nfev is None:
        return default_maxiter if maxiter is None else int(maxiter)
    if max_nfev < popsize:
        raise OptimizationError(
            f"max_nfev = {max_nfev} is smaller than one population (popsize = {popsize}); "
            f"give max_nfev >= {popsize} or a smaller popsize."
        )
    by_budget = max_nfev // popsize - 1
    return by_budget if maxiter is None else min(int(maxiter), by_budget)


def check_options(method: str, options: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict:
    """Merge user ``options`` into ``defaults``; unknown names raise with a suggestion."""
    for name in options:
        if name not in defaults:
            close = difflib.get_close_matches(name, list(defaults), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            valid = ", ".join(sorted(defaults)) or "(none)"
            raise OptimizationError(
                f"unknown option '{name}' for method '{method}'{hint}; valid options: {valid}."
            )
    for name, value in options.items():
        _check_option_type(method, name, value, defaults[name])
    merged = dict(defaults)
    merged.update(options)
    return merged


def _check_option_type(method: str, name: str, value: Any, default: Any) -> None:
    """An option takes the kind of its default: a finite number, an integer, a bool, a name."""
    if isinstance(default, bool):
        ok, kind = isinstance(value, bool), "true or false"
    elif isinstance(default, int):
        ok, kind = isinstance(value, int) and not isinstance(value, bool), "an integer"
    elif isinstance(default, float) or default is None:
        ok = (default is None and value is None) or (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and bool(np.isfinite(value))
        )
        kind = "a finite number" + (" or null" if default is None else "")
    elif isinstance(default, str):
        ok, kind = isinstance(value, str), "a name"
    else:
        return
    if not ok:
        text = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        raise OptimizationError(f"option '{name}' of method '{method}' must be {kind}, got {text}.")


def _eval_rows(fun: Callable[[FloatArray], float], x: FloatArray) -> FloatArray:
    return np.array([fun(row) for row in x], dtype=float)


def _eval_block(fun: Callable[[FloatArray], Any], x: FloatArray) -> FloatArray:
    return np.asarray(fun(x), dtype=float)


class Problem:
    """The objective, box, budget and bookkeeping of one run (see module docstring).

    Parameters
    ----------
    fun :
        Objective. ``vectorized=True``: ``(n, dim) -> (n,)``; else ``(dim,) -> float``.
    lower, upper :
        Box, shapes (dim,).
    popsize, maxiter :
        Population size and the number of iterations that will be run (see
        :func:`plan_iterations`).
    rng :
        Random generator used for every draw of the run.
    callback :
        ``callback(IntermediateResult) -> bool | None``; True stops the run.
    vectorized, workers :
        How to call ``fun``; with ``workers > 1`` the population is split into contiguous
        blocks evaluated in a process pool (results are put back in order, so they do not
        depend on ``workers``). ``fun`` must then be picklable.
    f_target, target_tol :
        Stop once ``best <= f_target + target_tol`` (paper eq. 7 uses 1e-8).
    """

    def __init__(
        self,
        fun: Callable[..., Any],
        lower: FloatArray,
        upper: FloatArray,
        *,
        popsize: int,
        maxiter: int,
        rng: np.random.Generator,
        callback: Callable[[IntermediateResult], Any] | None = None,
        vectorized: bool = True,
        workers: int = 1,
        f_target: float | None = None,
        target_tol: float = 1e-8,
        executor: Executor | None = None,
    ) -> None:
        self.fun = fun
        self.lower = lower
        self.upper = upper
        self.span = upper - lower
        self.dim = int(lower.shape[0])
        self.popsize = int(popsize)
        self.maxiter = int(maxiter)
        self.rng = rng
        self.callback = callback
        self.vectorized = vectorized
        self.workers = int(workers)
        self.executor = executor
        self.f_target = f_target
        self.target_tol = target_tol
        self.nfev = 0
        self.n_nonfinite = 0
        self.best_x = np.full(self.dim, np.nan)
        self.best_f = math.inf
        self._hist_best: list[float] = []
        self._hist_nfev: list[int] = []
        self.nit = 0
        self.stop_reason: str | None = None
        self.success = True
        self._warned = False

    # -- sampling ------------------------------------------------------------------------
    def uniform(self, n: int) -> FloatArray:
        """``n`` points uniformly distributed in the box, shape (n, dim)."""
        return self.lower + self.rng.random((n, self.dim)) * self.span

    def initial_population(self, x0: FloatArray | None) -> FloatArray:
        """``x0`` rows first (if given), the rest uniform in the box; shape (popsize, dim)."""
        pop = self.uniform(self.popsize)
        if x0 is not None:
            pop[: x0.shape[0]] = x0
        return pop

    # -- evaluation ----------------------------------------------------------------------
    def evaluate(self, x: FloatArray) -> FloatArray:
        """Evaluate a population (n, dim) -> (n,); non-finite values become +inf.

        Raises
        ------
        OptimizationError
            If the budget would be exceeded (a bug in a method) or ``fun`` returns the
            wrong shape.
        """
        n = x.shape[0]
        if self.nfev + n > self.popsize * (self.maxiter + 1):
            raise OptimizationError("internal: evaluation budget exceeded")  # pragma: no cover
        f = self._call(x)
        if f.shape != (n,):
            raise OptimizationError(
                f"the objective returned shape {f.shape} for {n} points; expected ({n},). "
                "With vectorized=True it must map (n_pop, dim) -> (n_pop,); pass "
                "vectorized=False for a function of one point."
            )
        self.nfev += n
        bad = ~np.isfinite(f)
        if bad.any():
            f = np.where(bad, np.inf, f)
            self.n_nonfinite += int(bad.sum())
            if not self._warned:
                self._warned = True
                warnings.warn(
                    "the objective returned NaN or inf; such points are treated as the worst "
                    "(+inf) and counted in OptimizeResult.n_nonfinite.",
                    IdentWarning,
                    stacklevel=4,
                )
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_f = float(f[i])
            self.best_x = x[i].copy()
        return f

    def _call(self, x: FloatArray) -> FloatArray:
        if self.executor is None or self.workers <= 1 or x.shape[0] < 2:
            if self.vectorized:
                return _eval_block(self.fun, x)
            return _eval_rows(self.fun, x)
        blocks = np.array_split(x, min(self.workers, x.shape[0]))
        worker = _eval_block if self.vectorized else _eval_rows
        parts = list(self.executor.map(worker, [self.fun] * len(blocks), blocks))
        return np.concatenate(parts)

    # -- iteration bookkeeping -----------------------------------------------------------
    def target_reached(self) -> bool:
        return self.f_target is not None and self.best_f <= self.f_target + self.target_tol

    def end_iteration(self, nit: int) -> bool:
        """Record iteration ``nit`` (0 = initial population); True means stop now."""
        self.nit = nit
        self._hist_best.append(self.best_f)
        self._hist_nfev.append(self.nfev)
        if self.target_reached():
            self.stop_reason = f"target f_target + {self.target_tol:g} reached"
            return True
        if self.callback is not None:
            info = IntermediateResult(
                x=self.best_x.copy(), fun=self.best_f, nit=nit, nfev=self.nfev
            )
            if self.callback(info) is True:
                self.stop_reason = "stopped by callback"
                self.success = False
                return True
        return False

    def history_arrays(self) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        return np.array(self._hist_best), np.array(self._hist_nfev, dtype=np.int64)

    def final_message(self) -> str:
        if self.stop_reason is not None:
            return self.stop_reason
        return f"iteration budget used ({self.nit} iterations, {self.nfev} evaluations)"


def make_executor(workers: int) -> ProcessPoolExecutor | None:
    """A process pool for ``workers > 1`` (caller shuts it down), else None."""
    if workers <= 1:
        return None
    return ProcessPoolExecutor(max_workers=workers)


def schedule_geometric(start: float, end: float, maxiter: int) -> FloatArray:
    """``start * n**(t-1)`` for t = 1..maxiter with ``n`` chosen so the last value is ``end``.

    Equation 3 (and, with ``c2 = c2_0 / m**t``, eq. 4: ``m = 1/n``) of the eMuPSO paper, with
    the coefficient fixed by the end points over the iterations that will really be run.
    Returns shape (maxiter,); for ``maxiter == 1`` the single value is ``start``.
    """
    if maxiter <= 0:
        return np.zeros(0)
    if maxiter == 1:
        return np.array([float(start)])
    n = (end / start) ** (1.0 / (maxiter - 1))
    return start * n ** np.arange(maxiter, dtype=float)


def as_population(x0: Any, dim: int, popsize: int, lower: FloatArray, upper: FloatArray) -> Any:
    """Validate an initial population ``x0`` of shape (k, dim) or (dim,), k <= popsize."""
    if x0 is None:
        return None
    x = np.atleast_2d(np.asarray(x0, dtype=float))
    if x.ndim != 2 or x.shape[1] != dim:
        raise OptimizationError(f"x0 must have shape (k, {dim}), got {np.shape(x0)}")
    if x.shape[0] > popsize:
        raise OptimizationError(
            f"x0 has {x.shape[0]} rows but popsize = {popsize}; give at most popsize rows "
            "or raise popsize."
        )
    if not np.all(np.isfinite(x)):
        raise OptimizationError("x0 contains NaN or inf")
    outside = np.any((x < lower) | (x > upper), axis=1)
    if outside.any():
        raise OptimizationError(
            f"x0 row {int(np.flatnonzero(outside)[0])} lies outside the bounds; clip it "
            "(e.g. np.clip(x0, low, high)) before passing it."
        )
    return x


def iter_names(names: Iterable[str]) -> str:
    return ", ".join(sorted(names))
