"""The optimizer comparison campaign: seeded runs, parallel execution, statistics.

Every method of the config runs on every function for ``runs`` independent runs at the same
evaluation budget (``max_nfev``, population ``popsize``). The seed of a run depends only on
``(seed, function key, method, run index)`` through ``numpy.random.SeedSequence`` with a
``spawn_key``, so results do not depend on the number of workers, on the scheduler, on the
order of completion, or on which other functions and methods are in the config.

Statistics (what the paper's tables hold; the errors are ``f(x_best) - f_star`` with the exact
minimum of each function):

* Tables 4-6: minimum, mean and standard deviation (``ddof=1``, like MATLAB's ``std``) of the
  final error over the runs.
* Table 8: the best algorithm of a function is the one with the lowest mean error (ties: the
  lower median, then config order); it is compared with every other algorithm by a two-sided
  Wilcoxon signed-rank test on the paired runs, with MATLAB ``signrank`` semantics: zero
  differences dropped, exact distribution for at most 15 non-zero pairs, normal approximation
  without continuity correction otherwise, ``p = 1`` if all pairs tie.
* Table 7 (by minimum error): an algorithm *wins* a function if its minimum error is the lowest
  and no other algorithm has the same (within ``tie_atol``), *ties* if it shares the lowest,
  *loses* otherwise.
* Table 9 (by Wilcoxon at level ``alpha``): the best-by-mean algorithm *wins* if it is
  significantly better than every other, else *ties*; another algorithm *loses* if the best is
  significantly better than it, else *ties*.
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import Field, ValidationInfo, field_validator

from ident.bench.functions import appendix_functions, get_function, table_functions
from ident.config import StrictModel, load_config_file
from ident.errors import ConfigError, OptimizationError
from ident.identify.estimation.log_chunks import connect_scheduler
from ident.inputs import JobEstimate, check_number, max_workers, safe_component

__all__ = [
    "CampaignConfig",
    "CampaignResult",
    "MAX_CURVE_POINTS",
    "MAX_NFEV",
    "MAX_POPSIZE",
    "MAX_RUNS",
    "RunRecord",
    "RunTask",
    "check_workers",
    "estimate_campaign",
    "load_campaign_config",
    "make_tasks",
    "run_campaign",
    "run_task",
    "summary_stats",
    "wilcoxon_p",
    "wilcoxon_table",
    "win_tie_loss",
]

FloatArray = npt.NDArray[np.float64]

ALL_METHODS = ("emupso", "pso", "woa", "gwo", "goa", "de")
# Hard bounds of a campaign config; within them, estimate_campaign() and check_job() decide.
MAX_RUNS = 1000
MAX_POPSIZE = 100_000
MAX_NFEV = 1_000_000_000
MAX_CURVE_POINTS = 10_000
# Cost model of estimate_campaign(): measured on 36 runs of 30000 evaluations (popsize 30,
# dimension 30), 5.3 s on one worker; an order of magnitude, not a promise.
_SECONDS_PER_ITERATION = 1.2e-4
_SECONDS_PER_EVALUATION = 1e-6
_BYTES_PER_WORKER = 200e6  # an interpreter with numpy and scipy loaded


class CampaignConfig(StrictModel):
    """``configs/bench.yaml``: what to run and how to compare.

    ``functions`` is ``"table"`` (the 36 rows of Tables 4-6), ``"appendix"`` (appendix order,
    with Schwefel 2.26 instead of Pen Holder) or a list of registry keys.
    """

    name: str = "bench"
    seed: int = Field(2026, ge=0)
    runs: int = Field(30, ge=2, le=MAX_RUNS)
    popsize: int = Field(30, ge=4, le=MAX_POPSIZE)
    max_nfev: int = Field(30_000, ge=1, le=MAX_NFEV)
    methods: list[str] = Field(default_factory=lambda: list(ALL_METHODS))
    functions: Literal["table", "appendix"] | list[str] = "table"
    method_options: dict[str, dict[str, Any]] = Field(default_factory=dict)
    curve_points: int = Field(51, ge=2, le=MAX_CURVE_POINTS)
    alpha: float = Field(0.05, gt=0.0, lt=1.0)
    tie_atol: float = Field(0.0, ge=0.0)

    @field_validator("name")
    @classmethod
    def _one_path_component(cls, v: str) -> str:
        # the name becomes a folder name: never a path that leaves the campaigns folder
        return safe_component(v, default="bench")

    @field_validator("methods")
    @classmethod
    def _known_methods(cls, v: list[str]) -> list[str]:
        from ident.optim import METHODS

        if not v:
            raise ValueError("give at least one method")
        for m in v:
            if m not in METHODS:
                import difflib

                close = difflib.get_close_matches(m, list(METHODS), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise ValueError(f"unknown method '{m}'{hint}; valid methods: {', '.join(METHODS)}")
        if len(set(v)) != len(v):
            raise ValueError("methods must not repeat")
        return v

    @field_validator("functions")
    @classmethod
    def _known_functions(cls, v: Any) -> Any:
        if isinstance(v, list):
            if not v:
                raise ValueError("give at least one function")
            for k in v:
                try:
                    get_function(k)
                except ConfigError as e:
                    raise ValueError(str(e)) from e
        return v

    @field_validator("max_nfev")
    @classmethod
    def _budget(cls, v: int, info: ValidationInfo) -> int:
        from ident.optim._common import plan_iterations

        popsize = info.data.get("popsize")
        if popsize is not None:
            try:
                plan_iterations(popsize, None, v, default_maxiter=0)
            except OptimizationError as e:
                raise ValueError(str(e)) from e
        return v

    @field_validator("method_options")
    @classmethod
    def _options(cls, v: dict[str, dict[str, Any]], info: ValidationInfo) -> dict:
        from ident.optim import method_defaults
        from ident.optim._common import check_options

        methods = info.data.get("methods") or []
        for m, opts in v.items():
            if m not in methods:
                raise ValueError(f"'{m}' is not in methods ({', '.join(methods)})")
            try:
                check_options(m, opts, method_defaults(m))
            except OptimizationError as e:
                raise ValueError(str(e)) from e
        return v

    def function_keys(self) -> list[str]:
        if self.functions == "table":
            return [f.key for f in table_functions()]
        if self.functions == "appendix":
            return [f.key for f in appendix_functions()]
        return list(self.functions)

    @property
    def maxiter(self) -> int:
        """Iterations per run: ``max_nfev // popsize - 1`` (initial population + iterations)."""
        return self.max_nfev // self.popsize - 1


def load_campaign_config(path: str | Path) -> CampaignConfig:
    """Read and validate a campaign YAML file."""
    return load_config_file(CampaignConfig, path)


def check_workers(workers: int) -> int:
    """``--workers`` between 1 and the CPUs available to this process.

    Raises
    ------
    ConfigError
        Outside that range.
    """
    return int(
        check_number(
            workers,
            "--workers",
            low=1,
            high=max_workers(),
            integer=True,
            hint=f"(this machine has {max_workers()} CPUs for this process)",
        )
    )


def estimate_campaign(config: CampaignConfig, workers: int = 1) -> JobEstimate:
    """Rough peak memory and wall time of a campaign, for :func:`ident.inputs.check_job`.

    Time: per run, a fixed cost per iteration plus a cost per evaluation, divided among the
    workers. Memory: an interpreter per worker, the population and the per-iteration history
    of the runs in flight, and the convergence curves of every finished run.
    """
    from ident.bench.functions import get_function

    n_tasks = len(config.methods) * len(config.function_keys()) * config.runs
    dim = max(get_function(f).dim for f in config.function_keys())
    iterations = config.maxiter + 1
    per_run_s = iterations * _SECONDS_PER_ITERATION + config.max_nfev * _SECONDS_PER_EVALUATION
    seconds = n_tasks * per_run_s / max(workers, 1)
    per_run_bytes = 20 * 8.0 * config.popsize * dim + 4 * 8.0 * iterations
    memory = workers * (_BYTES_PER_WORKER + per_run_bytes) + n_tasks * (
        16.0 * config.curve_points + 512
    )
    return JobEstimate(
        f"{n_tasks} runs of {config.max_nfev} evaluations on {workers} worker(s)",
        memory,
        seconds,
    )


@dataclass(frozen=True)
class RunTask:
    """One optimizer run (picklable; shipped to worker processes or a dask cluster)."""

    function: str
    method: str
    run: int
    seed: int
    popsize: int
    max_nfev: int
    options: tuple[tuple[str, Any], ...] = ()
    curve_points: int = 51

    def seed_sequence(self) -> np.random.SeedSequence:
        key = (zlib.crc32(self.function.encode()), zlib.crc32(self.method.encode()), self.run)
        return np.random.SeedSequence(self.seed, spawn_key=key)


@dataclass(frozen=True, eq=False)
class RunRecord:
    """Outcome of one run: final error ``f - f_star`` and the convergence curve."""

    function: str
    method: str
    run: int
    error: float
    fun: float
    nfev: int
    nit: int
    seconds: float
    n_nonfinite: int
    curve_nfev: npt.NDArray[np.int64]
    curve_error: FloatArray


def make_tasks(config: CampaignConfig) -> list[RunTask]:
    """All runs of the campaign, function-major, in a fixed order."""
    return [
        RunTask(
            function=f,
            method=m,
            run=r,
            seed=config.seed,
            popsize=config.popsize,
            max_nfev=config.max_nfev,
            options=tuple(sorted(config.method_options.get(m, {}).items())),
            curve_points=config.curve_points,
        )
        for f in config.function_keys()
        for m in config.methods
        for r in range(config.runs)
    ]


def run_task(task: RunTask) -> RunRecord:
    """Run one task (top-level so that process pools and dask can pickle it)."""
    from ident.optim import minimize

    bf = get_function(task.function)
    t0 = time.perf_counter()
    res = minimize(
        bf.fun,
        bf.bounds,
        task.method,
        rng=np.random.default_rng(task.seed_sequence()),
        popsize=task.popsize,
        max_nfev=task.max_nfev,
        **dict(task.options),
    )
    seconds = time.perf_counter() - t0
    hist_nfev, hist_best = res.history.nfev, res.history.best_fun
    grid = np.unique(
        np.linspace(hist_nfev[0], hist_nfev[-1], task.curve_points).round().astype(np.int64)
    )
    idx = np.searchsorted(hist_nfev, grid, side="right") - 1  # best so far at each grid point
    return RunRecord(
        function=task.function,
        method=task.method,
        run=task.run,
        error=float(res.fun - bf.f_star),
        fun=float(res.fun),
        nfev=res.nfev,
        nit=res.nit,
        seconds=seconds,
        n_nonfinite=res.n_nonfinite,
        curve_nfev=grid,
        curve_error=hist_best[idx] - bf.f_star,
    )


@dataclass(frozen=True, eq=False)
class CampaignResult:
    """All runs of a campaign, in task order, with timing."""

    config: CampaignConfig
    records: tuple[RunRecord, ...]
    wall_seconds: float
    workers: int
    scheduler: str | None = None
    _index: dict[tuple[str, str], list[RunRecord]] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for rec in self.records:
            self._index.setdefault((rec.function, rec.method), []).append(rec)

    def runs(self, function: str, method: str) -> list[RunRecord]:
        return self._index[(function, method)]

    def errors(self, function: str, method: str) -> FloatArray:
        """Final errors of the runs, shape (runs,), in run order."""
        return np.array([r.error for r in self.runs(function, method)])


ProgressFn = Callable[[int, int], None]


def run_campaign(
    config: CampaignConfig,
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: ProgressFn | None = None,
) -> CampaignResult:
    """Run every task of ``config``; results are identical for any ``workers``/``scheduler``.

    Parameters
    ----------
    workers :
        Local worker processes (1 = in this process).
    scheduler :
        Address of a running ``dask.distributed`` scheduler (``tcp://HOST:PORT``); the tasks
        are then run on its workers (``workers`` is ignored).
    progress :
        ``progress(done, total)`` after every finished run (the CLI draws a progress bar).

    Raises
    ------
    IdentError
        If ``workers`` is not between 1 and the CPU count, or a scheduler is given but
        ``dask.distributed`` is missing or unreachable.
    """
    if scheduler is None:
        check_workers(workers)
    tasks = make_tasks(config)
    results: list[RunRecord | None] = [None] * len(tasks)
    t0 = time.perf_counter()

    def done(i: int, rec: RunRecord) -> None:
        results[i] = rec
        if progress is not None:
            progress(sum(r is not None for r in results), len(tasks))

    if scheduler is not None:
        _run_dask(tasks, scheduler, done)
    elif workers == 1:
        for i, t in enumerate(tasks):
            done(i, run_task(t))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(run_task, t): i for i, t in enumerate(tasks)}
            for fut in as_completed(futures):
                done(futures[fut], fut.result())
    wall = time.perf_counter() - t0
    assert all(r is not None for r in results)
    return CampaignResult(
        config=config,
        records=tuple(r for r in results if r is not None),
        wall_seconds=wall,
        workers=workers if scheduler is None else 0,
        scheduler=scheduler,
    )


def _run_dask(
    tasks: Sequence[RunTask], address: str, done: Callable[[int, RunRecord], None]
) -> None:
    client = connect_scheduler(address, "--scheduler", "drop --scheduler")
    from distributed import as_completed as dask_as_completed

    try:
        futures = client.map(run_task, list(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in dask_as_completed(futures):
            done(index[fut.key], fut.result())
    finally:
        client.close()


# ---------------------------------------------------------------------------------------------
# statistics


def summary_stats(errors: FloatArray) -> tuple[float, float, float]:
    """(min, mean, standard deviation with ddof=1) of the final errors (Tables 4-6)."""
    e = np.asarray(errors, dtype=float)
    std = float(np.std(e, ddof=1)) if e.size > 1 else 0.0
    return float(np.min(e)), float(np.mean(e)), std


def wilcoxon_p(a: FloatArray, b: FloatArray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of paired samples (MATLAB ``signrank``).

    Zero differences are dropped; all pairs tied gives ``p = 1``; the exact distribution is
    used for at most 15 non-zero pairs, else the normal approximation without continuity
    correction. Non-finite differences (an infinite error) make ``p`` NaN.
    """
    from scipy.stats import wilcoxon

    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if not np.all(np.isfinite(d)):
        return float("nan")
    d = d[d != 0.0]
    if d.size == 0:
        return 1.0
    method = "exact" if d.size <= 15 else "approx"
    return float(wilcoxon(d, zero_method="wilcox", correction=False, method=method).pvalue)


def best_by_mean(result: CampaignResult, function: str) -> str:
    """Algorithm with the lowest mean error (ties: lower median, then config order)."""
    methods = result.config.methods
    keys = [
        (
            float(np.mean(result.errors(function, m))),
            float(np.median(result.errors(function, m))),
            i,
        )
        for i, m in enumerate(methods)
    ]
    return methods[min(keys)[2]]


def wilcoxon_table(result: CampaignResult) -> dict[str, tuple[str, dict[str, float | None]]]:
    """Table 8: per function the best-by-mean algorithm and its p-value against each other.

    The best algorithm's own entry is ``None`` (the paper's "NA").
    """
    table: dict[str, tuple[str, dict[str, float | None]]] = {}
    for f in result.config.function_keys():
        best = best_by_mean(result, f)
        eb = result.errors(f, best)
        row: dict[str, float | None] = {
            m: None if m == best else wilcoxon_p(eb, result.errors(f, m))
            for m in result.config.methods
        }
        table[f] = (best, row)
    return table


def win_tie_loss(
    result: CampaignResult, kind: Literal["min", "wilcoxon"]
) -> dict[str, dict[str, tuple[int, int, int]]]:
    """Tables 7 (``kind="min"``) and 9 (``kind="wilcoxon"``): counts per group and method.

    Returns ``{group: {method: (wins, ties, losses)}}`` with groups ``unimodal``,
    ``multimodal``, ``fixed`` (only those present) and ``total``.
    """
    cfg = result.config
    counts: dict[str, dict[str, list[int]]] = {}
    wt = wilcoxon_table(result) if kind == "wilcoxon" else {}
    for f in cfg.function_keys():
        group = get_function(f).group
        outcome: dict[str, int] = {}  # 0 win, 1 tie, 2 loss
        if kind == "min":
            mins = {m: float(np.min(result.errors(f, m))) for m in cfg.methods}
            low = min(mins.values())
            at_best = [m for m in cfg.methods if mins[m] - low <= cfg.tie_atol]
            for m in cfg.methods:
                outcome[m] = 2 if m not in at_best else (0 if len(at_best) == 1 else 1)
        else:
            best, row = wt[f]
            sig = {m: p is not None and p < cfg.alpha for m, p in row.items()}
            for m in cfg.methods:
                if m == best:
                    others = [sig[o] for o in cfg.methods if o != best]
                    outcome[m] = 0 if all(others) else 1
                else:
                    outcome[m] = 2 if sig[m] else 1
        for g in (group, "total"):
            for m in cfg.methods:
                counts.setdefault(g, {}).setdefault(m, [0, 0, 0])[outcome[m]] += 1
    order = [g for g in ("unimodal", "multimodal", "fixed", "total") if g in counts]
    return {g: {m: tuple(counts[g][m]) for m in cfg.methods} for g in order}  # type: ignore[misc]
