"""Time ``ident identify`` on the full Staubli TX40 log (45,000 samples at 5 kHz).

Target (issue 6): under 30 s on a 2-core machine. Prints the wall time of each stage for the
best of ``--repeat`` runs, the ratio to the 30 s budget, and the regressor stage against the
obvious alternative measured in the same run (a Python loop over
``pin.computeJointTorqueRegressor``).

    python benchmarks/bench_identify_tx40.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ident.identify.config import load_identify_config
from ident.identify.pipeline.real import identify, load_robot_model

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = 30.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    cfg = load_identify_config(ROOT / "configs" / "tx40.yaml")
    identify(cfg)  # warm-up: numba cache, imports
    runs = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        result = identify(cfg)
        runs.append((time.perf_counter() - t0, result))
    best_time, best = min(runs, key=lambda r: r[0])
    print(f"full TX40 log: {best.log.n_samples} samples, {best.estimate.n_observations} rows")
    print(
        f"wall time best of {args.repeat}: {best_time:.2f} s "
        f"(median {np.median([r[0] for r in runs]):.2f} s); budget {BUDGET_S:.0f} s, "
        f"ratio {best_time / BUDGET_S:.3f}"
    )
    for stage, seconds in best.timings.items():
        print(f"  {stage:16s} {seconds:7.3f} s")

    import pinocchio as pin

    from ident.dynamics.chain import chain_from_model
    from ident.dynamics.regressor import joint_torque_regressor

    model = load_robot_model(cfg.robot.urdf)
    chain = chain_from_model(model)
    q = best.log.q
    dq = np.gradient(q, 1.0 / best.log.sampling_rate_hz, axis=0)
    ddq = np.gradient(dq, 1.0 / best.log.sampling_rate_hz, axis=0)
    t0 = time.perf_counter()
    joint_torque_regressor(chain, q, dq, ddq)
    t_kernel = time.perf_counter() - t0
    data = model.createData()
    t0 = time.perf_counter()
    for k in range(q.shape[0]):
        pin.computeJointTorqueRegressor(model, data, q[k], dq[k], ddq[k])
    t_loop = time.perf_counter() - t0
    print(
        f"regressor, {q.shape[0]} samples: kernel {t_kernel:.3f} s, Pinocchio loop "
        f"{t_loop:.3f} s, ratio {t_loop / t_kernel:.1f}x"
    )


if __name__ == "__main__":
    main()
