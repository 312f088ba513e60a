from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import ERD_ROBOTS as ERD

from ident import Robot
from ident.errors import ConfigError, DataError, ModelError
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
        (_TWO_LINKS.format(kind="continuous", extra="<axis xyz='0 0 1'/>"), "continuous"),
        (
            _TWO_LINKS.format(kind="revolute", extra=_LIMIT).replace(
                'child link="b"', 'child link="c"'
            ),
            r"child link \[c\] of joint \[j\] not found",
        ),
        (
            _TWO_LINKS.format(kind="revolute", extra=""),
            r"Joint \[j\] is of type REVOLUTE but it does not specify limits",
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
