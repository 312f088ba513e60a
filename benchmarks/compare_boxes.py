"""The paper's +-10 box against a box sized to the workspace, over seeds.

For each pair of run configs (``configs/wrist.yaml`` vs ``configs/wrist-box.yaml``,
``configs/arm.yaml`` vs ``configs/arm-box.yaml``: the same Cartesian family, procedure,
noise and settings; only ``excitation.bounds`` and the ``safety`` section differ) and each
seed, the whole pipeline runs in this process (``ident.run.setup.load_run`` +
``ident.run.pipeline.run_pipeline``, as ``ident run CONFIG --seed k``), and of the chosen
elite (the first reported elite that passes the dense 1 kHz safety check, else elite 1, the
one ``ident run`` would have written) it takes:

- ``fitness``: the objective (eq. 15, scaled, with the constraint penalty);
- ``cond``: the condition number of the scaled base observation matrix (eq. 15's);
- ``err``: the worst relative error ``|x - true| / |true|`` of the WLS estimate over the
  stage's *major* base parameters (reference torque share >= 1 %, the same set for every
  trajectory of a stage);
- ``clear``: the smallest clearance of the dense check [m] (floor at z = 0, the pedestal,
  self-collision; negative: penetration);
- ``safe``: the number of seeds where a reported elite is safe (``ident run`` exits 0).

Printed: the per-seed rows, then per config the median and the range [min, max] over the
seeds. Paper configs have no ``safety`` section, so their optimization ignores collisions;
the dense check still runs with the defaults.

Run: ``python benchmarks/compare_boxes.py [--seeds 5] [--quick] [--stages wrist arm]``.
Full settings: about 10 s per run on a 2-core machine, so about 4 minutes for 5 seeds and
both stages. ``--quick`` uses each config's ``quick`` section (120 samples, small swarms).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ident.run.pipeline import run_pipeline
from ident.run.setup import load_run

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def measure(name: str, seed: int, quick: bool) -> dict[str, float]:
    """One run of ``configs/<name>.yaml`` at ``seed``: the chosen elite's measures."""
    setup = load_run(CONFIGS / f"{name}.yaml")
    config = setup.config.with_seed(seed)
    if quick:
        config = config.quick_version()
    result = run_pipeline(config)
    plan = result.executable
    safe = plan is not None and plan.usable
    elite = result.elites[(plan.elite if safe else 1) - 1]
    stage = result.stage
    major = stage.reference_share >= 1e-2
    true = stage.true_base[major]
    x = elite.estimates["wls"].x[major]
    worst = elite.safety_check.min_clearance if elite.safety_check is not None else None
    return {
        "fitness": float(elite.fitness),
        "cond": float(elite.details["cond"]),
        "err": float(np.max(np.abs(x - true) / np.abs(true))),
        "clear": float(worst.value) if worst is not None else float("nan"),
        "safe": float(safe),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--stages", nargs="+", default=["wrist", "arm"])
    args = parser.parse_args()
    names = [n for s in args.stages for n in (s, f"{s}-box")]
    rows: dict[str, list[dict[str, float]]] = {n: [] for n in names}
    print("config          seed  fitness      cond    err major  clearance [m]  safe")
    for name in names:
        for seed in range(args.seeds):
            m = measure(name, seed, args.quick)
            rows[name].append(m)
            print(
                f"{name:15s} {seed:4d} {m['fitness']:8.4g} {m['cond']:9.4g} {m['err']:10.3g}"
                f" {m['clear']:14.3f}  {'yes' if m['safe'] else 'no'}",
                flush=True,
            )
    settings = "quick" if args.quick else "full"
    print(f"\nmedian [min, max] over {args.seeds} seeds ({settings} settings), chosen elite, WLS")
    print(
        "| config | fitness | cond (scaled) | max rel. error, major | smallest clearance [m] "
        "| safe seeds |"
    )
    print("|---|---|---|---|---|---|")
    for name in names:
        cells = []
        for key, fmt in (("fitness", ".3g"), ("cond", ".3g"), ("err", ".2g"), ("clear", ".3f")):
            v = np.array([r[key] for r in rows[name]])
            cells.append(f"{np.median(v):{fmt}} [{v.min():{fmt}}, {v.max():{fmt}}]")
        n_safe = int(sum(r["safe"] for r in rows[name]))
        print(f"| `{name}.yaml` | " + " | ".join(cells) + f" | {n_safe} / {args.seeds} |")


if __name__ == "__main__":
    main()
