import numpy as np
import pytest

from ident import Robot
from ident.excitation.mfs import PaperArmFamily, mfs_path, mfs_variable_names

ROBOT = Robot.from_config("configs/paper6r.yaml")
OMEGA = 2 * np.pi / 10

# Table 3 of the paper (arm elites 1-6), rows a0(1..3), b0(1..3), c0, d0, e0, f0 [mm, mm/s]
TABLE3 = np.array(
    [
        [-1.2742, 5.2376, -3.2742, -2.8265, 0.72577, -3.2742],
        [-6.5754, 6.2129, -4.5754, -6.5754, -8.5754, -8.5754],
        [-9.0638, 8.2042, -7.0638, -9.0638, -6.8925, -6.7108],
        [-0.4967, 6.2173, 1.5033, -0.4967, 1.5033, -2.4967],
        [4.5411, -2.6712, 2.6293, 2.9774, 2.5411, 6.5411],
        [-1.6233, -7.73, -0.74646, 1.2535, -3.6233, 0.37674],
        [3.0295, 1.4518, 1.0295, 1.7199, 1.0295, 1.0295],
        [0.0] * 6,
        [173.11, 101.03, 184.34, 187.21, 188.04, 166.14],
        [5.7001, 6.0889, 1.0295, 1.7199, 1.0295, 1.0295],
    ]
).T


def _coefficients(seed=0, n=4):
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-0.01, 0.01, (2, n, 3))
    c = rng.uniform(0, 0.01, n)
    centre = rng.uniform(-1, 1, (n, 3))
    return a, b, c, centre


def test_closed_form_matches_equations_and_derivatives():
    a, b, c, centre = _coefficients()
    t = np.linspace(0.0, 10.0, 11)
    q, dq, ddq = mfs_path(t, a, b, c, centre, OMEGA)
    # eq. 16 written out for particle 0
    j = np.arange(1, 4)
    f = sum(b[0, k] / (OMEGA * j[k]) * np.sin(OMEGA * j[k] * t) for k in range(3)) - sum(
        c[0] / (OMEGA * j[k]) * np.cos(OMEGA * j[k] * t) for k in range(3)
    )
    np.testing.assert_allclose(q[0, :, 0], centre[0, 0] + a[0].sum() * np.cos(OMEGA * t) + f)
    np.testing.assert_allclose(q[0, :, 1], centre[0, 1] + a[0].sum() * np.sin(OMEGA * t) + f)
    np.testing.assert_allclose(q[0, :, 2], centre[0, 2] + f)
    h = 1e-4
    qp, dqp, _ = mfs_path(t + h, a, b, c, centre, OMEGA)
    qm, dqm, _ = mfs_path(t - h, a, b, c, centre, OMEGA)
    np.testing.assert_allclose(dq, (qp - qm) / (2 * h), atol=1e-10)
    np.testing.assert_allclose(ddq, (dqp - dqm) / (2 * h), atol=1e-10)


def test_periodic_and_only_the_radius_sum_matters():
    a, b, c, centre = _coefficients(1)
    start = mfs_path(np.array([0.0]), a, b, c, centre, OMEGA)
    end = mfs_path(np.array([10.0]), a, b, c, centre, OMEGA)
    for s, e in zip(start, end, strict=True):
        np.testing.assert_allclose(e, s, atol=1e-14)
    t = np.linspace(0, 10, 7)
    shuffled = mfs_path(t, a[:, ::-1], b, c, centre, OMEGA)
    for x, y in zip(mfs_path(t, a, b, c, centre, OMEGA), shuffled, strict=True):
        np.testing.assert_allclose(x, y, atol=1e-15)
    flat = mfs_path(t, a, b, c, centre, OMEGA, fourier_z=False)[0]
    np.testing.assert_allclose(flat[..., 2], np.broadcast_to(centre[:, None, 2], (4, 7)))


def test_circle_when_no_harmonics():
    a = np.array([[0.02, 0.01, 0.0]])
    zero = np.zeros((1, 3))
    q, _, _ = mfs_path(
        np.linspace(0, 10, 50), a, zero, np.zeros(1), np.array([[0.1, 0.2, 0.3]]), OMEGA
    )
    np.testing.assert_allclose(np.hypot(q[0, :, 0] - 0.1, q[0, :, 1] - 0.2), 0.03)
    np.testing.assert_allclose(q[0, :, 2], 0.3)


def test_variable_names():
    assert mfs_variable_names(3, with_f0=True) == (
        "a0(1)", "a0(2)", "a0(3)", "b0(1)", "b0(2)", "b0(3)", "c0", "d0", "e0", "f0",
    )  # fmt: skip


def test_arm_family_traces_the_wrist_centre():
    family = PaperArmFamily(ROBOT, n_samples=200)
    assert family.traced_frame == "wrist_centre"
    assert family.bounds.shape == (10, 2)
    batch = family.trajectories(TABLE3)
    assert batch.q.shape == (6, 200, 6)
    for i in range(6):
        fk = ROBOT.frame_positions(batch.q[i], "wrist_centre")
        np.testing.assert_allclose(fk, batch.traced_points[i], atol=1e-9)
    # Table 3's elites (mm) respect every constraint of configs/paper6r.yaml
    assert np.all(batch.violations.feasible())
    np.testing.assert_array_equal(batch.q[:, :, 3:], 0.0)  # wrist held


def test_arm_family_velocities_consistent_with_positions():
    family = PaperArmFamily(ROBOT, n_samples=2000)
    batch = family.trajectories(TABLE3[:2])
    dt = family.period / family.n_samples
    dq_num = (np.roll(batch.q, -1, axis=1) - np.roll(batch.q, 1, axis=1)) / (2 * dt)
    np.testing.assert_allclose(dq_num[:, :, :3], batch.dq[:, :, :3], atol=1e-5)


def test_length_unit_is_applied_once():
    mm = PaperArmFamily(ROBOT, n_samples=50).trajectories(TABLE3[:2])
    m = PaperArmFamily(ROBOT, n_samples=50, length_unit=1.0).trajectories(TABLE3[:2] * 1e-3)
    np.testing.assert_allclose(m.q, mm.q, atol=1e-12)


def test_unreachable_circle_flagged_not_nan():
    family = PaperArmFamily(ROBOT, n_samples=50, length_unit=1.0)
    x = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.3]])  # 5 m away
    batch = family.trajectories(x)
    assert np.all(np.isfinite(batch.q))
    assert batch.violations.as_dict(0)["reachability"] > 1.0
    with pytest.raises(ValueError, match="bounds"):
        PaperArmFamily(ROBOT, bounds=np.zeros((3, 2)))
