"""Speed of the excitation objective (paper eq. 15) on one 20-particle swarm.

Compares, in one run and on the same designs of the paper robot's wrist and arm stages:

- ``ident``: :class:`ident.excitation.objective.ExcitationObjective` -- the whole swarm in one
  call: vectorized trajectories, the fused numba Gram kernel (no regressor tensor), batched
  ``eigvalsh`` of the small Gram matrices;
- reference: the obvious implementation -- same trajectories, then per particle a loop over the
  samples calling ``pin.computeJointTorqueRegressor``, the stacked base observation matrix,
  ``numpy.linalg.svd``.

It checks that both give the same fitness (relative difference below 1e-8), prints both times
and their ratio, and the time of the optimizer budget of the paper (initial elites + 5 runs x
30 iterations x 20 particles) predicted from one swarm evaluation.

Run: ``python benchmarks/bench_objective.py [--samples 500] [--repeat 5]``. Timings are noisy
on a shared machine: the best of ``--repeat`` runs is reported.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

from ident import Robot
from ident.dynamics.stage import paper_stages
from ident.excitation.constraints import penalty
from ident.excitation.mfs import PaperArmFamily
from ident.excitation.objective import CRITERION_CAP, ExcitationObjective
from ident.excitation.wrist import PaperWristFamily


def reference_fitness(objective: ExcitationObjective, x: np.ndarray) -> np.ndarray:
    """Eq. 15 + penalty with a per-sample Pinocchio loop and an SVD of the tall matrix."""
    model = objective.robot.model
    data = model.createData()
    batch = objective.family.trajectories(x)
    rows, cols = list(objective.rows), list(objective.columns)
    out = np.empty(batch.n_particles)
    for i in range(batch.n_particles):
        blocks = []
        for k in range(batch.n_samples):
            y = pin.computeJointTorqueRegressor(
                model, data, batch.q[i, k], batch.dq[i, k], batch.ddq[i, k]
            )
            blocks.append(y[rows][:, cols])
        w = np.vstack(blocks) * objective.column_scale / np.sqrt(len(blocks) * len(rows))
        s = np.linalg.svd(w, compute_uv=False)
        value = s[0] / s[-1] + 1.0 / s[-1] + s[0] if s[-1] > 0 else CRITERION_CAP
        out[i] = min(value, CRITERION_CAP)
    return out + penalty(batch.violations, objective.penalty_weight)


def best_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500, help="samples per period")
    parser.add_argument("--particles", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    robot = Robot.from_config("configs/paper6r.yaml")
    rng = np.random.default_rng(0)
    print(f"paper robot, {args.particles} particles, {args.samples} samples per 10 s period")
    for name, family_type in (("wrist", PaperWristFamily), ("arm", PaperArmFamily)):
        family = family_type(robot, n_samples=args.samples)
        stage = paper_stages(robot.chain, family.held_positions)[name]
        objective = ExcitationObjective(robot, stage, family)
        x = rng.uniform(
            family.bounds[:, 0], family.bounds[:, 1], (args.particles, len(family.bounds))
        )
        fast = objective(x)  # compile the kernels before timing
        slow = reference_fitness(objective, x)
        rel = np.max(np.abs(fast - slow) / np.abs(slow))
        t_fast = best_time(lambda: objective(x), args.repeat)  # noqa: B023
        t_slow = best_time(lambda: reference_fitness(objective, x), max(1, args.repeat // 2))  # noqa: B023
        t_violation = best_time(lambda: objective.violation(x), args.repeat)  # noqa: B023
        n_evals = 5 * 30 + 1  # eMuPSO: 5 runs x 30 iterations (+ the initial swarm)
        print(
            f"{name:5s} stage, {len(objective.columns)} base columns: "
            f"ident {1e3 * t_fast:7.1f} ms   pinocchio loop + svd {1e3 * t_slow:7.1f} ms   "
            f"ratio {t_slow / t_fast:5.1f}x   max rel. fitness difference {rel:.1e}"
        )
        print(
            f"       constraint-only evaluation (initial elites) {1e3 * t_violation:.1f} ms; "
            f"paper budget 5 runs x 30 iterations x 20 particles: "
            f"{n_evals * t_fast * args.particles / 20:.1f} s of objective time"
        )
        if not rel < 1e-8:
            raise SystemExit(f"fitness mismatch: {rel:.2e} >= 1e-8")


if __name__ == "__main__":
    main()
