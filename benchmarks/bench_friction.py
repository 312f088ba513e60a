"""Recovery of friction models, torque delay and torque gains from MuJoCo logs (UR5, Panda).

For each friction model of the registry the MuJoCo source simulates the robot with that law
(plus a rotor inertia of 0.1 kg*m^2) tracking a 4 s Fourier excitation at 1 kHz, with encoder
quantization (2^19 counts per revolution) and 1 % Gaussian torque noise. The log is processed as
``ident identify`` does it (zero-phase 30 Hz low-pass of positions and torques, central
differences, velocity threshold 0.05 rad/s) and every parameter fitted by separable least squares
(:mod:`ident.identify.friction.friction_fit`); the table gives the largest relative error over
joints of each parameter, and whether the fit found a second minimum it cannot tell apart
(``FrictionFit.ambiguous``: ``friction: auto`` does not pick such a model). Then a 5 ms torque delay
(recovered by :func:`estimate_delay`) and torque gains of 0.97 / 1.03 on joints 3 and 4 (recovered
by :func:`estimate_gains` against the shoulder's known gain, on the rows above the velocity
threshold).

    python benchmarks/bench_friction.py    # 1.5-3 min; 4.5 min on 2 cores at load 11
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.friction_models import get_friction_model
from ident.dynamics.parameter_model import build_parameter_model, model_regressors
from ident.identify.corrections.signal_errors import estimate_delay, estimate_gains
from ident.identify.estimation import preprocess
from ident.identify.friction.friction_fit import FrictionRows, fit_friction_model
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate
from ident.model import Robot

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from robots import PANDA_URDF, UR5_URDF  # noqa: E402
from test_mujoco_sim import PANDA_LOCKS, fourier_reference  # noqa: E402

LAWS = {
    "viscous_coulomb": {"fv": 0.5, "fc": 1.5},
    "viscous_coulomb_offset": {"fv": 0.5, "fc": 1.5, "off": 0.4},
    "stribeck": {"fv": 0.5, "fc": 1.0, "fst": 0.8, "vs": 0.2},
    "sigmoid": {"phi1": 2.0, "phi2": 20.0, "phi3": 0.02},
    "load_dependent": {"fv": 0.5, "fc": 0.8, "fl": 0.05},
}
CUTOFF_HZ = 30.0
EDGE = 200  # samples dropped at each end (filter transients)
#: Velocity threshold [rad/s]: near a reversal the filtered velocity's sign is wrong for a few
#: samples (without it the UR5's viscous friction was off by up to 64 %, with it by 3-10 %).
THRESHOLD = 0.05


def robots() -> dict[str, Robot]:
    return {
        "UR5": Robot.from_urdf(UR5_URDF),
        "Panda": Robot.from_urdf(PANDA_URDF, lock_joints=PANDA_LOCKS),
    }


def processed(log, noise_rel: float, seed: int = 1):
    """Positions, velocities, accelerations and torques as identify processes them."""
    rng = np.random.default_rng(seed)
    tau = log.tau_measured + noise_rel * np.sqrt(np.mean(log.tau_cmd**2, 0)) * rng.standard_normal(
        log.tau_cmd.shape
    )
    fs = log.rate_hz
    q, _ = preprocess.lowpass(log.q, fs, CUTOFF_HZ)
    tau, _ = preprocess.lowpass(tau, fs, CUTOFF_HZ, what="tau")
    dq, ddq, _ = preprocess.differentiate(q, fs)
    inner = slice(EDGE, -EDGE)
    return q[inner], dq[inner], ddq[inner], tau[inner], log.t[inner]


def regressor(robot, terms, q, dq, ddq):
    pm = build_parameter_model(robot.model, terms)
    Yr, Ye = model_regressors(chain_from_model(robot.model), terms, q, dq, ddq)
    return pm.columns(Yr, Ye, np.arange(len(pm.names)))[:, :, list(pm.base.independent)]


def simulated(robot, t, q, dq, ddq, extra):
    config = {"armature": 0.1, "n_periods": 1, "encoder_counts_per_rev": 2**19, **extra}
    return simulate(robot, t, q, dq, ddq, load_mujoco_measurement(config), rng=0)


def friction_table(name: str, robot: Robot, reference) -> list[str]:
    rows = []
    terms = ExtraTerms.from_options(robot.nv, viscous=False, coulomb=False, offset=False)
    for model_name, values in LAWS.items():
        t0 = time.perf_counter()
        log = simulated(
            robot, *reference, {"friction": {"law": {"model": model_name, "values": values}}}
        )
        q, dq, ddq, tau, _ = processed(log, 0.01)
        W = regressor(robot, terms, q, dq, ddq)
        data = FrictionRows(W, dq, tau, np.abs(dq) > THRESHOLD, tuple(range(robot.nv)))
        fit = fit_friction_model(model_name, data)
        model = get_friction_model(model_name)
        found = dict(zip(model.linear, fit.linear.T, strict=True))
        found |= dict(zip(model.nonlinear, fit.nonlinear.T, strict=True))
        errors = []
        for label, true in values.items():
            err = np.max(np.abs(found[label] - true)) / abs(true)
            errors.append(f"{label} {100 * err:.1f} %")
        rows.append(
            f"| {name} | {model_name} | {', '.join(errors)} | {100 * fit.fit_residual:.2f} % | "
            f"{'yes' if fit.ambiguous else 'no'} | {time.perf_counter() - t0:.1f} s |"
        )
    return rows


def signal_rows(name: str, robot: Robot, reference) -> list[str]:
    terms = ExtraTerms.from_options(robot.nv)
    gains = np.ones(robot.nv)
    gains[2], gains[3] = 1.03, 0.97
    friction = {"viscous": 0.5, "coulomb": 1.0}
    log = simulated(robot, *reference, {"friction": friction, "signals": {"delay_s": 0.005}})
    q, dq, ddq, tau, t = processed(log, 0.01)
    Y = regressor(robot, terms, q, dq, ddq)
    # all rows: with the velocity threshold the delay came out 1.6-2.3 ms instead of 4.6-4.9
    delay = estimate_delay(t, tau, Y, max_delay_s=0.02)
    signals = {"torque_gain": gains.tolist(), "torque_offset": 0.3}
    log = simulated(robot, *reference, {"friction": friction, "signals": signals})
    q, dq, ddq, tau, _ = processed(log, 0.01)
    Y = regressor(robot, terms, q, dq, ddq)
    keep = np.abs(dq) > THRESHOLD
    elbow = estimate_gains(Y, tau, reference_joint=1, joints=[2], keep=keep)
    every = estimate_gains(Y, tau, reference_joint=1, keep=keep)
    err = 100 * (every.gains / gains - 1)
    return [
        f"| {name} | delay 5 ms | {1000 * delay.delay_s:.2f} ms | "
        f"{1000 * (delay.delay_s - 0.005):+.2f} ms |",
        f"| {name} | elbow gain 1.03 (shoulder known, rows 2-3) | {elbow.gains[2]:.4f} | "
        f"{100 * (elbow.gains[2] / 1.03 - 1):+.2f} % |",
        f"| {name} | every gain (shoulder known) | "
        + ", ".join(f"{g:.3f}" for g in every.gains)
        + " | "
        + ", ".join(f"{e:+.1f}" for e in err)
        + " % |",
    ]


def main() -> None:
    friction = [
        "| robot | model | largest error over joints | fit residual | ambiguous | time |",
        "| --- |" * 1 + " --- | --- | --- | --- | --- |",
    ]
    signal = ["| robot | injected | found | error |", "| --- | --- | --- | --- |"]
    for name, robot in robots().items():
        reference = fourier_reference(robot, period=4.0, seed=2)
        friction += friction_table(name, robot, reference)
        signal += signal_rows(name, robot, reference)
    print("\n".join(friction))
    print()
    print("\n".join(signal))


if __name__ == "__main__":
    main()
