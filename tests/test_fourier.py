import numpy as np
import pytest
from robots import ur5_with_limits

from ident.excitation.fourier import JointFourierFamily, fourier_series


@pytest.fixture(scope="module")
def family():
    return JointFourierFamily(
        ur5_with_limits(), [1, "wrist_1_joint", 4], n_harmonics=4, n_samples=400
    )


def _design(family, n=5, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(family.bounds[:, 0], family.bounds[:, 1], (n, family.bounds.shape[0]))


def test_variables_and_bounds(family):
    assert family.moving_joints == (1, 3, 4)
    assert len(family.variable_names) == 3 * (2 * 4 - 1)
    assert family.variable_names[0] == "q0[shoulder_lift_joint]"
    assert family.bounds.shape == (21, 2)
    assert np.all(family.bounds[:, 0] < family.bounds[:, 1])


def test_rest_at_both_ends_and_periodic(family):
    a, b, q0 = family.coefficients(_design(family))
    q, dq, ddq = fourier_series(np.array([0.0, family.period]), a, b, q0, family.base_frequency)
    np.testing.assert_allclose(dq, 0.0, atol=1e-12)
    np.testing.assert_allclose(ddq, 0.0, atol=1e-12)
    np.testing.assert_allclose(q[:, 1], q[:, 0], atol=1e-12)
    batch = family.trajectories(_design(family))
    np.testing.assert_allclose(batch.dq[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(batch.ddq[:, 0], 0.0, atol=1e-12)
    continuity = [i for i, n in enumerate(batch.violations.names) if n.startswith("continuity")]
    assert np.all(batch.violations.values[:, continuity] == 0.0)


def test_derivatives_match_finite_differences(family):
    a, b, q0 = family.coefficients(_design(family, 2))
    t = np.linspace(0.3, 9.1, 7)
    h = 1e-5
    q, dq, ddq = fourier_series(t, a, b, q0, family.base_frequency)
    qp, dqp, _ = fourier_series(t + h, a, b, q0, family.base_frequency)
    qm, dqm, _ = fourier_series(t - h, a, b, q0, family.base_frequency)
    np.testing.assert_allclose(dq, (qp - qm) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(ddq, (dqp - dqm) / (2 * h), atol=1e-7)


def test_held_joints_constant_and_shapes(family):
    x = _design(family, 3)
    batch = family.trajectories(x)
    assert batch.q.shape == (3, 400, 6)
    assert batch.t.shape == (400,)
    assert batch.t[-1] < family.period
    for j in (0, 2, 5):
        assert np.all(batch.q[:, :, j] == family.held_positions[j])
        assert np.all(batch.dq[:, :, j] == 0.0)
    single = family.trajectories(x[1])
    np.testing.assert_array_equal(single.q[0], batch.q[1])
    traj = batch.particle(2)
    np.testing.assert_array_equal(traj.q, batch.q[2])


def test_limit_violations_flagged(family):
    x = _design(family, 1)
    x[0, 1:7] = family.bounds[1:7, 1] * 4  # amplitudes beyond the box: too fast
    batch = family.trajectories(x)
    assert not batch.violations.feasible()[0]
    assert batch.violations.as_dict(0)["velocity:shoulder_lift_joint"] > 0.0


def test_invalid_arguments():
    robot = ur5_with_limits()
    with pytest.raises(ValueError, match="n_harmonics"):
        JointFourierFamily(robot, [0], n_harmonics=1)
    with pytest.raises(ValueError, match="unknown joint"):
        JointFourierFamily(robot, ["nope"])
