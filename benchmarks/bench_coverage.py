"""Do the 95 % intervals cover? MuJoCo-simulated UR5 and Panda logs with known truth.

For each robot (``configs/ur5.yaml``, ``configs/panda.yaml``: closed-loop computed-torque
control at 1 kHz, viscous and Coulomb friction, armature, 2^19-count encoders, torque noise),
one fixed good excitation trajectory (``benchmarks/data/coverage_trajectories.json``: the
chosen elite of a full ``ident run`` of that config, seed 0, which passed the dense safety
check; never re-optimized here) is simulated and identified once per seed exactly as
``ident run`` does (:func:`ident.run.log_measurement.measure_and_identify`: the simulator
writes a log, the log reader reads it, :func:`ident.identify.pipeline.core.identify_measurements`
identifies it). The seed draws the torque noise; the motion, hence the quantization, the
filter and differentiation errors, the friction and the closed-loop errors, is the same in
every seed: a bias the intervals must absorb, not average out.

Printed per robot and interval method (``ordinary``: ``sigma^2 (W^T W)^-1``; ``hac`` and
``bootstrap``: :mod:`ident.identify.estimation.uncertainty`):

- the fraction of true base parameters inside their 95 % interval (goal 90-98 %);
- the fraction of held-out torque samples (rows above the velocity threshold) inside their
  95 % prediction interval (goal 93-97 %);
- the largest ``|error| / std`` over parameters and seeds.

    python benchmarks/bench_coverage.py [--seeds 20] [--quick] [--robots ur5 panda]

``--quick``: 4 seeds. The result of a full run is kept in ``docs/uncertainty.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from ident.identify.estimation.uncertainty import DEFAULT_METHOD, z_value
from ident.run.config import load_run_config
from ident.run.elite_identification import elite_trajectory
from ident.run.log_measurement import log_stage_info, measure_and_identify
from ident.run.setup import prepare_run

ROOT = Path(__file__).resolve().parents[1]
TRAJECTORIES = ROOT / "benchmarks" / "data" / "coverage_trajectories.json"
METHODS = ("ordinary", "hac", "bootstrap")
LEVEL = 0.95


def coverage(robot: str, seeds: int) -> dict[str, dict[str, float]]:
    """Coverage per method for ``robot`` over ``seeds`` seeds (module docstring)."""
    spec = json.loads(TRAJECTORIES.read_text(encoding="utf-8"))[robot]
    config = load_run_config(ROOT / spec["config"])
    setup = prepare_run(config, source=spec["config"])
    t, q, dq, ddq, _ = elite_trajectory(setup.family, np.asarray(spec["x"], dtype=float))
    stage, _ = log_stage_info(config, setup.robot)
    truth = np.asarray(stage.true_base)
    z = z_value(LEVEL)
    base: dict[str, list] = {m: [] for m in METHODS}
    held: dict[str, list] = {m: [] for m in METHODS}
    worst = dict.fromkeys(METHODS, 0.0)
    for seed in range(seeds):
        t0 = time.perf_counter()
        result = measure_and_identify(config, setup.robot, t, q, dq, ddq, seed=seed).result
        unc = result.uncertainty
        assert unc is not None
        error = np.abs(result.estimate.x - truth)
        residual = np.abs(result.tau_validate - result.predictions["identified"].tau_pred)
        keep = result.keep_validate
        for m in METHODS:
            std = unc.std(m)
            base[m].append(error <= z * std)
            worst[m] = max(worst[m], float(np.max(error / std)))
            held[m].append((residual <= z * result.prediction_std[m])[keep])
        print(
            f"  {robot} seed {seed:2d}: {time.perf_counter() - t0:5.1f} s, bandwidth "
            f"{unc.bandwidth:.0f} x {unc.block_samples} samples, base inside (ord/hac/boot) "
            + "/".join(f"{np.mean(base[m][-1]):.2f}" for m in METHODS),
            flush=True,
        )
    return {
        m: {
            "base": float(np.mean(np.concatenate(base[m]))),
            "held_out": float(np.mean(np.concatenate(held[m]))),
            "worst": worst[m],
            "n_base": int(truth.size),
        }
        for m in METHODS
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--quick", action="store_true", help="4 seeds")
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    args = parser.parse_args()
    seeds = 4 if args.quick else args.seeds
    t0 = time.perf_counter()
    table = {robot: coverage(robot, seeds) for robot in args.robots}
    print(f"\n{seeds} seeds per robot, {time.perf_counter() - t0:.0f} s")
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}\n"
    )
    print(
        "| robot | method | base parameters in 95 % interval | held-out torques in 95 % "
        "prediction interval | worst abs(error) / std |"
    )
    print("|---|---|---|---|---|")
    for robot, rows in table.items():
        for m, r in rows.items():
            default = " (default)" if m == DEFAULT_METHOD else ""
            print(
                f"| {robot} ({r['n_base']} base) | {m}{default} | {100 * r['base']:.1f} % | "
                f"{100 * r['held_out']:.1f} % | {r['worst']:.1f} |"
            )


if __name__ == "__main__":
    main()
