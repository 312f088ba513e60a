"""eMuPSO: mutating particle swarm optimization with Gaussian mutation and elite archives.

Every component of section 3 of the paper, each parameter an option with the paper's default:

* **Schedules (eq. 3-4).** ``w_t = w0 * n**t`` decreasing from ``w_start = 2.1`` to
  ``w_end = 0.6``; ``c1 = 2.24`` constant; ``c2_t = c2_0 / m**t`` increasing from
  ``c2_start = 1.8`` to ``c2_end = 3.9``. ``n`` and ``m`` follow from the end points over the
  iteration budget that will really be run (``maxiter``, derived from ``max_nfev`` when given):
  the first iteration uses the start values, the last one the end values.
* **Swarm radius (eq. 5).** ``rad_t = GlobalBestCost_t - mean(personal best costs)_t`` (<= 0;
  over the finite personal bests). The global best here is the swarm's own (it restarts after
  a mutation), as in the paper. (A MATLAB "Yarpiz"-style code, which the paper's names
  ``GlobalBestCost``/``BestCost`` suggest, stores the best-cost *history* in ``BestCost``; we
  read it as the personal best costs of the current swarm, which a swarm radius measures.)
* **Stagnation counter (eq. 6)** with a *relative* tolerance instead of exact equality:
  ``g += 1`` if ``|rad_{t-1} - rad_t| <= stall_rtol * max(|rad_{t-1}|, |rad_t|)`` (or they are
  equal), else ``g = 0``.
* **Termination and mutation (eq. 7).** The run ends when ``f <= f_target + target_tol``
  (``target_tol = 1e-8`` as in the paper) if ``f_target`` is given, or when the budget is used
  up. When ``g >= G`` (``stall_threshold``, default 10) at the end of an iteration, the next
  iteration's population is a mutation of the swarm instead of a PSO step: so the first
  mutation happens at iteration ``G + 1`` if the radius never changes.
* **Gaussian mutation around k elites (eq. 8).** The swarm is split into ``k + 1`` nearly equal
  parts (``numpy.array_split`` sizes); part ``i < k`` holds offspring
  ``x_elite_i + N(0, sigma_i**2)`` per dimension with ``sigma_i = sigma_fraction * (high_i -
  low_i)``; the last part is uniform in the box. The ``k`` elites (``n_elites``) are the best
  distinct members of the global archive (elites of earlier cycles) joined with the local
  archive (distinct personal bests of the current cycle). After the mutation the global
  archive is updated with the local elites (best ``archive_size`` distinct). Velocities are
  reset to zero and personal bests to the new particles (a new cycle starts).
  ``mutation="random"`` gives the random-restart variant of MuPSO (whole swarm uniform).
* **Elite archive (section 3.3).** Returned as ``OptimizeResult.archive``: best distinct
  solutions of all cycles, so a user can choose among them.

Choices the paper leaves open (documented and tested):

* **Velocity clamping**: ``|v_i| <= vmax_fraction * (high_i - low_i) * vmax_decay**(t-1)`` per
  dimension at iteration ``t`` (defaults 0.1 and 0.97). A clamp is needed with ``w > 1``,
  otherwise velocities grow geometrically. Moreover ``c1 + c2 >= 4`` puts the paper's
  coefficients outside the PSO stability region for every ``w``, so the clamp is what bounds
  the particles' oscillation, and the attainable precision is about the clamp. It therefore
  shrinks by a fixed factor per iteration. This is our choice (the paper does not state its
  clamp), measured on Sphere/Rastrigin/Griewank-30 at 30 000 evaluations and on 6-D problems at
  30 iterations of 20 particles (the paper's trajectory setting): a constant clamp
  (``vmax_decay=1``) ends near 1e3 on Sphere-30; a clamp shrinking to 1e-8 of the range over
  the budget reaches 2e-11 there but collapses short runs (Sphere-6 at 600 evaluations: 2e3);
  0.97 per iteration gives 1e-23 and 15 respectively. The clamp deliberately does *not* follow
  the budget: it sets a precision, not a phase of the search.
* **Boundary handling**: a coordinate that leaves the box is put on the bound and its velocity
  component is reversed ("velocity mirror", as in the Yarpiz PSO code); Gaussian offspring are
  clipped to the box.
* Two solutions are *distinct* when their largest per-dimension distance, in units of the range,
  exceeds ``distinct_tol``.

References
----------
A. Umar, Z. Shi, L. Zheng, A. Khlil, Z. I. B. Farouk, "Parameter Estimation for Industrial Robot
Manipulators Using an Improved Particle Swarm Optimization Algorithm with Gaussian Mutation and
Archived Elite Learning", Advances in Science, Technology and Engineering Systems Journal 5(6),
1436-1457, 2020, doi:10.25046/aj0506174; section 3 (eq. 3-8).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import OptimizationError
from ident.optim._common import Problem, schedule_geometric
from ident.optim.result import EliteArchive

__all__ = [
    "DEFAULTS",
    "apply_bounds",
    "best_distinct",
    "clamp_velocity",
    "coefficient_schedules",
    "mutate_population",
    "partition_sizes",
    "run",
    "stagnation_update",
    "swarm_radius",
]

FloatArray = npt.NDArray[np.float64]

DEFAULTS: dict[str, Any] = {
    "w_start": 2.1,
    "w_end": 0.6,
    "c1": 2.24,
    "c2_start": 1.8,
    "c2_end": 3.9,
    "vmax_fraction": 0.1,
    "vmax_decay": 0.97,
    "stall_threshold": 10,
    "stall_rtol": 1e-6,
    "n_elites": 3,
    "sigma_fraction": 0.1,
    "mutation": "gaussian",
    "archive_size": 10,
    "distinct_tol": 1e-3,
}
DEFAULT_POPSIZE = 30
MUTATIONS = ("gaussian", "random")


def coefficient_schedules(
    maxiter: int,
    w_start: float = 2.1,
    w_end: float = 0.6,
    c2_start: float = 1.8,
    c2_end: float = 3.9,
) -> tuple[FloatArray, FloatArray]:
    """Eq. 3-4: ``w_t = w0 n**t`` and ``c2_t = c2_0 / m**t`` for iterations 1..maxiter.

    ``n = (w_end / w_start)**(1/(maxiter-1))``, ``m = (c2_start / c2_end)**(1/(maxiter-1))``,
    so iteration 1 uses the start values and iteration ``maxiter`` the end values.
    Returns two arrays of shape (maxiter,).
    """
    return (
        schedule_geometric(w_start, w_end, maxiter),
        schedule_geometric(c2_start, c2_end, maxiter),
    )


def swarm_radius(global_best_cost: float, personal_best_costs: FloatArray) -> float:
    """Swarm radius of eq. 5: ``GlobalBestCost - mean(personal best costs)`` (<= 0).

    Non-finite personal bests (particles that never produced a finite value) are left out;
    NaN when none is finite.
    """
    finite = personal_best_costs[np.isfinite(personal_best_costs)]
    if finite.size == 0 or not np.isfinite(global_best_cost):
        return float("nan")
    return float(global_best_cost - finite.mean())


def stagnation_update(g: int, rad_prev: float, rad: float, rtol: float) -> int:
    """Eq. 6 with a relative tolerance: ``g + 1`` if the radius did not change, else 0."""
    if np.isnan(rad_prev) or np.isnan(rad):
        return 0
    if rad_prev == rad or abs(rad_prev - rad) <= rtol * max(abs(rad_prev), abs(rad)):
        return g + 1
    return 0


def clamp_velocity(v: FloatArray, vmax: FloatArray) -> FloatArray:
    """Clamp each component to ``[-vmax_i, vmax_i]`` (in place); v (n, dim), vmax (dim,)."""
    return np.clip(v, -vmax, vmax, out=v)


def apply_bounds(
    x: FloatArray, v: FloatArray, lower: FloatArray, upper: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Velocity mirror: out-of-box coordinates go to the bound and their velocity flips sign.

    Both arrays (n, dim) are modified in place and returned.
    """
    outside = (x < lower) | (x > upper)
    if outside.any():
        np.negative(v, out=v, where=outside)
        np.clip(x, lower, upper, out=x)
    return x, v


def partition_sizes(n: int, k: int) -> list[int]:
    """Sizes of the ``k + 1`` parts of a swarm of ``n`` (``numpy.array_split`` rule)."""
    return [len(p) for p in np.array_split(np.arange(n), k + 1)]


def best_distinct(
    x: FloatArray,
    f: FloatArray,
    span: FloatArray,
    *,
    size: int,
    distinct_tol: float,
) -> tuple[FloatArray, FloatArray]:
    """The ``size`` best finite candidates that are pairwise distinct, best first.

    Parameters
    ----------
    x, f :
        Candidates (m, dim) and their values (m,).
    span :
        Search range per dimension (dim,), the unit of distance.
    size :
        Maximum number kept.
    distinct_tol :
        Two points are duplicates when ``max_i |x_i - y_i| / span_i <= distinct_tol``; the
        better one is kept.
    """
    order = np.argsort(f, kind="stable")
    order = order[np.isfinite(f[order])]
    keep: list[int] = []
    for i in order:
        if len(keep) >= size:
            break
        if keep:
            d = np.max(np.abs(x[keep] - x[i]) / span, axis=1)
            if np.any(d <= distinct_tol):
                continue
        keep.append(int(i))
    return x[keep].copy(), f[keep].copy()


def mutate_population(
    elites: FloatArray,
    n: int,
    lower: FloatArray,
    upper: FloatArray,
    sigma_fraction: float,
    rng: np.random.Generator,
) -> FloatArray:
    """Eq. 8: ``k + 1`` parts, ``k`` of Gaussian offspring of the elites, one uniform.

    Parameters
    ----------
    elites :
        Shape (k, dim); ``k = 0`` gives a uniform swarm.
    n :
        Swarm size.
    sigma_fraction :
        Standard deviation as a fraction of the range ``upper - lower`` of each dimension.

    Returns
    -------
    :
        Shape (n, dim): rows of part ``i`` are offspring of ``elites[i]`` (clipped to the box),
        the last part is uniform.
    """
    span = upper - lower
    k = elites.shape[0]
    sizes = partition_sizes(n, k)
    owner = np.repeat(np.arange(k + 1), sizes)  # part index per row; k = uniform part
    pop = lower + rng.random((n, lower.shape[0])) * span
    gauss = owner < k
    if k:
        centers = elites[owner[gauss]]
        pop[gauss] = centers + rng.standard_normal(centers.shape) * (sigma_fraction * span)
        np.clip(pop, lower, upper, out=pop)
    return pop


def _validate(opts: dict[str, Any]) -> None:
    if opts["mutation"] not in MUTATIONS:
        raise OptimizationError(
            f"emupso option mutation = {opts['mutation']!r}; choose one of {MUTATIONS}"
        )
    for name in ("w_start", "w_end", "c2_start", "c2_end", "vmax_fraction", "sigma_fraction"):
        if not opts[name] > 0:
            raise OptimizationError(f"emupso option {name} must be > 0, got {opts[name]}")
    if not 0 < opts["vmax_decay"] <= 1:
        raise OptimizationError(
            f"emupso option vmax_decay must be in (0, 1], got {opts['vmax_decay']}"
        )
    for name in ("stall_threshold", "n_elites", "archive_size"):
        if int(opts[name]) < 1:
            raise OptimizationError(f"emupso option {name} must be >= 1, got {opts[name]}")


def _archive_pool(
    arch_x: FloatArray,
    arch_f: FloatArray,
    p: FloatArray,
    pf: FloatArray,
    span: FloatArray,
    keep: dict[str, Any],
) -> tuple[FloatArray, FloatArray]:
    """The global archive (points (a, dim), values (a,)) joined with the local one: the best
    distinct personal bests ``p`` (n, dim), ``pf`` (n,) of the current cycle (``keep``: the
    ``size`` and ``distinct_tol`` of :func:`best_distinct`)."""
    loc_x, loc_f = best_distinct(p, pf, span, **keep)
    return np.vstack([arch_x, loc_x]), np.concatenate([arch_f, loc_f])


def _pso_step(
    x: FloatArray,
    v: FloatArray,
    p: FloatArray,
    g_best: FloatArray,
    w: float,
    c1: float,
    c2: float,
    vmax: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    rng: np.random.Generator,
) -> None:
    """One PSO move of positions ``x`` and velocities ``v`` (n, dim), in place.

    ``v = w v + c1 r1 (p - x) + c2 r2 (g_best - x)`` with uniform ``r1``, ``r2`` (n, dim),
    personal bests ``p`` (n, dim) and the swarm's best ``g_best`` (dim,); ``v`` clamped to
    ``vmax`` (dim,), ``x += v``, then the velocity mirror at the box ``lower``..``upper``.
    """
    r1 = rng.random(x.shape)
    r2 = rng.random(x.shape)
    v *= w
    v += c1 * r1 * (p - x)
    v += c2 * r2 * (g_best - x)
    clamp_velocity(v, vmax)
    x += v
    apply_bounds(x, v, lower, upper)


def run(problem: Problem, x0: FloatArray | None, **opts: Any) -> dict[str, Any]:
    """Run eMuPSO on ``problem``; returns the method-specific parts of the result."""
    _validate(opts)
    lo, hi, span = problem.lower, problem.upper, problem.span
    rng = problem.rng
    w, c2 = coefficient_schedules(
        problem.maxiter, opts["w_start"], opts["w_end"], opts["c2_start"], opts["c2_end"]
    )
    c1 = float(opts["c1"])
    decay = float(opts["vmax_decay"])
    vmax = opts["vmax_fraction"] * span
    big_g = int(opts["stall_threshold"])
    rtol = float(opts["stall_rtol"])
    keep: dict[str, Any] = {
        "size": int(opts["archive_size"]),
        "distinct_tol": float(opts["distinct_tol"]),
    }

    x = problem.initial_population(x0)
    v = np.zeros_like(x)
    f = problem.evaluate(x)
    p, pf = x.copy(), f.copy()
    gi = int(np.argmin(pf))
    rad = swarm_radius(pf[gi], pf)
    radii, stall, mutations = [rad], [0], []
    g = 0
    arch_x, arch_f = np.zeros((0, problem.dim)), np.zeros(0)
    stop = problem.end_iteration(0)

    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        if g >= big_g:  # eq. 7-8: new cycle from the archives (section 3.3)
            x, arch_x, arch_f = _new_cycle(problem, arch_x, arch_f, p, pf, keep, opts)
            v[:] = 0.0
            f = problem.evaluate(x)
            p, pf = x.copy(), f.copy()
            mutations.append(t)
            g = 0
            gi = int(np.argmin(pf))
            rad = swarm_radius(pf[gi], pf)
        else:
            _pso_step(x, v, p, p[gi], w[t - 1], c1, c2[t - 1], vmax * decay ** (t - 1), lo, hi, rng)
            f = problem.evaluate(x)
            _keep_better(p, pf, x, f)
            gi = int(np.argmin(pf))
            rad_new = swarm_radius(pf[gi], pf)
            g = stagnation_update(g, rad, rad_new, rtol)
            rad = rad_new
        radii.append(rad)
        stall.append(g)
        stop = problem.end_iteration(t)

    arch_x, arch_f = best_distinct(*_archive_pool(arch_x, arch_f, p, pf, span, keep), span, **keep)
    return {
        "radius": np.array(radii),
        "stagnation": np.array(stall, dtype=np.int64),
        "mutation_iterations": np.array(mutations, dtype=np.int64),
        "archive": EliteArchive(x=arch_x, fun=arch_f),
    }


def _new_cycle(
    problem: Problem,
    arch_x: FloatArray,
    arch_f: FloatArray,
    p: FloatArray,
    pf: FloatArray,
    keep: dict[str, Any],
    opts: dict[str, Any],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Eq. 7-8 (section 3.3): the new population (popsize, dim), mutated from the elites of the
    archive and personal bests ``p`` (popsize, dim) with values ``pf``, and the new archive
    (x, f)."""
    pool_x, pool_f = _archive_pool(arch_x, arch_f, p, pf, problem.span, keep)
    if opts["mutation"] == "gaussian":
        n_elites = int(opts["n_elites"])
        elites, _ = best_distinct(
            pool_x, pool_f, problem.span, size=n_elites, distinct_tol=keep["distinct_tol"]
        )
    else:
        elites = np.zeros((0, problem.dim))
    arch_x, arch_f = best_distinct(pool_x, pool_f, problem.span, **keep)
    x = mutate_population(
        elites, problem.popsize, problem.lower, problem.upper, opts["sigma_fraction"], problem.rng
    )
    return x, arch_x, arch_f


def _keep_better(p: FloatArray, pf: FloatArray, x: FloatArray, f: FloatArray) -> None:
    """Personal bests ``p`` (n, dim), ``pf`` (n,) replaced in place where ``f`` < ``pf``."""
    better = f < pf
    p[better] = x[better]
    pf[better] = f[better]
