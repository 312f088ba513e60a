import importlib.metadata

import numpy as np
import pinocchio as pin
import pytest

from ident.errors import DataError
from ident.measure.ideal import (
    NoiseModel,
    differentiate,
    inverse_dynamics,
    quantize,
    simulate_measurements,
)


@pytest.fixture(scope="module")
def ur5():
    root = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return pin.buildModelFromUrdf(str(root / "ur_description/urdf/ur5_robot.urdf"))


def _states(model, n, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (n, model.nq))
    return q, rng.normal(size=(n, model.nv)), rng.normal(size=(n, model.nv))


def test_inverse_dynamics_matches_mass_matrix_and_bias(ur5):
    q, dq, ddq = _states(ur5, 20)
    tau = inverse_dynamics(ur5, q, dq, ddq)
    data = ur5.createData()
    for k in range(20):
        M = pin.crba(ur5, data, q[k])
        M = np.triu(M) + np.triu(M, 1).T
        expected = M @ ddq[k] + pin.nonLinearEffects(ur5, data, q[k], dq[k])
        np.testing.assert_allclose(tau[k], expected, atol=1e-10)


def test_noise_free_measurements_equal_truth(ur5):
    q, dq, ddq = _states(ur5, 10)
    t = np.arange(10) * 0.01
    m = simulate_measurements(ur5, t, q, dq, ddq, NoiseModel(), rng=1)
    np.testing.assert_array_equal(m.tau, m.tau_true)
    np.testing.assert_array_equal(m.q, q)
    np.testing.assert_array_equal(m.ddq, ddq)
    assert NoiseModel().is_noise_free
    assert not NoiseModel(torque_std=0.1).is_noise_free


def test_torque_noise_has_requested_std_per_joint_and_is_seeded(ur5):
    n = 4000
    q, dq, ddq = _states(ur5, n)
    t = np.arange(n) * 0.01
    std = (0.1, 0.2, 0.3, 0.4, 0.5, 1.0)
    noise = NoiseModel(torque_std=std)
    m = simulate_measurements(ur5, t, q, dq, ddq, noise, rng=3)
    err = m.tau - m.tau_true
    np.testing.assert_allclose(err.std(axis=0), std, rtol=0.05)
    np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=4 * max(std) / np.sqrt(n))
    again = simulate_measurements(ur5, t, q, dq, ddq, noise, rng=3)
    np.testing.assert_array_equal(again.tau, m.tau)
    other = simulate_measurements(ur5, t, q, dq, ddq, noise, rng=4)
    assert not np.array_equal(other.tau, m.tau)


def test_torque_std_length_must_match_joints(ur5):
    q, dq, ddq = _states(ur5, 3)
    with pytest.raises(DataError, match="6 joints"):
        simulate_measurements(ur5, np.arange(3.0), q, dq, ddq, NoiseModel(torque_std=(1.0, 2.0)))
    with pytest.raises(DataError, match="torque_std"):
        NoiseModel(torque_std=-1.0)


def test_quantize_rounds_to_encoder_step():
    step = 2 * np.pi / 4096
    q = np.array([[0.4 * step, 0.6 * step, -1.6 * step]])
    np.testing.assert_allclose(quantize(q, 4096), [[0.0, step, -2 * step]])
    rng = np.random.default_rng(0)
    q = rng.uniform(-3, 3, (100, 3))
    assert np.max(np.abs(quantize(q, 4096) - q)) <= step / 2 + 1e-15


def test_differentiate_is_exact_on_quadratics():
    t = np.linspace(0.0, 2.0, 201)
    a = np.array([0.3, -1.0])
    b = np.array([2.0, 0.5])
    q = a[None, :] * t[:, None] ** 2 + b[None, :] * t[:, None]
    q_out, dq, ddq = differentiate(t, q)
    np.testing.assert_allclose(q_out, q)
    np.testing.assert_allclose(dq, 2 * a[None, :] * t[:, None] + b, atol=1e-10)
    np.testing.assert_allclose(ddq, np.broadcast_to(2 * a, ddq.shape), atol=1e-8)


def test_quantized_sine_differentiation_error_is_bounded_and_filter_helps():
    t = np.arange(0.0, 10.0, 0.01)
    w = 0.6283
    q = np.sin(w * t)[:, None]
    qq = quantize(q, 2**14)
    _, dq_raw, ddq_raw = differentiate(t, qq)
    _, dq_f, ddq_f = differentiate(t, qq, filter_cutoff_hz=2.0)
    inner = slice(100, -100)  # away from the filter's edge transients
    dq_exact = w * np.cos(w * t)[:, None]
    ddq_exact = -(w**2) * np.sin(w * t)[:, None]
    step = 2 * np.pi / 2**14
    assert np.max(np.abs(dq_raw - dq_exact)) <= step / 0.01 + 1e-3
    assert np.max(np.abs(ddq_f - ddq_exact)[inner]) < np.max(np.abs(ddq_raw - ddq_exact)[inner]) / 5


def test_differentiate_rejects_bad_input():
    with pytest.raises(DataError, match="uniformly"):
        differentiate(np.array([0.0, 0.1, 0.3]), np.zeros((3, 1)))
    with pytest.raises(DataError, match="Nyquist"):
        differentiate(np.arange(10) * 0.01, np.zeros((10, 1)), filter_cutoff_hz=60.0)


def test_encoder_measurements_use_quantized_positions(ur5):
    t = np.arange(0.0, 2.0, 0.01)
    q = 0.5 * np.sin(np.outer(t, np.arange(1, 7)))
    dq = 0.5 * np.arange(1, 7) * np.cos(np.outer(t, np.arange(1, 7)))
    ddq = -0.5 * np.arange(1, 7) ** 2 * np.sin(np.outer(t, np.arange(1, 7)))
    m = simulate_measurements(ur5, t, q, dq, ddq, NoiseModel(encoder_counts_per_rev=2**16), rng=0)
    np.testing.assert_allclose(m.q, quantize(q, 2**16))
    assert np.max(np.abs(m.dq - dq)) < 0.05
    np.testing.assert_array_equal(m.tau, m.tau_true)
    with pytest.raises(DataError, match="NaN"):
        simulate_measurements(ur5, t, q * np.nan, dq, ddq, NoiseModel())
