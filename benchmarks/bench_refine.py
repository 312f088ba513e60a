"""Refinement on MuJoCo rollouts: the truth, the regressor's MJCF and the refined one.

For each robot (``configs/ur5.yaml``, ``configs/panda.yaml``), the run config's measurement is
made MuJoCo-native (``friction.semantics: mujoco``: Coulomb friction as ``frictionloss`` with
the constraint solver, damping, armature); MuJoCo simulates the closed-loop computed-torque
controller tracking a smooth 3-harmonic reference (period 10 s, one settling period and the
config's logged periods; :func:`bounded_reference`: each joint's motion scaled down where it
would come within :data:`RANGE_MARGIN` of a position limit or above :data:`LIMIT_FRACTION` of a
velocity or acceleration limit) and writes the controller's log; ``ident identify`` runs with
the run config's ``identification`` section and ``refinement: rollout``, writing the identified
MJCF; the rollout check scores it against the simulator's truth (same MJCF writer), and the
refinement adjusts its joints' frictionloss, damping and armature. Printed first: the load
average at the start (the machine is shared: CPU seconds, not wall time, are the cost); per
robot and seed: the held-out rollout objective ``J`` of the truth, of the regressor's MJCF, of
the refined one and of the written MJCF reloaded (the file carries what was scored), the
refined one's distance to the truth's [%], the held-out torque errors before and after, whether
the refinement was accepted, its training / held-out windows, iterations and CPU seconds (and
the estimate); a NOTE when the held-out motion leaves a joint's range (:func:`outside_range`);
the log's length, the regressor's distance to the truth over the held-out windows with the
standard error of that paired difference (:func:`paired_gap`: how well the windows measure a
5 % distance) and the row's process CPU.

    python benchmarks/bench_refine.py [--robots ur5 panda] [--seeds 0 1] [--amplitude 0.8]
    python benchmarks/bench_refine.py --seeds 0 1 2 3 4 --periods 12 --keep runs/refine
    python benchmarks/bench_refine.py --seeds 0 1 2 3 4 --simulate-only --keep runs/refine

(``--periods``: the logged 10 s periods, default the config's 3, so 30 s; 30 % held out.)

(``--simulate-only``: the logs alone, each one's largest excursion past its joints' ranges
and velocity limits printed, no identification; with ``--keep`` the bench reuses them.)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_mujoco_sim import fourier_reference  # noqa: E402

from ident.identify.assessment.rollout import (  # noqa: E402
    held_out_windows,
    reference_mjcf,
    rollout_check,
    rollout_score,
)
from ident.identify.config import load_identify_config  # noqa: E402
from ident.identify.model_files.files import save_identified_model  # noqa: E402
from ident.identify.pipeline.real import identify  # noqa: E402
from ident.identify.refinement.rollout_refinement import refinement_entry, refinement_text  # noqa: E402
from ident.measure.mujoco_config import load_mujoco_measurement  # noqa: E402
from ident.measure.mujoco_sim import simulate, write_log  # noqa: E402
from ident.model.selection import RobotSelection, load_robot  # noqa: E402

PERIOD_S = 10.0
#: Closest a reference comes to a joint's position limit [rad or m]: the computed-torque
#: controller tracks it within milliradians, and the open-loop rollouts, which drift from the
#: measured motion, should not meet MuJoCo's limit constraint either.
RANGE_MARGIN = 0.1
#: Largest fraction of a joint's velocity and acceleration limits a reference reaches.
LIMIT_FRACTION = 0.8


def native_measurement(run: dict, periods: int | None = None) -> dict:
    """The run config's measurement, MuJoCo-native (friction loss through the solver), with
    ``periods`` logged periods of :data:`PERIOD_S` (None: the config's ``n_periods``)."""
    m = {k: v for k, v in run["measurement"].items() if k != "source"}
    m["friction"] = {**m["friction"], "semantics": "mujoco"}
    if periods is not None:
        m["n_periods"] = periods
    return m


def identify_config(folder: Path, run_path: Path, run: dict, refinement: dict) -> Path:
    """The identify config of the log in ``folder``: the run config's robot (absolute paths)
    and identification sections, ``refinement: rollout``."""
    robot = dict(run["robot"])
    robot["urdf"] = str((run_path.parent / robot["urdf"]).resolve())
    robot["package_dirs"] = [str((run_path.parent / p).resolve()) for p in robot["package_dirs"]]
    cfg = {
        "name": run_path.stem,
        "robot": robot,
        "log": yaml.safe_load((folder / "log.yaml").read_text())["log"],
        **run["identification"],
        "urdf_update": {"model": "consistent"},
        "refinement": {"method": "rollout", **refinement},
    }
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def truth_model(measurement: dict):
    """The reference model of the rollout check: the robot's bodies with the truth's extras."""

    def build(robot):
        extras = {
            name: {
                "rotor_inertia": float(measurement["armature"][j]),
                "viscous": float(measurement["friction"]["viscous"][j]),
                "coulomb": float(measurement["friction"]["coulomb"][j]),
            }
            for j, name in enumerate(robot.joint_names)
        }
        return reference_mjcf(robot, extras), 0.0, 1.0

    return build


def bench(
    name: str, folder: Path, seed: int, amplitude: float, refinement: dict, periods: int | None
) -> dict:
    """Simulate, identify, check and refine one robot; the refinement entry and timings."""
    run_path = ROOT / "configs" / f"{name}.yaml"
    run = yaml.safe_load(run_path.read_text())
    measurement = native_measurement(run, periods)
    t0 = time.process_time()
    if not (folder / "log.yaml").exists():  # --keep: a log simulated before is reused
        write_log(folder, _simulate(run_path, run, measurement, seed, amplitude))
    path = identify_config(folder, run_path, run, refinement)
    t_sim = time.process_time() - t0
    cfg = load_identify_config(path)
    result = identify(cfg)
    model = save_identified_model(result, folder)
    offsets = [0.0] * len(result.joint_names)
    rollout = rollout_check(
        result, folder / model["files"]["mjcf"], "truth", truth_model(measurement), offsets=offsets
    )
    held = held_out_windows(result)
    paired = paired_error(result, folder / model["files"]["mjcf"], measurement, held)
    entry = refinement_entry(result, folder, model, rollout)
    # the written MJCF reloaded, on the same (offset-free) held-out windows
    written = rollout_score(folder / model["files"]["mjcf"], *held).objective
    return {
        "entry": entry,
        "rollout": rollout,
        "t_sim": t_sim,
        "written_objective": written,
        "outside_range": outside_range(folder / model["files"]["mjcf"], held[0]),
        "paired": paired,
        "log_s": float(result.log.t[-1] - result.log.t[0]),
    }


def paired_error(result, mjcf: Path, measurement: dict, held) -> dict[str, float]:
    """The regressor's held-out ``J`` relative to the truth's, ``mean(J_reg) / mean(J_truth)
    - 1``, and the standard error of that ratio from the windows' paired differences
    ``J_reg,w - J_truth,w`` (their standard deviation over ``sqrt(W)``, over the truth's mean):
    how well the held-out windows measure a model's distance to the truth."""
    text, _, _ = truth_model(measurement)(load_robot(result.config.robot))
    truth = rollout_score(mujoco.MjModel.from_xml_string(text), *held).per_window
    gap, se = paired_gap(rollout_score(mjcf, *held).per_window, truth)
    return {"gap": gap, "se": se, "windows": truth.size}


def paired_gap(model: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """``mean(model) / mean(truth) - 1`` of two models' per-window ``J`` (W,) on the same
    windows, and its standard error from the paired differences: ``std(model - truth)`` (W - 1
    degrees of freedom) over ``sqrt(W) mean(truth)`` (the truth's mean taken as exact)."""
    d = model - truth
    se = float(np.std(d, ddof=1) / np.sqrt(d.size) / truth.mean())
    return float(model.mean() / truth.mean() - 1.0), se


def outside_range(mjcf: Path, measurements) -> dict[str, float]:
    """The joints whose held-out positions leave the MJCF's ``range`` and by how much [rad or
    m]: there MuJoCo's limit constraint acts in every rollout (the truth's too), while the
    simulator that wrote the log did not stop the joint, so those windows' ``J`` is large."""
    model = mujoco.MjModel.from_xml_path(str(mjcf))
    out = {}
    for j, name in enumerate(measurements.joint_names):
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if not model.jnt_limited[i]:
            continue
        low, high = model.jnt_range[i]
        q = measurements.q[:, j]
        excess = max(float(low - q.min()), float(q.max() - high))
        if excess > 0.0:
            out[name] = excess
    return out


def bounded_reference(robot, *, period: float, seed: int, amplitude: float, rate_hz: float):
    """:func:`fourier_reference` with each joint's motion about its middle scaled down (the same
    factor on its ``q - middle``, ``dq`` and ``ddq``, so still one smooth periodic motion) until
    it stays :data:`RANGE_MARGIN` inside the joint's range and within :data:`LIMIT_FRACTION` of
    its velocity and acceleration limits (unknown limits: inf, no bound).

    Returns ``t`` (n,) [s] and ``q, dq, ddq`` (n, nv) [rad, rad/s, rad/s^2 or m, m/s, m/s^2]; a
    joint already inside every bound is the unscaled reference's exactly.
    """
    t, q, dq, ddq = fourier_reference(
        robot, period=period, seed=seed, amplitude=amplitude, rate_hz=rate_hz
    )
    # fourier_reference's middle of the range (clipped to +-3 for unlimited joints); the room
    # on each side of it, which differs where the clip moved it
    middle = 0.5 * (np.clip(robot.q_lower, -3.0, 3.0) + np.clip(robot.q_upper, -3.0, 3.0))
    room_up = np.maximum(robot.q_upper - RANGE_MARGIN - middle, 0.0)
    room_down = np.maximum(middle - robot.q_lower - RANGE_MARGIN, 0.0)
    tiny = 1e-300
    scale = np.minimum.reduce(
        [
            np.ones_like(middle),
            room_up / np.maximum((q - middle).max(axis=0), tiny),
            room_down / np.maximum((middle - q).max(axis=0), tiny),
            LIMIT_FRACTION * robot.dq_max / np.maximum(np.abs(dq).max(axis=0), tiny),
            LIMIT_FRACTION * robot.ddq_max / np.maximum(np.abs(ddq).max(axis=0), tiny),
        ]
    )
    return t, middle + scale * (q - middle), scale * dq, scale * ddq


def limit_excess(robot, q, dq) -> dict[str, tuple[float, float]]:
    """Per joint, how far positions ``q`` (n, nv) pass its range and how far ``|dq|`` passes
    its velocity limit [rad, rad/s or m, m/s]; negative: the margin left (inf: no limit)."""
    over_q = np.maximum(robot.q_lower - q.min(axis=0), q.max(axis=0) - robot.q_upper)
    over_dq = np.abs(dq).max(axis=0) - robot.dq_max
    return {name: (float(over_q[j]), float(over_dq[j])) for j, name in enumerate(robot.joint_names)}


def _robot(run_path: Path, run: dict):
    """The run config's robot."""
    return load_robot(RobotSelection.model_validate(run["robot"]).resolved(run_path.parent))


def _simulate(run_path: Path, run: dict, measurement: dict, seed: int, amplitude: float):
    """The simulated log of the run config's robot on a smooth reference within its limits."""
    robot = _robot(run_path, run)
    reference = bounded_reference(
        robot, period=PERIOD_S, seed=seed, amplitude=amplitude, rate_hz=measurement["rate_hz"]
    )
    return simulate(robot, *reference, load_mujoco_measurement(measurement), rng=seed)


def simulate_only(name: str, folder: Path, seed: int, amplitude: float, periods: int | None) -> str:
    """Simulate (or reuse) one robot's log into ``folder``; the line of its limits' margins."""
    run_path = ROOT / "configs" / f"{name}.yaml"
    run = yaml.safe_load(run_path.read_text())
    log = _simulate(run_path, run, native_measurement(run, periods), seed, amplitude)
    write_log(folder, log)
    excess = limit_excess(_robot(run_path, run), log.q_true, log.dq_true)
    q_worst = max(excess, key=lambda k: excess[k][0])
    dq_worst = max(excess, key=lambda k: excess[k][1])
    return (
        f"{name} seed {seed}: closest to a position limit {q_worst} "
        f"{excess[q_worst][0]:+.3g} (inside: < 0), to a velocity limit {dq_worst} "
        f"{excess[dq_worst][1]:+.3g}"
    )


def _print_row(name: str, seed: int, got: dict) -> None:
    """One robot's table row, its refinement line and any range NOTE."""
    e = got["entry"]
    if e.get("accepted") is None:
        print(f"| {name} | {seed} | {e['note']} |", flush=True)
        return
    ref, after = e["reference_objective"], e["objective_after"]
    print(
        f"| {name} | {seed} | {ref:.4g} | {e['objective_before']:.4g} | {after:.4g} "
        f"| {got['written_objective']:.4g} | {100 * (after / ref - 1):+.1f} % "
        f"| {e['torque_error_before']:.4g} | {e['torque_error_after']:.4g} | {e['accepted']} "
        f"| {e['train_windows']} / {e['held_out_windows']} "
        f"| {e['iterations']} ({e['best_iteration']}) "
        f"| {e['cpu_s']:.1f} ({e['cpu_estimate_s']:.1f}) |",
        flush=True,
    )
    print(f"  {refinement_text(e)}", flush=True)
    p = got["paired"]
    print(
        f"  log {got['log_s']:.0f} s; regressor vs truth on the {p['windows']} held-out "
        f"windows {100 * p['gap']:+.1f} % (paired standard error {100 * p['se']:.1f} %); "
        f"process CPU {got['t_total']:.1f} s",
        flush=True,
    )
    if got["outside_range"]:
        where = ", ".join(f"{k} by {v:.3g}" for k, v in got["outside_range"].items())
        print(f"  NOTE: the held-out motion leaves the joint range of {where}", flush=True)


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["ur5", "panda"])
    parser.add_argument("--seeds", "--seed", nargs="+", type=int, default=[0])
    parser.add_argument("--amplitude", type=float, default=0.8, help="rad/s, Fourier bound")
    parser.add_argument("--json", type=Path, default=None, help="write the entries here")
    parser.add_argument(
        "--keep", type=Path, default=None, help="folder of the logs, reused when there"
    )
    parser.add_argument("--simulate-only", action="store_true", help="the logs, no refinement")
    for key in ("max_windows", "max_iterations"):
        parser.add_argument(f"--{key.replace('_', '-')}", type=int, default=None)
    parser.add_argument("--prior-weight", type=float, default=None)
    parser.add_argument(
        "--periods", type=int, default=None, help="logged 10 s periods (default: the config's 3)"
    )
    return parser.parse_args()


def main() -> None:
    args = _arguments()
    refinement = {
        key: getattr(args, key)
        for key in ("max_windows", "max_iterations", "prior_weight")
        if getattr(args, key) is not None
    }
    print(f"load average at start: {' / '.join(f'{x:.1f}' for x in os.getloadavg())}")
    if not args.simulate_only:
        print(
            "| robot | seed | J truth | J regressor | J refined | J written MJCF "
            "| refined vs truth | torque err before | torque err after | accepted "
            "| windows train / held | iterations (best) | CPU s (estimate) |"
        )
        print("| --- " + "| ---: " * 8 + "| --- " + "| ---: " * 3 + "|")
    out = {}
    for seed in args.seeds:
        for name in args.robots:
            with tempfile.TemporaryDirectory() as tmp:
                folder = Path(tmp)
                if args.keep is not None:  # <keep>/<robot>-seed<seed>[-<periods>p]
                    tail = "" if args.periods is None else f"-{args.periods}p"
                    folder = args.keep / f"{name}-seed{seed}{tail}"
                    folder.mkdir(parents=True, exist_ok=True)
                if args.simulate_only:
                    print(
                        simulate_only(name, folder, seed, args.amplitude, args.periods),
                        flush=True,
                    )
                    continue
                t0 = time.process_time()
                got = bench(name, folder, seed, args.amplitude, refinement, args.periods)
                got["t_total"] = time.process_time() - t0
            out[f"{name}-seed{seed}"] = got
            _print_row(name, seed, got)
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=2, default=float))


if __name__ == "__main__":
    main()
