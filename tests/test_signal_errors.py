"""Delay, gain and offset of the measured torque: the MuJoCo source injects them, we find them.

References: the values given to the simulator, and its exact states for the gains.
"""

import numpy as np
import pytest
from robots import UR5_URDF
from test_mujoco_sim import fourier_reference

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model, model_regressors
from ident.errors import DataError
from ident.identify.corrections.signal_errors import estimate_delay, estimate_gains
from ident.identify.estimation import preprocess
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate
from ident.model import Robot

GAINS = np.array([1.0, 1.0, 1.03, 0.97, 1.03, 0.97])
OFFSETS = np.array([0.3, -0.2, 0.1, 0.05, -0.05, 0.02])


@pytest.fixture(scope="module")
def ur5():
    robot = Robot.from_urdf(UR5_URDF)
    terms = ExtraTerms.from_options(robot.nv)  # rotor inertia, viscous, Coulomb, offset
    return robot, terms, build_parameter_model(robot.model, terms), chain_from_model(robot.model)


def base_regressor(ur5, q, dq, ddq):
    _, terms, pm, chain = ur5
    Yr, Ye = model_regressors(chain, terms, q, dq, ddq)
    return pm.columns(Yr, Ye, np.arange(len(pm.names)))[:, :, list(pm.base.independent)]


def run(ur5, period, signals, *, counts=None):
    t, q, dq, ddq = fourier_reference(ur5[0], period=period, seed=2)
    config = {
        "armature": 0.1,
        "friction": {"viscous": 0.5, "coulomb": 1.0},
        "signals": signals,
        "n_periods": 1,
        "encoder_counts_per_rev": counts,
    }
    return simulate(ur5[0], t, q, dq, ddq, load_mujoco_measurement(config), rng=0)


def test_a_5_ms_delay_is_recovered_to_1_ms_from_the_measured_log(ur5):
    """Encoder positions (2^19 counts), 1 % torque noise, low-pass and central differences."""
    log = run(ur5, 2.0, {"delay_s": 0.005}, counts=2**19)
    # the source's delay: 5 samples at 1 kHz (interpolation round-off only)
    scale = np.abs(log.tau_cmd).max()
    np.testing.assert_allclose(log.tau_measured[5:], log.tau_cmd[:-5], rtol=0, atol=1e-10 * scale)
    rng = np.random.default_rng(1)
    noise = 0.01 * np.sqrt(np.mean(log.tau_cmd**2, axis=0))
    tau = log.tau_measured + noise * rng.standard_normal(log.tau_cmd.shape)
    fs = log.rate_hz
    q, _ = preprocess.lowpass(log.q, fs, 30.0)
    tau, _ = preprocess.lowpass(tau, fs, 30.0, what="tau")
    dq, ddq, _ = preprocess.differentiate(q, fs)
    inner = slice(100, -100)  # the filter's edge transients
    Y = base_regressor(ur5, q, dq, ddq)[inner]
    found = estimate_delay(log.t[inner], tau[inner], Y, max_delay_s=0.02)
    assert found.delay_s == pytest.approx(0.005, abs=0.001)
    # the residual has its minimum there: the scan is worse 5 ms away on either side
    assert found.residual < np.interp(
        [found.delay_s - 0.005], found.scan_delays_s, found.scan_residuals
    )
    with pytest.raises(DataError, match="max_delay_s"):
        estimate_delay(log.t, tau, Y, max_delay_s=1.0)


def test_gains_and_offsets_are_recovered_with_one_joint_known(ur5):
    """Exact states: every gain to 1e-8 with the shoulder's gain known (or the base's), and
    the offsets as ``g_j theta_off_j``."""
    log = run(ur5, 1.0, {"torque_gain": GAINS.tolist(), "torque_offset": OFFSETS.tolist()})
    Y = base_regressor(ur5, log.q_true, log.dq_true, log.ddq_true)
    for reference in (1, 0):
        found = estimate_gains(
            Y, log.tau_measured, reference_joint=reference, reference_gain=GAINS[reference]
        )
        np.testing.assert_allclose(found.gains, GAINS, rtol=1e-8)
    names = ur5[2].base_names
    offsets = [found.theta[names.index(f"off{j + 1}")] * found.gains[j] for j in range(6)]
    np.testing.assert_allclose(offsets, OFFSETS, rtol=1e-7)
    # a subset of joints: the others are NaN, the elbow's gain found against the shoulder
    elbow = estimate_gains(Y, log.tau_measured, reference_joint=1, joints=[2])
    assert elbow.gains[2] == pytest.approx(GAINS[2], rel=1e-8)
    assert np.isnan(elbow.gains[[0, 3, 4, 5]]).all()
