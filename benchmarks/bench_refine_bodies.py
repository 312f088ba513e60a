"""Refining the bodies on rollouts too: a measurement on bench_refine's logs (not built in).

For each ``<keep>/<robot>-seed<seed>[-<periods>p]`` folder that ``bench_refine.py --keep``
left (its log, identify config and written MJCF, which carries the joint refinement when it was
accepted), the identification is run again and the MJCF's bodies are moved along the ``k``
worst-determined combinations of the base parameters: the leading eigenvectors ``v_i`` of the
correlation matrix ``R`` of the written covariance (``<stem>_identified_covariance.json``,
``beta = P theta``), one standard deviation each, ``d_beta_i = D v_i sqrt(mu_i)`` (``D`` the
standard deviations, ``mu_i`` the eigenvalue), taken to the standard parameters by the
minimum-norm ``d_theta_i = pinv(P) d_beta_i``. A move ``c`` (k,) gives
``theta = theta_c + sum_i c_i d_theta_i`` from the consistent estimate ``theta_c``; every body
is then projected onto physical consistency (its pseudo-inertia's negative eigenvalues set to
0), so a body on the consistency boundary stays consistent, and the MJCF body's inertial (the
link's and any fused fixed child's) changes by the projected body's change; the joint extras
change by theirs (``armature``, ``damping``, ``frictionloss``, never below 0).
``scipy.optimize.least_squares`` minimises ``J_train(c) / J_train(0) + w ||c||^2``: in these
units ``||c||^2`` is the move's ``d_beta^T C^-1 d_beta``, the torque fit's own chi-square, so
the prior keeps the torque information (``w``: ``--prior-weight``, 0.01: a one-sigma move costs
1 % of the start). The held-out ``J`` picks the iterate (stop after 2 iterations without a
better one, at most 8) and the refinement's acceptance rule is applied: the held-out ``J``
improves and the held-out torque error is no worse.

    python benchmarks/bench_refine_bodies.py --keep runs/refine --seeds 0 1 2 3 4 --periods 12
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import yaml
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT.parent / "tests"))

import bench_refine  # noqa: E402

from ident.identify.assessment.rollout import (  # noqa: E402
    held_out_windows,
    identification_windows,
    rollout_residuals,
    rollout_score,
)
from ident.identify.config import load_identify_config  # noqa: E402
from ident.identify.estimation.consistency import (  # noqa: E402
    parameters_from_pseudo_inertia,
    pseudo_inertia,
)
from ident.identify.pipeline.real import identify  # noqa: E402
from ident.identify.refinement.rollout_refinement import torque_error  # noqa: E402
from ident.model.selection import load_robot  # noqa: E402
from ident.robot.inertia import (  # noqa: E402
    PINOCCHIO_ORDER,
    com_and_inertia,
    parameters_from_com,
)

EXTRAS = {"Ia": "dof_armature", "fv": "dof_damping", "fs": "dof_frictionloss"}
MAX_ITERATIONS, PATIENCE = 8, 2


def directions(cov: dict, k: int) -> np.ndarray:
    """``d_theta`` (n_theta, k) of the module docstring, one standard deviation each."""
    P, C = np.array(cov["projection"]), np.array(cov["covariance"])
    sd = np.sqrt(np.diag(C))
    mu, V = np.linalg.eigh(C / np.outer(sd, sd))
    top = np.argsort(-mu)[:k]
    return np.linalg.pinv(P) @ ((sd[:, None] * V[:, top]) * np.sqrt(mu[top]))


def consistent(theta_b: np.ndarray) -> np.ndarray:
    """A body's parameters (Pinocchio order) with its pseudo-inertia made positive semi-definite."""
    lam, U = np.linalg.eigh(pseudo_inertia(theta_b))
    return parameters_from_pseudo_inertia((U * np.maximum(lam, 0.0)) @ U.T)


def mj_inertial(m: mujoco.MjModel, b: int) -> np.ndarray:
    """The MuJoCo body's inertial as standard parameters about its frame (Pinocchio order)."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, m.body_iquat[b])
    R = R.reshape(3, 3)
    I_com = R @ np.diag(m.body_inertia[b]) @ R.T
    return parameters_from_com(m.body_mass[b], m.body_ipos[b], I_com)


def set_mj_inertial(m: mujoco.MjModel, b: int, tp: np.ndarray) -> None:
    """Set the MuJoCo body's inertial from standard parameters about its frame."""
    mass, c, I_com = com_and_inertia(tp)
    lam, U = np.linalg.eigh(I_com)
    if np.linalg.det(U) < 0:
        U[:, 0] *= -1
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, U.ravel())
    m.body_mass[b], m.body_ipos[b], m.body_inertia[b], m.body_iquat[b] = mass, c, lam, q


class Bodies:
    """The MJCF with the bodies and extras moved by ``c`` (module docstring)."""

    def __init__(self, mj: mujoco.MjModel, names, theta_c, pnames, d_theta) -> None:
        self.mj, self.names, self.theta_c, self.pnames, self.d = mj, names, theta_c, pnames, d_theta
        self.joints = [mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]

    def body(self, theta: np.ndarray, j: int) -> np.ndarray:
        """Joint ``j``'s body (0-based) in ``theta``, Pinocchio's order."""
        return np.array([theta[self.pnames.index(f"{n}{j + 1}")] for n in PINOCCHIO_ORDER])

    def model(self, c: np.ndarray) -> mujoco.MjModel:
        """A copy of the MJCF's model moved by ``c`` (k,) [standard deviations]."""
        theta, m = self.theta_c + self.d @ c, copy.copy(self.mj)
        for j, jid in enumerate(self.joints):
            b, dof = m.jnt_bodyid[jid], m.jnt_dofadr[jid]
            change = consistent(self.body(theta, j)) - self.body(self.theta_c, j)
            set_mj_inertial(m, b, mj_inertial(self.mj, b) + change)
            for kind, field in EXTRAS.items():
                if f"{kind}{j + 1}" in self.pnames:
                    i = self.pnames.index(f"{kind}{j + 1}")
                    value = getattr(self.mj, field)[dof] + theta[i] - self.theta_c[i]
                    getattr(m, field)[dof] = max(value, 0.0)
        mujoco.mj_setConst(m, mujoco.MjData(m))
        return m


def refine_bodies(folder: Path, stem: str, k: int, w: float) -> dict:
    """One folder's body refinement: held-out J and torque error before and at the kept
    iterate, the truth's J, iterations, acceptance, CPU seconds."""
    t0 = time.process_time()
    result = identify(load_identify_config(folder / "identify.yaml"))
    held, train = held_out_windows(result), identification_windows(result)
    mj = mujoco.MjModel.from_xml_path(str(folder / f"{stem}_identified.xml"))
    cov = json.loads((folder / f"{stem}_identified_covariance.json").read_text())
    assert list(result.model.structure.names) == cov["parameter_names"]
    theta_c = np.asarray(result.model.constrained.theta, dtype=float)
    p = Bodies(mj, held[0].joint_names, theta_c, cov["parameter_names"], directions(cov, k))
    r0 = rollout_residuals(p.model(np.zeros(k)), *train)
    j0 = float(r0 @ r0)
    course = {"held": [rollout_score(mj, *held).objective], "best": 0, "c": np.zeros(k)}

    def residuals(c: np.ndarray) -> np.ndarray:
        r = rollout_residuals(p.model(c), *train) / math.sqrt(j0)
        return np.concatenate([r, math.sqrt(w) * c])

    def callback(intermediate_result) -> None:  # the name scipy's introspection wants
        c = np.asarray(intermediate_result.x, dtype=float)
        course["held"].append(rollout_score(p.model(c), *held).objective)
        if course["held"][-1] < course["held"][course["best"]]:
            course["best"], course["c"] = len(course["held"]) - 1, c.copy()
        done = len(course["held"]) - 1
        if done >= MAX_ITERATIONS or done - course["best"] >= PATIENCE:
            raise StopIteration

    least_squares(residuals, np.zeros(k), method="trf", diff_step=1e-2, callback=callback)
    return _row(result, stem, mj, p.model(course["c"]), held, course, time.process_time() - t0)


def _row(result, stem, mj, best, held, course, cpu) -> dict:
    """The figures of one refinement (:func:`refine_bodies`)."""
    run = yaml.safe_load((ROOT.parent / "configs" / f"{stem}.yaml").read_text())
    truth_text, _, _ = bench_refine.truth_model(bench_refine.native_measurement(run))(
        load_robot(result.config.robot)
    )
    truth = rollout_score(mujoco.MjModel.from_xml_string(truth_text), *held).objective
    before, after = torque_error(mj, *held), torque_error(best, *held)
    return {
        "truth": truth,
        "before": course["held"][0],
        "best": course["held"][course["best"]],
        "torque_before": before,
        "torque_after": after,
        "iterations": len(course["held"]) - 1,
        "best_iteration": course["best"],
        "accepted": course["best"] > 0 and after <= before,
        "c": course["c"].tolist(),
        "cpu_s": cpu,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, required=True, help="bench_refine's --keep")
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--periods", type=int, default=None)
    parser.add_argument("--directions", type=int, default=6)
    parser.add_argument("--prior-weight", type=float, default=0.01)
    args = parser.parse_args()
    tail = "" if args.periods is None else f"-{args.periods}p"
    print("| robot | seed | J truth | J before | J bodies | bodies vs truth | torque error before "
          "| after | accepted | iterations (best) | CPU s |")  # fmt: skip
    for seed in args.seeds:
        for name in args.robots:
            folder = args.keep / f"{name}-seed{seed}{tail}"
            r = refine_bodies(folder, name, args.directions, args.prior_weight)
            print(
                f"| {name} | {seed} | {r['truth']:.4g} | {r['before']:.4g} | {r['best']:.4g} "
                f"| {100 * (r['best'] / r['truth'] - 1):+.1f} % | {r['torque_before']:.5g} "
                f"| {r['torque_after']:.5g} | {r['accepted']} "
                f"| {r['iterations']} ({r['best_iteration']}) | {r['cpu_s']:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
