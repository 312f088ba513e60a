"""Physically consistent identification: TX40 log and a simulated UR5 with known truth.

Part ``tx40`` runs ``ident identify`` with ``configs/tx40-consistent.yaml`` (LMI, prior weight
chosen on held-out rows) on the full log and prints, against WLS on the same rows: the time
the constrained estimate adds (target < 5 s on 2 cores), the relative residual on the
identification rows and on the held-out part (targets: within 2 %), friction and rotor
inertia (target: friction within 2 % where WLS's is positive), per-link consistency; then the
same with the whole log identifying, and with ``estimation.friction: free``; each with the
log-Cholesky estimator on the same problem as a cross-check.

Part ``simulated`` identifies a UR5 (example-robot-data) from ideal Pinocchio torques plus
friction and noise, on a poorly and a well exciting trajectory, and compares OLS, WLS, LMI
without prior, with the prior floor only, with the prior weight chosen on held-out rows, the
same with friction estimated jointly (``estimation.friction: free``) and log-Cholesky: errors
of the standard and base parameters and torque prediction on another trajectory.

    python benchmarks/bench_consistent.py [--part tx40|simulated|all] [--seeds 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.dynamics.friction import ExtraTerms
from ident.identify.config import load_identify_config
from ident.identify.estimators import choose_regularization, get_estimator
from ident.identify.estimators.identification import problem_from_states, standard_regressor
from ident.identify.pipeline.real import build_parameter_model, identify

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = 5.0


# ---- TX40 -----------------------------------------------------------------------------------
def _tx40(fraction: float | None, friction: str = "least_squares") -> None:
    cfg = load_identify_config(ROOT / "configs" / "tx40-consistent.yaml")
    if fraction is not None:
        cfg = cfg.model_copy(
            update={"validation": cfg.validation.model_copy(update={"identify_fraction": fraction})}
        )
    cfg = cfg.model_copy(
        update={"estimation": cfg.estimation.model_copy(update={"friction": friction})}
    )
    t0 = time.perf_counter()
    result = identify(cfg)
    total = time.perf_counter() - t0
    c = result.consistent
    wls, lmi = c.estimates["wls"], c.constrained
    print(
        f"\n## TX40, identify_fraction = {cfg.validation.identify_fraction}, "
        f"estimation.friction = {friction}"
    )
    print(
        f"identify total {total:.2f} s; constrained estimate adds {c.seconds:.2f} s "
        f"(weight choice included) = {c.seconds / BUDGET_S:.2f} of the {BUDGET_S:g} s budget; "
        f"prior weight {lmi.regularization:g}"
    )
    ratio = lmi.relative_residual / wls.relative_residual
    print(
        f"relative residual, identification rows: WLS {wls.relative_residual:.5f}, "
        f"LMI {lmi.relative_residual:.5f} (ratio {ratio:.4f}, target <= 1.02)"
    )
    if cfg.validation.identify_fraction < 1.0:
        w = result.predictions["identified"].metrics.total_relative_residual
        m = result.predictions["lmi"].metrics.total_relative_residual
        print(
            f"relative residual, held-out rows: WLS {w:.5f}, LMI {m:.5f} "
            f"(ratio {m / w:.4f}, target <= 1.02)"
        )
    print("link consistency (min pseudo-inertia eigenvalue):")
    for name, est in c.estimates.items():
        cells = ", ".join(
            f"{b.body} {'yes' if b.consistent else 'NO'} ({b.min_eigenvalue:.2g})"
            for b in est.consistency
        )
        print(f"  {name:>4}: {cells}")
    print("friction and rotor inertia: WLS (rel. std %) -> LMI, change %")
    names = result.parameters.base_names
    for k, name in enumerate(names):
        if re.fullmatch(r"(fv|fs|Ia)m?\d+", name):
            change = 100 * (lmi.x[k] - wls.x[k]) / abs(wls.x[k])
            flag = "" if abs(change) <= 2 or wls.x[k] <= 0 else "  > 2 %"
            print(
                f"  {name:>6}: {wls.x[k]: .5g} ({wls.relative_std[k]:5.1f}) -> "
                f"{lmi.x[k]: .5g}  {change:+6.2f}{flag}"
            )
    t1 = time.perf_counter()
    lc = get_estimator("log_cholesky")(
        dataclasses.replace(c.problem, regularization=lmi.regularization)
    )
    t_lc = time.perf_counter() - t1
    scale = np.abs(lmi.x).max()
    print(
        f"log-Cholesky cross-check: {t_lc:.2f} s, {lc.message}; relative residual "
        f"{lc.relative_residual:.5f}; max |x_lc - x_lmi| / max|x_lmi| = "
        f"{np.abs(lc.x - lmi.x).max() / scale:.2e}; consistent: {lc.consistent}"
    )


# ---- simulated UR5 ------------------------------------------------------------------------
def _multisine(rng, n_joints, amplitude, n_harmonics, base_hz, duration_s, rate_hz):
    """q, dq, ddq of ``q_j = sum_k a_jk sin(2 pi k f t + phi_jk)`` (analytic derivatives)."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    k = np.arange(1, n_harmonics + 1)
    w = 2 * np.pi * base_hz * k
    a = amplitude * rng.uniform(0.5, 1.0, size=(n_joints, n_harmonics)) / k
    phi = rng.uniform(0, 2 * np.pi, size=(n_joints, n_harmonics))
    arg = w[None, None, :] * t[:, None, None] + phi[None]
    q = np.sum(a * np.sin(arg), axis=2)
    dq = np.sum(a * w * np.cos(arg), axis=2)
    ddq = -np.sum(a * w**2 * np.sin(arg), axis=2)
    return q, dq, ddq


def _truth(pm, rng):
    """URDF bodies changed by up to 20 % (still consistent) plus friction: the 'real' robot."""
    theta = pm.nominal.copy()
    index = {n: i for i, n in enumerate(pm.names)}
    for j in range(1, 7):
        body = np.array([theta[index[f"{lab}{j}"]] for lab in _LABELS])
        inertia = pin.Inertia.FromDynamicParameters(body)
        scaled = pin.Inertia(
            inertia.mass * rng.uniform(0.8, 1.2),
            inertia.lever + rng.uniform(-0.02, 0.02, 3),
            inertia.inertia * rng.uniform(0.8, 1.2),
        )
        for k, lab in enumerate(_LABELS):
            theta[index[f"{lab}{j}"]] = scaled.toDynamicParameters()[k]
    for i, name in enumerate(pm.names):
        if name.startswith("fv"):
            theta[i] = rng.uniform(0.5, 3.0)
        elif name.startswith("fs"):
            theta[i] = rng.uniform(0.5, 4.0)
    return theta


_LABELS = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def _ur5_urdf() -> Path:
    """The UR5 URDF of example-robot-data (a data-only package under the cmeel prefix)."""
    import importlib.metadata

    share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    return Path(str(share)) / "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"


def _simulated(seeds: int) -> None:
    model = pin.buildModelFromUrdf(str(_ur5_urdf()))
    terms = ExtraTerms.from_options(
        6, rotor_inertia=False, viscous=True, coulomb=True, offset=False
    )
    pm = build_parameter_model(model, terms)
    cases = {
        "poor": dict(amplitude=0.15, n_harmonics=2, base_hz=0.1),
        "good": dict(amplitude=1.2, n_harmonics=5, base_hz=0.1),
    }
    methods = (
        "ols",
        "wls",
        "lmi, no prior",
        "lmi, floor only",
        "lmi",
        "lmi, friction free",
        "log_cholesky",
    )
    free = {"friction": "free"}
    table = {(case, m): [] for case in cases for m in methods}
    chosen: list[float] = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        theta = _truth(pm, rng)
        test = _multisine(rng, 6, 1.0, 5, 0.13, 10.0, 50.0)
        Y_test = standard_regressor(model, pm, *test)
        tau_test = Y_test @ theta
        Wb_test = Y_test[:, :, pm.base.independent].reshape(-1, len(pm.base_names))
        col = np.linalg.norm(Wb_test, axis=0)
        beta = pm.base.project(theta)
        scales = None
        for case, opts in cases.items():
            q, dq, ddq = _multisine(rng, 6, duration_s=20.0, rate_hz=50.0, **opts)
            tau = standard_regressor(model, pm, q, dq, ddq) @ theta
            # heteroscedastic noise: 3 % of each joint's RMS torque, at least 0.05 N*m
            sigma = np.maximum(0.03 * np.sqrt(np.mean(tau**2, axis=0)), 0.05)
            tau = tau + rng.normal(size=tau.shape) * sigma
            split = int(0.8 * len(q))
            full = problem_from_states(model, pm, q, dq, ddq, tau)
            first = problem_from_states(model, pm, q[:split], dq[:split], ddq[:split], tau[:split])
            last = problem_from_states(model, pm, q[split:], dq[split:], ddq[split:], tau[split:])
            scales = full.structure.scales()
            inertial = full.structure.bodies.reshape(-1)
            weight = choose_regularization(first, last.observations).weight
            weight_free = choose_regularization(
                dataclasses.replace(first, options=free), last.observations
            ).weight
            for m in methods:
                if m == "lmi, no prior":
                    est = get_estimator("lmi")(
                        dataclasses.replace(full, options={"prior_floor": 0.0})
                    )
                elif m == "lmi, friction free":
                    est = get_estimator("lmi")(
                        dataclasses.replace(full, regularization=weight_free, options=free)
                    )
                    chosen.append(weight_free)
                elif m == "lmi, floor only":
                    est = get_estimator("lmi")(full)
                elif m in ("lmi", "log_cholesky"):  # weight chosen on held-out rows
                    est = get_estimator(m)(dataclasses.replace(full, regularization=weight))
                    chosen.append(weight)
                else:
                    est = get_estimator(m)(full)
                err_std = np.sqrt(
                    np.mean(((est.theta[inertial] - theta[inertial]) / scales[inertial]) ** 2)
                )
                err_base = np.linalg.norm(col * (est.x - beta)) / np.linalg.norm(col * beta)
                pred = (Wb_test @ est.x).reshape(tau_test.shape)
                err_pred = np.linalg.norm(pred - tau_test) / np.linalg.norm(tau_test)
                n_bad = sum(not b.consistent for b in est.consistency)
                table[(case, m)].append((err_std, err_base, err_pred, n_bad, est.relative_residual))
    print(f"\n## Simulated UR5, {seeds} seeds (mean; inconsistent links: total over seeds)")
    print(f"prior weights chosen on held-out rows: {sorted(set(chosen))}")
    print(
        "| trajectory | estimator | standard params, scaled RMS error | base params, rel. "
        "error | held-out torque, rel. error | inconsistent links | fit residual |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for (case, m), rows in table.items():
        a = np.array(rows)
        print(
            f"| {case} | {m} | {a[:, 0].mean():.4f} | {a[:, 1].mean():.4f} | "
            f"{a[:, 2].mean():.4f} | {int(a[:, 3].sum())} | {a[:, 4].mean():.4f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("tx40", "simulated", "all"), default="all")
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    if args.part in ("tx40", "all"):
        _tx40(None)
        _tx40(1.0)
        _tx40(None, friction="free")
    if args.part in ("simulated", "all"):
        _simulated(args.seeds)


if __name__ == "__main__":
    main()
