"""Chunked accumulation (ident.identify.estimation.accumulate) at its boundaries.

What a user relies on: cutting a log in chunks changes nothing (chunked normal equations equal
the whole log's for any chunk size, with or without filters); the margins are as long as the
filters' impulse responses (computed here by brute force); the plan covers every decimated
sample once; memory and chunk-size rules are the documented formulas; the report's record
states the counts. (Raised the mutation score of the module; see benchmarks/mutation.py.)
"""

import os
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from robots import random_chain
from scipy import signal

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import ExtraTerms, extra_columns
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import DataError
from ident.identify.config import PreprocessConfig
from ident.identify.estimation import accumulate, log_chunks, preprocess
from ident.identify.estimation.observations import ReducedObservations


def _decay(sos, n=400_000):
    """Brute force: 1 + the last index where |h| exceeds 1e-14 of its peak."""
    x = np.zeros(n)
    x[0] = 1.0
    h = np.abs(signal.sosfilt(sos, x))
    return int(np.flatnonzero(h > 1e-14 * h.max())[-1]) + 1


def test_margins_are_the_filters_impulse_response_lengths():
    fs = 1000.0
    none = PreprocessConfig(lowpass=None, decimation=[])
    assert accumulate.margin_samples(none, fs) == (4, 0)  # np.gradient twice: 4 neighbours
    pp = PreprocessConfig(
        lowpass={"cutoff_hz": 20.0, "order": 4},
        torque_lowpass={"cutoff_hz": 5.0, "order": 2},
        decimation=[1, 5, 3],
    )
    q_sos = signal.butter(4, 20.0, fs=fs, output="sos")
    t_sos = signal.butter(2, 5.0, fs=fs, output="sos")
    sig, dec = accumulate.margin_samples(pp, fs)
    # the longer of the two low-passes (the torques' 5 Hz), both ways, plus the differences
    assert sig == 2 * max(_decay(q_sos), _decay(t_sos)) + 4
    assert _decay(t_sos) > _decay(q_sos)
    # stage 1 (x5) at the trimmed rate, stage 2 (x3) at 1/5 of it: in trimmed samples,
    # rounded up to a multiple of the step 15
    raw = (
        2 * _decay(preprocess.antialias_sos(5))
        + 2
        + 5 * (2 * _decay(preprocess.antialias_sos(3)) + 2)
    )
    assert dec == 15 * int(np.ceil(raw / 15))
    assert dec % 15 == 0
    torque_only = PreprocessConfig(
        lowpass=None, torque_lowpass={"cutoff_hz": 5.0, "order": 2}, decimation=[]
    )
    assert accumulate.margin_samples(torque_only, fs) == (2 * _decay(t_sos) + 4, 0)


def test_plan_covers_every_decimated_sample_once():
    pp = PreprocessConfig(lowpass=None, trim_samples=3, decimation=[4, 3])
    plan = accumulate.make_plan(1000, pp, 100.0, chunk_samples=250)
    # 994 trimmed samples -> ceil(994 / 4) = 249 -> ceil(249 / 3) = 83 decimated
    assert (plan.n_samples, plan.n_edge, plan.step, plan.n_decimated) == (1000, 3, 12, 83)
    assert plan.chunk_decimated == 250 // 12
    assert plan.ranges() == [(0, 20), (20, 40), (40, 60), (60, 80), (80, 83)]
    assert plan.ranges(10, 45) == [(10, 30), (30, 45)]
    assert plan.ranges(5, 5) == []
    tiny = accumulate.make_plan(1000, pp, 100.0, chunk_samples=5)  # below one step: 1 each
    assert tiny.chunk_decimated == 1
    assert len(tiny.ranges()) == 83
    with pytest.raises(DataError) as err:
        accumulate.make_plan(6, pp, 100.0, chunk_samples=100)
    assert str(err.value) == "trim_samples = 3 removes all 6 samples."
    assert accumulate.make_plan(7, pp, 100.0, chunk_samples=100).n_decimated == 1


@pytest.fixture(scope="module")
def arm():
    model = random_chain([pin.JointModelRevoluteUnaligned] * 2, seed=5)
    chain = chain_from_model(model)
    terms = ExtraTerms.from_options(2)

    def columns(q, dq, ddq):
        return np.concatenate(
            [joint_torque_regressor(chain, q, dq, ddq), extra_columns(terms, dq, ddq)], axis=2
        )

    fs, n = 200.0, 1500
    rng = np.random.default_rng(2)
    t = np.arange(n) / fs
    q = np.column_stack([np.sin(2 * np.pi * 0.7 * t), np.cos(2 * np.pi * 1.1 * t + 0.3)])
    q = q + 1e-4 * rng.normal(size=q.shape)  # encoder noise: an unfiltered edge would show
    tau = rng.normal(size=(n, 2))
    return columns, q, tau, fs


@pytest.mark.parametrize(
    ("lowpass", "decimation", "chunk_samples"),
    [
        (None, [], 37),  # no filter at all: only the differences' 4-sample margin
        (None, [3], 100),
        ({"cutoff_hz": 15.0}, [], 211),
        ({"cutoff_hz": 15.0}, [2, 2], 64),
        ({"cutoff_hz": 15.0}, [2, 2], 10_000),  # one chunk
    ],
)
def test_chunked_normal_equations_equal_the_whole_log(arm, lowpass, decimation, chunk_samples):
    columns, q, tau, fs = arm
    pp = PreprocessConfig(lowpass=lowpass, trim_samples=5, decimation=decimation)
    whole = accumulate.make_plan(q.shape[0], pp, fs, chunk_samples=10**9)
    (ref,) = accumulate.iter_chunks(whole, q, tau, fs, pp, columns, whole.ranges())
    plan = accumulate.make_plan(q.shape[0], pp, fs, chunk_samples=chunk_samples)
    chunks = list(accumulate.iter_chunks(plan, q, tau, fs, pp, columns, plan.ranges()))
    assert [c.start for c in chunks] == [a for a, _ in plan.ranges()]
    Y = np.concatenate([c.Yb for c in chunks])
    assert Y.shape == ref.Yb.shape
    np.testing.assert_allclose(Y, ref.Yb, rtol=0, atol=1e-9 * np.abs(ref.Yb).max())
    np.testing.assert_allclose(np.concatenate([c.tau for c in chunks]), ref.tau, atol=1e-12)
    # the whole path itself: filter, differences, trim, decimate on the whole log
    qf = q if lowpass is None else preprocess.lowpass(q, fs, 15.0, 4)[0]
    dq, ddq, _ = preprocess.differentiate(qf, fs)
    (qf, dq, ddq, tf), _ = preprocess.trim([qf, dq, ddq, tau], 5)
    (tau_d, Y_d), _, _ = preprocess.decimate([tf, columns(qf, dq, ddq)], decimation, fs)
    np.testing.assert_allclose(ref.Yb, Y_d, rtol=0, atol=1e-12 * np.abs(Y_d).max())
    np.testing.assert_allclose(ref.tau, tau_d, atol=1e-12)
    # the normal equations accumulated chunk by chunk equal the whole log's
    keep = np.ones(ref.tau.shape, bool)
    red = None
    for c in chunks:
        r = accumulate.reduce_chunk(c.Yb, c.tau, np.ones(c.tau.shape, bool))
        red = r if red is None else red.merge(r)
    dense = accumulate.reduce_chunk(ref.Yb, ref.tau, keep)
    x = np.random.default_rng(0).normal(size=ref.Yb.shape[2])
    np.testing.assert_allclose(red.residual_ss(x), dense.residual_ss(x), rtol=1e-9)
    np.testing.assert_allclose(red.yty, dense.yty, rtol=1e-12)
    np.testing.assert_array_equal(red.n_rows, [ref.tau.shape[0]] * 2)


def test_reduce_chunk_per_joint_rows_counts_and_zero_columns():
    rng = np.random.default_rng(3)
    n, nv, p = 40, 2, 4
    Yb = rng.normal(size=(n, nv, p))
    Yb[:, 1, :2] = 0.0  # joint 2 carries no term of the first two columns
    tau = rng.normal(size=(n, nv))
    keep = np.ones((n, nv), bool)
    keep[::4, 0] = False
    red = accumulate.reduce_chunk(Yb, tau, keep)
    np.testing.assert_array_equal(red.n_rows, [30, 40])
    np.testing.assert_allclose(
        red.yty, [tau[keep[:, 0], 0] @ tau[keep[:, 0], 0], tau[:, 1] @ tau[:, 1]]
    )
    for j in range(nv):
        W, y = Yb[keep[:, j], j], tau[keep[:, j], j]
        # R^T R = W^T W and R^T z = W^T y (the normal equations), rho the LS residual
        np.testing.assert_allclose(red.R[j].T @ red.R[j], W.T @ W, atol=1e-10)
        np.testing.assert_allclose(red.R[j].T @ red.z[j], W.T @ y, atol=1e-10)
        x, *_ = np.linalg.lstsq(W, y, rcond=None)
        assert red.rho[j] == pytest.approx(np.sum((y - W @ x) ** 2), rel=1e-8)
    np.testing.assert_array_equal(red.R[1][:, :2], 0.0)


def test_reduce_chunk_with_few_or_no_rows():
    rng = np.random.default_rng(4)
    Yb = rng.normal(size=(3, 1, 3))
    tau = rng.normal(size=(3, 1))
    none = accumulate.reduce_chunk(Yb, tau, np.zeros((3, 1), bool))
    assert none.n_rows.tolist() == [0]
    assert not none.R.any()
    assert not none.z.any()
    assert (none.rho[0], none.yty[0]) == (0.0, 0.0)
    # 3 rows for 3 columns (m <= n + 1): exact, no residual; the normal equations hold
    red = accumulate.reduce_chunk(Yb, tau, np.ones((3, 1), bool))
    W = Yb[:, 0]
    np.testing.assert_allclose(red.R[0].T @ red.R[0], W.T @ W, atol=1e-12)
    np.testing.assert_allclose(red.R[0].T @ red.z[0], W.T @ tau[:, 0], atol=1e-12)
    assert red.rho[0] == pytest.approx(0.0, abs=1e-20)


def test_reduce_chunk_of_a_rank_deficient_chunk_falls_back_to_householder():
    # a chunk whose rows do not excite a column pair (equal columns): the Gram matrix is
    # singular, CholeskyQR fails; the Householder reduction keeps the normal equations
    rng = np.random.default_rng(6)
    W = rng.normal(size=(50, 1, 3))
    W[:, 0, 2] = W[:, 0, 1]
    tau = rng.normal(size=(50, 1))
    red = accumulate.reduce_chunk(W, tau, np.ones((50, 1), bool))
    ref = ReducedObservations.from_rows(W[:, 0], tau[:, 0], np.zeros(50, np.int64), 1)
    x = rng.normal(size=3)
    np.testing.assert_allclose(red.residual_ss(x), ref.residual_ss(x), rtol=1e-10)
    np.testing.assert_allclose(red.R[0].T @ red.R[0], W[:, 0].T @ W[:, 0], atol=1e-10)


def test_memory_and_chunk_size_rules():
    assert accumulate.regressor_bytes(1000, 6, 50) == 8 * 1000 * 6 * 50 * 3
    workers = log_chunks.local_workers()
    assert workers == max(1, min(4, len(os.sched_getaffinity(0))))
    # a chunk: 4 position-sized arrays per raw sample, the decimated rows twice, and blocks
    row = 8.0 * 6 * (60 + 2)
    assert log_chunks.chunk_bytes(1000, 6, 60, 20) == pytest.approx(
        1000 * (8 * 4 * 6 + 2 * row / 20) + 4 * accumulate.ROW_BLOCK * row
    )
    per_sample = 8 * 4 * 6 + 2 * row / 20
    extent = int(log_chunks.CHUNK_BUDGET_BYTES // per_sample)
    # the budget holds the chunk with its margins on both sides
    assert log_chunks.default_chunk_samples((10, 20), 6, 60, 20) == extent - 60
    # the margins set a floor: never more margin than chunk
    assert log_chunks.default_chunk_samples((10**6, 10**6), 6, 60, 20) == 2 * 10**6
    # a huge regressor row: at least 1024 samples
    assert log_chunks.default_chunk_samples((1, 1), 7, 10**7) == 1024
    # without decimation the rows are kept at full rate: smaller chunks
    assert log_chunks.default_chunk_samples((0, 0), 6, 60) < extent / 5


def _log(n, nv=2, segments=None):
    return SimpleNamespace(q=np.zeros((n, nv)), segments=segments or [(0, n)])


def test_use_chunks_follows_the_setting_the_segments_and_the_memory_bound():
    always = PreprocessConfig(chunked="always")
    never = PreprocessConfig(chunked="never", max_regressor_mb=1e-6)
    assert log_chunks.use_chunks(_log(100), always, 10)
    assert not log_chunks.use_chunks(_log(100, segments=[(0, 50), (50, 100)]), never, 10)
    auto = PreprocessConfig(max_regressor_mb=1.0)  # 2^20 bytes
    assert log_chunks.use_chunks(_log(100, segments=[(0, 50), (50, 100)]), auto, 10)
    # 8 n nv c 3 bytes against the bound: 192 000 bytes (n = 1000) is not above it
    at_bound = PreprocessConfig(max_regressor_mb=192_000 / 2**20)
    assert not log_chunks.use_chunks(_log(1000), at_bound, 4)
    assert log_chunks.use_chunks(_log(1001), at_bound, 4)


def test_chunk_record_states_the_counts():
    seg_a, seg_b = np.zeros(3), np.zeros(4)
    chunked = SimpleNamespace(
        fit_tasks=[SimpleNamespace(q=seg_a)] * 3 + [SimpleNamespace(q=seg_b)] * 2,
        val_tasks=[SimpleNamespace(q=seg_b)] * 2,
        chunk_samples=5000,
        margins=(120, 45),
        skipped=(),
    )
    red = SimpleNamespace(n_rows=np.array([100, 90]))
    record = log_chunks.chunk_record(chunked, red)
    assert record == {
        "step": "chunked accumulation",
        "detail": "2 segment(s) in 7 chunks of at most 5000 raw samples (+ margins 120 raw / "
        "45 trimmed samples for the filters); identification rows reduced per joint chunk by "
        "chunk (Cholesky of the scaled Gram matrix where its condition number is at most 1000, "
        "QR elsewhere): 190 rows, no per-sample regressor kept",
    }
    skipped = SimpleNamespace(**{**vars(chunked), "skipped": ("0.1 s (short)", "0.2 s (x)")})
    assert log_chunks.chunk_record(skipped, red)["detail"].endswith(
        "no per-sample regressor kept; skipped too-short segment(s): 0.1 s (short); 0.2 s (x)"
    )
