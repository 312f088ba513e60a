"""A simulated execution of the exported files (MuJoCo, closed loop) follows the plan.

The re-read ROS 2 bag (positions, velocities, accelerations at the plan's samples) and the
re-read Franka file (positions at 1 kHz; velocities and accelerations by central differences,
as a position interface derives them) drive the closed-loop simulator of
:mod:`ident.measure.mujoco_sim` (computed torque at 1 kHz on the nominal model, with friction
and rotor inertia the controller does not know, as the shipped configs simulate). Its tracking
error is the plan's own (docs/execute.md): a file off by one sample (1 ms late) or by a wrong
joint order would add ~ |dq| * 1 ms = 1 mrad or more.
"""

from __future__ import annotations

import numpy as np
import pytest
from robots import PANDA_URDF

from ident.excitation.executable import quintic
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate
from ident.model import Robot
from ident.run.exports.common import target_from_urdf
from ident.run.exports.franka import read_franka
from ident.run.exports.registry import export_trajectory
from ident.run.exports.ros2 import read_ros2
from ident.trajectory import JointTrajectory

PANDA_LOCKS = {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.035}
MEASUREMENT = {
    "friction": {"viscous": 0.5, "coulomb": 1.0},
    "armature": 0.05,
    "controller": {"kind": "computed_torque"},
    "settle_periods": 0,
    "n_periods": 1,
}


@pytest.fixture(scope="module")
def panda():
    return Robot.from_urdf(PANDA_URDF, lock_joints=PANDA_LOCKS)


def excursion(robot, duration=1.2):
    """Rest at home, a quintic excursion of every joint and back, at 1 kHz (ends at home)."""
    home = np.array([0.0, -0.6, 0.0, -2.2, 0.0, 1.6, 0.8])
    away = home + np.array([0.4, 0.3, -0.4, 0.3, 0.5, -0.3, 0.6])
    zero = np.zeros(7)
    half = duration / 2
    n = int(round(half * 1000))
    t = np.arange(n) / 1000
    out = quintic((home, zero, zero), (away, zero, zero), half, t)
    back = quintic((away, zero, zero), (home, zero, zero), half, np.arange(n + 1) / 1000)
    q, dq, ddq = (np.vstack([a, b]) for a, b in zip(out, back, strict=True))
    return JointTrajectory(
        t=np.arange(2 * n + 1) / 1000, q=q, dq=dq, ddq=ddq, joint_names=tuple(robot.joint_names)
    )


def run(robot, t, q, dq, ddq):
    """Simulated true positions while tracking one pass of the reference."""
    config = load_mujoco_measurement(MEASUREMENT)
    return simulate(robot, t, q, dq, ddq, config).q_true


def test_simulated_execution_of_the_reread_exports_follows_the_plan(tmp_path, panda):
    plan = excursion(panda)
    target = target_from_urdf(panda.urdf_text)
    outcome = export_trajectory(["ros2", "franka"], plan, target, tmp_path)
    assert set(outcome.written) == {"ros2", "franka"}, outcome.refused

    planned = run(panda, plan.t, plan.q, plan.dq, plan.ddq)
    plan_error = np.max(np.abs(planned - plan.q), axis=0)

    bag = read_ros2(tmp_path / "joint_trajectory_bag")
    from_bag = run(panda, bag.t, bag.q, bag.dq, bag.ddq)
    np.testing.assert_allclose(from_bag, planned, rtol=0, atol=1e-8)

    franka = read_franka(tmp_path / "franka_q_1khz.csv")
    dq = np.gradient(franka.q, 1e-3, axis=0)
    ddq = np.gradient(dq, 1e-3, axis=0)
    from_file = run(panda, franka.t, franka.q, dq, ddq)
    error = np.max(np.abs(from_file - plan.q), axis=0)
    assert np.all(error <= 1.05 * plan_error + 2e-5), (error, plan_error)

    # a file one sample late is told apart: the check above has the resolution
    late = run(panda, franka.t, np.vstack([franka.q[:1], franka.q[:-1]]), dq, ddq)
    late_error = np.max(np.abs(late - plan.q), axis=0)
    assert np.any(late_error > 1.05 * plan_error + 2e-5), (late_error, plan_error)
