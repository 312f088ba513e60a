"""Optimizer overhead vs scipy, and campaign speed-up with workers.

Run: ``python benchmarks/bench_optim.py`` (prints; nothing is written).

1. Per-iteration overhead of each ``ident.optim`` method (wall time minus the time spent in
   the objective, per iteration) on a trivial vectorized objective, against
   ``scipy.optimize.differential_evolution`` at the same population and number of evaluations
   (``vectorized=True, polish=False, updating='deferred', tol=0``), measured in the same run.
   Target: our overhead no higher than scipy's.
2. Wall time of the smoke campaign (``configs/bench-smoke.yaml``) and of a larger variant with
   1 and 2 worker processes. Target: near-linear speed-up (the machine may be shared: the
   numbers are only meaningful when the cores are idle).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
from scipy.optimize import differential_evolution

from ident.bench.campaign import CampaignConfig, load_campaign_config, run_campaign
from ident.optim import METHODS, minimize

ROOT = Path(__file__).resolve().parents[1]
DIM, POP, MAXITER, REPEAT = 10, 30, 300, 3


class Timed:
    """Trivial objective that accumulates the time spent inside it."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.points = 0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.points += x.shape[0]
        t0 = time.perf_counter()
        f = np.sum(x * x, axis=-1)
        self.seconds += time.perf_counter() - t0
        return f


def overhead_ours(method: str) -> tuple[float, int]:
    best = np.inf
    for k in range(REPEAT):
        obj = Timed()
        t0 = time.perf_counter()
        res = minimize(obj, [(-5, 5)] * DIM, method, rng=k, popsize=POP, maxiter=MAXITER)
        wall = time.perf_counter() - t0
        best = min(best, (wall - obj.seconds) / res.nit)
    return best, obj.points


def overhead_scipy() -> tuple[float, int]:
    best = np.inf
    for k in range(REPEAT):
        obj = Timed()
        t0 = time.perf_counter()
        res = differential_evolution(
            lambda x, obj=obj: obj(x.T),  # scipy passes (dim, S) when vectorized
            [(-5, 5)] * DIM,
            popsize=POP // DIM,  # scipy's popsize is a multiplier of dim
            maxiter=MAXITER,
            tol=0.0,
            atol=0.0,
            polish=False,
            updating="deferred",
            vectorized=True,
            init="random",
            rng=k,
        )
        wall = time.perf_counter() - t0
        best = min(best, (wall - obj.seconds) / res.nit)
    return best, obj.points  # scipy's res.nfev counts calls when vectorized


def campaign_times(cfg: CampaignConfig) -> tuple[float, float]:
    t1 = run_campaign(cfg, workers=1).wall_seconds
    t2 = run_campaign(cfg, workers=2).wall_seconds
    return t1, t2


def main() -> None:
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} "
          "(shared machine: timings are noisy)")  # fmt: skip
    print(f"\n1. overhead per iteration, dim {DIM}, population {POP}, {MAXITER} iterations, "
          f"best of {REPEAT}")  # fmt: skip
    ref, ref_nfev = overhead_scipy()
    print(f"   scipy differential_evolution: {ref * 1e6:8.1f} us/iteration  (nfev {ref_nfev})")
    for m in METHODS:
        ours, nfev = overhead_ours(m)
        print(f"   {m:8s}                    : {ours * 1e6:8.1f} us/iteration  (nfev {nfev})"
              f"  ratio to scipy {ours / ref:5.2f}")  # fmt: skip
    print("\n2. campaign wall time with 1 and 2 worker processes")
    smoke = load_campaign_config(ROOT / "configs" / "bench-smoke.yaml")
    larger = smoke.model_copy(update={"max_nfev": 4000, "runs": 8})
    for label, cfg in (("smoke", smoke), ("smoke x10 budget, 8 runs", larger)):
        t1, t2 = campaign_times(cfg)
        print(f"   {label:26s}: 1 worker {t1:6.2f} s, 2 workers {t2:6.2f} s, "
              f"speed-up {t1 / t2:4.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
