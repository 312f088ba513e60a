"""Population-based optimizers behind one ``scipy.optimize``-like function, :func:`minimize`.

Methods: ``emupso`` (the paper's eMuPSO), ``pso`` (standard PSO), ``woa``, ``gwo``, ``goa``,
``de`` (DE/rand/1/bin), ``cma`` (CMA-ES through the ``cma`` package). More are added with
:func:`register_method`. See ``docs/optimizers.md`` and each module's docstring for the
equations, defaults and boundary handling. :mod:`ident.optim.elites` adds the paper's
"initial elites" stage for constrained problems.
"""

from __future__ import annotations

import difflib
import importlib
import pickle
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Executor
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import OptimizationError
from ident.optim._common import (
    DEFAULT_MAXITER,
    Problem,
    as_population,
    as_rng,
    check_options,
    make_executor,
    parse_bounds,
    plan_iterations,
)
from ident.optim.result import EliteArchive, IntermediateResult, OptimizeHistory, OptimizeResult

__all__ = [
    "METHODS",
    "EliteArchive",
    "IntermediateResult",
    "MethodSpec",
    "OptimizeHistory",
    "OptimizeResult",
    "method_defaults",
    "minimize",
    "register_method",
]


@dataclass(frozen=True)
class MethodSpec:
    """How :func:`minimize` runs one method.

    Attributes
    ----------
    run :
        ``run(problem, x0, **options) -> dict``: iterates on a
        :class:`ident.optim._common.Problem` (``problem.initial_population(x0)``,
        ``problem.evaluate(x)``, ``problem.end_iteration(t)`` until it returns True or
        ``t == problem.maxiter``) and returns method-specific extras (``radius``,
        ``stagnation``, ``mutation_iterations``, ``archive``; all optional).
    defaults :
        The method's options and their defaults (unknown options are rejected).
    default_popsize, min_popsize :
        Population size when the caller gives none, and the smallest one accepted.
    """

    run: Callable[..., dict[str, Any]]
    defaults: Mapping[str, Any] = field(default_factory=dict)
    default_popsize: int = 30
    min_popsize: int = 1


#: Method name -> a :class:`MethodSpec`, or the module of a built-in method (imported on
#: first use; it defines ``run``, ``DEFAULTS``, ``DEFAULT_POPSIZE`` and maybe ``MIN_POPSIZE``).
METHODS: dict[str, MethodSpec | str] = {
    "emupso": "ident.optim.emupso",
    "pso": "ident.optim.pso",
    "woa": "ident.optim.woa",
    "gwo": "ident.optim.gwo",
    "goa": "ident.optim.goa",
    "de": "ident.optim.de",
    "cma": "ident.optim.cma_es",
}

#: Options every method accepts.
COMMON_OPTIONS: dict[str, Any] = {"f_target": None, "target_tol": 1e-8}


def register_method(
    name: str,
    run: Callable[..., dict[str, Any]],
    *,
    defaults: Mapping[str, Any] | None = None,
    default_popsize: int = 30,
    min_popsize: int = 1,
) -> MethodSpec:
    """Make ``run`` available as ``minimize(..., method=name)``.

    Parameters
    ----------
    name :
        The method's name (also the name a run config gives).
    run :
        ``run(problem, x0, **options) -> dict``, see :class:`MethodSpec`.
    defaults :
        The method's options and their defaults.
    default_popsize, min_popsize :
        See :class:`MethodSpec`.

    Returns
    -------
    :
        The registered spec.

    Raises
    ------
    OptimizationError
        If ``name`` is already registered.
    """
    if name in METHODS:
        raise OptimizationError(f"optimizer method {name!r} is registered twice")
    spec = MethodSpec(run, dict(defaults or {}), int(default_popsize), int(min_popsize))
    METHODS[name] = spec
    return spec


def _module(method: str) -> MethodSpec:
    if method not in METHODS:
        close = difflib.get_close_matches(str(method), list(METHODS), n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise OptimizationError(
            f"unknown method '{method}'{hint}; valid methods: {', '.join(METHODS)}."
        )
    entry = METHODS[method]
    if isinstance(entry, MethodSpec):
        return entry
    mod = importlib.import_module(entry)
    return MethodSpec(
        mod.run, mod.DEFAULTS, int(mod.DEFAULT_POPSIZE), int(getattr(mod, "MIN_POPSIZE", 1))
    )


def _check_workers(workers: Any, fun: Callable[..., Any]) -> int:
    """``workers`` as an int >= 1; with more than one, ``fun`` must pickle (process pool)."""
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)):
        raise OptimizationError(
            f"workers must be a whole number >= 1 (processes evaluating the population), "
            f"got {workers!r}"
        )
    if workers < 1:
        raise OptimizationError(f"workers must be >= 1, got {workers}")
    if workers > 1:
        try:
            pickle.dumps(fun)
        except Exception as e:  # PicklingError, AttributeError, TypeError by object kind
            raise OptimizationError(
                f"workers={workers} sends the objective to other processes, but it cannot be "
                f"pickled ({type(e).__name__}: {e}); define the objective at module level "
                "(not a lambda or a nested function), or use workers=1 with "
                "vectorized=True."
            ) from e
    return int(workers)


def method_defaults(method: str) -> dict[str, Any]:
    """Default options of ``method`` (including the common ``f_target``, ``target_tol``)."""
    return {**COMMON_OPTIONS, **_module(method).defaults}


def minimize(
    fun: Callable[..., Any],
    bounds: Any,
    method: str = "emupso",
    *,
    rng: np.random.Generator | int | None = None,
    maxiter: int | None = None,
    popsize: int | None = None,
    max_nfev: int | None = None,
    callback: Callable[[IntermediateResult], Any] | None = None,
    vectorized: bool = True,
    workers: int = 1,
    x0: Any = None,
    **options: Any,
) -> OptimizeResult:
    """Minimize ``fun`` over a box with a population-based method.

    Parameters
    ----------
    fun :
        Objective. With ``vectorized=True`` it maps a population (n_pop, dim) to (n_pop,);
        with ``vectorized=False`` it maps one point (dim,) to a float.
    bounds :
        ``(low, high)`` per variable: a sequence of pairs, or an array (dim, 2) / (2, dim).
    method :
        One of :data:`METHODS`.
    rng :
        Generator or seed; the same ``rng`` gives an identical result (any ``workers``).
    maxiter, popsize :
        Iterations after the initial population (each evaluates one population; default 1000,
        or what ``max_nfev`` allows); population size (default 30, the paper's benchmark).
    max_nfev :
        Evaluation budget, never exceeded: ``maxiter = min(maxiter, max_nfev // popsize - 1)``.
        Every time-varying schedule (eMuPSO ``w``/``c2``, WOA/GWO ``a``, GOA ``c``) is spread
        over that number of iterations.
    callback :
        ``callback(IntermediateResult)`` after every iteration; returning True stops the run.
    vectorized, workers :
        See ``fun``; processes evaluating the population (``fun`` picklable when > 1).
    x0 :
        Optional initial points (k, dim), k <= popsize, inside the bounds; the rest of the
        initial population is uniform (used to seed a run from elites).
    **options :
        Method options (see ``method_defaults(method)``), plus ``f_target`` and
        ``target_tol``: stop when ``fun <= f_target + target_tol`` (paper eq. 7).

    Returns an :class:`OptimizeResult`. Raises :class:`OptimizationError` for invalid bounds, an
    unknown method or option (with the closest valid name), a budget smaller than one
    population, a bad ``x0``, a ``workers`` that is not a whole number >= 1, or
    (``workers > 1``) an objective that cannot be pickled.
    """
    setup = _setup(fun, bounds, method, popsize, maxiter, max_nfev, x0, workers, options)
    with _process_pool(setup.workers) as executor:
        problem = _problem(fun, setup, as_rng(rng), callback, vectorized, executor)
        # called here, so that warnings from problem.evaluate name the caller of minimize
        extras = setup.spec.run(problem, setup.x0, **setup.options)
    return _optimize_result(problem, extras, method)


@dataclass(frozen=True, eq=False)
class _Setup:
    """A checked :func:`minimize` call: the method, its options and the box.

    Attributes
    ----------
    spec, options :
        The method and its options (``f_target``, ``target_tol`` taken out).
    lower, upper :
        The box, shape (dim,) each.
    popsize, maxiter :
        Population size and the number of iterations that will really be run.
    x0 :
        The checked initial points (k, dim), or None.
    workers :
        Processes evaluating the population.
    f_target, target_tol :
        Stop when ``fun <= f_target + target_tol`` (``f_target`` None: never).
    """

    spec: MethodSpec
    options: dict[str, Any]
    lower: npt.NDArray[np.float64]
    upper: npt.NDArray[np.float64]
    popsize: int
    maxiter: int
    x0: Any
    workers: int
    f_target: float | None
    target_tol: float


def _setup(
    fun: Callable[..., Any],
    bounds: Any,
    method: str,
    popsize: int | None,
    maxiter: int | None,
    max_nfev: int | None,
    x0: Any,
    workers: Any,
    options: Mapping[str, Any],
) -> _Setup:
    """Check the arguments of :func:`minimize` (same meaning) in the order its ``Raises``
    lists them. Raises :class:`OptimizationError`."""
    spec = _module(method)
    opts = check_options(method, options, {**COMMON_OPTIONS, **spec.defaults})
    lower, upper = parse_bounds(bounds)
    popsize = int(spec.default_popsize if popsize is None else popsize)
    min_pop = spec.min_popsize
    if popsize < min_pop:
        raise OptimizationError(f"method '{method}' needs popsize >= {min_pop}, got {popsize}")
    n_iter = plan_iterations(popsize, maxiter, max_nfev, default_maxiter=DEFAULT_MAXITER)
    pop0 = as_population(x0, lower.shape[0], popsize, lower, upper)
    workers = _check_workers(workers, fun)
    f_target, target_tol = opts.pop("f_target"), float(opts.pop("target_tol"))
    return _Setup(spec, opts, lower, upper, popsize, n_iter, pop0, workers, f_target, target_tol)


@contextmanager
def _process_pool(workers: int) -> Iterator[Executor | None]:
    """A process pool for ``workers > 1`` (None otherwise), shut down on exit, also on an
    error."""
    executor = make_executor(int(workers))
    try:
        yield executor
    finally:
        if executor is not None:
            executor.shutdown()


def _problem(
    fun: Callable[..., Any],
    setup: _Setup,
    rng: np.random.Generator,
    callback: Callable[[IntermediateResult], Any] | None,
    vectorized: bool,
    executor: Executor | None,
) -> Problem:
    """The :class:`~ident.optim._common.Problem` a method iterates on (arguments as in
    :func:`minimize`)."""
    return Problem(
        fun,
        setup.lower,
        setup.upper,
        popsize=setup.popsize,
        maxiter=setup.maxiter,
        rng=rng,
        callback=callback,
        vectorized=vectorized,
        workers=int(setup.workers),
        f_target=setup.f_target,
        target_tol=setup.target_tol,
        executor=executor,
    )


def _optimize_result(problem: Problem, extras: Mapping[str, Any], method: str) -> OptimizeResult:
    """The :class:`OptimizeResult` of a finished run: the best point, the history and the
    method's extras; not a success when no finite objective value was found."""
    best, nfev = problem.history_arrays()
    history = OptimizeHistory(
        best_fun=best,
        nfev=nfev,
        radius=extras.get("radius"),
        stagnation=extras.get("stagnation"),
        mutation_iterations=extras.get("mutation_iterations", np.zeros(0, np.int64)),
    )
    success = problem.success and np.isfinite(problem.best_f)
    message = problem.final_message()
    if not np.isfinite(problem.best_f):
        message += "; no finite objective value was found"
    return OptimizeResult(
        x=problem.best_x,
        fun=problem.best_f,
        nit=problem.nit,
        nfev=problem.nfev,
        success=bool(success),
        message=message,
        history=history,
        method=method,
        n_nonfinite=problem.n_nonfinite,
        archive=extras.get("archive"),
    )
