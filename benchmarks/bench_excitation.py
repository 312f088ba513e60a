"""Optimizers on the excitation problems `ident run` solves, at equal evaluation budgets.

Each problem is a shipped run config, optimized exactly as the pipeline does it
(:func:`ident.run.problem.excitation_problem`: eq. 15 on the scaled base Gram matrix, the
family's constraint penalties and, with a ``safety:`` section, the clearance and torque terms):
``wrist``, ``arm`` (the paper's), ``wrist-fourier``, ``arm-fourier``, ``wrist-box``,
``arm-box`` (the paper robot beyond the paper) and ``ur5`` (a robot from its URDF, mesh
collision geometry; ``panda`` on request). Per problem and seed:

1. the initial elites are searched once with the config's elite settings
   (:func:`ident.optim.elites.find_feasible_elites`) and every method starts from the same
   population of 20 spawned from them (:func:`ident.optim.elites.spawn_from_elites`);
2. every method (``emupso pso de woa gwo goa cma``) minimizes the objective in ONE run of the
   budget: the paper pipeline's 5 runs x (30 + 1) iterations x 20 = 3100 evaluations
   (``--budget-factor 10``: 31 000); ``emupso-5x`` is what the paper's pipeline does, 5
   independent eMuPSO runs of 620 evaluations, each from its own spawn of the elites, best of
   five;
3. each method's best point is identified as the pipeline identifies an elite
   (:func:`ident.run.elite_identification.identify_elite`: Pinocchio torques plus the config's
   noise, the same noise draw for every method, OLS), and the error of the stage's *major*
   parameters (those explaining at least 1 % of the stage's torques) is its largest relative
   error. ``ur5``'s config measures with MuJoCo (about a minute per trajectory); here it is
   the ideal measurement with the config's noise levels and encoder.

Printed per problem: median and interquartile range of the best fitness and of the major
parameters' error, the number of seeds whose best point is feasible (every constraint, safety
included), the mean rank of the fitness, Friedman's test over the methods, and Wilcoxon's
signed-rank test (two-sided) of every method against ``emupso`` (one long run), for the
fitness and for the error; ``<`` / ``>``: the method's median is lower / higher. Lower is
better for both. Also how many seeds' elite search found every elite.

``--split config`` runs every method at each config's own split of the budget instead:
``emupso.n_runs`` runs of ``n_particles x (maxiter + 1)`` evaluations, each from its own spawn
of the elites, best of the runs (as ``ident run`` spends it), labelled ``method:RUNSxEVALS``;
``--split both`` adds one run of the same total per method (``docs/optimizers.md``).

Run: ``python benchmarks/bench_excitation.py [--seeds 10] [--budget-factor 1]
[--problems wrist arm ...] [--methods emupso cma ...] [--split one|config|both]
[--save FILE.json] [--quick]``.
``--quick``: 2 seeds, budget 620, problems wrist and wrist-fourier (a smoke run of a minute).
The full run (10 seeds, 7 problems, 8 methods) takes about 40 minutes on one core; the 10x
budget ten times that, so run it on a subset (``--methods emupso emupso-5x pso cma``).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import stats

from ident.blas import one_blas_thread
from ident.optim import minimize
from ident.optim.elites import find_feasible_elites, spawn_from_elites
from ident.run.config import MeasurementSection, RunConfig, load_run_config
from ident.run.elite_identification import identify_elite
from ident.run.problem import ExcitationProblem, excitation_problem
from ident.run.setup import RunSetup, prepare_run

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("emupso", "pso", "de", "woa", "gwo", "goa", "cma")
ALL_METHODS = (*METHODS, "emupso-5x")
PROBLEMS = ("wrist", "arm", "wrist-fourier", "arm-fourier", "wrist-box", "arm-box", "ur5")
POPSIZE = 20
PIPELINE_BUDGET = 5 * (30 + 1) * POPSIZE  # 3100
MAJOR_SHARE = 1e-2


def load_problem(name: str) -> tuple[RunSetup, ExcitationProblem]:
    """The prepared config ``configs/<name>.yaml`` (ideal measurement) and its problem."""
    config = load_run_config(ROOT / "configs" / f"{name}.yaml")
    m = config.measurement
    if m.source != "ideal":  # the simulator's noise and encoder, measured ideally
        config = config.model_copy(
            update={
                "measurement": MeasurementSection(
                    torque_noise_std=m.torque_noise_std,
                    encoder_counts_per_rev=getattr(m, "encoder_counts_per_rev", None),
                )
            }
        )
    setup = prepare_run(config)
    # the pipeline's stream for the stage's base parameters: the very objective it optimizes
    stream = np.random.SeedSequence(config.seed).spawn(4)[3]
    return setup, excitation_problem(setup, np.random.default_rng(stream))


def major_error(setup: RunSetup, problem: ExcitationProblem, x: np.ndarray, seed: int) -> float:
    """Largest relative error of the major base parameters when ``x`` is identified (OLS)."""
    info = problem.stage_info
    with one_blas_thread():
        outcome = identify_elite(
            setup.config, setup.robot, setup.family, info, 1, x, float("nan"), {}, seed
        )
    est = outcome.estimates.get("ols") or next(iter(outcome.estimates.values()), None)
    if est is None:
        return float("inf")
    true = np.asarray(info.true_base, dtype=float)
    major = np.asarray(info.reference_share) >= MAJOR_SHARE
    return float(np.max(np.abs(np.asarray(est.x)[major] - true[major]) / np.abs(true[major])))


@dataclass
class ProblemResult:
    """Per method, one value per seed."""

    fitness: dict[str, list[float]] = field(default_factory=dict)
    error: dict[str, list[float]] = field(default_factory=dict)
    feasible: dict[str, list[bool]] = field(default_factory=dict)
    elites_found: list[bool] = field(default_factory=list)
    seconds: float = 0.0


def _run_method(
    problem: ExcitationProblem, method: str, x0: np.ndarray, budget: int, rng, stall: int
):  # noqa: ANN001, ANN202
    options = {"stall_threshold": stall} if method == "emupso" else {}
    return minimize(
        problem.objective, problem.bounds, method, rng=rng, popsize=POPSIZE, max_nfev=budget,
        x0=x0, **options,
    )  # fmt: skip


def config_split(cfg: RunConfig) -> tuple[int, int]:
    """The config's split of its budget: (runs, evaluations per run = particles x (iter + 1))."""
    o = cfg.emupso
    return o.n_runs, o.n_particles * (o.maxiter + 1)


def entries(
    methods: tuple[str, ...], split: str, budget: int, cfg: RunConfig
) -> list[tuple[str, str, int, int]]:
    """What runs per seed: ``(label, method, runs, evaluations per run)``.

    ``split="one"``: every method in one run of ``budget`` (``emupso-5x``: 5 runs of a fifth);
    ``"config"``: every method at the config's own split (``emupso.n_runs`` runs of
    ``n_particles x (maxiter + 1)``, best of the runs), labelled ``method:RxE``; ``"both"``:
    each method at the config's split and in one run of the config's whole budget.
    """
    n_runs, per_run = config_split(cfg)
    out = []
    for m in methods:
        if split == "one":
            out.append((m, "emupso", 5, budget // 5) if m == "emupso-5x" else (m, m, 1, budget))
            continue
        base = "emupso" if m == "emupso-5x" else m
        out.append((f"{base}:{n_runs}x{per_run}", base, n_runs, per_run))
        if split == "both" and n_runs > 1:
            out.append((f"{base}:1x{n_runs * per_run}", base, 1, n_runs * per_run))
    return list(dict.fromkeys(out))


def run_problem(
    name: str, seeds: list[int], budget: int, methods: tuple[str, ...], split: str = "one"
) -> ProblemResult:
    """Every method on every seed of one problem (module docstring)."""
    start = time.perf_counter()
    setup, problem = load_problem(name)
    cfg = setup.config
    out = ProblemResult()
    plan = entries(methods, split, budget, cfg)
    for label, *_ in plan:
        out.fitness[label], out.error[label], out.feasible[label] = [], [], []
    for seed in seeds:
        streams = np.random.SeedSequence(seed).spawn(4)
        search = find_feasible_elites(
            problem.objective.violation, problem.bounds, n_particles=cfg.elites.n_particles,
            n_elites=cfg.elites.n_elites, maxiter=cfg.elites.maxiter,
            rng=np.random.default_rng(streams[0]),
        )  # fmt: skip
        out.elites_found.append(bool(search.success))
        elites = np.asarray(search.elites) if len(search.elites) else problem.bounds.mean(1)[None]
        sigma = cfg.emupso.sigma_fraction
        x0 = spawn_from_elites(elites, POPSIZE, problem.bounds, sigma, streams[1])
        noise_seed = int(streams[3].generate_state(1)[0])
        for label, method, n_runs, per_run in plan:
            if n_runs == 1:
                gen = np.random.default_rng(streams[2])
                res = _run_method(problem, method, x0, per_run, gen, cfg.emupso.stagnation)
            else:  # the pipeline's way: independent runs, each from its own spawn, best one
                runs = []
                for k, child in enumerate(streams[2].spawn(n_runs)):
                    gen = np.random.default_rng(child)
                    start_x = (
                        x0
                        if k == 0
                        else spawn_from_elites(elites, POPSIZE, problem.bounds, sigma, gen)
                    )
                    runs.append(
                        _run_method(problem, method, start_x, per_run, gen, cfg.emupso.stagnation)
                    )
                res = min(runs, key=lambda r: r.fun)
            out.fitness[label].append(float(res.fun))
            out.feasible[label].append(bool(problem.objective.violation(res.x[None])[0] <= 0.0))
            out.error[label].append(major_error(setup, problem, res.x, noise_seed))
    out.seconds = time.perf_counter() - start
    return out


def wilcoxon_vs(values: dict[str, list[float]], method: str, reference: str) -> str:
    """Two-sided Wilcoxon p-value of ``method`` vs ``reference`` and the side of the median."""
    a, b = np.asarray(values[method]), np.asarray(values[reference])
    if method == reference or a.size < 5:
        return "-"
    diff = a - b
    if np.all(diff == 0):
        return "="
    p = stats.wilcoxon(a, b).pvalue
    return f"{p:.3f} {'<' if np.median(diff) < 0 else '>'}"


def mean_ranks(values: dict[str, list[float]]) -> dict[str, float]:
    """Mean rank (1 = lowest) of each method over the seeds."""
    names = list(values)
    table = np.column_stack([values[m] for m in names])
    ranks = stats.rankdata(table, axis=1).mean(axis=0)
    return dict(zip(names, ranks.tolist(), strict=True))


def report(name: str, result: ProblemResult) -> list[str]:
    """The printed table of one problem."""
    n = len(result.elites_found)
    ranks = mean_ranks(result.fitness)
    ref = "emupso" if "emupso" in result.fitness else next(iter(result.fitness))
    lines = [
        f"\n== {name}  ({n} seeds, {result.seconds:.0f} s; elite search found every elite on "
        f"{sum(result.elites_found)} of {n} seeds)",
        f"{'method':14s} {'fitness':>10s} {'IQR':>21s} {'rank':>5s} {'feas.':>5s} "
        f"{'vs ' + ref + ' (p)':>16s}  {'major err':>9s} {'IQR':>17s} {'vs ' + ref + ' (p)':>16s}",
    ]
    for m in result.fitness:
        f = np.percentile(result.fitness[m], [25, 50, 75])
        e = np.percentile(result.error[m], [25, 50, 75])
        lines.append(
            f"{m:14s} {f[1]:10.5g} [{f[0]:9.4g}, {f[2]:9.4g}] {ranks[m]:5.2f} "
            f"{sum(result.feasible[m]):5d} {wilcoxon_vs(result.fitness, m, ref):>16s}  "
            f"{e[1]:9.3g} [{e[0]:7.3g}, {e[2]:7.3g}] {wilcoxon_vs(result.error, m, ref):>16s}"
        )
    if n >= 3 and len(result.fitness) >= 3:
        fit = stats.friedmanchisquare(*result.fitness.values())
        err = stats.friedmanchisquare(*result.error.values())
        lines.append(
            f"Friedman: fitness chi2 = {fit.statistic:.1f}, p = {fit.pvalue:.2g}; major error "
            f"chi2 = {err.statistic:.1f}, p = {err.pvalue:.2g}"
        )
    lines.append("by mean fitness rank: " + " < ".join(sorted(ranks, key=ranks.get)))
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--budget-factor", type=float, default=1.0, help="1: 3100 evaluations")
    parser.add_argument("--problems", nargs="*", default=list(PROBLEMS))
    parser.add_argument("--methods", nargs="*", default=list(ALL_METHODS))
    parser.add_argument("--save", type=Path, default=None, help="write the raw values (JSON)")
    parser.add_argument("--quick", action="store_true", help="2 seeds, 620 evaluations")
    parser.add_argument(
        "--split",
        choices=("one", "config", "both"),
        default="one",
        help="one run of the budget (default), the config's runs x iterations, or both",
    )
    args = parser.parse_args(argv)
    unknown = sorted(set(args.methods) - set(ALL_METHODS))
    if unknown:
        parser.error(f"unknown method(s) {unknown}; choose from {list(ALL_METHODS)}")
    seeds = list(range(2 if args.quick else args.seeds))
    problems = ["wrist", "wrist-fourier"] if args.quick else args.problems
    budget = int(PIPELINE_BUDGET * (0.2 if args.quick else args.budget_factor))
    print(
        f"budget {budget} evaluations per method and seed, population {POPSIZE}, split "
        f"{args.split} (config: each config's emupso.n_runs x n_particles x (maxiter + 1))",
        flush=True,
    )
    saved = {}
    for name in problems:
        result = run_problem(name, seeds, budget, tuple(args.methods), args.split)
        print("\n".join(report(name, result)), flush=True)
        saved[name] = {
            "budget": budget,
            "split": args.split,
            "seeds": seeds,
            "seconds": result.seconds,
            "elites_found": result.elites_found,
            "fitness": result.fitness,
            "major_error": result.error,
            "feasible": result.feasible,
        }
        if args.save is not None:  # after every problem: nothing finished is lost
            args.save.write_text(json.dumps(saved, indent=1))


if __name__ == "__main__":
    main()
