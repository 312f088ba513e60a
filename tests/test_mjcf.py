"""The identified model's MJCF: loads without meshes, and MuJoCo's inverse dynamics equals the
estimate's prediction (rigid body + rotor inertia + viscous friction) to 1e-9 relative."""

import json

import mujoco
import numpy as np
import pytest
from test_urdf_update import ROBOTS, perturbed_theta, robot_under_test

from ident.errors import ModelError
from ident.identify.model_files.files import model_files, write_model_files
from ident.measure.mujoco_model import mujoco_urdf

PARITY = [
    "erd-tiago-torso-arm",
    "paper6r",
    "ur5",
    "panda-hand-locked",
    "tx40",
    "erd-z1-gripper-locked",
    "erd-kinova",
]


def _mj_inverse(model, joint_names, q, dq, ddq):
    """MuJoCo's inverse dynamics at the robot's joints, shape (n_samples, nv)."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in joint_names]
    qpos = np.array([model.jnt_qposadr[i] for i in ids])
    dof = np.array([model.jnt_dofadr[i] for i in ids])
    assert model.nv == len(joint_names)  # the locked joints are fixed
    data = mujoco.MjData(model)
    out = np.empty_like(dq)
    for k in range(q.shape[0]):
        data.qpos[qpos], data.qvel[dof], data.qacc[dof] = q[k], dq[k], ddq[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse[dof]
    return out, dof


@pytest.mark.parametrize("key", PARITY)
def test_mjcf_inverse_dynamics_equals_the_estimate(key):
    robot = robot_under_test(key)
    theta, names = perturbed_theta(robot, seed=11 + len(key))
    files = model_files(robot, theta, names, nominal=None)
    assert "<mesh" not in files.mjcf
    assert "<geom" not in files.mjcf
    model = mujoco.MjModel.from_xml_string(files.mjcf)  # no mesh file needed
    index = {n: i for i, n in enumerate(names)}
    n = robot.n_bodies
    ia, fv, fs = (
        np.array([theta[index[f"{p}{j}"]] for j in range(1, n + 1)]) for p in ("Ia", "fv", "fs")
    )
    q, dq, ddq = robot.random_configurations(40, rng=5)
    expected = robot.regressor(q, dq, ddq) @ theta[: 10 * n] + ia * ddq + fv * dq
    # friction loss is a constraint: off for the rigid-body + armature + damping comparison
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    got, dof = _mj_inverse(model, robot.joint_names, q, dq, ddq)
    scale = np.abs(expected).max()
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * scale)
    # the extras land where MuJoCo reads them
    np.testing.assert_array_equal(model.dof_armature[dof], ia)
    np.testing.assert_array_equal(model.dof_damping[dof], fv)
    np.testing.assert_array_equal(model.dof_frictionloss[dof], fs)
    # gravity and limits kept
    np.testing.assert_array_equal(model.opt.gravity, robot.model.gravity.linear)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in robot.joint_names]
    limited = np.isfinite(robot.q_lower)
    np.testing.assert_array_equal(model.jnt_range[ids][limited, 0], robot.q_lower[limited])
    np.testing.assert_array_equal(model.jnt_range[ids][limited, 1], robot.q_upper[limited])


def test_mjcf_of_a_light_body_with_a_scaled_hand():
    """Welded links scaled down (body lighter than the nominal hand): still exact."""
    robot = robot_under_test("panda-hand-locked")
    theta, names = perturbed_theta(robot, seed=3, scale={6: 0.1})
    files = model_files(robot, theta, names)
    assert files.urdf.welded_scale
    model = mujoco.MjModel.from_xml_string(files.mjcf)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.dof_damping[:] = model.dof_armature[:] = 0.0
    q, dq, ddq = robot.random_configurations(20, rng=2)
    expected = robot.regressor(q, dq, ddq) @ theta[:70]
    got, _ = _mj_inverse(model, robot.joint_names, q, dq, ddq)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())


def test_write_model_files_writes_three_files_or_none(tmp_path):
    robot = robot_under_test("ur5")
    theta, names = perturbed_theta(robot, seed=1)
    files = write_model_files(robot, theta, names, tmp_path, "ur5")
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "ur5_identified.urdf",
        "ur5_identified.xml",
        "ur5_joint_extras.json",
    ]
    extras = json.loads(files.paths["joint_extras"].read_text())
    index = {n: i for i, n in enumerate(names)}
    assert extras["joints"]["elbow_joint"]["offset"] == theta[index["off3"]]
    # an inconsistent estimate: an error and no file
    theta_ok = theta.copy()
    theta[0] = -1.0
    out = tmp_path / "bad"
    out.mkdir()
    with pytest.raises(ModelError, match="not physically consistent"):
        write_model_files(robot, theta, names, out, "ur5")
    assert list(out.iterdir()) == []
    write_model_files(robot, theta_ok, names, out, "ur5", suffix="consistent")
    assert sorted(p.name for p in out.iterdir()) == [
        "ur5_consistent.urdf",
        "ur5_consistent.xml",
        "ur5_joint_extras.json",
    ]


def test_mjcf_does_not_depend_on_impossible_inertials_of_fused_or_fixed_links(tmp_path):
    """Real files carry impossible inertials on links that never move or are welded to a
    moving one (MuJoCo refuses them): the MJCF puts each identified body on its joint's child
    link, the other links massless, and reproduces the estimate."""
    from ident.model import Robot

    text = ROBOTS["panda-hand-locked"][0].read_text()
    text = text.replace('ixx="0.00315"', 'ixx="-0.5"', 1)  # panda_link0, fixed to the world
    text = text.replace(  # panda_hand, welded to panda_link7: I1 + I2 < I3
        'ixx="0.001" ixy="0" ixz="0" iyy="0.0025" iyz="0" izz="0.0017"',
        'ixx="0.001" ixy="0" ixz="0" iyy="0.0025" iyz="0" izz="0.01"',
        1,
    )
    path = tmp_path / "panda.urdf"
    path.write_text(text)
    robot = Robot.from_urdf(
        path,
        lock_joints=ROBOTS["panda-hand-locked"][1]["lock_joints"],
        inertia_check=False,
    )
    with pytest.raises(ValueError, match="inertia"):  # the file's own inertials, no meshes
        mujoco.MjModel.from_xml_string(mujoco_urdf(text, robot.locked_joints, "panda"))
    theta, names = perturbed_theta(robot, seed=4)
    files = model_files(robot, theta, names)
    model = mujoco.MjModel.from_xml_string(files.mjcf)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.dof_damping[:] = model.dof_armature[:] = 0.0
    q, dq, ddq = robot.random_configurations(20, rng=1)
    expected = robot.regressor(q, dq, ddq) @ theta[:70]
    got, _ = _mj_inverse(model, robot.joint_names, q, dq, ddq)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())


def test_reload_parity_reports_the_files_errors():
    """The run-time check: ~1e-15 on the written files, large when a file is off."""
    import dataclasses

    from ident.identify.model_files.files import reload_parity

    robot = robot_under_test("panda-hand-locked")
    theta, names = perturbed_theta(robot, seed=9)
    files = model_files(robot, theta, names)
    parity = reload_parity(robot, files, theta, names, n_states=20)
    assert parity.urdf_relative_error < 1e-12
    assert parity.mjcf_relative_error < 1e-12
    # a URDF and an MJCF written from another estimate
    other_theta, _ = perturbed_theta(robot, seed=10)
    other = model_files(robot, other_theta, names)
    swapped = dataclasses.replace(files, urdf=other.urdf, mjcf=other.mjcf)
    parity = reload_parity(robot, swapped, theta, names, n_states=20)
    assert parity.urdf_relative_error > 1e-3
    assert parity.mjcf_relative_error > 1e-3


def test_tx40_coupled_wrist_motor_is_a_tendon():
    """The TX40's shared wrist motor (Iam6, fvm6 on joints 5 and 6) is a fixed tendon
    q5 + q6 in the MJCF: mj_inverse has its inertia and viscous terms exactly."""
    from ident.identify.model_files.files import reload_parity

    robot = robot_under_test("tx40")
    theta, names = perturbed_theta(robot, seed=21)
    theta = np.concatenate([theta, [0.07, 0.4, 0.9]])
    names = names + ("Iam6", "fvm6", "fsm6")
    with pytest.raises(ModelError, match="coupled_pair"):
        model_files(robot, theta, names)
    files = model_files(robot, theta, names, coupled_pair=(4, 5))
    (motor,) = json.loads(files.extras_json)["coupled_motors"]
    assert motor["joints"] == ["joint_5", "joint_6"]
    model = mujoco.MjModel.from_xml_string(files.mjcf)
    assert model.ntendon == 1
    assert (model.tendon_armature[0], model.tendon_damping[0]) == (0.07, 0.4)
    assert model.tendon_frictionloss[0] == 0.9
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    index = {n: i for i, n in enumerate(names)}
    q, dq, ddq = robot.random_configurations(30, rng=8)
    ia, fv = (np.array([theta[index[f"{p}{j}"]] for j in range(1, 7)]) for p in ("Ia", "fv"))
    expected = robot.regressor(q, dq, ddq) @ theta[:60] + ia * ddq + fv * dq
    for j in (4, 5):  # as ident.dynamics.friction's coupled columns
        expected[:, j] += 0.07 * (ddq[:, 4] + ddq[:, 5]) + 0.4 * (dq[:, 4] + dq[:, 5])
    got, _ = _mj_inverse(model, robot.joint_names, q, dq, ddq)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    parity = reload_parity(robot, files, theta, names, n_states=10)
    assert max(parity.urdf_relative_error, parity.mjcf_relative_error) < 1e-12
