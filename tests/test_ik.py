import dataclasses

import numpy as np
import pytest

from ident import Robot
from ident.errors import ModelError
from ident.excitation.ik import ArmGeometry, arm_inverse_kinematics

ROBOT = Robot.from_config("configs/paper6r.yaml")
GEOMETRY = ArmGeometry.from_dh(ROBOT.dh)


def _random_q(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(ROBOT.q_lower, ROBOT.q_upper, (n, 6))


def test_closed_form_kinematics_equal_dh_product():
    q = _random_q(200)
    frames = ROBOT.dh.forward_kinematics(q)
    np.testing.assert_allclose(GEOMETRY.wrist_centre(q[:, :3]), frames[:, 4, :3, 3], atol=1e-12)
    np.testing.assert_allclose(GEOMETRY.rotation_0_3(q[:, :3]), frames[:, 3, :3, :3], atol=1e-12)
    np.testing.assert_allclose(GEOMETRY.flange(q), frames[:, 6, :3, 3], atol=1e-12)
    assert GEOMETRY.d6 == pytest.approx(0.1275)


def test_fk_of_ik_reproduces_reachable_points():
    q = _random_q(500, seed=1)
    p = ROBOT.frame_positions(q, "wrist_centre")  # Pinocchio, independent of the closed form
    for elbow in (1, -1):
        sol = arm_inverse_kinematics(GEOMETRY, p, elbow=elbow)
        assert np.all(sol.excess == 0.0)
        q_full = np.concatenate([sol.q, np.zeros((500, 3))], axis=1)
        np.testing.assert_allclose(ROBOT.frame_positions(q_full, "wrist_centre"), p, atol=1e-9)
    # the elbow-up branch returns the original joints where q3 + gamma lies in [0, pi]
    sol = arm_inverse_kinematics(GEOMETRY, p, elbow=1)
    same = q[:, 2] + GEOMETRY.gamma >= 0
    rho = np.hypot(p[:, 0], p[:, 1])
    # front-shoulder configurations: the wrist centre is in front of joint 2's axis
    u = GEOMETRY.a2 * np.cos(q[:, 1]) + GEOMETRY.forearm * np.cos(
        q[:, 1] + q[:, 2] + GEOMETRY.gamma
    )
    front = GEOMETRY.a1 + u > 0
    pick = same & front & (rho > 1e-3)
    assert pick.sum() > 100
    diff = (sol.q[pick] - q[pick, :3] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(diff, 0.0, atol=1e-9)


def test_velocities_and_accelerations_are_exact():
    t = np.linspace(0.0, 2.0, 9)
    h = 1e-5

    def path(t):
        c = np.array([0.9, 0.3, 0.6])
        p = c + 0.1 * np.stack([np.cos(t), np.sin(2 * t), np.sin(t) * np.cos(t)], axis=-1)
        dp = 0.1 * np.stack([-np.sin(t), 2 * np.cos(2 * t), np.cos(2 * t)], axis=-1)
        ddp = 0.1 * np.stack([-np.cos(t), -4 * np.sin(2 * t), -2 * np.sin(2 * t)], axis=-1)
        return p, dp, ddp

    sol = arm_inverse_kinematics(GEOMETRY, *path(t))
    plus = arm_inverse_kinematics(GEOMETRY, *path(t + h))
    minus = arm_inverse_kinematics(GEOMETRY, *path(t - h))
    np.testing.assert_allclose(sol.dq, (plus.q - minus.q) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(sol.ddq, (plus.dq - minus.dq) / (2 * h), atol=1e-6)


def test_unreachable_points_flagged_and_finite():
    p = np.array([[3.0, 0.0, 0.3], [0.3, 0.0, 0.32], [0.0, 0.0, 5.0], [1e-6, 0.0, 0.0]])
    dp = np.tile([0.0, 1.0, 0.0], (4, 1))
    sol = arm_inverse_kinematics(GEOMETRY, p, dp, np.ones_like(p))
    for a in (sol.q, sol.dq, sol.ddq, sol.excess):
        assert np.all(np.isfinite(a))
    assert sol.excess[0] > 0.0  # beyond the outer shell
    assert sol.excess[1] > 0.0  # at the shoulder: inside the inner shell |a2 - L|
    assert sol.excess[2] > 0.0
    # reachable but next to joint 1's axis (shoulder singularity): finite, huge velocity
    assert sol.excess[3] == 0.0
    assert np.abs(sol.dq[3]).max() > 1e3


def test_non_paper_robots_rejected():
    with pytest.raises(ModelError, match="joint_fourier"):
        ArmGeometry.from_dh(None)
    dh = dataclasses.replace(ROBOT.dh, alpha=np.zeros(6))
    with pytest.raises(ModelError, match="alpha"):
        ArmGeometry.from_dh(dh)
    d = ROBOT.dh.d.copy()
    d[1] = 0.1
    with pytest.raises(ModelError, match="d2"):
        ArmGeometry.from_dh(dataclasses.replace(ROBOT.dh, d=d))


def test_unwrap_samples_is_numpy_unwrap_bit_for_bit():
    """Jumps of any size (several turns between samples, exactly pi, NaN) as np.unwrap."""
    from ident.excitation.ik import unwrap_samples

    rng = np.random.default_rng(0)
    for scale in (0.1, 1.0, 3.0, 10.0):
        steps = rng.normal(scale=scale, size=(5, 200, 3))
        angles = np.angle(np.exp(1j * np.cumsum(steps, axis=1)))
        angles[0, 5, 1] = np.nan
        angles[1, :, 0] = np.pi * (np.arange(200) % 3)  # steps of exactly +-pi, 2 pi
        np.testing.assert_array_equal(unwrap_samples(angles), np.unwrap(angles, axis=1))
