"""Generate the LeRobot dataset of the SO-101-like arm, data/examples/so101/, from MuJoCo.

    python data/examples/make_so101.py

The arm (``robot/urdf/so101.urdf``, written by ``ident urdf configs/so101.yaml``) is driven by
MuJoCo's ``<position>`` servos (:data:`SERVO`: gain, velocity gain, saturation, a 4 ms command
delay) with joint damping, friction loss and a geared motor's armature, on a smooth periodic
reference per episode (3 harmonics, :func:`reference`) whose positions are whole servo ticks,
as a leader arm sends them. The encoders count 4096 ticks per turn. Each episode is written as
LeRobot records it (:func:`ident.measure.lerobot_dataset.write_simulated_dataset`):
``observation.state`` and ``action`` in ticks, a gripper motor held at its centre, at 500
frames per second. ``configs/examples/lerobot-so101.yaml`` identifies it; the benchmark
``benchmarks/bench_servo.py --robot so101`` uses the same truth and reference. Deterministic.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ident.measure.lerobot_dataset import write_simulated_dataset
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import SimulatedLog, simulate
from ident.model import Robot

HERE = Path(__file__).resolve().parent
URDF = HERE.parents[1] / "robot" / "urdf" / "so101.urdf"
DATASET = HERE / "so101"
RATE_HZ = 500.0  # frames per second, and the servos' command rate
COUNTS_PER_REV, ZERO_TICK = 4096, 2048  # Feetech STS3215
#: The simulated servos (per joint, SI): gain [N*m/rad], velocity gain and joint damping
#: [N*m*s/rad], friction loss [N*m], armature [kg*m^2] (rotor inertia times gear ratio
#: squared), saturation [N*m], command delay [MuJoCo steps of 1 / RATE_HZ; of
#: 1 / (RATE_HZ substeps) with an optional ``substeps``: MuJoCo steps per frame].
SERVO = {
    "kp": [18.0, 18.0, 18.0, 12.0, 12.0],
    "kv": [0.4, 0.4, 0.4, 0.25, 0.25],
    "damping": [0.2, 0.2, 0.2, 0.1, 0.1],
    "coulomb": [0.05, 0.05, 0.05, 0.03, 0.03],
    "armature": [0.02, 0.02, 0.02, 0.012, 0.012],
    "forcerange": 2.9,
    "delay_steps": 2,
}
PERIOD_S = 4.0
AMPLITUDE = 1.2  # rad/s, the reference's velocity coefficients
FAST_AMPLITUDE = 0.15  # rad/s, those of the fast harmonics (reference(fast=...))
EPISODE_SEEDS = (0, 1)
SETTLE_PERIODS, N_PERIODS = 1, 1


def measurement(servo: dict = SERVO, n_periods: int = N_PERIODS) -> dict:
    """The simulator's ``measurement:`` section of the servos."""
    actuator = {"kind": "position", "kp": servo["kp"], "kv": servo["kv"]}
    actuator |= {"forcerange": servo["forcerange"], "delay_steps": servo["delay_steps"]}
    friction = {"viscous": servo["damping"], "coulomb": servo["coulomb"], "semantics": "mujoco"}
    return {
        "rate_hz": RATE_HZ,
        "friction": friction,
        "armature": servo["armature"],
        "actuator": actuator,
        "encoder_counts_per_rev": COUNTS_PER_REV,
        "settle_periods": SETTLE_PERIODS,
        "n_periods": n_periods,
        "substeps": servo.get("substeps", 1),
    }


def reference(robot: Robot, seed: int, fast: Sequence[int] = ()) -> tuple[np.ndarray, ...]:
    """One period of the episode's reference at RATE_HZ: t [s], q [rad] on the ticks' grid,
    dq [rad/s], ddq [rad/s^2], shapes (n,) and (n, nv). 3 harmonics of 1 / PERIOD_S about
    the middle of the joint ranges, and the harmonics ``fast`` (of velocity amplitude up to
    FAST_AMPLITUDE, whatever their order): the torque's rate of change at a few Hz is what
    tells the command's delay from the servo's velocity gain (see ``bench_servo.py``)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(PERIOD_S * RATE_HZ))) / RATE_HZ
    w = 2.0 * np.pi / PERIOD_S
    q, dq, ddq = (np.zeros((t.size, robot.nv)) for _ in range(3))
    orders = [(h, AMPLITUDE, h) for h in (1, 2, 3)] + [(h, FAST_AMPLITUDE, 1) for h in fast]
    for h, amplitude, shrink in orders:
        a, b = rng.uniform(-amplitude, amplitude, (2, robot.nv)) / shrink
        phase = w * h * t[:, None]
        q += (a * np.sin(phase) - b * np.cos(phase)) / (w * h)
        dq += a * np.cos(phase) + b * np.sin(phase)
        ddq += (-a * np.sin(phase) + b * np.cos(phase)) * w * h
    q += 0.5 * (robot.q_lower + robot.q_upper)
    tick = 2.0 * np.pi / COUNTS_PER_REV
    return t, np.rint(q / tick) * tick, dq, ddq


def simulate_episodes(
    robot: Robot,
    seeds: Sequence[int],
    servo: dict = SERVO,
    n_periods: int = N_PERIODS,
    fast: Sequence[int] = (),
) -> list[SimulatedLog]:
    """One simulated servo log per seed (its reference, with the harmonics ``fast``), logged
    after SETTLE_PERIODS."""
    config = load_mujoco_measurement(measurement(servo, n_periods))
    return [simulate(robot, *reference(robot, s, fast), config, rng=0) for s in seeds]


def write(folder: Path, logs: Sequence[SimulatedLog]) -> Path:
    """The logs as a LeRobot dataset in ``folder`` (a gripper motor held at its centre)."""
    return write_simulated_dataset(
        folder,
        logs,
        counts_per_rev=COUNTS_PER_REV,
        zero_tick=ZERO_TICK,
        extra_motors={"gripper": ZERO_TICK},
    )


def main() -> None:
    robot = Robot.from_urdf(URDF)
    root = write(DATASET, simulate_episodes(robot, EPISODE_SEEDS))
    size = sum(p.stat().st_size for p in root.rglob("*") if p.is_file())
    print(f"wrote {root} ({size / 1e3:.0f} kB)", file=sys.stderr)


if __name__ == "__main__":
    main()
