"""Optimizers on ident's own excitation problems, at equal evaluation budgets.

For each problem (the shipped run configs ``configs/wrist.yaml``, ``arm.yaml``,
``wrist-fourier.yaml``, ``arm-fourier.yaml``, and UR5 from example-robot-data with a joint
Fourier family over its six joints) and each seed:

1. the initial elites are searched once (the pipeline's constraint-compliance swarm,
   :func:`ident.optim.elites.find_feasible_elites`) and every method starts from the same
   population spawned from them (:func:`ident.optim.elites.spawn_from_elites`, 20 points);
2. every method (``emupso``, ``pso``, ``de``, ``woa``, ``gwo``, ``goa``, ``cma``) minimizes
   the excitation objective (the pipeline's: eq. 15, scaled, with the constraint penalty) with
   a population of 20 and the budget of the pipeline: 5 runs x (30 + 1) iterations x 20 =
   3100 evaluations (``--budget-factor 10``: 31 000), in ONE run;
3. ``emupso-5x`` is what the pipeline does: 5 independent eMuPSO runs of 620 evaluations
   (each spawned from the elites with its own draw), the best of the five.

Printed per problem: median and interquartile range of the best fitness over the seeds, the
number of seeds whose best point is feasible, the mean rank, a Friedman test over all methods
and a one-sided Wilcoxon signed-rank test of every method against ``emupso`` (the pipeline's
method, one long run) and of ``emupso`` against ``emupso-5x``. Lower fitness is better.

Run: ``python benchmarks/bench_excitation.py [--seeds 10] [--budget-factor 1]
[--problems wrist arm ...] [--quick]``; ``--quick`` = 2 seeds, 3 problems, a smoke check of a
few minutes. The full run (10 seeds, 5 problems, 8 methods) takes about half an hour per
budget factor on one core.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy import stats

from ident.excitation import ExcitationObjective, JointFourierFamily
from ident.optim import minimize
from ident.optim.elites import find_feasible_elites, spawn_from_elites

METHODS = ("emupso", "pso", "de", "woa", "gwo", "goa", "cma")
CONFIGS = ("wrist", "arm", "wrist-fourier", "arm-fourier")
POPSIZE = 20
PIPELINE_BUDGET = 5 * (30 + 1) * POPSIZE  # 3100


def paper_problem(name: str) -> tuple[ExcitationObjective, np.ndarray]:
    """The objective and bounds `ident run configs/<name>.yaml` optimizes."""
    from ident.run.config import load_run_config
    from ident.run.pipeline import build_stage_info, get_stage, load_robot, make_family

    config = load_run_config(Path("configs") / f"{name}.yaml")
    robot = load_robot(Path(config.robot))
    stage = get_stage(robot, config.stage)
    family = make_family(config, robot, stage)
    info = build_stage_info(
        robot, stage, family, config.estimation.base_method, np.random.default_rng(0)
    )
    objective = ExcitationObjective(
        robot,
        stage,
        family,
        criterion=config.excitation.criterion,
        base_columns=[info.columns[i] for i in info.base.independent],
    )
    return objective, np.asarray(family.bounds, dtype=float)


def ur5_problem() -> tuple[ExcitationObjective, np.ndarray]:
    """UR5 (example-robot-data), joint Fourier series over all six joints, 10 s period."""
    import importlib.metadata

    from ident import Robot

    share = Path(
        str(importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share"))
    )
    robot = Robot.from_urdf(share / "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    # the URDF has no acceleration limits: 10 rad/s^2 (a UR5 reaches ~ 15)
    limits = SimpleNamespace(
        joint_names=robot.joint_names,
        q_lower=robot.q_lower,
        q_upper=robot.q_upper,
        dq_max=robot.dq_max,
        ddq_max=np.full(6, 10.0),
    )
    family = JointFourierFamily(
        limits, range(6), n_harmonics=4, base_frequency=2 * np.pi / 10, n_samples=250,
        amplitude_bound=0.4,
    )  # fmt: skip
    return ExcitationObjective(robot, None, family), np.asarray(family.bounds, dtype=float)


def run_problem(
    objective: ExcitationObjective, bounds: np.ndarray, seeds: list[int], budget: int
) -> dict[str, np.ndarray]:
    """Best fitness and feasibility per method and seed."""
    names = (*METHODS, "emupso-5x")
    best = {m: np.full(len(seeds), np.nan) for m in names}
    feasible = {m: np.zeros(len(seeds), dtype=bool) for m in names}
    for s, seed in enumerate(seeds):
        streams = np.random.SeedSequence(seed).spawn(3)
        search = find_feasible_elites(
            objective.violation, bounds, n_particles=10, n_elites=5, maxiter=100,
            rng=np.random.default_rng(streams[0]),
        )  # fmt: skip
        elites = np.asarray(search.elites) if search.success else bounds.mean(axis=1)[None]
        gen = np.random.default_rng(streams[1])
        x0 = spawn_from_elites(elites, POPSIZE, bounds, 0.1, gen)
        for method in METHODS:
            res = minimize(
                objective, bounds, method, rng=np.random.default_rng(streams[2]),
                popsize=POPSIZE, max_nfev=budget, x0=x0,
            )  # fmt: skip
            best[method][s] = res.fun
            feasible[method][s] = objective.violation(res.x[None])[0] <= 0.0
        # the pipeline: 5 independent short runs, each from its own spawn of the elites
        runs = []
        for k, stream in enumerate(np.random.SeedSequence(seed).spawn(5)):
            g = np.random.default_rng(stream)
            start = x0 if k == 0 else spawn_from_elites(elites, POPSIZE, bounds, 0.1, g)
            runs.append(
                minimize(
                    objective,
                    bounds,
                    "emupso",
                    rng=g,
                    popsize=POPSIZE,
                    max_nfev=budget // 5,
                    x0=start,
                )  # fmt: skip
            )
        top = min(runs, key=lambda r: r.fun)
        best["emupso-5x"][s] = top.fun
        feasible["emupso-5x"][s] = objective.violation(top.x[None])[0] <= 0.0
    return {"best": best, "feasible": feasible}


def report(name: str, result: dict, seconds: float) -> None:
    best, feasible = result["best"], result["feasible"]
    names = list(best)
    table = np.column_stack([best[m] for m in names])  # (n_seeds, n_methods)
    ranks = stats.rankdata(table, axis=1).mean(axis=0)
    print(f"\n== {name}  ({table.shape[0]} seeds, {seconds:.0f} s)")
    print(f"{'method':10s} {'median':>12s} {'q25':>12s} {'q75':>12s} {'feasible':>9s} {'rank':>5s}"
          f" {'vs emupso (p)':>14s}")  # fmt: skip
    for k, m in enumerate(names):
        q25, med, q75 = np.percentile(best[m], [25, 50, 75])
        if m == "emupso" or table.shape[0] < 5:
            p = "-"
        else:
            other = best["emupso"]
            diff = best[m] - other
            p = "=" if np.all(diff == 0) else f"{stats.wilcoxon(best[m], other).pvalue:.3f}"
            p += " <" if np.median(diff) < 0 else " >"
        print(f"{m:10s} {med:12.5g} {q25:12.5g} {q75:12.5g} {int(feasible[m].sum()):9d} "
              f"{ranks[k]:5.2f} {p:>14s}")  # fmt: skip
    if table.shape[0] >= 3:
        f = stats.friedmanchisquare(*table.T)
        print(f"Friedman chi2 = {f.statistic:.1f}, p = {f.pvalue:.2g} (all methods)")
    order = [names[i] for i in np.argsort(ranks)]
    print("by mean rank: " + " < ".join(order))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--budget-factor", type=int, default=1, help="1: 3100 evaluations")
    parser.add_argument("--problems", nargs="*", default=[*CONFIGS, "ur5"])
    parser.add_argument("--quick", action="store_true", help="2 seeds, 3 problems")
    args = parser.parse_args()
    seeds = list(range(2 if args.quick else args.seeds))
    problems = ["wrist", "wrist-fourier", "ur5"] if args.quick else args.problems
    budget = PIPELINE_BUDGET * args.budget_factor
    print(f"budget {budget} evaluations per method and seed, population {POPSIZE}")
    for name in problems:
        start = time.perf_counter()
        objective, bounds = ur5_problem() if name == "ur5" else paper_problem(name)
        result = run_problem(objective, bounds, seeds, budget)
        report(name, result, time.perf_counter() - start)


if __name__ == "__main__":
    main()
