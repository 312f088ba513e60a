import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import ERD_ROBOTS as ERD

from ident import Robot
from ident.errors import ConfigError, DataError, ModelError
from ident.model import continuous_as_revolute
from ident.robot.inertia import PAPER_TO_PINOCCHIO, pinocchio_to_paper
from ident.robot.robot_config import load_robot_config

DATA = Path("tests/data/robots")
PAPER = Path("configs/paper6r.yaml")
CONFIGS = [PAPER, DATA / "puma_modified.yaml", DATA / "rpr.yaml"]


@pytest.fixture(scope="module")
def paper():
    return Robot.from_config(PAPER)


def test_paper_robot_attributes(paper):
    assert paper.name == "paper6r"
    assert (paper.nq, paper.nv, paper.n_bodies) == (6, 6, 6)
    assert paper.joint_names == tuple(f"joint_{i}" for i in range(1, 7))
    assert paper.dh is not None
    assert paper.urdf_path is None
    np.testing.assert_allclose(np.rad2deg(paper.q_upper), [165, 110, 70, 160, 120, 242])
    np.testing.assert_allclose(np.rad2deg(paper.ddq_max), [300, 320, 340, 640, 800, 920])
    np.testing.assert_allclose(paper.model.gravity.linear, [0, 0, -9.81])
    assert paper.urdf_text == Path("robot/urdf/paper6r.urdf").read_text()


def test_gravity_comes_from_config():
    robot = Robot.from_config(DATA / "planar2r.yaml")
    np.testing.assert_allclose(robot.model.gravity.linear, [0, -9.81, 0])


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_parameters_are_the_config_bodies(path):
    """Model parameters equal each config body moved from DH frame i by Pinocchio's SE3 action."""
    robot = Robot.from_config(path)
    description = load_robot_config(path)
    expected = []
    for i in range(robot.n_bodies):
        body = pin.Inertia(description.mass[i], description.com[i], description.inertia_com[i])
        if description.dh.convention == "standard":
            dh_in_link = pin.SE3(description.dh.fixed_transform(i))
            body = dh_in_link.act(body)
        expected.append(body.toDynamicParameters())
    np.testing.assert_allclose(robot.parameters(), np.concatenate(expected), rtol=0, atol=1e-15)
    mapped = robot.dh_to_model_parameters() @ robot.parameters_dh()
    np.testing.assert_allclose(mapped, robot.parameters(), rtol=0, atol=1e-15)


def test_paper_parameters_in_dh_frames_reproduce_eq25_26(paper):
    by_link = pinocchio_to_paper(paper.parameters_dh().reshape(6, 10))
    np.testing.assert_allclose(
        by_link[:, 0], [5.029912009, 4.530794148, 3.05678343, 1.815211338, 0.990530741, 0.186899621]
    )
    np.testing.assert_allclose(by_link[1, 1:4] * 1e3, [-44.1094, 93.9465, 183.7506])
    np.testing.assert_allclose(PAPER_TO_PINOCCHIO @ by_link[2], paper.parameters_dh()[20:30])


def _energies_from_dh(description, q, dq, h=1e-6):
    """Kinetic and potential energy from the DH product alone (finite-difference velocities)."""
    frames = description.dh.forward_kinematics(np.stack([q - h * dq, q, q + h * dq]))
    kinetic, potential = 0.0, 0.0
    for i in range(description.n_joints):
        before, now, after = frames[0, i + 1], frames[1, i + 1], frames[2, i + 1]
        rotation, position = now[:3, :3], now[:3, 3]
        com = position + rotation @ description.com[i]
        com_velocity = (
            (after[:3, 3] + after[:3, :3] @ description.com[i])
            - (before[:3, 3] + before[:3, :3] @ description.com[i])
        ) / (2 * h)
        omega_skew = (after[:3, :3] - before[:3, :3]) / (2 * h) @ rotation.T
        omega = np.array([omega_skew[2, 1], omega_skew[0, 2], omega_skew[1, 0]])
        inertia_world = rotation @ description.inertia_com[i] @ rotation.T
        kinetic += 0.5 * description.mass[i] * com_velocity @ com_velocity
        kinetic += 0.5 * omega @ inertia_world @ omega
        potential -= description.mass[i] * description.gravity @ com
    return kinetic, potential


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_pinocchio_energies_equal_dh_energies(path):
    """The URDF's bodies move like the config's bodies on the DH chain (independent check)."""
    robot = Robot.from_config(path)
    description = robot.description
    data = robot.model.createData()
    q, dq, _ = robot.random_configurations(5, rng=4)
    for k in range(q.shape[0]):
        kinetic, potential = _energies_from_dh(description, q[k], dq[k])
        pin.computeAllTerms(robot.model, data, q[k], dq[k])
        mass_matrix = np.triu(data.M) + np.triu(data.M, 1).T
        assert abs(0.5 * dq[k] @ mass_matrix @ dq[k] - kinetic) < 1e-7 * (1 + abs(kinetic))
        assert abs(pin.computePotentialEnergy(robot.model, data, q[k]) - potential) < 1e-10


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_regressor_times_parameters_is_rnea(path):
    robot = Robot.from_config(path)
    q, dq, ddq = robot.random_configurations(20, rng=0)
    regressor = robot.regressor(q, dq, ddq)
    assert regressor.shape == (20, robot.nv, 10 * robot.n_bodies)
    tau = robot.rnea(q, dq, ddq)
    scale = np.abs(tau).max()
    np.testing.assert_allclose(regressor @ robot.parameters(), tau, rtol=0, atol=1e-10 * scale)
    data = robot.model.createData()
    for k in range(3):
        expected = pin.computeJointTorqueRegressor(robot.model, data, q[k], dq[k], ddq[k])
        np.testing.assert_allclose(regressor[k], expected, rtol=0, atol=1e-10 * scale)


def test_rnea_single_state_and_shape_errors(paper):
    tau = paper.rnea(np.zeros(6), np.zeros(6), np.zeros(6))
    assert tau.shape == (1, 6)
    with pytest.raises(DataError, match=r"dq must have shape \(3, 6\)"):
        paper.rnea(np.zeros((3, 6)), np.zeros((2, 6)), np.zeros((3, 6)))
    with pytest.raises(DataError, match=r"q must have shape \(n_samples, 6\)"):
        paper.frame_positions(np.zeros((3, 5)), "flange")


def test_frame_positions_equal_dh_product(paper):
    q, _, _ = paper.random_configurations(25, rng=1)
    frames = paper.dh.forward_kinematics(q)
    np.testing.assert_allclose(paper.frame_positions(q, "flange"), frames[:, -1, :3, 3], atol=1e-12)
    np.testing.assert_allclose(paper.frame_placements(q, "flange"), frames[:, -1], atol=1e-12)
    np.testing.assert_allclose(
        paper.frame_positions(q, "wrist_centre"), frames[:, 4, :3, 3], atol=1e-12
    )


def test_unknown_frame_lists_frames(paper):
    with pytest.raises(ModelError, match="did you mean 'flange'.*available frames: .*wrist_centre"):
        paper.frame_positions(np.zeros(6), "flang")


def test_random_configurations_within_limits_and_reproducible(paper):
    q, dq, ddq = paper.random_configurations(500, rng=7)
    assert q.shape == dq.shape == ddq.shape == (500, 6)
    assert np.all((q >= paper.q_lower) & (q <= paper.q_upper))
    assert np.all(np.abs(dq) <= paper.dq_max)
    assert np.all(np.abs(ddq) <= paper.ddq_max)
    again = paper.random_configurations(500, rng=np.random.default_rng(7))
    for a, b in zip((q, dq, ddq), again, strict=True):
        np.testing.assert_array_equal(a, b)


def test_from_urdf_matches_from_config(paper):
    loaded = Robot.from_urdf("robot/urdf/paper6r.urdf")
    assert loaded.urdf_path == Path("robot/urdf/paper6r.urdf")
    assert loaded.dh is None
    assert loaded.joint_names == paper.joint_names
    np.testing.assert_array_equal(loaded.parameters(), paper.parameters())
    np.testing.assert_array_equal(loaded.q_lower, paper.q_lower)
    np.testing.assert_array_equal(loaded.dq_max, paper.dq_max)
    assert np.all(np.isinf(loaded.ddq_max))  # URDFs carry no acceleration limits
    with pytest.raises(ModelError, match="has no DH table"):
        loaded.parameters_dh()


@pytest.mark.parametrize(
    "relative", ["ur_description/urdf/ur5_robot.urdf", "ur_description/urdf/ur10_robot.urdf"]
)
def test_third_party_urdf(relative):
    robot = Robot.from_urdf(ERD / relative)
    assert robot.nq == 6
    q, dq, ddq = robot.random_configurations(10, rng=2)
    assert np.all(np.isfinite(q))
    tau = robot.rnea(q, dq, ddq)
    np.testing.assert_allclose(
        robot.regressor(q, dq, ddq) @ robot.parameters(),
        tau,
        rtol=0,
        atol=1e-10 * np.abs(tau).max(),
    )
    model = pin.buildModelFromUrdf(str(ERD / relative))
    data = model.createData()
    pin.framesForwardKinematics(model, data, q[0])
    tool = model.frames[-1].name
    np.testing.assert_allclose(robot.frame_positions(q[:1], tool)[0], data.oMf[-1].translation)


def test_branched_third_party_urdf_is_refused():
    path = ERD / "panda_description/urdf/panda.urdf"
    with pytest.raises(ModelError, match=r"panda.urdf: .*branched"):
        Robot.from_urdf(path)


_TWO_LINKS = """<robot name="t"><link name="a"/><link name="b">
<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
</link><joint name="j" type="{kind}"><parent link="a"/><child link="b"/>{extra}</joint></robot>"""
_LIMIT = "<axis xyz='0 0 1'/><limit lower='-1' upper='1' effort='1' velocity='1'/>"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("<robot name='x'><link name='a'/>", "malformed URDF XML"),
        ("<sdf version='1.6'/>", "root element is <sdf>"),
        ("<robot name='x'><link name='a'/></robot>", "no moving joint"),
        (_TWO_LINKS.format(kind="floating", extra=""), "floating base"),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace('value="1"', 'value="-1"'),
            r"link 'b': the <inertial> is physically impossible: mass = -1 kg must be > 0",
        ),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace('izz="1"', 'izz="5"'),
            r"link 'b': .*triangle inequality I1 \+ I2 >= I3 \(1 \+ 1 < 5",
        ),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace('izz="1"', 'izz="-1"'),
            r"link 'b': .*not positive semi-definite",
        ),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace('ixy="0"', 'ixy="x"'),
            r"link 'b': the <inertial> has a value that is not a number",
        ),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace(
                'child link="b"', 'child link="c"'
            ),
            r"child link \[c\] of joint \[j\] not found",
        ),
        (  # a missing <limit> is unknown (tests/test_urdf_limits.py); a swapped one is not
            _TWO_LINKS.format(
                kind="revolute", extra='<limit lower="1" upper="-1" effort="1" velocity="1"/>'
            ),
            r"joint 'j': <limit lower=\"1\" upper=\"-1\">: lower is above upper",
        ),
    ],
)
def test_bad_urdfs(tmp_path, capfd, text, expected):
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    with pytest.raises(ModelError, match=expected) as info:
        Robot.from_urdf(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)
    assert capfd.readouterr().err == ""  # the parser's own complaints are in the message


def test_missing_files(tmp_path):
    with pytest.raises(ModelError, match="URDF file not found"):
        Robot.from_urdf(tmp_path / "nope.urdf")
    with pytest.raises(ConfigError, match="config file not found"):
        Robot.from_config(tmp_path / "nope.yaml")


def test_parameter_names(paper):
    names = paper.parameter_names()
    assert len(names) == paper.parameters().size == 60
    assert names[:4] == ("m1", "mcx1", "mcy1", "mcz1")
    assert names[-1] == "Izz6"


# ---------------------------------------------------------------- third-party URDFs
ARMS = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "talos_left_arm": "talos_data/robots/talos_left_arm.urdf",
    "so100": "so_arm_description/urdf/so100.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "double_pendulum_continuous": (
        "double_pendulum_description/urdf/double_pendulum_continuous.urdf"
    ),
}
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")


def test_real_arms_pass_the_inertial_check_at_its_tolerance():
    """Every link inertial of the arms we test (read by yourdfpy) is consistent even at the
    strict 1e-9 default: the URDF_INERTIA_RTOL of 1e-6 is round-off room, not needed here."""
    import yourdfpy

    from ident.model import URDF_INERTIA_RTOL
    from ident.robot.inertia import consistency_problems, parameters_from_com

    assert URDF_INERTIA_RTOL == 1e-6
    for relative in (*ARMS.values(), "panda_description/urdf/panda.urdf"):
        urdf = yourdfpy.URDF.load(str(ERD / relative), build_scene_graph=False, load_meshes=False)
        checked = 0
        for link in urdf.robot.links:
            inertial = link.inertial
            if inertial is None or (inertial.mass == 0 and not np.any(inertial.inertia)):
                continue
            params = parameters_from_com(inertial.mass, np.zeros(3), inertial.inertia)
            assert consistency_problems(params) == [], (relative, link.name)
            checked += 1
        assert checked >= 2, relative
    lock = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    assert Robot.from_urdf(ERD / "panda_description/urdf/panda.urdf", lock_joints=lock).nq == 7


@pytest.mark.parametrize("name", ["kinova", "double_pendulum_continuous"])
def test_continuous_joints_match_the_original_unbounded_model(name):
    """Regressor, torques and FK of the revolute rewrite equal Pinocchio's on the ORIGINAL model
    (continuous joints as (cos, sin)) at the corresponding states."""
    path = ERD / ARMS[name]
    robot = Robot.from_urdf(path)
    original = pin.buildModelFromUrdf(str(path))
    unbounded = [
        original.names[j] for j in range(1, original.njoints) if original.joints[j].nq == 2
    ]
    assert unbounded
    assert robot.continuous_joints == tuple(unbounded)
    assert robot.nq == robot.nv == original.nv < original.nq
    assert robot.joint_names == tuple(original.names[1:])
    for joint in unbounded:
        index = robot.joint_names.index(joint)
        assert np.isinf(robot.q_lower[index])
        assert np.isinf(robot.q_upper[index])
        assert np.isinf(robot.chain.q_lower[index])
        assert np.isinf(robot.chain.q_upper[index])
    q, dq, ddq = robot.random_configurations(8, rng=5)
    q[0, :] = 3.0  # beyond pi on every continuous joint
    q_original = np.empty((q.shape[0], original.nq))
    for j in range(1, original.njoints):
        joint = original.joints[j]
        angle = q[:, j - 1]
        if joint.nq == 2:
            q_original[:, joint.idx_q] = np.cos(angle)
            q_original[:, joint.idx_q + 1] = np.sin(angle)
        else:
            q_original[:, joint.idx_q] = angle
    regressor = robot.regressor(q, dq, ddq)
    data = original.createData()
    tip = original.frames[-1].name
    for k in range(q.shape[0]):
        expected = pin.computeJointTorqueRegressor(original, data, q_original[k], dq[k], ddq[k])
        scale = np.abs(expected).max()
        np.testing.assert_allclose(regressor[k], expected, rtol=0, atol=1e-10 * scale)
        tau = pin.rnea(original, data, q_original[k], dq[k], ddq[k])
        np.testing.assert_allclose(robot.rnea(q[k], dq[k], ddq[k])[0], tau, atol=1e-10 * scale)
        pin.framesForwardKinematics(original, data, q_original[k])
        np.testing.assert_allclose(
            robot.frame_placements(q[k], tip)[0], data.oMf[-1].homogeneous, atol=1e-12
        )
    np.testing.assert_allclose(
        robot.parameters(),
        np.concatenate(
            [original.inertias[j].toDynamicParameters() for j in range(1, original.njoints)]
        ),
    )


def test_continuous_fixture_keeps_effort_and_velocity():
    robot = Robot.from_urdf(Path("tests/data/urdf/continuous.urdf"))
    assert robot.continuous_joints == ("wheel_joint",)
    assert robot.nq == 1
    assert np.isinf(robot.q_lower[0])
    assert np.isinf(robot.dq_max[0])
    # urdf_text is the file as written; the model is built from a revolute rewrite of it
    assert robot.urdf_text == Path("tests/data/urdf/continuous.urdf").read_text()
    root = ET.fromstring(robot.urdf_text)
    rewritten, names = continuous_as_revolute(root, robot.urdf_text)
    assert names == ("wheel_joint",)
    assert 'type="continuous"' not in rewritten
    assert 'type="revolute"' in rewritten
    assert 'effort="0" velocity="0"' in rewritten
    kinova = Robot.from_urdf(ERD / ARMS["kinova"])
    original = pin.buildModelFromUrdf(str(ERD / ARMS["kinova"]))
    np.testing.assert_allclose(kinova.dq_max, original.velocityLimit)
    np.testing.assert_allclose(kinova.model.effortLimit, original.effortLimit)


def test_locked_panda_fingers_follow_their_values():
    """The fingers are held where asked: FK of the locked model equals the full model's."""
    path = ERD / "panda_description/urdf/panda.urdf"
    full = pin.buildModelFromUrdf(str(path))
    data = full.createData()
    for values in ({FINGERS[0]: 0.0, FINGERS[1]: 0.0}, {FINGERS[0]: 0.01, FINGERS[1]: 0.035}):
        robot = Robot.from_urdf(path, lock_joints=values)
        assert robot.nq == 7
        assert robot.locked_joints == values
        q, dq, ddq = robot.random_configurations(4, rng=1)
        tau = robot.rnea(q, dq, ddq)
        np.testing.assert_allclose(
            robot.regressor(q, dq, ddq) @ robot.parameters(), tau, atol=1e-10 * np.abs(tau).max()
        )
        for k in range(q.shape[0]):
            q_full = np.concatenate([q[k], [values[FINGERS[0]], values[FINGERS[1]]]])
            pin.framesForwardKinematics(full, data, q_full)
            for link in ("panda_leftfinger", "panda_rightfinger"):
                np.testing.assert_allclose(
                    robot.frame_placements(q[k], link)[0],
                    data.oMf[full.getFrameId(link)].homogeneous,
                    atol=1e-12,
                )
    # the leader finger locked: the other mimics it (multiplier 1), so it is locked with it
    one = Robot.from_urdf(path, lock_joints={FINGERS[0]: 0.03})
    assert one.nq == 7
    assert one.locked_joints == {FINGERS[0]: 0.03, FINGERS[1]: 0.03}
    # names only: locked at 0
    assert Robot.from_urdf(path, lock_joints=list(FINGERS)).locked_joints == dict.fromkeys(
        FINGERS, 0.0
    )


@pytest.mark.parametrize(
    ("lock", "expected"),
    [
        (["panda_finger_joint3"], r"cannot lock joint 'panda_finger_joint3'.*did you mean"),
        ({"panda_finger_joint1": 0.5}, r"locked at 0.5, outside its limits \[0, 0.04\]"),
        (["panda_finger_joint1", "panda_finger_joint1"], "locked twice"),
        (["panda_joint7"], r"--lock panda_finger_joint1 --lock panda_finger_joint2"),
    ],
)
def test_bad_locks(lock, expected):
    path = ERD / "panda_description/urdf/panda.urdf"
    with pytest.raises(ModelError, match=expected) as info:
        Robot.from_urdf(path, lock_joints=lock)
    assert str(info.value).startswith(str(path))


def test_suggested_locks_follow_the_longest_branch():
    from ident.model import suggested_locks

    assert suggested_locks(pin.buildModelFromUrdf(str(ERD / ARMS["ur5"]))) == ()
    panda = pin.buildModelFromUrdf(str(ERD / "panda_description/urdf/panda.urdf"))
    assert suggested_locks(panda) == FINGERS
    branched = pin.buildModelFromUrdf("tests/data/urdf/branched.urdf")
    assert suggested_locks(branched) == ("right_joint",)
    # an arm on a base that also carries a one-joint branch: lock the short branch only
    model = pin.Model()
    first = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "a1")
    model.addJoint(first, pin.JointModelRY(), pin.SE3.Identity(), "a2")
    model.addJoint(0, pin.JointModelRX(), pin.SE3.Identity(), "side")
    assert suggested_locks(model) == ("side",)
    assert Robot.from_urdf("tests/data/urdf/branched.urdf", lock_joints=["right_joint"]).nq == 1


@pytest.mark.parametrize("name", ["ur5", "xarm7", "kinova"])
def test_forward_kinematics_agree_with_yourdfpy(name):
    """Every link's pose from Robot (Pinocchio) equals yourdfpy's, an independent URDF FK
    (kinova: yourdfpy reads its continuous joints itself, as angles)."""
    import yourdfpy

    path = ERD / ARMS[name]
    robot = Robot.from_urdf(path)
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, load_collision_meshes=False)
    assert tuple(urdf.actuated_joint_names) == robot.joint_names
    links = [
        f.name
        for f in robot.model.frames
        if f.type == pin.FrameType.BODY and f.name != urdf.base_link
    ]
    assert len(links) >= robot.nq
    q, _, _ = robot.random_configurations(5, rng=11)
    for k in range(q.shape[0]):
        urdf.update_cfg(q[k])
        for link in links:
            np.testing.assert_allclose(
                robot.frame_placements(q[k], link)[0],
                urdf.get_transform(link, urdf.base_link),
                rtol=0,
                atol=1e-9,
                err_msg=f"{name} {link}",
            )
