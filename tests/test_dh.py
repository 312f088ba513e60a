import numpy as np
import pytest

from ident.errors import ModelError
from ident.robot.dh import DHTable, rot_x, trans_x
from ident.robot.robot_config import load_robot_config

PAPER = "configs/paper6r.yaml"


def _classic_standard_matrix(theta, d, a, alpha):
    """Textbook standard DH link matrix (Spong), written out entry by entry."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _classic_modified_matrix(alpha_prev, a_prev, theta, d):
    """Textbook modified DH link matrix (Craig eq. 3.6)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha_prev), np.sin(alpha_prev)
    return np.array(
        [
            [ct, -st, 0.0, a_prev],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _random_table(rng, convention, n=5, prismatic=()):
    return DHTable(
        convention=convention,
        a=rng.uniform(-1, 1, n),
        d=rng.uniform(-1, 1, n),
        alpha=rng.uniform(-np.pi, np.pi, n),
        theta=rng.uniform(-np.pi, np.pi, n),
        joint_types=tuple("prismatic" if i in prismatic else "revolute" for i in range(n)),
    )


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_link_transforms_match_textbook_matrices(convention):
    rng = np.random.default_rng(0)
    table = _random_table(rng, convention, prismatic=(2,))
    q = rng.uniform(-2, 2, (7, table.n_joints))
    links = table.link_transforms(q)
    for k in range(q.shape[0]):
        for i in range(table.n_joints):
            theta = table.theta[i] + (q[k, i] if i != 2 else 0.0)
            d = table.d[i] + (q[k, i] if i == 2 else 0.0)
            if convention == "standard":
                expected = _classic_standard_matrix(theta, d, table.a[i], table.alpha[i])
            else:
                expected = _classic_modified_matrix(table.alpha[i], table.a[i], theta, d)
            np.testing.assert_allclose(links[k, i], expected, atol=1e-14)


def test_planar_two_link_closed_form():
    robot = load_robot_config("tests/data/robots/planar2r.yaml")
    rng = np.random.default_rng(1)
    q = rng.uniform(-2.5, 2.5, (20, 2))
    tip = robot.dh.forward_kinematics(q)[:, -1, :3, 3]
    x = 0.4 * np.cos(q[:, 0]) + 0.3 * np.cos(q[:, 0] + q[:, 1])
    y = 0.4 * np.sin(q[:, 0]) + 0.3 * np.sin(q[:, 0] + q[:, 1])
    np.testing.assert_allclose(tip, np.stack([x, y, np.zeros(20)], axis=1), atol=1e-15)


def test_standard_equals_modified_rewrite():
    """A standard table rewritten in Craig's convention gives the same flange pose."""
    rng = np.random.default_rng(2)
    std = _random_table(rng, "standard", n=6, prismatic=(1,))
    mod = DHTable(
        convention="modified",
        a=np.r_[0.0, std.a[:-1]],
        alpha=np.r_[0.0, std.alpha[:-1]],
        d=std.d,
        theta=std.theta,
        joint_types=std.joint_types,
    )
    q = rng.uniform(-2, 2, (10, 6))
    tool = trans_x(std.a[-1])[0] @ rot_x(std.alpha[-1])[0]
    np.testing.assert_allclose(
        std.forward_kinematics(q)[:, -1], mod.forward_kinematics(q)[:, -1] @ tool, atol=1e-13
    )


def test_paper_robot_known_poses():
    dh = load_robot_config(PAPER).dh
    # q = 0: the forearm (d4 + d6 = 0.825 m) hangs down from the elbow at x = 1.0 m, z = 0.32 m
    flange = dh.forward_kinematics(np.zeros(6))[0, -1]
    np.testing.assert_allclose(flange[:3, 3], [1.0, 0.0, 0.32 - 0.825], atol=1e-15)
    # q3 = -90 deg: the forearm is horizontal and the arm fully stretched along x
    q = np.array([0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(dh.forward_kinematics(q)[0, -1, :3, 3], [1.825, 0, 0.32], atol=1e-15)
    # joint 1 turns the whole arm about the base z axis
    q1 = np.array([0.7, 0.3, -0.4, 0.2, 0.5, -0.1])
    q0 = q1.copy()
    q0[0] = 0.0
    p1 = dh.forward_kinematics(q1)[0, -1, :3, 3]
    p0 = dh.forward_kinematics(q0)[0, -1, :3, 3]
    c, s = np.cos(0.7), np.sin(0.7)
    np.testing.assert_allclose(
        p1, [c * p0[0] - s * p0[1], s * p0[0] + c * p0[1], p0[2]], atol=1e-15
    )


def test_paper_wrist_axes_intersect_at_frame_4():
    dh = load_robot_config(PAPER).dh
    rng = np.random.default_rng(3)
    frames = dh.forward_kinematics(rng.uniform(-1, 1, (5, 6)))
    centre = frames[:, 4, :3, 3]
    for joint in (4, 5, 6):  # axis of joint i is z of DH frame i-1
        origin, axis = frames[:, joint - 1, :3, 3], frames[:, joint - 1, :3, 2]
        offset = centre - origin
        distance = np.linalg.norm(offset - np.sum(offset * axis, axis=1)[:, None] * axis, axis=1)
        np.testing.assert_allclose(distance, 0.0, atol=1e-15)


def test_forward_kinematics_accepts_one_configuration():
    dh = load_robot_config(PAPER).dh
    assert dh.forward_kinematics(np.zeros(6)).shape == (1, 7, 4, 4)
    with pytest.raises(ModelError, match=r"shape \(n_samples, 6\)"):
        dh.forward_kinematics(np.zeros((3, 5)))


def test_table_checks():
    with pytest.raises(ModelError, match="has 2 rows for 3 joints"):
        DHTable("standard", np.zeros(2), np.zeros(3), np.zeros(3), np.zeros(3), ("revolute",) * 3)
    with pytest.raises(ModelError, match="convention"):
        DHTable("craig", np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), ("revolute",))
    with pytest.raises(ModelError, match="type 'spherical'"):
        DHTable("standard", np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1), ("spherical",))
