"""The payload's calibrated σ: the block bootstrap of ``ident payload``'s WLS estimate.

References: the payload the torques were computed with (Pinocchio RNEA of the arm with the
payload added to its last body), AR(1) torque noise of known correlation (the ordinary σ is
too small by about ``sqrt((1 + rho) / (1 - rho))`` on slowly varying rows), and the reduced
normal equations of the same rows (the blocks must add up to them).
"""

import numpy as np
import pinocchio as pin
import pytest
from robots import UR5_URDF

from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameters import parameters_from_model
from ident.excitation.fourier import fourier_series
from ident.identify.config import ModelConfig, PreprocessConfig
from ident.identify.estimation import preprocess
from ident.identify.payload.payload import (
    PayloadColumns,
    block_length,
    decimated_samples,
    estimate_payload,
    merge_blocks,
    payload_rows,
)
from ident.measure.logs import RobotLog
from ident.model import Robot

PHI = pin.Inertia(2.5, np.array([-0.03, 0.02, 0.08]), np.diag([0.01, 0.012, 0.008]))
FS = 100.0  # [Hz] no filter, no decimation: the rows are the samples
RHO = 0.8  # AR(1) coefficient of the torque noise
PP = PreprocessConfig(lowpass=None, decimation=[], trim_samples=2, chunk_samples=700)
NO_EXTRAS = ModelConfig(viscous=False, coulomb=False, offset=False, rotor_inertia=False)


@pytest.fixture(scope="module")
def setup():
    """UR5, the payload columns, a 30 s motion and its noise-free torques with the payload."""
    robot = Robot.from_urdf(UR5_URDF)
    model = robot.model
    t = np.arange(int(30 * FS)) / FS
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-0.3, 0.3, (2, 1, model.nv, 4))
    q0 = np.array([0.0, -1.57, 1.0, -0.5, 0.5, 0.0])
    q = fourier_series(t, a, b, q0[None, :], 2 * np.pi / 15.0)[0][0]
    dq, ddq, _ = preprocess.differentiate(q, FS)  # what the pipeline differentiates
    loaded = model.copy()
    loaded.inertias[model.njoints - 1] = loaded.inertias[model.njoints - 1] + PHI
    data = loaded.createData()
    tau = np.array([pin.rnea(loaded, data, *s) for s in zip(q, dq, ddq, strict=True)])
    columns = PayloadColumns(
        chain_from_model(model), NO_EXTRAS.extra_terms(model.nv, "test"),
        parameters_from_model(model),
    )  # fmt: skip
    sigma = 0.01 * np.sqrt(np.mean(tau**2, axis=0))
    return model, t, q, tau, columns, sigma


def ar1(rng, n, sigma, rho=RHO):
    """AR(1) noise of stationary standard deviation ``sigma`` (nv,), shape (n, nv)."""
    e = rng.normal(size=(n, sigma.size)) * np.sqrt(1 - rho**2)
    e[0] /= np.sqrt(1 - rho**2)
    for k in range(1, n):
        e[k] += rho * e[k - 1]
    return e * sigma


def log_of(model, t, q, tau, segments=None):
    names = tuple(model.names[1:])
    return RobotLog(t=t, q=q, tau=tau, sampling_rate_hz=FS, joint_names=names,
                    segments=segments or ((0, t.size),))  # fmt: skip


def estimate(setup, tau, segments=None, pp=PP):
    model, t, q, _, columns, _ = setup
    log = log_of(model, t, q, tau, segments)
    red, blocks = payload_rows(log, pp, columns, block_length(decimated_samples(log, pp)))
    return estimate_payload(red, (), method="wls", blocks=blocks), blocks, red


def test_blocks_add_up_to_the_rows_and_stop_at_chunk_and_segment_boundaries(setup):
    """The per-joint blocks sum to the reduced normal equations (``R_j^T R_j``, ``R_j^T z_j``),
    and their count is that of blocks restarted at every chunk and segment (a block across a
    boundary, or a lost chunk, fails)."""
    model, t, q, tau, columns, _ = setup
    segments = ((0, 1300), (1300, t.size))
    result, blocks, red = estimate(setup, tau, segments)
    step = blocks[0].block_samples
    assert step == block_length(sum(b - a - 4 for a, b in segments)) == 2  # 2992 / 2048
    expected = 0
    for a, b in segments:
        n = b - a - 4
        chunks = [min(700, n - s) for s in range(0, n, 700)]
        expected += sum(-(-c // step) for c in chunks)
    assert all(b.n_blocks == expected for b in blocks)
    for j, b in enumerate(blocks):
        np.testing.assert_allclose(b.A.sum(0), red.R[j].T @ red.R[j], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(b.c.sum(0), red.R[j].T @ red.z[j], rtol=1e-9, atol=1e-9)
    # a second log's blocks follow the first's
    both = merge_blocks(blocks, blocks)
    assert both[0].n_blocks == 2 * expected
    # noise-free rows: the estimate is the payload, the bootstrap reported
    np.testing.assert_allclose(result.phi, PHI.toDynamicParameters(), rtol=1e-5, atol=1e-6)
    assert result.std_method == "bootstrap"
    assert result.std_note == ""
    np.testing.assert_allclose(result.uncertainty.x_blocks, result.wls.x, rtol=1e-6, atol=1e-9)


def test_bootstrap_sigma_covers_ar1_noise_where_the_ordinary_does_not(setup):
    """20 seeds of AR(1) noise (rho 0.8): the bootstrap's 95 % intervals of the mass and
    centre of mass hold the truth >= 85 % of the time, the ordinary ones < 75 %; the bootstrap
    σ is about ``sqrt((1 + rho) / (1 - rho)) = 3`` ordinary σ (measured: 94 %, 46 %, 2.9;
    keeping the ordinary σ, or blocks without WLS's joint weights, fails)."""
    model, t, q, tau, _, sigma = setup
    inside = {"bootstrap": [], "ordinary": []}
    ratios = []
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        result, _, _ = estimate(setup, tau + ar1(rng, t.size, sigma))
        truth_mass, truth_com = 2.5, np.array([-0.03, 0.02, 0.08])
        mass_iv, com_iv = result.intervals()
        inside["bootstrap"] += [mass_iv[0] <= truth_mass <= mass_iv[1]]
        inside["bootstrap"] += list((com_iv[:, 0] <= truth_com) & (truth_com <= com_iv[:, 1]))
        errors = np.abs(np.r_[result.mass - truth_mass, result.com - truth_com])
        ordinary = np.r_[result.ordinary_mass_std, result.ordinary_com_std]
        inside["ordinary"] += list(errors <= 1.96 * ordinary)
        ratios.append(np.r_[result.mass_std, result.com_std] / ordinary)
        assert result.std_method == "bootstrap"
        # the blocks carry WLS's joint weights: their solution is the WLS estimate
        dx = result.uncertainty.x_blocks - result.wls.x
        assert np.all(np.abs(dx) < 1e-6 * result.wls.std)
    ratio = np.median(ratios)
    assert 2.0 < ratio < 4.5, ratio
    assert np.mean(inside["bootstrap"]) >= 0.85, np.mean(inside["bootstrap"])
    assert np.mean(inside["ordinary"]) < 0.75, np.mean(inside["ordinary"])


def test_too_few_blocks_fall_back_to_the_ordinary_sigma_with_a_note(setup):
    """8 samples (8 blocks for 10 unknowns): the ordinary σ, named, with the reason."""
    model, t, q, tau, columns, _ = setup
    pp = PreprocessConfig(lowpass=None, decimation=[], trim_samples=2)
    log = log_of(model, t[:12], q[:12], tau[:12])
    red, blocks = payload_rows(log, pp, columns, block_length(decimated_samples(log, pp)))
    assert blocks[0].n_blocks == 8
    result = estimate_payload(red, (), method="wls", blocks=blocks)
    assert result.std_method == "ordinary"
    assert "too few blocks" in result.std_note
    assert result.mass_std == pytest.approx(result.ordinary_mass_std)
    summary = result.summary()
    assert summary["std_method"] == "ordinary"
    assert "too few blocks" in summary["std_note"]
    assert "bootstrap" not in summary
