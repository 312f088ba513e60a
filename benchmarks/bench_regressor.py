"""Speed of the hand-derived regressor against a Python loop over Pinocchio.

Times, in one run and on the same random states of one robot (default: the paper's robot),

* ``joint_torque_regressor`` (compiled numba kernel) for the full (n_samples, nv, 10 n) tensor,
* a Python loop over ``pin.computeJointTorqueRegressor`` (the obvious alternative),
* ``regressor_gram`` (the Gram matrix the excitation objective uses, no tensor),
* the numpy reference implementation (for information),

and prints per-sample times, the ratio and the largest difference. Each timing is the best
of ``--repeat`` interleaved runs after a warm-up call (numba compiles, or loads its cache, on
the first call). Usage::

    python benchmarks/bench_regressor.py [--urdf robot/urdf/paper6r.urdf] [--samples 1000]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.gram import regressor_gram
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.dynamics.regressor import joint_torque_regressor, joint_torque_regressor_numpy
from ident.dynamics.stage import paper_stages

ROOT = Path(__file__).resolve().parents[1]


def best_times(functions: dict[str, Callable[[], object]], repeat: int) -> dict[str, float]:
    """Smallest wall time [s] of ``repeat`` calls of each function, calls interleaved so that
    every method sees the same (shared, noisy) machine load."""
    times: dict[str, list[float]] = {name: [] for name in functions}
    for _ in range(repeat):
        for name, function in functions.items():
            start = time.perf_counter()
            function()
            times[name].append(time.perf_counter() - start)
    return {name: min(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urdf", type=Path, default=ROOT / "robot/urdf/paper6r.urdf")
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    model = pin.buildModelFromUrdf(str(args.urdf))
    chain = chain_from_model(model)
    q, dq, ddq = random_states(chain, args.samples, rng=args.seed)
    n = args.samples
    wrist = {}
    if chain.n_joints == 6:  # the excitation objective's typical call: one stage's rows/columns
        stage = paper_stages(chain)["wrist"]
        wrist = {"rows": stage.torque_rows, "columns": stage.columns}

    ours = joint_torque_regressor(chain, q, dq, ddq)  # warm-up: compile or load the cache
    regressor_gram(chain, q[:2], dq[:2], ddq[:2])
    reference = pinocchio_regressor(model, q, dq, ddq)
    difference = float(np.max(np.abs(ours - reference)))

    times = best_times(
        {
            "ours": lambda: joint_torque_regressor(chain, q, dq, ddq),
            "pin": lambda: pinocchio_regressor(model, q, dq, ddq),
            "gram": lambda: regressor_gram(chain, q, dq, ddq),
            "gram_wrist": lambda: regressor_gram(chain, q, dq, ddq, **wrist),
        },
        args.repeat,
    )
    t_ours, t_pin, t_gram, t_wrist = (times[k] for k in ("ours", "pin", "gram", "gram_wrist"))
    # timed apart: its many large temporaries make the allocator hand fresh (page-faulting)
    # memory to the next output array, which would bias the interleaved timings above
    t_numpy = best_times({"numpy": lambda: joint_torque_regressor_numpy(chain, q, dq, ddq)}, 3)[
        "numpy"
    ]
    gram = regressor_gram(chain, q, dq, ddq)
    full = reference.reshape(-1, reference.shape[-1])
    gram_difference = float(np.max(np.abs(gram - full.T @ full)) / np.max(np.abs(full.T @ full)))

    print(f"robot {args.urdf.name}: {chain.n_joints} joints, {n} random states (seed {args.seed})")
    print(f"{'method':44s} {'us/sample':>10s}")
    print(f"{'Python loop over pin.computeJointTorqueRegressor':44s} {1e6 * t_pin / n:10.3f}")
    print(f"{'joint_torque_regressor (numba)':44s} {1e6 * t_ours / n:10.3f}")
    print(f"{'regressor_gram, all rows and columns (numba)':44s} {1e6 * t_gram / n:10.3f}")
    label = "regressor_gram, wrist rows 4-6, bodies 4-6" if wrist else "regressor_gram (again)"
    print(f"{label:44s} {1e6 * t_wrist / n:10.3f}")
    print(f"{'joint_torque_regressor_numpy (reference)':44s} {1e6 * t_numpy / n:10.3f}")
    print(f"speed-up of joint_torque_regressor over the Pinocchio loop: {t_pin / t_ours:.2f}x")
    print(f"speed-up of regressor_gram over the Pinocchio loop:         {t_pin / t_gram:.2f}x")
    print(f"max |Y - Y_pinocchio| = {difference:.3e} (tensor scale {np.abs(reference).max():.3e})")
    print(f"max relative difference of the Gram matrix = {gram_difference:.3e}")
    print("(timings on a shared machine are noisy: compare ratios of one run, not absolute times)")


if __name__ == "__main__":
    main()
