"""URDF mimic joints: a follower on the chain moves with its leader, one of a locked leader is
locked with it, and the safety certificate and MuJoCo follow the coupling.

References: Pinocchio's RNEA and regressor of the *uncoupled* model (every joint independent,
the file read without mimic) at ``q_f = m q_l + o``, projected with the mapping's Jacobian
``G^T``; Pinocchio's forward kinematics and coal distances of that model; MuJoCo's simulation.
"""

from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from ident.errors import ModelError
from ident.excitation.check import check_trajectory
from ident.excitation.safety import build_safety_model
from ident.measure.mujoco_model import load_mujoco
from ident.model import Robot
from ident.run.init_robot import choose_locks

M, O = -0.5, 0.1  # j3 = M * j2 + O


def _link(name: str, size: float = 0.3) -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="0.1 0.02 -0.03" rpy="0 0 0"/>'
        '<mass value="1.3"/><inertia ixx="0.02" ixy="0.001" ixz="0.002" iyy="0.025" iyz="0.001" '
        'izz="0.03"/></inertial><collision><origin xyz="0.15 0 0" rpy="0 1.5708 0"/>'
        f'<geometry><cylinder radius="0.03" length="{size}"/></geometry></collision></link>'
    )


def _joint(name, parent, child, axis, mimic="", lower=-2.0, upper=2.0, kind="revolute", v=3.0):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0.3 0 0.05" rpy="0.1 0.2 0.3"/><axis xyz="{axis}"/>'
        f'<limit lower="{lower}" upper="{upper}" effort="50" velocity="{v}"/>{mimic}</joint>'
    )


def arm_urdf(follower_range=(-2.0, 2.0), follower_velocity=3.0) -> str:
    """A 3-joint arm whose joint j3 mimics j2 (multiplier M, offset O)."""
    mimic = f'<mimic joint="j2" multiplier="{M}" offset="{O}"/>'
    return (
        '<robot name="arm"><link name="base"/>'
        + "".join(_link(n) for n in ("l1", "l2", "l3"))
        + _joint("j1", "base", "l1", "0 0 1")
        + _joint("j2", "l1", "l2", "0 1 0")
        + _joint("j3", "l2", "l3", "1 0 0", mimic, *follower_range, v=follower_velocity)
        + "</robot>"
    )


def gripper_urdf() -> str:
    """A 2-joint arm with two sliding fingers; finger_b mimics finger_a (2 x - 0.005)."""
    mimic = '<mimic joint="finger_a" multiplier="2" offset="-0.005"/>'
    return (
        '<robot name="gripper"><link name="base"/>'
        + "".join(_link(n) for n in ("l1", "l2", "fa", "fb"))
        + _joint("j1", "base", "l1", "0 0 1")
        + _joint("j2", "l1", "l2", "0 1 0")
        + _joint("finger_a", "l2", "fa", "0 1 0", "", 0.0, 0.04, "prismatic")
        + _joint("finger_b", "l2", "fb", "0 -1 0", mimic, 0.0, 0.08, "prismatic")
        + "</robot>"
    )


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _uncoupled(text: str) -> tuple[pin.Model, np.ndarray, np.ndarray]:
    """The file read with every joint independent, and the mapping q_full = G q + offset."""
    model = pin.buildModelFromXML(text)  # mimic=False: j3 is a joint of its own
    G = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, M]])
    return model, G, np.array([0.0, 0.0, O])


def test_reduced_dynamics_equal_pinocchio_projected_from_the_uncoupled_model(tmp_path):
    robot = Robot.from_urdf(_write(tmp_path, "arm.urdf", arm_urdf()))
    assert robot.joint_names == ("j1", "j2")
    assert robot.nq == robot.nv == 2
    assert robot.n_bodies == 3
    assert [m.follower for m in robot.mimic_joints] == ["j3"]
    full, G, offset = _uncoupled(robot.urdf_text)
    data = full.createData()
    q, dq, ddq = robot.random_configurations(20, rng=3)
    Y = robot.regressor(q, dq, ddq)
    assert Y.shape == (20, 2, 30)
    for k in range(20):
        args = (G @ q[k] + offset, G @ dq[k], G @ ddq[k])
        tau_full = pin.rnea(full, data, *args)
        Y_full = pin.computeJointTorqueRegressor(full, data, *args)
        np.testing.assert_allclose(Y[k], G.T @ Y_full, rtol=0, atol=1e-9)
        np.testing.assert_allclose(Y[k] @ robot.parameters(), G.T @ tau_full, rtol=0, atol=1e-9)
        np.testing.assert_allclose(robot.rnea(q[k], dq[k], ddq[k])[0], G.T @ tau_full, atol=1e-9)
        # the follower's link sits where the uncoupled model puts it at q_f = m q_l + o
        pin.framesForwardKinematics(full, data, args[0])
        np.testing.assert_allclose(
            robot.frame_placements(q[k], "l3")[0],
            data.oMf[full.getFrameId("l3")].homogeneous,
            atol=1e-12,
        )


def test_follower_range_narrows_the_leader_and_the_certificate_names_the_follower(tmp_path):
    # j3 in [-0.5, 0.5] <=> j2 in [(0.5 - O) / M, (-0.5 - O) / M] = [-0.8, 1.2]
    robot = Robot.from_urdf(_write(tmp_path, "arm.urdf", arm_urdf((-0.5, 0.5), 1.0)))
    np.testing.assert_allclose([robot.q_lower[1], robot.q_upper[1]], [-0.8, 1.2])
    assert robot.dq_max[1] == pytest.approx(1.0 / abs(M))  # below j2's own 3 rad/s
    q = robot.random_configurations(500, rng=0)[0]
    assert np.all(np.abs(M * q[:, 1] + O) <= 0.5 + 1e-12)
    safety = build_safety_model(robot, {"clearance_m": 0.0})
    t = np.linspace(0.0, 2.0 * np.pi, 6284)
    w = 1.0  # slow: |dq_j3| = |M| * amplitude * w within its 1 rad/s
    for amplitude, ok in ((0.7, True), (1.5, False)):  # both within j2's own [-2, 2]
        q = np.column_stack([0.2 * np.sin(w * t), amplitude * np.sin(w * t)])
        dq = np.column_stack([0.2 * w * np.cos(w * t), amplitude * w * np.cos(w * t)])
        report = check_trajectory(robot, safety, t, q, dq, -(w**2) * q)
        follower = report.check("position:j3")
        assert follower.value == pytest.approx(M * -amplitude + O, abs=1e-6)
        assert follower.ok is ok
        assert report.check("velocity:j3").value == pytest.approx(abs(M) * amplitude * w, 1e-6)


def test_locked_leader_locks_its_follower_at_the_mimic_value(tmp_path):
    path = _write(tmp_path, "gripper.urdf", gripper_urdf())
    robot = Robot.from_urdf(path, lock_joints={"finger_a": 0.01})
    assert robot.joint_names == ("j1", "j2")
    assert robot.mimic_joints == ()
    assert robot.locked_joints == {"finger_a": 0.01, "finger_b": 2 * 0.01 - 0.005}
    full = pin.buildModelFromXML(robot.urdf_text)
    data = full.createData()
    q = np.array([0.4, -0.7])
    pin.framesForwardKinematics(full, data, np.array([0.4, -0.7, 0.01, 0.015]))
    np.testing.assert_allclose(
        robot.frame_placements(q, "fb")[0], data.oMf[full.getFrameId("fb")].homogeneous, atol=1e-12
    )
    # ident init: the fingers are locked, the follower with its reason
    values, lines = choose_locks(path, None, None, {"finger_a": 0.01})
    assert values["finger_b"] == pytest.approx(0.015)
    assert "finger_b locked at 0.015: follows finger_a (mimic)" in lines
    # a follower locked while its leader moves, or off the chain of a moving leader: an error
    with pytest.raises(ModelError, match="'finger_b' mimics 'finger_a', which moves"):
        Robot.from_urdf(path, lock_joints={"finger_b": 0.01})
    with pytest.raises(ModelError, match="outside its limits"):
        Robot.from_urdf(path, lock_joints={"finger_a": 0.0})  # finger_b at -0.005 < 0


def test_safety_clearances_follow_the_mimic(tmp_path):
    robot = Robot.from_urdf(_write(tmp_path, "arm.urdf", arm_urdf()))
    safety = build_safety_model(robot, {"clearance_m": 0.0})
    full, G, offset = _uncoupled(robot.urdf_text)
    geom = pin.buildGeomFromUrdfString(full, robot.urdf_text, pin.GeometryType.COLLISION)
    names = [o.name for o in geom.geometryObjects]
    q = robot.random_configurations(30, rng=2)[0]
    ours = safety.clearances(q)
    assert "l1|l3" in safety.pair_names  # adjacent links are excluded
    for column, pair in enumerate(safety.pair_names):
        if "floor" in pair:
            continue
        a, b = (names.index(next(n for n in names if n.startswith(x))) for x in pair.split("|"))
        geom.addCollisionPair(pin.CollisionPair(a, b))
        gdata = geom.createData()
        for k in range(q.shape[0]):
            pin.updateGeometryPlacements(full, full.createData(), geom, gdata, G @ q[k] + offset)
            reference = pin.computeDistance(geom, gdata, len(geom.collisionPairs) - 1).min_distance
            assert ours[k, column] == pytest.approx(reference, abs=1e-6)


def test_mujoco_follower_tracks_its_leader(tmp_path):
    robot = Robot.from_urdf(_write(tmp_path, "arm.urdf", arm_urdf()))
    mj = load_mujoco(robot, timestep_s=1e-3)
    assert mj.model.nv == 3  # the follower is a MuJoCo joint ...
    assert mj.model.neq == 1  # ... on an equality constraint
    data = mujoco.MjData(mj.model)
    follower = mujoco.mj_name2id(mj.model, mujoco.mjtObj.mjOBJ_JOINT, "j3")
    t = np.arange(1500) * 1e-3
    w = 2.0 * np.pi
    q_ref = np.column_stack([0.5 * np.sin(w * t), 0.8 * np.sin(2 * w * t)])
    dq_ref = np.column_stack([0.5 * w * np.cos(w * t), 1.6 * w * np.cos(2 * w * t)])
    ddq_ref = np.column_stack([-0.5 * w**2 * np.sin(w * t), -3.2 * w**2 * np.sin(2 * w * t)])
    mj.set_state(data, q_ref[0], dq_ref[0])
    coupling, tracking = [], []
    for k in range(t.size):  # computed torque on ident's reduced model drives the leaders only
        q, dq = data.qpos[mj.qpos_index].copy(), data.qvel[mj.dof_index].copy()
        target = ddq_ref[k] + 400.0 * (q_ref[k] - q) + 40.0 * (dq_ref[k] - dq)
        data.qfrc_applied[mj.dof_index] = robot.rnea(q, dq, target)[0]
        mujoco.mj_step(mj.model, data)
        coupling.append(
            data.qpos[mj.model.jnt_qposadr[follower]] - (M * data.qpos[mj.qpos_index[1]] + O)
        )
        tracking.append(np.abs(q_ref[k] - q).max())
    assert np.abs(coupling).max() < 1e-3
    assert max(tracking) < 1e-2  # the reduced model is MuJoCo's dynamics: tight tracking
