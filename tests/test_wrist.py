import numpy as np
import pytest

from ident import Robot
from ident.excitation.wrist import (
    PaperWristFamily,
    band_limited,
    sphere_point,
    theta6_eq23,
    wrist_angles,
)

ROBOT = Robot.from_config("configs/paper6r.yaml")

# Table 2 of the paper (wrist elites 1-6), rows a0(1..3), b0(1..3), c0, d0, e0 [mm, mm/s]
TABLE2 = np.array(
    [
        [-3.8711, -8.7566, -6.1829, -4.824, -6.7566, -4.4276],
        [9.8782, 1.1156, 5.7223, -2.4838, 3.1156, 4.0066],
        [0.42207, 4.5867, -4.0733, -3.0035, 3.748, -5.7368],
        [2.1907, 2.8328, 4.9482, 2.6421, 4.7319, 6.1336],
        [-3.5264, -7.3354, -2.4158, -1.0079, -5.3354, 5.1722],
        [-2.293, -7.4121, 0.31497, -3.5628, -5.4121, 0.91808],
        [6.5802, 5.4755, 6.423, 6.8105, 5.0595, 2.9898],
        [6.5802, 3.1097, 6.423, 0.85837, 5.0595, 2.9898],
        [0.0] * 6,
    ]
).T


@pytest.fixture(scope="module")
def family():
    return PaperWristFamily(ROBOT, n_samples=300)


def test_flange_on_the_sphere_and_fk_reproduces_it(family):
    batch = family.trajectories(TABLE2)
    wc = ROBOT.frame_positions(family.held_positions, "wrist_centre")[0]
    np.testing.assert_allclose(family.wrist_centre, wc, atol=1e-12)
    for i in range(6):
        flange = ROBOT.frame_positions(batch.q[i], "flange")  # Pinocchio FK
        np.testing.assert_allclose(flange, batch.traced_points[i], atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(flange - wc, axis=1), family.geometry.d6)
        # eq. 20: the DH z5 axis points from the wrist centre to the flange, -vec / d6
        z5 = ROBOT.dh.forward_kinematics(batch.q[i])[:, 5, :3, 2]
        np.testing.assert_allclose(
            z5, (batch.traced_points[i] - wc) / family.geometry.d6, atol=1e-9
        )
    np.testing.assert_array_equal(
        batch.q[:, :, :3], np.broadcast_to(family.held_positions[:3], (6, 300, 3))
    )
    assert family.traced_frame == "flange"
    assert family.variable_names[-1] == "e0"


def test_wrist_angle_derivatives_exact():
    t = np.linspace(0.1, 3.0, 8)
    h = 1e-5

    def direction(t):
        v = np.stack([np.cos(t), 0.5 * np.sin(2 * t), np.full_like(t, 0.7)], -1)
        n = np.linalg.norm(v, axis=-1, keepdims=True)
        return v / n

    w = direction(t)
    dw = (direction(t + h) - direction(t - h)) / (2 * h)
    ddw = (direction(t + h) - 2 * w + direction(t - h)) / h**2
    for branch in (1, -1):
        q, dq, ddq = wrist_angles(w, dw, ddw, branch)
        s5 = np.sin(q[:, 1])
        z5 = np.stack([-np.cos(q[:, 0]) * s5, -np.sin(q[:, 0]) * s5, np.cos(q[:, 1])], -1)
        np.testing.assert_allclose(z5, w, atol=1e-12)
        qp = wrist_angles(direction(t + h), dw, ddw, branch)[0]
        qm = wrist_angles(direction(t - h), dw, ddw, branch)[0]
        np.testing.assert_allclose(dq, (qp - qm) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(ddq, (qp - 2 * q + qm) / h**2, atol=1e-3)


def test_sphere_point_derivatives_and_reach():
    t = np.linspace(0, 1, 5)
    r = 0.1275

    def rel(t):
        return np.stack([0.05 * np.cos(t), 0.03 * np.sin(3 * t), 0 * t], -1)

    h = 1e-5
    d = (rel(t + h) - rel(t - h)) / (2 * h)
    dd = (rel(t + h) - 2 * rel(t) + rel(t - h)) / h**2
    p, dp, ddp, excess = sphere_point(rel(t), d, dd, r)
    np.testing.assert_allclose(np.linalg.norm(p, axis=-1), r)
    pp = sphere_point(rel(t + h), d, dd, r)[0]
    pm = sphere_point(rel(t - h), d, dd, r)[0]
    np.testing.assert_allclose(dp, (pp - pm) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(ddp, (pp - 2 * p + pm) / h**2, atol=1e-3)
    assert np.all(excess == 0)
    far = sphere_point(np.array([[0.2, 0.0, 0.0]]), np.zeros((1, 3)), np.zeros((1, 3)), r)
    assert far[3][0] == pytest.approx(0.2 / r - 1)
    assert np.all(np.isfinite(far[0]))


def test_eq23_initial_equals_last_and_winding():
    n, period = 40, 10.0
    theta = 2 * np.pi * np.arange(n) / n
    vec = np.stack([np.zeros(n), np.cos(theta), np.sin(theta)], -1)[None]  # circle in y-z
    q6, dq6, ddq6, winding = theta6_eq23(vec, period)
    # chord k joins samples k-1 and k; for k = 0 the previous sample is the last one
    expected = theta - np.pi / n + np.pi / 2
    np.testing.assert_allclose(np.exp(1j * q6[0]), np.exp(1j * expected), atol=1e-12)
    assert winding[0] == pytest.approx(2 * np.pi)
    np.testing.assert_allclose(dq6, 2 * np.pi / period, atol=1e-9)
    np.testing.assert_allclose(ddq6, 0.0, atol=1e-9)


def test_band_limited_keeps_low_harmonics_exactly():
    n, period = 64, 10.0
    t = np.arange(n) * period / n
    w = 2 * np.pi / period
    q = (np.sin(w * t) + 0.5 * np.cos(3 * w * t) + 0.2 * np.sin(9 * w * t))[None]
    smooth, dsmooth, ddsmooth = band_limited(
        q + 2 * np.pi * t / period, np.array([2 * np.pi]), period, 3
    )
    np.testing.assert_allclose(
        smooth[0], np.sin(w * t) + 0.5 * np.cos(3 * w * t) + w * t, atol=1e-12
    )
    np.testing.assert_allclose(
        dsmooth[0], w * np.cos(w * t) - 1.5 * w * np.sin(3 * w * t) + w, atol=1e-12
    )
    np.testing.assert_allclose(
        ddsmooth[0], -(w**2) * np.sin(w * t) - 4.5 * w**2 * np.cos(3 * w * t), atol=1e-12
    )


def test_theta6_modes(family):
    literal = PaperWristFamily(ROBOT, n_samples=300, theta6="eq23").trajectories(TABLE2)
    smooth = family.trajectories(TABLE2)
    hold = PaperWristFamily(ROBOT, n_samples=300, theta6="hold").trajectories(TABLE2)
    np.testing.assert_allclose(literal.q[:, :, 3:5], smooth.q[:, :, 3:5])
    assert np.all(hold.q[:, :, 5] == 0.0)
    assert np.all(hold.dq[:, :, 5] == 0.0)
    # the literal eq. 23 jumps: far beyond joint 6's velocity limit; the smooth one is not
    assert np.abs(literal.dq[:, :, 5]).max() > 3 * ROBOT.dq_max[5]
    assert np.abs(smooth.dq[:, :, 5]).max() < ROBOT.dq_max[5]
    assert smooth.violations.feasible()[2]  # Table 2, elite 3, is feasible
    with pytest.raises(ValueError, match="theta6"):
        PaperWristFamily(ROBOT, theta6="nope")


def test_unreachable_flange_flagged(family):
    x = TABLE2[:1].copy()
    x[0, 7] = 200.0  # d0 = 200 mm > d6
    batch = family.trajectories(x)
    assert np.all(np.isfinite(batch.q))
    assert batch.violations.as_dict(0)["reachability"] > 0.5
