"""Position servos that log no torque: gains, ``kd + fv``, armature and friction over seeds.

For each seed (the Fourier coefficients of the reference), MuJoCo simulates the robot driven by
``<position>`` servos (``kp``, ``kv``, a 2-step command delay) with joint damping, friction loss
and armature, logs the encoder positions (2^19 counts per revolution on the UR5) and the
commands, no torque; ``ident identify`` then runs with ``actuator: {kind: position}`` twice:
the gains identified (scale from the URDF's gravity load) and given (``scale_from: kp``).
Printed per seed and scale: the delay found, the largest relative error of ``kp`` (of every
joint, and of the joints whose gain the shared parameters tie to the scale; the others are
named, as the result names them), ``kd + fv`` (against ``kv + damping``), the rotor inertias
(``Ia``, where a base parameter is one) and the Coulomb friction (``fs``, against the friction
loss), and the seconds of the identification.

    python benchmarks/bench_servo.py [--robot ur5|arm2|so101] [--seeds 5] [--threshold 0.2]

``so101``: the SO-101-like arm of ``data/examples/make_so101.py`` (4096-tick encoders, a
``--delay-ms`` delay, 4 ms by default, 5 ms is 2.5 samples, a force range) on its 0.25-0.75 Hz
reference with two fast harmonics (2 and 3 Hz, :data:`FAST`: the torque's rate of change tells
the delay from the velocity gain), each seed two episodes written as a LeRobot dataset and
identified with ``configs/examples/lerobot-so101.yaml`` three ways: the scale from the URDF's
gravity load (``scale_from: mass``, the shoulder-elbow and wrist servos' gains equal,
``equal_kp``) and the delay scanned; ``kp`` given, the delay scanned; both given. Beside the
errors, the held-out rollout (1 s windows,
:func:`~ident.identify.assessment.rollout.rollout_score`) of the identified MJCF over that of
the truth's (1.00: as good as the truth).

    python benchmarks/bench_servo.py --robot so101 [--seeds 5] [--delay-ms 4]

``--peer sysid`` (the ``peers`` extra): the same episodes through mujoco.sysid at its best
set-up found (``bench_peers.run_sysid``: 0.5 s windows, positions and velocities in the
residual, ``x_scale='jac'``, run to its own convergence under ``--max-iters`` a stage),
given the log ident reads, commanded and measured positions and no torque, of the
identification part; its model is the simulator's class (``<position>`` servos, the force
range and the 2-sample delay given: sysid has no delay parameter), its parameters one
log-Cholesky inertia per link, armature, damping, friction loss per joint and the servos'
``kp``, tied as ident's ``equal_kp`` with the velocity gain in the damping
(:func:`sysid_case`; ``--sysid-per-joint-gains``: ``kp`` and ``kv`` per joint), in
``--sysid-stages`` (default: the joint terms and gains with the links frozen, then
everything), from each of ``--sysid-starts`` (:data:`SYSID_STARTS`). Against ident's
mass-scale, delay-scanned way, both scored by the held-out 1 s rollout over the truth's, with
the process CPU time of each call.

    PYTHONPATH=src python benchmarks/bench_servo.py --robot so101 --peer sysid [--seeds 5]
        [--seed-list 0 3] [--sysid-starts datasheet ident cad near-cad] [--max-iters 200]
        [--sysid-cpu-budget S | --sysid-budget-x-ident F] [--sysid-velocity-weight 1]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "data" / "examples"))

import bench_peers  # noqa: E402
import make_so101  # noqa: E402
from test_mujoco_sim import fourier_reference  # noqa: E402
from test_servo import ARM  # noqa: E402

from ident.dynamics.actuators import servo_error  # noqa: E402
from ident.errors import IdentError  # noqa: E402
from ident.identify.actuators.servo_fit import MIN_SHARED_SHARE  # noqa: E402
from ident.identify.assessment.rollout import (  # noqa: E402
    held_out_windows,
    identification_ranges,
    log_motion_scale,
    reference_mjcf,
    rollout_score,
)
from ident.identify.config import load_identify_config  # noqa: E402
from ident.identify.model_files.files import save_identified_model  # noqa: E402
from ident.identify.pipeline.real import identify  # noqa: E402
from ident.measure.mujoco_config import load_mujoco_measurement  # noqa: E402
from ident.measure.mujoco_sim import SimulatedLog, simulate, write_log  # noqa: E402
from ident.model import Robot  # noqa: E402

RATE = 500.0
DELAY_STEPS = 2
#: Per robot: the URDF, the servos' kp [N*m/rad] and kv [N*m*s/rad], MuJoCo's damping, friction
#: loss and armature, the reference's period [s] and amplitude [rad/s], the encoder.
ROBOTS = {
    "ur5": {
        "urdf": ROOT / "robot" / "urdf" / "ur5.urdf",
        "kp": [3000.0, 3000.0, 1500.0, 300.0, 300.0, 150.0],
        "kv": [60.0, 60.0, 30.0, 5.0, 5.0, 3.0],
        "damping": [3.0, 3.0, 2.0, 0.5, 0.5, 0.5],
        "coulomb": [5.0, 5.0, 3.0, 1.0, 1.0, 1.0],
        "armature": [0.5, 0.5, 0.3, 0.05, 0.05, 0.05],
        "period": 4.0,
        "amplitude": 1.5,
        "encoder": 2**19,
    },
    "arm2": {
        "urdf": None,  # tests/test_servo.py's two links
        "kp": [60.0, 30.0],
        "kv": [1.5, 0.8],
        "damping": [0.3, 0.2],
        "coulomb": [0.4, 0.2],
        "armature": [0.05, 0.05],
        "period": 3.0,
        "amplitude": 2.0,
        "encoder": 2**16,
    },
}


def simulated_log(folder: Path, robot: Robot, spec: dict, seed: int) -> None:
    """Simulate the servos on the seed's reference and write ``log.csv`` / ``log.yaml``."""
    actuator = {"kind": "position", "kp": spec["kp"], "kv": spec["kv"]}
    measurement = {
        "rate_hz": RATE,
        "friction": {"viscous": spec["damping"], "coulomb": spec["coulomb"]}
        | {"semantics": "mujoco"},
        "armature": spec["armature"],
        "actuator": actuator | {"delay_steps": DELAY_STEPS},
        "encoder_counts_per_rev": spec["encoder"],
        "settle_periods": 1,
        "n_periods": 2,
    }
    reference = fourier_reference(
        robot, period=spec["period"], seed=seed, amplitude=spec["amplitude"], rate_hz=RATE
    )
    write_log(folder, simulate(robot, *reference, load_mujoco_measurement(measurement), rng=0))


def identify_config(
    folder: Path, robot: Robot, urdf: Path, actuator: dict, threshold: float
) -> Path:
    """The identify config of the log in ``folder``: torque dropped, commands named, rows
    below ``threshold`` [rad/s] dropped (the friction loss's stiction)."""
    log = yaml.safe_load((folder / "log.yaml").read_text())["log"]
    del log["torque"]
    log["command"] = {"columns": [f"q_cmd_{name}" for name in robot.joint_names]}
    cfg = {
        "robot": {"urdf": str(urdf)},
        "log": log,
        "actuator": actuator,
        "preprocess": {"lowpass": {"cutoff_hz": 20.0}, "trim_samples": 100, "decimation": [5]}
        | {"velocity_threshold": [threshold] * robot.nv},
        "model": {"offset": False},
        "urdf_update": {"model": "none"},
    }
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def worst(found: np.ndarray, true: np.ndarray, names: list[str]) -> str:
    """The largest relative error [%] and its parameter's name."""
    errors = 100.0 * np.abs(np.asarray(found) / np.asarray(true) - 1.0)
    k = int(np.nanargmax(errors))
    return f"{errors[k]:.2f} % ({names[k]})"


def extras(result, prefix: str, true: list[float]) -> str:
    """The worst error of the base parameters ``<prefix><j>`` that stand alone (how many)."""
    found = dict(zip(result.estimate.names, result.estimate.x, strict=True))
    names = [f"{prefix}{j + 1}" for j in range(len(true)) if f"{prefix}{j + 1}" in found]
    if not names:
        return "n/a"
    truth = [true[int(n[len(prefix) :]) - 1] for n in names]
    return worst([found[n] for n in names], truth, names) + f" of {len(names)}"


def row(result, spec: dict, seconds: float) -> str:
    fit = result.actuator
    kp, kdfv = np.array(spec["kp"]), np.add(spec["kv"], spec["damping"])
    joints = [f"j{j + 1}" for j in range(kp.size)]
    tied = np.flatnonzero(fit.shared_share >= MIN_SHARED_SHARE)
    named = [joints[j] for j in tied]
    loose = [j for k, j in enumerate(joints) if k not in tied] if fit.scale == "mass" else []
    return (
        f"| {fit.scale} | {fit.delay_samples:.2f} | {worst(fit.kp, kp, joints)} "
        f"| {worst(fit.kp[tied], kp[tied], named) if fit.scale == 'mass' else '-'} "
        f"| {', '.join(loose) or '-'} | {worst(fit.damping, kdfv, joints)} "
        f"| {extras(result, 'Ia', spec['armature'])} | {extras(result, 'fs', spec['coulomb'])} "
        f"| {fit.n_excluded} | {seconds:.1f} |"
    )


#: The fast harmonics of the SO-101's reference (orders of 1 / PERIOD_S: 2 and 3 Hz), added to
#: its 0.25-0.75 Hz motion: they tell the delay from the velocity gain.
FAST = (8, 12)
#: The SO-101-like arm's servos of one gain: the shoulder and elbow, the wrist.
EQUAL_KP = [["shoulder_pan", "shoulder_lift", "elbow_flex"], ["wrist_flex", "wrist_roll"]]
SO101 = make_so101.SERVO | {"period": make_so101.PERIOD_S, "encoder": make_so101.COUNTS_PER_REV}
ROLLOUT_WINDOW_S = 1.0


def so101_rollout(result, folder: Path, peers: tuple = ()) -> list[float]:
    """Held-out rollout objective of the identified MJCF over the truth's, 1 s windows: the
    identified model driven by the log's ``kp e`` (its gains and delay), the truth (URDF
    bodies, armature, kv + damping, friction loss) by the servos' own ``kp e`` (true gains,
    the 2-sample delay) on the same samples. Then the same ratio of each of ``peers``:
    ``(model, kp)``, a MuJoCo model (its velocity gain in its damping) driven by its ``kp``
    (nv,) [N*m/rad] times the error of the true delay (its model class's, given)."""
    entry = save_identified_model(result, folder)
    if not entry["written"]:
        return [float("nan")] * (1 + len(peers))
    measured, windows = held_out_windows(result, window_s=ROLLOUT_WINDOW_S)
    score = rollout_score(folder / entry["files"]["mjcf"], measured, windows)
    spec = SO101
    extras = {
        name: {
            "rotor_inertia": spec["armature"][j],
            "viscous": spec["kv"][j] + spec["damping"][j],
            "coulomb": spec["coulomb"][j],
        }
        for j, name in enumerate(result.joint_names)
    }
    truth = mujoco.MjModel.from_xml_string(reference_mjcf(Robot.from_urdf(make_so101.URDF), extras))
    driven = [(truth, spec["kp"]), *peers]
    objectives = [
        servo_rollout(result, model, kp, measured, windows, score.substeps) for model, kp in driven
    ]
    return [score.objective / objectives[0]] + [y / objectives[0] for y in objectives[1:]]


def servo_rollout(result, model, kp, measured, windows, substeps: int) -> float:
    """The rollout objective of ``model`` on the held-out ``windows`` of ``measured``, driven
    by ``kp`` (nv,) [N*m/rad] times the servos' error ``q_cmd(t - d) - q`` of the log with
    the true delay ``d``."""
    log = result.log
    e = servo_error(log.q, log.q_cmd, true_delay_samples(), log.segments)
    rows = np.searchsorted(log.t, measured.t)  # the windows' samples in the log
    tau = np.asarray(kp) * e[rows]
    return rollout_score(model, measured.with_torque(tau), windows, substeps=substeps).objective


def so101_config(folder: Path, actuator: dict) -> Path:
    """The example's identify config on the dataset in ``folder``, ``actuator`` replaced."""
    cfg = yaml.safe_load((ROOT / "configs" / "examples" / "lerobot-so101.yaml").read_text())
    cfg["robot"]["urdf"] = str(make_so101.URDF)
    cfg["log"]["path"] = str(folder / "dataset")
    cfg["actuator"] = {"kind": "position", "forcerange": SO101["forcerange"]} | actuator
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def true_delay_samples() -> float:
    """The simulated servos' command delay [samples of the log] (a fraction with substeps)."""
    return SO101["delay_steps"] / SO101.get("substeps", 1)


def set_delay(delay_ms: float) -> None:
    """Set the simulated servos' delay to ``delay_ms`` [ms], to half a sample (MuJoCo steps
    of half a frame when it is not a whole number of frames), and print it."""
    half_samples = int(round(2e-3 * delay_ms * make_so101.RATE_HZ))
    substeps = 1 if half_samples % 2 == 0 else 2
    SO101.update(delay_steps=half_samples * substeps // 2, substeps=substeps)
    delay_s = true_delay_samples() / make_so101.RATE_HZ
    print(f"SO-101-like arm: servo delay {1e3 * delay_s:g} ms ({true_delay_samples():g} samples)")


def run_so101(seeds: int) -> None:
    """Print one row per seed and way of fixing the scale and the delay (module docstring)."""
    delay_s = true_delay_samples() / make_so101.RATE_HZ
    print(
        "| seed | scale | delay | delay [samples] | kp | kd + fv | Ia | Ia, lag-corrected | fs "
        "| rollout / truth | s |\n| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: "
        "| ---: | ---: |"
    )
    robot = Robot.from_urdf(make_so101.URDF)
    ways = [
        ("mass", "scan", {"max_delay_s": 0.01, "equal_kp": EQUAL_KP}),
        ("kp", "scan", {"max_delay_s": 0.01, "kp": SO101["kp"]}),
        ("kp", "given", {"delay": delay_s, "kp": SO101["kp"]}),
    ]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for seed in range(seeds):
            logs = make_so101.simulate_episodes(robot, (2 * seed, 2 * seed + 1), SO101, fast=FAST)
            make_so101.write(folder / "dataset", logs)
            for scale, delay, actuator in ways:
                t0 = time.perf_counter()
                try:
                    result = identify(load_identify_config(so101_config(folder, actuator)))
                except IdentError as e:  # the row says why, the other ways still run
                    print(f"| {seed} | {scale} | {delay} | failed: {e} |", flush=True)
                    continue
                seconds = time.perf_counter() - t0
                ratio = so101_rollout(result, folder / f"model-{seed}-{scale}-{delay}")[0]
                row = so101_row(result, ratio, seconds)
                print(f"| {seed} | {scale} | {delay} " + row, flush=True)


#: ident's way against mujoco.sysid: the gains from the URDF's gravity load, the delay scanned
#: (a user who knows neither), the example's config otherwise.
IDENT_WAY = {"max_delay_s": 0.01, "equal_kp": EQUAL_KP}
#: mujoco.sysid's rollout windows [s] (its best set-up, as in bench_peers.py).
SYSID_WINDOW_S = 0.5
#: mujoco.sysid's starts (``--sysid-starts``, bench_peers.SYSID_STARTS): ``datasheet``, the
#: URDF's bodies, the armature and gains 1.5x the truth, no friction; ``ident``, ident's
#: written model (bodies, joint terms, gains); ``cad``, the URDF's bodies with the joint terms
#: off and the gains 1.5x; ``near-cad``, the URDF's bodies, joint terms and gains 1.5x.
SYSID_STARTS = ("datasheet", "ident")
#: Its stages (``--sysid-stages``, bench_peers.SYSID_STAGE_FREE).
SYSID_STAGES = ("joints", "all")


def sysid_case(result, robot: Robot, first: SimulatedLog, tied: bool = True) -> bench_peers.Case:
    """The log ident read (``result.log``: measured and commanded positions of every episode,
    SI) as bench_peers.py's mujoco.sysid gets it: the identification part's samples
    (:func:`identification_ranges`: the held-out part and the trims left out), the servos'
    force range and delay (its model class's, given) and true gains (its start, 1.5x);
    ``tied``: the gains as ident's config has them (one ``kp`` per ``equal_kp`` group of
    :data:`EQUAL_KP`, the velocity gain in the joint damping), else ``kp`` and ``kv`` per
    joint."""
    log = result.log
    if tuple(log.joint_names) != tuple(robot.joint_names):
        raise ValueError(f"the log's joints {log.joint_names} are not the URDF's order")
    servo = bench_peers.ServoLog(
        q=np.asarray(log.q),
        q_cmd=np.asarray(log.q_cmd),
        segments=[tuple(s) for s in log.segments],
        ranges=[r for _, r in identification_ranges(result)],
        kp=np.asarray(SO101["kp"], dtype=float),
        kv=np.asarray(SO101["kv"], dtype=float),
        forcerange=float(SO101["forcerange"]),
        delay_steps=int(SO101["delay_steps"]),
    )
    if tied:  # what ident's config knows: the servos of one setting, kd + fv
        names = list(robot.joint_names)
        servo.kp_groups = [[names.index(j) for j in group] for group in EQUAL_KP]
        servo.fold_kv = True
    return bench_peers.Case("so101", SimpleNamespace(robot=robot), first, 0, servo)


@dataclass
class SysidSetup:
    """mujoco.sysid's set-up in ``--peer sysid`` (its command-line options): iteration cap a
    stage, starts, stages, ``tied`` (:func:`sysid_case`) and its CPU budget: ``cpu_budget_s``
    [s], or ``budget_x_ident`` times ident's CPU on the same seed (None: no budget)."""

    max_iters: int = 200
    starts: tuple[str, ...] = SYSID_STARTS
    stages: tuple[str, ...] = SYSID_STAGES
    tied: bool = True
    cpu_budget_s: float | None = None
    budget_x_ident: float | None = None
    velocity_weight: float = 1.0


def run_so101_sysid(seeds: list[int], setup: SysidSetup) -> None:
    """Per seed: ident (``IDENT_WAY``) and mujoco.sysid (``setup``, :func:`sysid_case`) from
    each of its starts on the same episodes, each scored by the held-out 1 s rollout over the
    truth's (:func:`so101_rollout`), with its process CPU time; one row per seed and start."""
    if SO101.get("substeps", 1) != 1:
        raise SystemExit(
            "error: --peer sysid needs a delay of whole samples (--delay-ms 2, 4, ...)"
        )
    print(
        "| seed | sysid start | ident rollout / truth | sysid rollout / truth | ident CPU [s] "
        "| sysid CPU [s] | sysid / ident CPU | ident kp | sysid kp | sysid iterations, stop "
        "| load |\n| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: |"
    )
    robot = Robot.from_urdf(make_so101.URDF)
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            _sysid_seed(seed, Path(tmp), robot, setup)


def _sysid_seed(seed: int, folder: Path, robot: Robot, setup: SysidSetup) -> None:
    """One seed of :func:`run_so101_sysid`: its rows printed."""
    joints = [f"j{j + 1}" for j in range(robot.nv)]
    load = os.getloadavg()[0]
    logs = make_so101.simulate_episodes(robot, (2 * seed, 2 * seed + 1), SO101, fast=FAST)
    make_so101.write(folder / "dataset", logs)
    c0 = time.process_time()
    result = identify(load_identify_config(so101_config(folder, IDENT_WAY)))
    ident_cpu = time.process_time() - c0
    case = sysid_case(result, robot, logs[0], setup.tied)
    ident_model = bench_peers.ident_written_model(result)
    budget = setup.cpu_budget_s
    if setup.budget_x_ident is not None:
        budget = setup.budget_x_ident * ident_cpu
    runs = [
        bench_peers.run_sysid(
            case,
            result.parameters,
            start=start,
            window_s=SYSID_WINDOW_S,
            max_iters=setup.max_iters,
            ident_model=ident_model,
            cpu_budget_s=budget,
            stages=setup.stages,
            velocity_weight=setup.velocity_weight,
            scale=log_motion_scale(result),  # the rollout objective's
        )
        for start in setup.starts
    ]
    peers = [(bench_peers.model_mjcf(case, result.parameters, r.x), r.info["kp"]) for r in runs]
    ours, *theirs = so101_rollout(result, folder / f"model-{seed}", tuple(peers))
    ident_kp = worst(result.actuator.kp, SO101["kp"], joints)
    for start, run, ratio in zip(setup.starts, runs, theirs, strict=True):
        print(
            f"| {seed} | {start} | {ours:.3f} | {ratio:.3g} | {ident_cpu:.1f} "
            f"| {run.cpu_s:.1f} | {run.cpu_s / ident_cpu:.1f} | {ident_kp} "
            f"| {worst(run.info['kp'], SO101['kp'], joints)} "
            f"| {run.info['iterations']}: {run.info['status']} | {load:.1f} |",
            flush=True,
        )
        print(f"  sysid ({start}): {run.note}", file=sys.stderr, flush=True)
        print(f"  sysid ({start}) {joint_terms(result.parameters.names, run.x)}", file=sys.stderr)
    pm, names = result.parameters, list(robot.joint_names)
    ours_x = bench_peers.standard_from_mujoco(ident_model, pm, names)
    print(f"  ident: {joint_terms(pm.names, ours_x)}", file=sys.stderr, flush=True)


def joint_terms(names: list[str], x: np.ndarray) -> str:
    """``Ia``, ``fv`` (``kd + fv``) and ``fs`` per joint of ``x`` over ``names``, over the
    simulated servos' truth (armature, kv + damping, friction loss)."""
    spec, found = SO101, dict(zip(names, np.asarray(x, dtype=float), strict=True))
    truth = {"Ia": spec["armature"], "fv": np.add(spec["kv"], spec["damping"])}
    truth["fs"] = spec["coulomb"]
    return "; ".join(
        f"{key}/truth "
        + " ".join(f"{found.get(f'{key}{j + 1}', np.nan) / t[j]:.2f}" for j in range(len(t)))
        for key, t in truth.items()
    )


def so101_row(result, ratio: float, seconds: float) -> str:
    fit, spec = result.actuator, SO101
    kp, kdfv = np.array(spec["kp"]), np.add(spec["kv"], spec["damping"])
    joints = [f"j{j + 1}" for j in range(kp.size)]
    kp_text = worst(fit.kp, kp, joints) if fit.scale == "mass" else "given"
    # the simulated positions lag their velocity by half a step (semi-implicit Euler): the
    # central differences see an armature smaller by (kd + fv) h / 2
    lagged = np.asarray(spec["armature"]) - kdfv / (2.0 * make_so101.RATE_HZ)
    return (
        f"| {fit.delay_samples:.2f} | {kp_text} | {worst(fit.damping, kdfv, joints)} "
        f"| {extras(result, 'Ia', spec['armature'])} | {extras(result, 'Ia', list(lagged))} "
        f"| {extras(result, 'fs', spec['coulomb'])} | {ratio:.3f} | {seconds:.1f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=[*sorted(ROBOTS), "so101"], default="ur5")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument(
        "--threshold", type=float, default=0.2, help="velocity threshold [rad/s] of every joint"
    )
    parser.add_argument(
        "--delay-ms", type=float, default=4.0, help="so101: the servos' delay [ms], to 1 ms"
    )
    parser.add_argument(
        "--peer", choices=["sysid"], default=None, help="so101: ident against mujoco.sysid"
    )
    parser.add_argument(
        "--max-iters", type=int, default=200, help="--peer sysid: its iteration cap"
    )
    parser.add_argument(
        "--sysid-starts",
        nargs="+",
        default=list(SYSID_STARTS),
        choices=["cad", "ident", "near-cad", "datasheet"],
        help="--peer sysid: its starting models",
    )
    parser.add_argument(
        "--sysid-cpu-budget",
        type=float,
        default=None,
        help="--peer sysid: stop it after this many CPU seconds, reported as not converged",
    )
    parser.add_argument(
        "--sysid-budget-x-ident",
        type=float,
        default=None,
        help="--peer sysid: its CPU budget, this many times ident's CPU on the seed",
    )
    parser.add_argument(
        "--sysid-velocity-weight",
        type=float,
        default=1.0,
        help="--peer sysid: the velocities' weight in its residual (0: positions only)",
    )
    parser.add_argument(
        "--seed-list", type=int, nargs="+", default=None, help="these seeds (not --seeds)"
    )
    parser.add_argument(
        "--sysid-stages",
        nargs="+",
        default=list(SYSID_STAGES),
        choices=sorted(bench_peers.SYSID_STAGE_FREE),
        help="--peer sysid: its stages, each from the previous one's stop",
    )
    parser.add_argument(
        "--sysid-per-joint-gains",
        action="store_true",
        help="--peer sysid: kp and kv per joint (default: as ident's config, sysid_case)",
    )
    args = parser.parse_args()
    if args.peer is not None and args.robot != "so101":
        parser.error("--peer sysid runs on --robot so101")
    if args.robot == "so101":
        set_delay(args.delay_ms)
        if args.peer == "sysid":
            setup = SysidSetup(
                max_iters=args.max_iters,
                starts=tuple(args.sysid_starts),
                stages=tuple(args.sysid_stages),
                tied=not args.sysid_per_joint_gains,
                cpu_budget_s=args.sysid_cpu_budget,
                budget_x_ident=args.sysid_budget_x_ident,
                velocity_weight=args.sysid_velocity_weight,
            )
            run_so101_sysid(args.seed_list or list(range(args.seeds)), setup)
        else:
            run_so101(args.seeds)
        return
    spec = ROBOTS[args.robot]
    print(
        f"{args.robot}: servos kp {spec['kp']}, kv {spec['kv']}, delay {DELAY_STEPS} steps; "
        f"velocity threshold {args.threshold} rad/s"
    )
    print(
        "| seed | scale | delay [samples] | kp | kp, tied joints | named loose | kd + fv | Ia | fs "
        "| excluded | s |"
    )
    print("| --- | --- | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        urdf = spec["urdf"]
        if urdf is None:
            urdf = folder / "arm2.urdf"
            urdf.write_text(ARM)
        robot = Robot.from_urdf(urdf)
        for seed in range(args.seeds):
            simulated_log(folder, robot, spec, seed)
            for actuator in ({}, {"kp": spec["kp"]}):
                section = {"kind": "position"} | actuator
                path = identify_config(folder, robot, urdf, section, args.threshold)
                t0 = time.perf_counter()
                result = identify(load_identify_config(path))
                print(f"| {seed} " + row(result, spec, time.perf_counter() - t0), flush=True)


if __name__ == "__main__":
    main()
