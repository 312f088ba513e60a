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

Then the same with the safety constraints (floor, self-collision, torque limits of
:mod:`ident.excitation.safety`, clearances at ``check_samples`` samples per trajectory):

- ``ident``: the objective with ``safety=``: the clearances of the whole swarm's sampled
  postures in one vectorized call (exact against the floor, capsule lower bounds between the
  cylinders of the generated URDF);
- reference: the per-sample loop above plus, at the same samples, ``pin.computeDistances``
  (coal) per posture and ``pin.rnea`` per sample.

Both must agree on which particles are feasible where the reference's exact distances keep
the margin by more than the capsules' slack (the cheap term is conservative).

The last line is the figure quoted in the docs: ``swarm objective vs Pinocchio loop: N.Nx
(with safety terms: wrist N.Nx, arm N.Nx)`` (without safety, the smaller of the two stages).

Run: ``python benchmarks/bench_objective.py [--samples 500] [--repeat 5]``. Timings are noisy
on a shared machine: the best of ``--repeat`` runs is reported, the fast and the reference
calls alternating, all measured in the same run, with one BLAS thread (OpenBLAS threads on a loaded
2-core machine made the reference's SVD 4-17x slower from one run to the next).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

from ident import Robot
from ident.blas import one_blas_thread
from ident.dynamics.stage import paper_stages
from ident.excitation.constraints import penalty
from ident.excitation.mfs import PaperArmFamily
from ident.excitation.objective import CRITERION_CAP, ExcitationObjective
from ident.excitation.safety import build_safety_model
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


def reference_safety_violation(objective: ExcitationObjective, x: np.ndarray) -> np.ndarray:
    """Worst clearance excess per particle with coal, one posture at a time (+ rnea)."""
    from ident.excitation.safety import _subsample

    safety = objective.safety
    model, geom = safety.model, safety.geometry_model
    data, gdata = model.createData(), pin.GeometryData(geom)
    dyn = safety.robot_model.createData()
    batch = objective.family.trajectories(x)
    idx = _subsample(batch.n_samples, safety.config.check_samples)
    out = np.zeros(batch.n_particles)
    for i in range(batch.n_particles):
        for k in idx:
            pin.computeDistances(model, data, geom, gdata, batch.q[i, k])
            d = min(r.min_distance for r in gdata.distanceResults)
            pin.rnea(safety.robot_model, dyn, batch.q[i, k], batch.dq[i, k], batch.ddq[i, k])
            out[i] = max(out[i], safety.clearance_m - d)
    return out


def reference_fitness_safe(objective: ExcitationObjective, x: np.ndarray) -> np.ndarray:
    """The reference objective plus the coal clearance check at the same samples."""
    return reference_fitness(objective, x), reference_safety_violation(objective, x)


def best_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def best_times(fast, slow, repeat: int) -> tuple[float, float]:
    """Best of ``repeat`` of each, the two calls alternating (a load that changes during the
    measurement then reaches both sides)."""
    pairs = [(best_time(fast, 1), best_time(slow, 1)) for _ in range(repeat)]
    return min(p[0] for p in pairs), min(p[1] for p in pairs)


def main() -> None:
    with (
        one_blas_thread()
    ):  # one BLAS thread for both sides: threads on a loaded machine only add noise
        _main()


def _main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500, help="samples per period")
    parser.add_argument("--particles", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    robot = Robot.from_config("configs/paper6r.yaml")
    safety = build_safety_model(robot)
    rng = np.random.default_rng(0)
    print(f"paper robot, {args.particles} particles, {args.samples} samples per 10 s period")
    ratios: dict[str, float] = {}
    safe_ratios: dict[str, float] = {}
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
        t_fast, t_slow = best_times(
            lambda: objective(x),  # noqa: B023
            lambda: reference_fitness(objective, x),  # noqa: B023
            args.repeat,
        )
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

        # with the safety constraints (floor, self-collision, torque limits)
        safe = ExcitationObjective(
            robot, stage, family, safety=safety, base_columns=objective.columns
        )
        safe(x)
        t_safe, t_ref = best_times(
            lambda: safe(x),  # noqa: B023
            lambda: reference_fitness_safe(safe, x),  # noqa: B023
            args.repeat,
        )
        cheap = safe.violation(x) > objective.violation(x)
        _, excess = reference_fitness_safe(safe, x)
        disagree = np.flatnonzero(~cheap & (excess > 0.0))  # coal sees a violation, ident not
        print(
            f"       + safety ({safety.n_pairs} link pairs, {safety.config.check_samples} "
            f"samples/particle): ident {1e3 * t_safe:7.1f} ms   pinocchio loop + svd + coal "
            f"{1e3 * t_ref:7.1f} ms   ratio {t_ref / t_safe:5.1f}x   "
            f"{int(cheap.sum())}/{len(cheap)} particles unsafe"
        )
        if disagree.size:
            raise SystemExit(f"cheap term missed violations coal sees: particles {disagree}")
        ratios[name], safe_ratios[name] = t_slow / t_fast, t_ref / t_safe
    print(
        f"swarm objective vs Pinocchio loop: {min(ratios.values()):.1f}x (with safety terms: "
        f"wrist {safe_ratios['wrist']:.1f}x, arm {safe_ratios['arm']:.1f}x)"
    )


if __name__ == "__main__":
    main()
