"""Chunked identification: chunks equal the whole-log processing; the reduction's estimate
equals the dense least squares; TX40 by chunks equals TX40 in memory."""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import random_chain

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms, extra_columns
from ident.dynamics.regressor import joint_torque_regressor
from ident.identify.config import PreprocessConfig, load_identify_config
from ident.identify.estimation import accumulate, preprocess
from ident.identify.estimation.essential import essential_parameters
from ident.identify.estimation.estimate import least_squares
from ident.identify.estimation.observations import ReducedObservations

ROOT = Path(__file__).resolve().parents[1]


def _signals(n, nv, fs, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    f = rng.uniform(0.2, 2.0, size=(3, nv))
    q = sum(np.sin(2 * np.pi * f[k] * t[:, None] + k) for k in range(3))
    tau = rng.normal(size=(n, nv))
    return q, tau


@pytest.mark.parametrize("decimation", [[], [4], [5, 3]])
def test_chunks_equal_the_whole_log(decimation):
    fs, n = 500.0, 6000
    model = random_chain([pin.JointModelRevoluteUnaligned] * 3, seed=3)
    chain = chain_from_model(model)
    terms = ExtraTerms.from_options(3)
    pp = PreprocessConfig(
        lowpass={"cutoff_hz": 20.0, "order": 4},
        torque_lowpass={"cutoff_hz": 40.0, "order": 2},
        trim_samples=7,
        decimation=decimation,
    )
    q, tau = _signals(n, 3, fs)
    # whole-log path, as ident.identify.pipeline.real does it
    qf, _ = preprocess.lowpass(q, fs, 20.0, 4)
    tf, _ = preprocess.lowpass(tau, fs, 40.0, 2)
    dq, ddq, _ = preprocess.differentiate(qf, fs)
    (qf, dq, ddq, tf), _ = preprocess.trim([qf, dq, ddq, tf], 7)
    Y = np.concatenate(
        [joint_torque_regressor(chain, qf, dq, ddq), extra_columns(terms, dq, ddq)], axis=2
    )
    (tau_d, Y_d, dq_d), _, _ = preprocess.decimate([tf, Y, dq], decimation, fs)

    def columns(q, dq, ddq):
        return np.concatenate(
            [joint_torque_regressor(chain, q, dq, ddq), extra_columns(terms, dq, ddq)], axis=2
        )

    plan = accumulate.make_plan(n, pp, fs, chunk_samples=700)
    assert plan.n_decimated == tau_d.shape[0]
    chunks = list(accumulate.iter_chunks(plan, q, tau, fs, pp, columns, plan.ranges()))
    assert len(chunks) > 3
    Yc = np.concatenate([c.Yb for c in chunks])
    scale = np.abs(Y_d).max()
    np.testing.assert_allclose(Yc, Y_d, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.concatenate([c.tau for c in chunks]), tau_d, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([c.dq for c in chunks]), dq_d, atol=1e-12)


def _problem(seed=1, n=400, g=3, p=6):
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(n, g, p)) * np.logspace(0, 3, p)
    x = rng.normal(size=p)
    noise = rng.normal(size=(n, g)) * [0.1, 1.0, 3.0][:g]
    tau = W @ x + noise
    keep = rng.uniform(size=(n, g)) > 0.2
    return W, tau, keep


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_estimate_from_reduction_equals_least_squares(method):
    W, tau, keep = _problem()
    names = [f"p{k}" for k in range(W.shape[2])]
    groups = np.broadcast_to(np.arange(3), keep.shape)[keep]
    dense = least_squares(W[keep], tau[keep], names, method=method, groups=groups)
    red = accumulate.reduce_chunk(W[:150], tau[:150], keep[:150]).merge(
        accumulate.reduce_chunk(W[150:], tau[150:], keep[150:])
    )
    ours = accumulate.estimate_reduced(red, names, method=method)
    np.testing.assert_allclose(ours.x, dense.x, rtol=1e-10)
    np.testing.assert_allclose(ours.std, dense.std, rtol=1e-9)
    np.testing.assert_allclose(ours.residual_rms, dense.residual_rms, rtol=1e-9)
    np.testing.assert_allclose(ours.sigma, dense.sigma, rtol=1e-9)
    assert ours.relative_residual == pytest.approx(dense.relative_residual, rel=1e-10)
    assert ours.condition_number == pytest.approx(dense.condition_number, rel=1e-8)
    assert ours.n_observations == dense.n_observations


def test_chunk_reduction_equals_householder():
    W, tau, keep = _problem(seed=2)
    ours = accumulate.reduce_chunk(W, tau, keep)
    groups = np.broadcast_to(np.arange(3), keep.shape)[keep]
    ref = ReducedObservations.from_rows(W[keep], tau[keep], groups, 3)
    x = np.random.default_rng(0).normal(size=W.shape[2])
    np.testing.assert_allclose(ours.residual_ss(x), ref.residual_ss(x), rtol=1e-10)
    np.testing.assert_allclose(ours.rho, ref.rho, rtol=1e-8)


def test_essential_from_reduction_equals_dense():
    W, tau, keep = _problem(seed=4, p=8)
    W[:, :, 7] *= 1e-4  # a badly determined parameter that the reduction drops
    names = tuple(f"p{k}" for k in range(8))
    groups = np.broadcast_to(np.arange(3), keep.shape)[keep]
    dense = essential_parameters(W[keep], tau[keep], names, method="wls", groups=groups)
    red = accumulate.reduce_chunk(W, tau, keep)
    ours = accumulate.essential_reduced(
        red, names, method="wls", max_relative_std_pct=10.0, max_residual_increase=0.05
    )
    assert ours.kept == dense.kept
    np.testing.assert_allclose(ours.estimate.x, dense.estimate.x, rtol=1e-9)


@pytest.mark.slow
def test_tx40_chunked_equals_in_memory():
    from ident.identify.pipeline.real import identify

    cfg = load_identify_config(ROOT / "configs" / "tx40.yaml")
    # 12 000 samples in 5 chunks (as the constrained case below): the same number of chunk
    # boundaries as 30 000 in chunks of 6 000, each chunk still longer than the filter margins
    # No consistent model: it is solved from the estimate and normal equations compared here
    # (the constrained case below compares a consistent estimate); its 30 bootstrap re-solves
    # of 6 links were most of the test's CPU
    cfg = cfg.model_copy(
        update={
            "log": cfg.log.model_copy(update={"max_samples": 12000}),
            "urdf_update": cfg.urdf_update.model_copy(update={"model": "none"}),
        }
    )
    a = identify(cfg)
    pp = cfg.preprocess.model_copy(update={"chunked": "always", "chunk_samples": 2500})
    b = identify(cfg.model_copy(update={"preprocess": pp}))
    assert any(r["step"] == "chunked accumulation" for r in b.records)
    np.testing.assert_allclose(b.estimate.x, a.estimate.x, rtol=1e-9)
    np.testing.assert_allclose(b.estimate.std, a.estimate.std, rtol=1e-9)
    assert b.essential.kept == a.essential.kept
    for label in ("identified", "essential", "URDF nominal"):
        np.testing.assert_allclose(
            b.predictions[label].tau_pred, a.predictions[label].tau_pred, rtol=0, atol=1e-9
        )


def test_dask_scheduler_gives_the_local_result():
    distributed = pytest.importorskip("distributed")
    cfg = load_identify_config(ROOT / "configs" / "examples" / "wide-csv.yaml")
    pp = cfg.preprocess.model_copy(update={"chunked": "always", "chunk_samples": 300})
    cfg = cfg.model_copy(update={"preprocess": pp})
    from ident.identify.pipeline.real import identify

    local = identify(cfg)
    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None) as lc:
        remote = identify(cfg, scheduler=lc.scheduler_address)
    np.testing.assert_array_equal(remote.estimate.x, local.estimate.x)
    np.testing.assert_array_equal(
        remote.predictions["identified"].tau_pred, local.predictions["identified"].tau_pred
    )


def test_segments_of_one_log_merge(tmp_path):
    # a gap splits the example log in two segments: identified together, by chunks
    import yaml

    data = (ROOT / "data" / "examples" / "wide.csv").read_text().splitlines()
    header, rows = data[0], data[1:]
    shifted = [
        ",".join([f"{float(r.split(',')[0]) + (5.0 if k >= 800 else 0.0):.7g}", *r.split(",")[1:]])
        for k, r in enumerate(rows)
    ]
    (tmp_path / "gap.csv").write_text("\n".join([header, *shifted]) + "\n")
    cfg = yaml.safe_load((ROOT / "configs" / "examples" / "wide-jitter.yaml").read_text())
    cfg["robot"]["urdf"] = str(ROOT / "data" / "examples" / "arm3.urdf")
    cfg["log"]["path"] = str(tmp_path / "gap.csv")
    (tmp_path / "gap.yaml").write_text(yaml.safe_dump(cfg))
    from ident.identify.pipeline.real import identify

    result = identify(load_identify_config(tmp_path / "gap.yaml"))
    assert result.log.segments == ((0, 800), (800, 1600))
    assert any(r["step"] == "chunked accumulation" for r in result.records)
    assert result.warnings == ()
    x = dict(zip(result.estimate.names, result.estimate.x, strict=True))
    assert x["fv1"] == pytest.approx(0.8, rel=0.06)


@pytest.mark.slow
def test_long_log_benchmark_short_version():
    import os
    import re
    import subprocess
    import sys

    # 250 Hz: 1 500 samples per 0.1 min case; the chunked-vs-in-memory comparison on 0.4 min
    # (6 000 samples: still more than one chunk of 4 096)
    args = ["--rate", "250", "--minutes", "0.1", "--per-sample", "300"]
    args += ["--compare-minutes", "0.4"]
    # the MCAP and CSV cases skipped: three more ident identify processes (about 45 s of CPU)
    # for readers whose long files tests/test_readers.py and the examples already read
    args += ["--mcap-minutes", "0", "--csv-minutes", "0"]
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_identify_long.py"), *args],
        capture_output=True,
        text=True,
        env=os.environ,
        check=False,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr
    assert "ident identify (chunked): wall" in proc.stdout
    diff = float(re.search(r"difference \(norm\) ([0-9.e+-]+)", proc.stdout).group(1))
    assert diff < 1e-9


@pytest.mark.slow
def test_tx40_constrained_estimate_by_chunks_equals_in_memory():
    # tx40-consistent (lmi): the chunked path (several logs, long logs) gives the same
    # consistent estimate, its held-out prediction and the whole-model URDF's parameters
    from ident.identify.pipeline.real import identify

    cfg = load_identify_config(ROOT / "configs" / "tx40-consistent.yaml")
    estimation = cfg.estimation.model_copy(
        update={"regularization": cfg.estimation.regularization.model_copy(update={"weight": 0.1})}
    )
    cfg = cfg.model_copy(
        update={
            "log": cfg.log.model_copy(update={"max_samples": 12000}),
            "estimation": estimation,
            # the model file's bootstrap intervals (30 re-solves) are not compared: the
            # consistent estimate is, and the model is written from it
            "urdf_update": cfg.urdf_update.model_copy(update={"model_bootstrap": 0}),
        }
    )
    a = identify(cfg)
    pp = cfg.preprocess.model_copy(update={"chunked": "always", "chunk_samples": 2500})
    b = identify(cfg.model_copy(update={"preprocess": pp}))
    assert any(r["step"] == "chunked accumulation" for r in b.records)
    assert b.consistent.constrained.consistent
    assert not b.consistent.estimates["wls"].consistent  # the constraints bind here
    theta_a, theta_b = a.consistent.constrained.theta, b.consistent.constrained.theta
    # measured: 5e-11 of the largest parameter, 8e-10 N*m
    np.testing.assert_allclose(theta_b, theta_a, rtol=0, atol=1e-8 * np.abs(theta_a).max())
    np.testing.assert_allclose(
        b.predictions["lmi"].tau_pred, a.predictions["lmi"].tau_pred, rtol=0, atol=1e-7
    )


def test_a_column_zero_at_first_is_filtered_once_it_moves():
    """Columns zero in the first block are left out of the filtering; one that turns nonzero
    later (a joint held, then moving) must still come out as the whole log's decimation."""
    fs, n = 1000.0, 30_000
    rng = np.random.default_rng(7)
    tau = rng.normal(size=(n, 2))
    dq = rng.normal(size=(n, 2))
    late = np.where(np.arange(n) > 2 * accumulate.ROW_BLOCK, np.sin(np.arange(n) / 50.0), 0.0)

    def columns(q, dq, ddq):
        k = q[:, 0].astype(int)  # the sample index, carried in q
        Y = np.zeros((k.size, 2, 3))
        Y[:, 0, 0] = np.cos(k / 30.0)
        Y[:, 1, 2] = late[k]  # zero in the first blocks, then not
        return Y

    q = np.repeat(np.arange(n, dtype=float)[:, None], 2, axis=1)
    tau_d, Yb_d, dq_d = accumulate.decimated_rows(columns, q, dq, dq, tau, [10, 2])
    (t_ref, Y_ref, dq_ref), _, _ = preprocess.decimate([tau, columns(q, dq, dq), dq], [10, 2], fs)
    assert np.abs(Y_ref[:, 1, 2]).max() > 0.5
    np.testing.assert_allclose(Yb_d, Y_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(tau_d, t_ref, rtol=0, atol=1e-13 * np.abs(t_ref).max())
    np.testing.assert_allclose(dq_d, dq_ref, rtol=0, atol=1e-13 * np.abs(dq_ref).max())
    assert not Yb_d[:, 0, 1].any()  # a column zero throughout stays zero
